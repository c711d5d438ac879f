"""The assignment rules, the assignment action and its teachers share one slew controller: a
rule's actions equal the wrapper's for the same assignment, episode for episode."""

from __future__ import annotations

import numpy as np
import pytest

from sensorgym.agents.registry import rules_for
from sensorgym.agents.stereo_pointing import HoldCue, OrthogonalPairs, PlanEstimate, TruthPlan
from sensorgym.envs.stereo_pointing.simulation import PointingParams, assignment_actions
from sensorgym.train.env_wrappers.stereo_pointing import (
    AssignmentAction,
    hold_cue_expert,
    orthogonal_pairs_expert,
    truth_plan_expert,
)
from sensorgym.train.evaluation import evaluate, make_sb3_env, simulator_state

ENV_ID = "sensorgym/StereoPointing-v0"


def _returns(policy, env, seed: int, episodes: int = 8) -> float:
    return evaluate(policy, env, episodes, seed).mean


class _Constant:
    """Always the same assignment, in the wrapper's action space."""

    def __init__(self, target: np.ndarray):
        self.target = target

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        return np.broadcast_to(self.target, (len(observation), self.target.size)).copy(), None


def test_the_wrapper_holding_the_cue_scores_exactly_the_hold_cue_rule():
    """Same seed, same scenarios: the constant assignment ``k mod m`` through the wrapper and
    the hold-cue rule on gimbal rates give identical returns (one slew controller)."""
    env = make_sb3_env(ENV_ID, 4, 0)
    rule = HoldCue(PointingParams())
    wrapped = AssignmentAction(make_sb3_env(ENV_ID, 4, 0))
    assert wrapped.action_space.nvec.tolist() == [2, 2, 2, 2]
    r_rule = evaluate(rule, env, 8, 3)
    r_wrap = evaluate(_Constant(np.array([0, 1, 0, 1])), wrapped, 8, 3)
    assert r_rule.mean == pytest.approx(r_wrap.mean, rel=1e-6)
    # the hold-cue expert answers the same assignment
    obs = wrapped.reset()
    assert (hold_cue_expert(wrapped).predict(obs)[0] == [0, 1, 0, 1]).all()


def test_orthogonal_pairs_through_the_wrapper_scores_as_the_rule():
    env = make_sb3_env(ENV_ID, 4, 0)
    wrapped = AssignmentAction(make_sb3_env(ENV_ID, 4, 0))
    rule = OrthogonalPairs(PointingParams())
    want = evaluate(rule, env, 4, 5).mean
    assert evaluate(orthogonal_pairs_expert(wrapped), wrapped, 4, 5).mean == pytest.approx(
        want, rel=1e-6
    )


def test_rules_keep_the_cue_at_the_start_when_nothing_is_seen():
    """Step 0 (nothing seen yet, receivers on the cue): the assignment rules keep the cue
    pairing unless another beats it by more than the hysteresis — no longer the near-tie that
    sent every receiver to the other drone."""
    env = make_sb3_env(ENV_ID, 64, 0)
    env.seed(11)
    obs = env.reset()
    params = PointingParams()
    cue = np.arange(4) % 2
    for name in ("orthogonal-pairs", "greedy-information"):
        choice = rules_for(ENV_ID, params, lambda: None)[name].assign(obs)
        # the all-swapped pairing (every receiver to the other drone) is chosen rarely
        swapped = (choice == 1 - cue).all(axis=1).mean()
        kept = (choice == cue).all(axis=1).mean()
        assert swapped < 0.1 and kept > 0.5, (name, swapped, kept)


def test_slew_controller_turns_at_full_rate_and_stops_on_the_track():
    """Actions are in [−1, 1]; a receiver on its drone's cue only follows the prediction one step
    ahead (less than a full-rate step); one sent to the other drone turns at full rate."""
    params = PointingParams()
    env = make_sb3_env(ENV_ID, 8, 0)
    env.seed(2)
    obs = env.reset()
    a = assignment_actions(params, obs, np.tile(np.arange(4) % 2, (8, 1)))
    assert a.shape == (8, 8) and np.all(np.abs(a) <= 1.0)
    assert np.abs(a).max() < 1.0  # the cued start: on the cue already
    b = assignment_actions(params, obs, np.tile(1 - np.arange(4) % 2, (8, 1)))
    assert np.abs(b).max() == pytest.approx(1.0)  # off by more than one step: full rate
    with pytest.raises(ValueError, match="target"):
        assignment_actions(params, obs, np.full((8, 4), 2))


def test_the_truth_plan_scores_at_least_the_hold_cue_rule():
    """On the truth, planning the held assignment scores at least the cue pairing (seeded)."""
    env = make_sb3_env(ENV_ID, 8, 0)
    params = PointingParams()
    truth_plan = TruthPlan(simulator_state(env), params)
    assert _returns(truth_plan, env, 21, 16) >= _returns(HoldCue(params), env, 21, 16)
    wrapped = AssignmentAction(make_sb3_env(ENV_ID, 8, 0))
    expert = truth_plan_expert(wrapped)
    obs = wrapped.reset()
    assert expert.predict(obs)[0].shape == (8, 4)


def test_the_estimate_planner_on_an_exact_cue_plans_as_the_truth_plan():
    """With a near-exact cue the tracker's estimate is the truth: at the start, planning over
    the whole episode on the estimate picks ``TruthPlan``'s assignment (the same planner)."""
    params = PointingParams(cue_sigma=(1e-6, 1e-6))
    env = make_sb3_env(ENV_ID, 16, 0, cue_sigma=(1e-6, 1e-6))
    env.seed(4)
    obs = env.reset()
    truth_plan = TruthPlan(simulator_state(env), params, stride=1)
    planner = PlanEstimate(params, horizon=150, stride=1)
    agree = (truth_plan.assign(obs) == planner.assign(obs)).all(axis=1).mean()
    assert agree >= 0.9
