"""GimbalTracking-v0's training wrapper (aim offset from the carrier-feedforward servo) and its
imitation teacher."""

from __future__ import annotations

import numpy as np
import pytest

from sensorgym.agents.gimbal_search import FeedForwardSearch
from sensorgym.agents.gimbal_tracking import CarrierFeedForward
from sensorgym.train.env_wrappers.gimbal_tracking import AimOffsetAction, truth_aim
from sensorgym.train.evaluation import env_params, make_sb3_env

ENV_ID = "sensorgym/GimbalTracking-v0"


def _returns(env, act, steps=200):
    obs = env.reset()
    total, live = np.zeros(env.num_envs), np.ones(env.num_envs, dtype=bool)
    for _ in range(steps):
        obs, reward, done, _ = env.step(act(obs))
        total[live] += reward[live]
        live &= ~done
    return total


@pytest.mark.parametrize("base", ["carrier-feedforward", "feedforward-search"])
def test_zero_offset_is_the_base_rule(base):
    # 300 frames: long enough for occlusions and the search's hops
    wrapped = AimOffsetAction(make_sb3_env(ENV_ID, 4, seed=3), base=base)
    plain = make_sb3_env(ENV_ID, 4, seed=3)
    params = env_params(plain)
    rule = (
        CarrierFeedForward(params) if base == "carrier-feedforward" else FeedForwardSearch(params)
    )
    assert wrapped.action_space.shape == (2,)
    zeros = _returns(wrapped, lambda obs: np.zeros((4, 2), np.float32), steps=300)
    servo = _returns(plain, lambda obs: rule.predict(obs)[0], steps=300)
    np.testing.assert_array_equal(zeros, servo)


def test_the_truth_aim_teacher_keeps_the_target_the_rule_loses():
    """Aiming at the true direction instead of the coasting prediction pays on the same
    scenarios (occlusions across turns lose the rule some targets)."""
    wrapped = AimOffsetAction(make_sb3_env(ENV_ID, 12, seed=4))
    teacher = truth_aim(wrapped)
    taught = _returns(wrapped, lambda obs: teacher.predict(obs)[0], steps=500)
    wrapped = AimOffsetAction(make_sb3_env(ENV_ID, 12, seed=4))
    servo = _returns(wrapped, lambda obs: np.zeros((12, 2), np.float32), steps=500)
    assert taught.mean() > servo.mean() + 50.0


def test_bad_arguments_are_named():
    env = make_sb3_env(ENV_ID, 2, seed=0)
    with pytest.raises(ValueError, match="scale"):
        AimOffsetAction(env, scale=0.0)
    with pytest.raises(ValueError, match="base"):
        AimOffsetAction(env, base="truth-servo")
    wrapped = AimOffsetAction(env)
    wrapped.reset()
    with pytest.raises(ValueError, match="actions"):
        wrapped.step(np.full((2, 2), np.nan, np.float32))
    with pytest.raises(ValueError, match="AimOffsetAction"):
        truth_aim(env)
