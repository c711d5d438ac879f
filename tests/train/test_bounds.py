"""The benchmark's headroom: every episode's bound beside its return, the normalised score."""

from __future__ import annotations

import json

import numpy as np
import pytest

from sensorgym.cli.main import main
from sensorgym.train.benchmark import PolicySpec, score
from sensorgym.train.bounds import PASSIVE_RULES, bound_violations, headroom
from sensorgym.train.shipped import shipped_policies

POINTING = "sensorgym/StereoPointing-v0"


def _result(returns, bounds) -> dict:
    r = np.asarray(returns, dtype=np.float64)
    return {"mean": float(r.mean()), "returns": list(r), "bounds": list(bounds)}


def test_the_normalised_score_is_0_for_the_passive_rule_and_1_at_the_bound():
    bounds = [10.0, 20.0, 30.0, 5.0]
    results = {
        "passive": _result([0.0, 0.0, 10.0, 5.0], bounds),  # no headroom on the last episode
        "best": _result([5.0, 10.0, 20.0, 5.0], bounds),
        "policy": _result([10.0, 20.0, 30.0, 5.0], bounds),
    }
    room = headroom(results, "passive", "best")
    assert room["passive"]["normalised"] == 0.0
    assert room["policy"]["normalised"] == pytest.approx(1.0)
    assert room["best"]["normalised"] == pytest.approx(0.5)
    assert room["policy"]["episodes_with_headroom"] == 3
    assert room["policy"]["bound"] == pytest.approx(16.25)
    # the best rule's mean is 10, the bound's 16.25, the policy's 16.25: all the headroom closed
    assert room["policy"]["closes"] == pytest.approx(1.0)
    assert room["best"]["closes"] is None
    assert headroom(results, None, "best") == {}


def test_a_return_above_its_bound_is_reported():
    assert bound_violations(_result([1.0, 2.0], [1.0, 2.0])) == []
    assert bound_violations(_result([1.0, 2.1], [1.0, 2.0])) == [1]
    assert bound_violations({"returns": [1.0]}) == []  # an env without a bound


#: per env with a bound: a fieldable rule to score beside the passive one and a shipped policy
RULE_OF = {
    POINTING: "plan-search",
    "sensorgym/StereoPlacement-v0": "lookahead-information",
    "sensorgym/StereoScanning-v0": "cue-entry-search",
}


@pytest.mark.parametrize(
    ("env_id", "episodes"),
    [
        (POINTING, 8),
        (POINTING, 16),
        ("sensorgym/StereoPlacement-v0", 16),
        ("sensorgym/StereoScanning-v0", 16),
    ],
)  # one round, and a second after the autoreset
def test_no_policy_exceeds_its_bound_on_a_benchmark_episode(env_id, episodes):
    passive, rule = PASSIVE_RULES[env_id], RULE_OF[env_id]
    specs = {name: PolicySpec("rule", name) for name in (passive, rule)}
    run, folder = next(iter(shipped_policies(env_id).items()))
    specs[f"shipped:{run}"] = PolicySpec("model", str(folder), shipped=True)
    results = {name: score(env_id, spec, episodes, 8, 10_000) for name, spec in specs.items()}
    for name, r in results.items():
        assert len(r["bounds"]) == episodes, name
        assert bound_violations(r) == [], name
        # no policy ends these episodes (StereoScanning's end with the drones' paths), and
        # the drones' paths are the scenario's alone: every policy meets the same bounds
        assert r["bounds"] == results[passive]["bounds"], name
    room = headroom(results, passive, rule)
    assert room[passive]["normalised"] == 0.0
    assert 0.0 < room[rule]["normalised"] <= 1.0


def test_the_benchmark_json_has_each_episodes_bound_and_the_headroom(tmp_path, capsys):
    assert main(["benchmark", "--env", POINTING, "--episodes", "8", "--no-shipped",
                 "--no-chart", "--out", str(tmp_path)]) == 0  # fmt: skip
    doc = json.loads((tmp_path / "sensorgym__StereoPointing-v0.json").read_text())
    assert doc["passive_rule"] == "hold-still"
    assert set(doc["headroom"]) == set(doc["results"])
    for name, r in doc["results"].items():
        assert all(x <= b + 1e-6 * max(abs(b), 1.0) for x, b in zip(r["returns"], r["bounds"], strict=True)), name  # fmt: skip
    assert "normalised" in capsys.readouterr().out


HINDSIGHT = {
    "sensorgym/BearingsManeuver-v0": "lookahead-estimate",
    "sensorgym/BearingsManeuverBook-v0": "book-optimised-plan",
}


@pytest.mark.parametrize("env_id", sorted(HINDSIGHT))
def test_the_hindsight_bound_holds_every_policy_on_the_benchmark_episodes(env_id):
    """Every rule and shipped policy, two rounds of four scenarios (an autoreset between): all
    meet the same episodes (one stream per episode), each episode's bound is at least every
    policy's return, and the recorded actions do not reach the JSON."""
    from sensorgym.train.benchmark import policies_for
    from sensorgym.train.bounds import add_hindsight_bounds
    from sensorgym.train.env_params import resolve

    passive, rule = PASSIVE_RULES[env_id], HINDSIGHT[env_id]
    specs = policies_for(env_id)
    assert {passive, rule} <= set(specs) and any(n.startswith("shipped:") for n in specs)
    results = {
        name: score(env_id, spec, 8, 4, 10_000, record_actions=True) for name, spec in specs.items()
    }
    assert results[passive]["keys"] == [(s, k) for k in range(2) for s in range(4)]
    summary = add_hindsight_bounds(env_id, resolve(env_id, {}), 10_000, results)
    assert summary["gain_mean"] >= 0.0
    for name, r in results.items():
        assert "actions" not in r and "keys" not in r
        assert len(r["bounds"]) == 8 and bound_violations(r) == [], name
        json.dumps(r)  # what the benchmark writes
    room = headroom(results, passive, rule)
    assert room[passive]["normalised"] == 0.0
    assert 0.0 < room[rule]["normalised"] <= 1.0
