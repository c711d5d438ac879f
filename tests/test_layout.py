"""The architecture the code promises, checked on the source: the simulator state is reached
through its public accessor and every document reference resolves (worlds importing no
estimator: ``tests/envs/worlds/test_no_trackers.py``)."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("envs", "agents", "trackers", "train", "cli", "reproduce")
THEORY = ROOT / "docs" / "theory.md"


def _sources(*folders: str) -> list[Path]:
    return sorted(
        p for d in folders for p in (ROOT / d).rglob("*.py") if "__pycache__" not in p.parts
    )


def _theory_sections() -> set[str]:
    headings = re.findall(r"^#{2,4} (\d+(?:\.\d+)*)\.? ", THEORY.read_text(), flags=re.M)
    return set(headings)


def test_only_the_shells_touch_the_private_simulator_state():
    offenders = [
        str(p.relative_to(ROOT))
        for p in _sources(*PACKAGES, "tests", "benchmarks", "research")
        if "._state" in p.read_text() and "envs/shells" not in p.as_posix()
    ]
    offenders = [o for o in offenders if o != "tests/test_layout.py"]
    assert not offenders, f"use the public simulator_state instead: {offenders}"


def test_no_reference_to_a_document_outside_the_repository():
    files = [
        *_sources(*PACKAGES, "tests", "benchmarks", "research"),
        *(ROOT / "docs").rglob("*.md"),
    ]
    files += [ROOT / "README.md", *(ROOT / "train" / "hyperparams").glob("*.yml")]
    hits = [
        f"{p.relative_to(ROOT)}:{i}"
        for p in files
        if p != Path(__file__).resolve()
        for i, line in enumerate(p.read_text().splitlines(), 1)
        if re.search(r"\bS[P]EC\b", line)
    ]
    assert not hits, f"no retired-spec references; cite docs/theory.md: {hits[:10]}"


def test_every_theory_reference_names_a_section_of_docs_theory():
    sections = _theory_sections()
    assert len(sections) > 20
    files = [
        *_sources(*PACKAGES, "benchmarks", "research"),
        *(ROOT / "docs").rglob("*.md"),
        ROOT / "README.md",
    ]
    missing = []
    for p in files:
        for ref in re.findall(r"theory §(\d+(?:\.\d+)*)(?:[–-](\d+(?:\.\d+)*))?", p.read_text()):
            for end in ref:
                if end and end not in sections:
                    missing.append(f"{p.relative_to(ROOT)}: §{end}")
    assert not missing, missing
