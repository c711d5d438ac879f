"""StereoPlacement-v0's training wrapper (planning-target action) and its imitation teacher."""

from __future__ import annotations

import numpy as np
import pytest

from sensorgym.agents.stereo_placement import GreedyPlacement
from sensorgym.train.env_wrappers.stereo_placement import PlanTargetAction, truth_target
from sensorgym.train.evaluation import env_params, make_sb3_env

ENV_ID = "sensorgym/StereoPlacement-v0"


def _returns(env, act, steps=60):
    obs = env.reset()
    total = np.zeros(env.num_envs)
    for _ in range(steps):
        obs, reward, _, _ = env.step(act(obs))
        total += reward
    return total


def test_zero_target_correction_is_the_greedy_rule():
    """The zero action plans on the tracker's own prediction: GreedyPlacement's episodes."""
    wrapped = PlanTargetAction(make_sb3_env(ENV_ID, 4, seed=3))
    plain = make_sb3_env(ENV_ID, 4, seed=3)
    rule = GreedyPlacement(env_params(plain))
    assert wrapped.action_space.shape == (3,)
    zeros = _returns(wrapped, lambda obs: np.zeros((4, 3), np.float32), steps=20)
    greedy = _returns(plain, lambda obs: rule.predict(obs)[0], steps=20)
    np.testing.assert_array_equal(zeros, greedy)


def test_truth_target_teacher_beats_the_greedy_rule():
    """Planning on the true drone instead of the noisy single-period fix pays (same seeds)."""
    wrapped = PlanTargetAction(make_sb3_env(ENV_ID, 16, seed=4))
    teacher = truth_target(wrapped)
    taught = _returns(wrapped, lambda obs: teacher.predict(obs)[0])
    wrapped = PlanTargetAction(make_sb3_env(ENV_ID, 16, seed=4))  # the same scenarios
    greedy = _returns(wrapped, lambda obs: np.zeros((16, 3), np.float32))
    assert taught.mean() > greedy.mean() + 2.0


def test_bad_arguments_are_named():
    env = make_sb3_env(ENV_ID, 2, seed=0)
    with pytest.raises(ValueError, match="scale"):
        PlanTargetAction(env, scale=(1.0, -1.0, 1.0))
    wrapped = PlanTargetAction(env)
    wrapped.reset()
    with pytest.raises(ValueError, match="actions"):
        wrapped.step(np.full((2, 3), np.nan, np.float32))
    with pytest.raises(ValueError, match="PlanTargetAction"):
        truth_target(env)
