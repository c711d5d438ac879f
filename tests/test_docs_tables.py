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


def test_an_ablation_appears_once_in_the_generated_tables():
    """The per-env score tables show the benchmark's default set; each ablation of
    ``agents.registry.ABLATIONS`` in the committed scores is in its env's ablation table
    only."""
    import json

    from sensorgym.agents.registry import ABLATIONS

    spec = importlib.util.spec_from_file_location("tables", ROOT / "benchmarks" / "tables.py")
    tables = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tables)
    for env in tables.SCORE_ENVS:
        env_id = f"sensorgym/{env}"
        scored = json.loads((tables.SCORES / f"sensorgym__{env}.json").read_text())["results"]
        shown = [tables.TABLES[f"results-{env.split('-')[0]}"]()]
        shown += [fn() for key, fn in tables.TABLES.items() if key.startswith("scores-")]
        shown = [t for t in shown if f"sensorgym__{env}.json" in t]
        assert len(shown) == 2, env  # the env's score table and its paired table
        for name in ABLATIONS.get(env_id, ()):
            assert all(f"`{name}`" not in t and f"| {name} |" not in t for t in shown), name
        if ABLATIONS.get(env_id):
            table = tables.ablations(env)
            for name in ABLATIONS[env_id] & set(scored):
                assert table.count(f"| `{name}`") == 1, name
