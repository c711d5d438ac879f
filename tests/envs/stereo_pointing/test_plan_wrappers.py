"""The candidate action and the planner features: the candidates are the rules', the features
hold the plan-estimate rule's own evidence (its choice is their argmax), they are
deterministic, and a teacher through the wrappers scores as the rule."""

from __future__ import annotations

import numpy as np
import pytest

from sensorgym.agents.stereo_pointing import PlanEstimate, all_assignments
from sensorgym.envs.stereo_pointing.simulation import PointingParams
from sensorgym.train.env_wrappers.stereo_pointing import PlanAction, PlanFeatures
from sensorgym.train.evaluation import evaluate, make_sb3_env
from sensorgym.train.experts import expert_factory
from sensorgym.train.wrappers import base_observation

ENV_ID = "sensorgym/StereoPointing-v0"
STACK = [{"name": "pointing-plan"}, {"name": "plan-features"}, {"name": "time-feature"}]


def test_the_plan_action_indexes_the_rules_candidates():
    env = PlanAction(make_sb3_env(ENV_ID, 4, 0))
    params = PointingParams()
    assert env.action_space.n == 16
    np.testing.assert_array_equal(env.candidates, all_assignments(params))
    assert (env.index(env.candidates) == np.arange(16)).all()
    env.reset()
    with pytest.raises(ValueError, match="candidate"):
        env.step(np.array([0, 1, 2, 16]))


def test_the_features_hold_the_planners_values_and_choice():
    """Horizon 100's best candidate is plan-estimate's assignment; the time-left horizon at
    step t plans over 150 − t steps; every feature lies in the declared box."""
    params = PointingParams()
    env = PlanFeatures(make_sb3_env(ENV_ID, 8, 0), horizons=(15, 100))
    env.seed(6)
    obs = env.reset()
    rule = PlanEstimate(params)
    zero = PlanEstimate(params, horizon=150)
    C, base = 16, params.obs_dim
    assert obs.shape == (8, base + C * (2 * 3 + 1))
    for t in range(6):
        f = obs[:, base:]
        best100 = np.argmax(f[:, 3 * C : 4 * C], axis=1)  # horizon 100's one-hot
        np.testing.assert_array_equal(all_assignments(params)[best100], rule.assign(obs[:, :base]))
        if t == 0:  # at the start the time left is the whole episode
            best_left = np.argmax(f[:, 5 * C : 6 * C], axis=1)
            want = zero.assign(obs[:, :base])
            np.testing.assert_array_equal(all_assignments(params)[best_left], want)
        assert (f[:, 3 * C : 4 * C].sum(axis=1) == 1).all()
        assert np.all(obs >= env.observation_space.low) and np.all(
            obs <= env.observation_space.high
        )
        assert np.isclose(f[:, 2 * C : 3 * C], 0.0).any(axis=1).all()  # the best loses nothing
        obs, *_ = env.step(np.zeros((8, 8), dtype=np.float32))
    assert env._steps.t.tolist() == [6] * 8


def test_the_features_are_deterministic_and_recover_the_base_observation():
    a = make_sb3_env(ENV_ID, 4, 0, wrappers=STACK)
    b = make_sb3_env(ENV_ID, 4, 0, wrappers=STACK)
    raw = make_sb3_env(ENV_ID, 4, 0)
    for env in (a, b, raw):
        env.seed(3)
    oa, ob, oraw = a.reset(), b.reset(), raw.reset()
    np.testing.assert_array_equal(oa, ob)
    np.testing.assert_array_equal(base_observation(a, oa), oraw)
    assert a.action_space.n == 16 and a.observation_space.shape == (52 + 16 * 9 + 1,)


def test_the_plan_choice_teacher_through_the_wrappers_scores_as_plan_estimate():
    env = make_sb3_env(ENV_ID, 4, 0, wrappers=STACK)
    teacher = expert_factory("plan-choice-estimate")(env)
    want = evaluate(PlanEstimate(PointingParams()), make_sb3_env(ENV_ID, 4, 0), 4, 9).mean
    assert abs(evaluate(teacher, env, 4, 9).mean - want) <= 1e-6 * max(abs(want), 1.0)


def test_the_features_refuse_what_they_cannot_compute():
    with pytest.raises(ValueError, match="horizons"):
        PlanFeatures(make_sb3_env(ENV_ID, 2, 0), horizons=(0,))
    with pytest.raises(ValueError, match="stride"):
        PlanFeatures(make_sb3_env(ENV_ID, 2, 0), stride=0)
    with pytest.raises(ValueError, match="joint observation"):
        PlanFeatures(make_sb3_env(ENV_ID, 2, 0, wrappers=[{"name": "time-feature"}]))


def test_the_final_observation_gets_its_features_and_the_count_restarts():
    """At the time limit the final observation carries the features of its own last step (the
    time-left plan over one step) and the next episode's first counts from zero again."""
    env = PlanFeatures(make_sb3_env(ENV_ID, 2, 0), horizons=(15,))
    env.seed(1)
    obs = env.reset()
    hold = np.zeros((2, 8), dtype=np.float32)
    for _ in range(150):
        obs, _, dones, infos = env.step(hold)
    assert dones.all() and env._steps.t.tolist() == [0, 0]
    final = np.stack([info["terminal_observation"] for info in infos])
    assert final.shape == obs.shape
    np.testing.assert_array_equal(final[:, 52:], env.features(final[:, :52], np.array([150, 150])))
    np.testing.assert_array_equal(obs[:, 52:], env.features(obs[:, :52], np.zeros(2, np.int64)))
