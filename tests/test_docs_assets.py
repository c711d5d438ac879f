"""The pictures in README and docs exist, are small, and say how they were made."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
ASSETS = ROOT / "docs" / "assets"


def test_assets_are_small():
    files = [p for p in ASSETS.rglob("*") if p.is_file()]
    assert files
    for p in files:
        assert p.stat().st_size < 1_000_000, f"{p.relative_to(ROOT)}: over 1 MB"


def test_every_referenced_picture_exists_and_states_its_command():
    for doc in (ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))):
        text = doc.read_text()
        for src in re.findall(r'src="([^"]+\.(?:png|gif))"', text):
            path = (doc.parent / src).resolve()
            assert path.is_file(), f"{doc.name}: {src} does not exist"
            # the command that made it is written next to it
            assert f"--out {path.relative_to(ROOT).as_posix()}" in text or (
                f"--out {path.parent.relative_to(ROOT).as_posix()}" in text
            ), f"{doc.name}: no command given for {src}"


def test_readme_opens_with_an_animated_episode_and_the_benchmark_chart():
    from PIL import Image

    head = (ROOT / "README.md").read_text().split("## ", 1)[0]
    gif = re.search(r'src="(docs/assets/[^"]+\.gif)"', head)
    assert gif and "docs/scores/benchmark.png" in head
    with Image.open(ROOT / gif.group(1)) as im:
        assert im.n_frames > 10
