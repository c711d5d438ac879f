"""``benchmarks/headroom_gap.py``: its split of the gap ``bound − return`` adds up, on a tiny
seeded run of the real script (4 episodes of StereoScanning, its shipped policy and best rule)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]


def _script():
    spec = importlib.util.spec_from_file_location(
        "headroom_gap", ROOT / "benchmarks" / "headroom_gap.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def tiny():
    return _script().run_env("sensorgym/StereoScanning-v0", episodes=4, seed=10000, n_envs=4)


def test_the_phases_sum_to_the_gap(tiny):
    assert tiny["episodes"] == 4 and tiny["policy"] is not None
    for d in tiny["players"].values():
        gap = d["mean_gap"]
        assert gap == pytest.approx(d["mean_bound"] - d["mean_return"], rel=1e-9, abs=1e-9)
        assert sum(p["gap"] for p in d["phases"]) == pytest.approx(gap, rel=1e-9, abs=1e-9)
        assert sum(p["share"] for p in d["phases"]) == pytest.approx(1.0, rel=1e-9)
        steps = [s for p in d["phases"] for s in range(p["steps"][0], p["steps"][1] + 1)]
        assert steps == list(range(1, tiny["steps"] + 1))  # every step in one phase
        assert 0.0 <= d["worst"]["10 %"] <= d["worst"]["25 %"] <= 1.0 + 1e-12
        for parts in d["splits"].values():  # StereoScanning: tracks, drones present
            assert sum(v["gap"] for v in parts.values()) == pytest.approx(gap, rel=1e-9, abs=1e-9)
        assert set(d["splits"]) == {"tracks", "drones present"}


def test_the_gain_split_sums_to_closes(tiny):
    g = tiny["gain"]
    pol, rule = tiny["players"][tiny["policy"]], tiny["players"][tiny["best_rule"]]
    assert g["gain"] == pytest.approx(rule["mean_gap"] - pol["mean_gap"], rel=1e-9, abs=1e-9)
    assert sum(p["gain"] for p in g["phases"]) == pytest.approx(g["gain"], rel=1e-9, abs=1e-9)
    assert sum(p["closes"] for p in g["phases"]) == pytest.approx(g["closes"], rel=1e-9)
    # the benchmark's closes, (R̄ − R̄_best)/(B̄ − R̄_best), on these episodes
    closes = (pol["mean_return"] - rule["mean_return"]) / (rule["mean_bound"] - rule["mean_return"])
    assert g["closes"] == pytest.approx(closes, rel=1e-9)


def test_the_episodes_are_the_benchmarks(tiny):
    # the per-step bounds sum to the committed episode bound, the returns are the committed ones
    assert tiny["bound"]["max_abs_diff_to_benchmark"] < 1e-9
    for d in tiny["players"].values():
        assert d["max_abs_diff_to_benchmark_returns"] < 0.05 * max(1.0, abs(d["mean_return"]))


def test_decompose_on_numbers():
    hg = _script()
    rng = np.random.default_rng(0)
    bounds = rng.uniform(0.0, 2.0, (6, 20))
    rewards = bounds - rng.uniform(0.0, 1.0, (6, 20))
    lengths = np.array([20, 20, 15, 20, 10, 20])
    for e, n in enumerate(lengths):
        rewards[e, n:] = 0.0
    feats = {"x": np.arange(6.0)}
    labels = np.where(rng.uniform(0, 1, (6, 20)) > 0.5, "a", "b")
    d = hg.decompose(bounds, rewards, lengths, feats, {"fix": labels})
    total = (bounds - rewards).sum() / 6
    assert d["mean_gap"] == pytest.approx(total)
    assert sum(p["gap"] for p in d["phases"]) == pytest.approx(total)
    parts = d["splits"]["fix"]
    assert set(parts) == {"a", "b", "after the end"}
    assert sum(v["gap"] for v in parts.values()) == pytest.approx(total)
    assert parts["after the end"]["gap"] == pytest.approx(d["after_end"]["gap"])
    assert sum(v["steps"] for v in parts.values()) == pytest.approx(20)
