"""GimbalTracking-v0's training wrapper (aim offset from the carrier-feedforward servo) and its
imitation teacher."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from stable_baselines3.common.vec_env import VecEnv

from sensorgym.agents.gimbal_search import FeedForwardSearch
from sensorgym.agents.gimbal_tracking import ANGLE_SCALE, ESTIMATE_LEVEL, CarrierFeedForward
from sensorgym.envs.gimbal_tracking.simulation import GimbalParams
from sensorgym.train.env_wrappers.gimbal_tracking import (
    AimOffsetAction,
    TurnMemory,
    truth_aim,
    truth_centre,
)
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


class _Scripted(VecEnv):
    """A vector env of one slot whose observations follow a script: the level estimate on a
    quadratic path, detected on the frames the script says, an episode end where it says."""

    render_mode = None

    def __init__(self, params, azimuth, elevation, seen, done):
        self.params, self.k = params, 0
        self.script = (azimuth, elevation, seen, done)
        box = gym.spaces.Box(-10.0, 10.0, (params.obs_dim,), np.float32)
        super().__init__(1, box, gym.spaces.Box(-1.0, 1.0, (2,), np.float32))

    def _obs(self):
        az, el, seen, _ = self.script
        obs = np.zeros((1, self.params.obs_dim), np.float32)
        obs[0, ESTIMATE_LEVEL] = np.array([az[self.k], el[self.k]]) / ANGLE_SCALE
        obs[0, 19 + self.params.n_channels] = float(seen[self.k])
        return obs

    def reset(self):
        self.k = 0
        return self._obs()

    def step_async(self, actions):
        pass

    def step_wait(self):
        self.k += 1
        done = np.array([self.script[3][self.k]])
        info = (
            [{"terminal_observation": np.zeros(self.params.obs_dim, np.float32)}]
            if done[0]
            else [{}]
        )
        return self._obs(), np.zeros(1), done, info

    def close(self):
        pass

    def get_attr(self, name, indices=None):
        return [getattr(self, name)]

    def set_attr(self, name, value, indices=None):
        setattr(self, name, value)

    def env_method(self, *args, **kwargs):
        return [None]

    def env_is_wrapped(self, wrapper_class, indices=None):
        return [False]


def test_turn_memory_recovers_a_quadratic_path_and_restarts_with_the_episode():
    params = GimbalParams()
    W, frames = 40, 120
    t = np.arange(frames, dtype=np.float64)
    # float32 observations: angles near 0.3 rad keep ~3e-8 rad, far below the path's bend
    rate, bend = np.array([2e-4, -1e-4]), np.array([3e-6, 1e-6])  # rad/frame, rad/frame² / 2
    az = 0.3 + rate[0] * t + bend[0] * t**2
    el = 0.1 + rate[1] * t + bend[1] * t**2
    seen = (t < 70) | (t >= 100)
    done = np.zeros(frames, bool)
    env = TurnMemory(_Scripted(params, az, el, seen, done), window=W)
    assert env.observation_space.shape == (params.obs_dim + 6,)
    obs = env.reset()
    np.testing.assert_array_equal(obs[0, -6:], 0.0)  # fewer than W/2 detections
    fov = params.field_of_view
    for _ in range(1, 95):
        obs = env.step(np.zeros((1, 2), np.float32))[0]
    # 94 frames in, the last detection at frame 69, lost for 25 frames
    last = 69
    slope = rate + 2.0 * bend * last  # θ̇ at the last detection
    np.testing.assert_allclose(obs[0, -6:-4], slope * W / fov, rtol=2e-3)
    np.testing.assert_allclose(obs[0, -4:-2], bend * W * W / fov, rtol=2e-2)
    np.testing.assert_allclose(obs[0, -2:], bend * (94 - last + 1) ** 2 / fov, rtol=2e-2)
    # an episode end clears the memory
    done[95] = True
    obs = env.step(np.zeros((1, 2), np.float32))[0]
    np.testing.assert_array_equal(obs[0, -6:], 0.0)
    with pytest.raises(ValueError, match="window"):
        TurnMemory(_Scripted(params, az, el, seen, done), window=2)


def test_the_truth_centre_teacher_ignores_the_search_hops():
    """Over a ``feedforward-search`` base the centre teacher's offset is the true direction's
    from the carrier-feedforward servo's aim (where to centre the search), while the aim
    teacher's also cancels the search's hop."""
    wrapped = AimOffsetAction(make_sb3_env(ENV_ID, 6, seed=5), base="feedforward-search")
    centre, aim = truth_centre(wrapped), truth_aim(wrapped)
    servo = CarrierFeedForward(wrapped.params)
    wrapped.reset()
    hops = 0
    for _ in range(300):
        obs = np.asarray(wrapped.last_obs, dtype=np.float64)
        truth = centre.truth.change(obs)
        for teacher, reference in ((centre, servo), (aim, wrapped.rule)):
            a = teacher.predict(obs)[0].astype(np.float64)
            want = np.clip((truth - reference.change(obs)) / wrapped.scale, -1.0, 1.0)
            np.testing.assert_allclose(a * np.abs(a), want, atol=1e-6)
        hops += int(np.any(wrapped.rule.change(obs) != servo.change(obs)))
        wrapped.step(np.zeros((6, 2), np.float32))
    assert hops > 0  # the episodes searched, so the two teachers differed


def _turn_features_one_slot(memory, i):
    """The turn memory's six features of slot ``i``, fitted alone by ``numpy.linalg.lstsq`` in
    frames (the definition, not the batched normal equations)."""
    k, W, fov = memory._count[i], memory.window, memory.params.field_of_view
    if k < W // 2:
        return np.zeros(6)
    y = memory._angles[i, -k:].copy()
    y[:, 0] = np.unwrap(y[:, 0])
    t = memory._frames[i, -k:] - memory._frames[i, -1]
    coef = np.linalg.lstsq(np.stack([np.ones_like(t), t, t * t], -1), y, rcond=None)[0]
    since = memory._frame[i] - memory._frames[i, -1]
    return np.clip(
        np.concatenate([coef[1] * W, coef[2] * W * W, coef[2] * (since + 1.0) ** 2]) / fov,
        -10.0,
        10.0,
    )


def test_turn_memory_batched_fit_is_each_slots_least_squares():
    """Over real episodes (occlusions, losses, episode ends) the batched fit equals each slot's
    own least squares (to 1e-9 of a field of view: the normal equations in τ = t/W are well
    conditioned, a 3 × 3 solve loses a few digits of float64 against the SVD)."""
    memory = TurnMemory(make_sb3_env(ENV_ID, 8, seed=6), window=40)
    rule = FeedForwardSearch(memory.params)
    obs = memory.reset()
    checked = 0
    for step in range(400):
        obs = memory.step(rule.predict(obs[:, :-6])[0])[0]
        if step % 7 == 0:
            want = np.stack([_turn_features_one_slot(memory, i) for i in range(8)])
            np.testing.assert_allclose(memory.features(), want, rtol=0, atol=1e-9)
            checked += int((memory._count >= 20).sum())
    assert checked > 100
