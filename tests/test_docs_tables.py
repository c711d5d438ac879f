"""Numbers in the docs come from committed result files: the generated tables are current."""

from __future__ import annotations

import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_generated_tables_match_the_committed_results():
    spec = importlib.util.spec_from_file_location("tables", ROOT / "benchmarks" / "tables.py")
    tables = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tables)
    for path in tables.DOCS:
        text = path.read_text()
        assert "<!-- table:" in text or path.name == "README.md"
        assert tables.render(text) == text, f"{path}: run `python benchmarks/tables.py`"
