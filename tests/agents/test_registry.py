"""The benchmark's default rule set (issue 38, item 3): the fieldable rules a user compares
against, at most seven per env, and the truth-informed ones; the ablations stay registered."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from sensorgym.agents.registry import ABLATIONS, RULES, default_rules
from sensorgym.train.benchmark import TRUTH_PREFIX, policies_for
from sensorgym.train.bounds import PASSIVE_RULES
from tests.pending import having

SCORES = Path(__file__).resolve().parents[2] / "docs" / "scores"


@pytest.mark.parametrize("env_id", sorted(RULES))
def test_the_default_set_is_at_most_seven_fieldable_rules_and_the_truth_informed(env_id):
    rules = default_rules(env_id)
    fieldable = [name for name in rules if not name.startswith(TRUTH_PREFIX)]
    truth = [name for name in RULES[env_id] if name.startswith(TRUTH_PREFIX)]
    assert 1 <= len(fieldable) <= 7, fieldable
    assert set(truth) <= set(rules)  # what knowing the truth buys: in every table
    assert rules == [name for name in RULES[env_id] if name in rules]  # registration order
    assert set(rules) | ABLATIONS.get(env_id, frozenset()) == set(RULES[env_id])


@pytest.mark.parametrize("env_id", sorted(ABLATIONS))
def test_every_ablation_stays_registered_and_none_is_truth_informed(env_id):
    assert env_id in RULES
    assert ABLATIONS[env_id] <= set(RULES[env_id])
    assert not any(name.startswith(TRUTH_PREFIX) for name in ABLATIONS[env_id])


@pytest.mark.parametrize("env_id", sorted(RULES))
def test_the_passive_and_the_committed_best_rule_are_in_the_default_set(env_id):
    """The headroom's 0 and the rule every shipped policy is compared to do not move when the
    benchmark scores only the default set."""
    rules = default_rules(env_id)
    assert PASSIVE_RULES[env_id] in rules
    if env_id not in having("scores", [env_id]):  # tests/pending.py: no scores committed yet
        return
    for path in (SCORES, SCORES / "seed31337"):
        doc = json.loads((path / f"{env_id.replace('/', '__')}.json").read_text())
        assert doc["best_rule"] in rules, (path, doc["best_rule"])


def test_the_issue_37_rules_are_in_the_default_sets():
    assert {"book-plan-tuned", "book-optimised-plan", "mpc-estimate"} <= set(
        default_rules("sensorgym/BearingsManeuverBook-v0")
    )
    crowded = default_rules("sensorgym/StereoPointingCrowded-v0")
    assert {"plan-search-exhaustive", "plan-schedule", "plan-search"} <= set(crowded)


def test_the_benchmark_scores_the_default_set_unless_rules_are_named():
    env_id = "sensorgym/StereoPointing-v0"
    specs = policies_for(env_id, shipped=False)
    assert list(specs) == default_rules(env_id)
    named = policies_for(env_id, shipped=False, rules=["plan-fix-first", "hold-cue"])
    assert list(named) == ["plan-fix-first", "hold-cue"]
    assert all(spec.kind == "rule" for spec in named.values())
    with pytest.raises(KeyError, match=r"no rule plan-nothing registered.*known: hold-still"):
        policies_for(env_id, shipped=False, rules=["plan-nothing"])


def test_a_default_rule_set_for_an_env_without_rules_is_empty():
    assert default_rules("sensorgym/NoSuchEnv-v0") == []
