"""The plan-horizon rule: its decisions are the argmax of the plan features it is defined by
(the horizon-100 plan while 100 or more steps are left, the time-left plan after, plus the
hysteresis count), it counts its steps from ``episode_start``, it is deterministic, and its
teacher through the candidate action scores as the rule."""

from __future__ import annotations

import numpy as np
import pytest

from sensorgym.agents.registry import rules_for
from sensorgym.agents.stereo_pointing import all_assignments
from sensorgym.agents.stereo_pointing_horizon import PlanHorizon
from sensorgym.envs.stereo_pointing.simulation import PointingParams
from sensorgym.train.env_wrappers.stereo_pointing import PlanFeatures
from sensorgym.train.evaluation import evaluate, make_sb3_env
from sensorgym.train.experts import expert_factory

ENV_ID = "sensorgym/StereoPointing-v0"


def _feature_argmax(f: np.ndarray, t: int, C: int, n: int, keep: float) -> np.ndarray:
    """The rule's choice rebuilt from PlanFeatures(horizons=(100,)) features ``f (N, 5C)``:
    blocks [loss 100 | best 100 | loss time-left | best time-left | kept fraction]."""
    left = max(150 - t, 1)
    h, loss = (100, f[:, :C]) if left >= 100 else (left, f[:, 2 * C : 3 * C])
    score = h * loss.astype(np.float64) + keep * n * f[:, 4 * C : 5 * C]
    return np.argmax(score, axis=1)


@pytest.mark.parametrize("seed", [3, 11])
def test_decisions_are_the_argmax_of_the_plan_features(seed):
    """Over whole episodes (the switch to the time-left plan at step 50 included), the rule's
    assignment is the features' argmax of h × per-step loss + keep bonus × receivers kept."""
    params = PointingParams()
    rule = PlanHorizon(params)
    env = PlanFeatures(make_sb3_env(ENV_ID, 8, 0), horizons=(100,))
    env.seed(seed)
    obs = env.reset()
    base, C, n = params.obs_dim, 16, params.n_receivers
    state, start = None, np.ones(8, dtype=bool)
    cand = all_assignments(params)
    for t in range(150):
        if t % 7 == 0 or t >= 45:
            want = cand[_feature_argmax(obs[:, base:], t, C, n, rule.keep_bonus)]
            np.testing.assert_array_equal(rule.assign(obs[:, :base], t), want)
        action, state = rule.predict(obs[:, :base], state=state, episode_start=start)
        assert state.tolist() == [t + 1] * 8
        obs, _, dones, _ = env.step(action)
        start = dones
    assert dones.all()


def test_the_step_count_restarts_with_the_episode_and_the_rule_is_deterministic():
    params = PointingParams()
    rule = rules_for(ENV_ID, params, lambda: None)["plan-horizon"]
    assert isinstance(rule, PlanHorizon)
    obs = make_sb3_env(ENV_ID, 4, 0).reset()
    a1, s1 = rule.predict(obs, state=np.array([140, 3, 149, 7]))
    a2, _ = rule.predict(obs, state=np.array([140, 3, 149, 7]))
    np.testing.assert_array_equal(a1, a2)
    assert s1.tolist() == [141, 4, 150, 8]
    _, s3 = rule.predict(
        obs, state=np.array([140, 3, 149, 7]), episode_start=np.array([1, 0, 1, 0])
    )
    assert s3.tolist() == [1, 4, 1, 8]
    np.testing.assert_array_equal(
        rule.planning_horizon(np.array([0, 50, 51, 149, 150])), [100, 100, 99, 1, 1]
    )
    one, state = rule.predict(obs[0])
    assert one.shape == (8,) and state.tolist() == [1]
    a = evaluate(PlanHorizon(params), make_sb3_env(ENV_ID, 4, 0), 4, 5)
    b = evaluate(PlanHorizon(params), make_sb3_env(ENV_ID, 4, 0), 4, 5)
    assert a.returns == b.returns


def test_the_teacher_through_the_candidate_action_scores_as_the_rule():
    stack = [{"name": "pointing-plan"}, {"name": "plan-features"}, {"name": "time-feature"}]
    env = make_sb3_env(ENV_ID, 4, 0, wrappers=stack)
    teacher = expert_factory("plan-horizon-choice")(env)
    want = evaluate(PlanHorizon(PointingParams()), make_sb3_env(ENV_ID, 4, 0), 4, 9).mean
    assert abs(evaluate(teacher, env, 4, 9).mean - want) <= 1e-6 * max(abs(want), 1.0)


def test_bad_settings_are_refused():
    with pytest.raises(ValueError, match="horizon"):
        PlanHorizon(horizon=0)
    with pytest.raises(ValueError, match="keep_bonus"):
        PlanHorizon(keep_bonus=-1.0)
    with pytest.raises(ValueError, match="state"):
        PlanHorizon().predict(make_sb3_env(ENV_ID, 2, 0).reset(), state=np.zeros(3, np.int64))
