"""Shared fixtures: seeded generators and random receiver geometries."""

from __future__ import annotations

import os

import numpy as np
import pytest

from sensorgym.envs.worlds.scanning import ReceiverLayout
from sensorgym.envs.worlds.stereo_scene import StereoScene
from sensorgym.trackers.geometry import look_at_rotation


def pytest_configure(config: pytest.Config) -> None:
    """A pytest-xdist worker shares the CPUs with the other workers: its env batches are not
    split over threads (``SENSORGYM_THREADS``) and torch keeps to one thread, unless the
    environment says otherwise. Tests of the threaded paths set ``SENSORGYM_THREADS``
    themselves. Set before any test imports torch, which reads ``OMP_NUM_THREADS`` then."""
    if hasattr(config, "workerinput"):
        for name in ("SENSORGYM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
            os.environ.setdefault(name, "1")


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20261122)


def random_moving_scene(
    rng: np.random.Generator, n: int, batch: int, order: int
) -> tuple[StereoScene, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Receivers scattered around a moving target; returns measurements at distinct fix times.

    Returns ``(scene_at_t1, a (batch, n, 3) own-frame directions at each receiver's fix time,
    dt (batch, n-1), V_world, Vdot_world)``.
    """
    T = rng.normal(size=(batch, 3)) * 20.0 + np.array([0.0, 40.0, 120.0])
    V = rng.normal(size=(batch, 3)) * 8.0
    Vd = rng.normal(size=(batch, 3)) * (2.0 if order == 2 else 0.0)
    if order == 0:
        V = np.zeros_like(V)
    o = rng.normal(size=(batch, n, 3)) * 70.0
    R = look_at_rotation(o, T[:, None, :] + rng.normal(size=(batch, n, 3)) * 3.0)
    t = np.concatenate([np.zeros((batch, 1)), rng.uniform(0.05, 0.6, size=(batch, n - 1))], 1)
    # the target at each receiver's fix time: M(t_k) = T + V t_k + V̇ t_k²/2
    Mk = T[:, None, :] + V[:, None, :] * t[..., None] + 0.5 * Vd[:, None, :] * t[..., None] ** 2
    u = Mk - o
    u /= np.linalg.norm(u, axis=-1, keepdims=True)
    a = np.einsum("bkji,bkj->bki", R, u)
    return StereoScene(ReceiverLayout(R, o), T), a, t[:, 1:], V, Vd


def assert_same_tree(x, y) -> None:
    """``x`` and ``y`` equal bit for bit (values and dtypes), through tuples, lists and dicts:
    for two runs in this process, where the same instructions meet the same inputs (numbers
    recorded on another machine are compared with :mod:`tests.arithmetic` instead)."""
    if isinstance(x, dict):
        assert x.keys() == y.keys()
        for key in x:
            assert_same_tree(x[key], y[key])
    elif isinstance(x, tuple | list):
        assert len(x) == len(y)
        for a, b in zip(x, y, strict=True):
            assert_same_tree(a, b)
    else:
        np.testing.assert_array_equal(x, y, strict=True)


def random_play(env, steps: int, reset_seed: int = 3, action_seed: int = 4) -> list:
    """Every output of a vector env's ``reset(seed=reset_seed)`` and of ``steps`` steps under
    seeded uniform actions in ``[−1.2, 1.2]`` (out-of-range ones included), flattened."""
    out = list(env.reset(seed=reset_seed))
    actions = np.random.default_rng(action_seed).uniform(
        -1.2, 1.2, (steps, *env.action_space.shape)
    )
    for a in actions:
        out.extend(env.step(a))
    return out
