"""Frames of the envs whose renderer keeps one figure per episode (``Scene``): the frame's type,
determinism, that the kept figure draws what a fresh one draws, and the shared helpers."""

from __future__ import annotations

import importlib
import itertools
import pickle

import gymnasium as gym
import numpy as np
import pytest

import sensorgym.envs  # noqa: F401  (registers the ids)
from sensorgym.envs.shells.rendering import sigma_ellipse, status_line

SCENE_ENVS = [
    "sensorgym/BearingsManeuver-v0",
    "sensorgym/StereoPointing-v0",
    "sensorgym/StereoPlacement-v0",
    "sensorgym/StereoScanning-v0",
    "sensorgym/GimbalTracking-v0",
]


def _episode(env_id: str, seed: int, steps: int) -> tuple[gym.Env, list[np.ndarray]]:
    env = gym.make(env_id, render_mode="rgb_array")
    env.reset(seed=seed)
    env.action_space.seed(seed)
    frames = [env.render()]
    for _ in range(steps):
        env.step(env.action_space.sample())
        frames.append(env.render())
    return env, frames


@pytest.mark.parametrize("env_id", SCENE_ENVS)
def test_frames_are_rgb_deterministic_and_follow_the_state(env_id):
    env, frames = _episode(env_id, seed=3, steps=4)
    _, again = _episode(env_id, seed=3, steps=4)
    for frame, same in zip(frames, again, strict=True):
        assert frame.dtype == np.uint8 and frame.ndim == 3 and frame.shape[2] == 3
        np.testing.assert_array_equal(frame, same)
    assert all(not np.array_equal(a, b) for a, b in itertools.pairwise(frames))
    # the kept figure draws the pixels of a figure drawn afresh from the same episode
    inner = env.unwrapped
    module = importlib.import_module(inner.renderer)
    fresh = module.draw(inner.params, inner._frames.history, inner._frames.rewards)
    np.testing.assert_array_equal(frames[-1], fresh)


@pytest.mark.parametrize("env_id", SCENE_ENVS)
def test_a_rendered_env_pickles_and_draws_on(env_id):
    env, frames = _episode(env_id, seed=5, steps=2)
    copy = pickle.loads(pickle.dumps(env.unwrapped))
    np.testing.assert_array_equal(copy.render(), frames[-1])
    action = env.action_space.sample()
    env.step(action)
    copy.step(action)
    np.testing.assert_array_equal(copy.render(), env.render())
    env.close()
    assert env.render().shape == frames[0].shape  # close drops the figure; the next is new


def test_sigma_ellipse_is_the_2_sigma_ring_of_the_covariance():
    ring = sigma_ellipse(np.diag([4.0, 1.0]))  # σ = 2 m along x, 1 m along y
    assert ring.shape == (2, 65)
    np.testing.assert_allclose(np.abs(ring[0]).max(), 4.0)
    np.testing.assert_allclose(np.abs(ring[1]).max(), 2.0, rtol=1e-3)
    np.testing.assert_allclose(ring[:, 0], ring[:, -1], atol=1e-12)  # a closed ring
    rotated = sigma_ellipse(np.array([[2.5, 1.5], [1.5, 2.5]]))  # eigenvalues 4 and 1 at 45°
    np.testing.assert_allclose(np.hypot(*rotated).max(), 4.0, rtol=1e-3)
    assert np.isnan(sigma_ellipse(np.full((2, 2), np.inf))).all()  # nothing to draw
    assert np.isfinite(sigma_ellipse(np.array([[1.0, 1.0], [1.0, 1.0 - 1e-17]]))).all()


def test_status_line_counts_steps_and_the_return():
    assert status_line(0.0, []) == "step 0   t 0.0 s"
    assert status_line(0.4, [1.0, -0.5]) == "step 2   t 0.4 s   reward -0.50   return +0.50"
    assert status_line(0.2, [np.nan]) == "step 1   t 0.2 s"  # reward not known
