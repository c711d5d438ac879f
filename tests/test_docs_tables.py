"""Numbers in the docs come from committed result files: the generated tables are current."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_generated_tables_match_the_committed_results():
    spec = importlib.util.spec_from_file_location("tables", ROOT / "benchmarks" / "tables.py")
    tables = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tables)
    for path in tables.DOCS:
        text = path.read_text()
        assert "<!-- table:" in text or path.name == "README.md"
        assert tables.render(text) == text, f"{path}: run `python benchmarks/tables.py`"


@pytest.mark.arithmetic
def test_committed_paired_differences_follow_from_the_committed_returns():
    """``docs/scores``' paired statistics (mean interval, IQM with its bootstrap interval,
    episodes better and worse) are what :func:`paired_to_best_rule` makes of the per-episode
    returns in the same file: nothing in them was typed in."""
    import json

    from sensorgym.train.benchmark import paired_to_best_rule

    files = sorted((ROOT / "docs" / "scores").glob("**/sensorgym__*.json"))
    assert len(files) >= 10
    for path in files:
        doc = json.loads(path.read_text())
        best, paired = paired_to_best_rule(doc["results"])
        assert best == doc["best_rule"], path
        assert set(paired) == set(doc["paired"]), path
        for name, d in paired.items():
            committed = doc["paired"][name]
            assert set(d) == set(committed), f"{path}: rescore or rewrite its `paired`"
            for key, value in d.items():
                # to rounding: the committed numbers were made on another machine, whose
                # SIMD reductions may sum the same returns in another order (a few ulp)
                assert committed[key] == pytest.approx(value, rel=1e-9, abs=1e-9), (
                    f"{path}: {name} {key}"
                )
