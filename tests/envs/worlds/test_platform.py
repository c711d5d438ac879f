"""Platform world: exact kinematics, limits, target noise statistics, batching."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from sensorgym.envs.worlds.platform import (
    PlatformWorldParams,
    PlatformWorldState,
    fly,
    noisy_bearings,
    rollout,
    step,
    true_bearings,
)
from sensorgym.trackers.bearings.models import cwna_covariance


def _state(B: int = 3, heading: float = 0.0, speed: float = 10.0) -> PlatformWorldState:
    target = np.tile([1000.0, 5000.0, -3.0, 1.0], (B, 1))
    return PlatformWorldState(0.0, np.zeros((B, 2)), np.full(B, heading), np.full(B, speed), target)


def test_straight_line_and_bearing_convention():
    params = PlatformWorldParams(dt=10.0)
    s = step(params, _state(1, heading=np.pi / 2), [[0.0, 0.0]])  # due East
    np.testing.assert_allclose(s.platform_position, [[100.0, 0.0]], atol=1e-12)
    np.testing.assert_allclose(s.target[0], [970.0, 5010.0, -3.0, 1.0])
    probe = dataclasses.replace(s, target=np.array([[100.0, 50.0, 0.0, 0.0]]))
    np.testing.assert_allclose(true_bearings(probe), [0.0], atol=1e-15)  # due North
    probe = dataclasses.replace(s, target=np.array([[200.0, 0.0, 0.0, 0.0]]))
    np.testing.assert_allclose(true_bearings(probe), [np.pi / 2])  # East = +90°


def test_constant_turn_flies_exact_circle():
    # 90° turn over one step at constant rate: quarter circle of radius v/ω
    params = PlatformWorldParams(dt=90.0, max_turn_rate=np.deg2rad(1.0))
    omega = np.deg2rad(1.0)
    s = step(params, _state(1, heading=0.0, speed=10.0), [[omega, 0.0]])
    R = 10.0 / omega
    np.testing.assert_allclose(s.platform_position[0], [R, R], rtol=1e-12)
    np.testing.assert_allclose(s.heading, [np.pi / 2])
    # many small steps land on the same point
    params_small = dataclasses.replace(params, dt=1.0)
    s2 = _state(1, heading=0.0, speed=10.0)
    for _ in range(90):
        s2 = step(params_small, s2, [[omega, 0.0]])
    np.testing.assert_allclose(s2.platform_position, s.platform_position, rtol=1e-9)


def test_fly_broadcasts_one_platform_over_many_commands():
    # one platform state broadcast (zero strides) over (rows, commands): each command flies
    # from that state, as the same arrays given in full do
    params = PlatformWorldParams(dt=10.0, max_turn_rate=0.05)
    n, C = 4, 3
    command = np.zeros((n, C, 2))
    command[..., 0] = np.linspace(-0.05, 0.05, C)
    full = fly(np.zeros((n, C, 2)), np.zeros((n, C)), np.full((n, C), 10.0), command, params)
    broadcast = fly(
        np.broadcast_to(np.zeros((n, 1, 2)), (n, C, 2)),
        np.broadcast_to(np.zeros((n, 1)), (n, C)),
        np.broadcast_to(np.full((n, 1), 10.0), (n, C)),
        command,
        params,
    )
    for a, b in zip(full, broadcast, strict=True):
        np.testing.assert_array_equal(a, b)
    assert np.all(broadcast[0][..., 1] > 90.0)  # every platform moved ahead


def test_action_limits_are_enforced():
    params = PlatformWorldParams(
        dt=1.0, max_turn_rate=0.1, min_speed=2.0, max_speed=12.0, max_speed_change=1.0
    )
    s = _state(3, speed=11.5)
    s2 = step(params, s, [[1.0, 5.0], [-1.0, -5.0], [0.05, 0.2]])
    np.testing.assert_allclose(s2.speed, [12.0, 10.5, 11.7])
    # the turn rate is clipped to ±0.1 rad/s over the 1-s step
    np.testing.assert_allclose(s2.heading, [0.1, -0.1, 0.05])
    slow = step(params, _state(1, speed=2.5), [[0.0, -1.0]])
    np.testing.assert_allclose(slow.speed, [2.0])


def test_target_noise_matches_cwna_covariance():
    params = PlatformWorldParams(dt=60.0, q_tilde=1e-3)
    rng = np.random.default_rng(1)
    s0 = _state(40_000)
    s1 = step(params, s0, [[0.0, 0.0]], rng)
    d = s1.target - np.array([1000.0 - 180.0, 5060.0, -3.0, 1.0])
    C = np.cov(d.T)
    Q = cwna_covariance(60.0, 1e-3)
    np.testing.assert_allclose(np.diag(C), np.diag(Q), rtol=0.03)
    np.testing.assert_allclose(C[0, 2] / np.sqrt(Q[0, 0] * Q[2, 2]), np.sqrt(3) / 2, atol=0.02)
    with pytest.raises(ValueError, match="rng"):
        step(params, s0, [[0.0, 0.0]])


def test_measurement_noise_and_seed_determinism():
    sigma = np.deg2rad(2.0)
    s = _state(50_000)
    z1 = noisy_bearings(s.target[:, :2], s.platform_position, sigma, np.random.default_rng(7))
    z2 = noisy_bearings(s.target[:, :2], s.platform_position, sigma, np.random.default_rng(7))
    np.testing.assert_array_equal(z1, z2)
    err = z1 - true_bearings(s)
    assert abs(np.std(err) / sigma - 1.0) < 0.02
    assert abs(np.mean(err)) < 4 * sigma / np.sqrt(err.size)


def test_batched_rollout_equals_looped():
    params = PlatformWorldParams(dt=30.0, q_tilde=1e-4, max_speed_change=3.0)
    rng = np.random.default_rng(3)
    B, K = 4, 6
    actions = rng.uniform(-0.05, 0.05, (K, B, 2))
    heads = rng.uniform(-np.pi, np.pi, B)
    s0 = PlatformWorldState(
        0.0, rng.normal(size=(B, 2)), heads, np.full(B, 8.0), rng.normal(size=(B, 4)) * 1e3
    )
    params0 = dataclasses.replace(params, q_tilde=0.0)
    batched = rollout(params0, s0, actions)
    for b in range(B):
        sb = PlatformWorldState(
            0.0, s0.platform_position[b : b + 1], heads[b : b + 1], s0.speed[b : b + 1],
            s0.target[b : b + 1],
        )  # fmt: skip
        one = rollout(params0, sb, actions[:, b : b + 1])
        np.testing.assert_allclose(one.platform_position[0], batched.platform_position[b])
        np.testing.assert_allclose(one.target[0], batched.target[b])


def test_scenarios_keep_their_own_clocks_but_rollout_needs_one():
    params = PlatformWorldParams(dt=10.0)
    s = dataclasses.replace(_state(3), t=np.array([0.0, 10.0, 0.0]))
    np.testing.assert_array_equal(step(params, s, [[0.0, 0.0]] * 3).t, [10.0, 20.0, 10.0])
    with pytest.raises(ValueError, match="one clock"):
        rollout(params, s, np.zeros((2, 2)))


def test_invalid_inputs_raise():
    with pytest.raises(ValueError, match="min_speed"):
        PlatformWorldParams(min_speed=5.0, max_speed=1.0)
    with pytest.raises(ValueError, match="dt"):
        PlatformWorldParams(dt=0.0)
    with pytest.raises(ValueError, match="heading"):
        PlatformWorldState(0.0, np.zeros((2, 2)), np.zeros(3), np.zeros(2), np.zeros((2, 4)))
    with pytest.raises(ValueError, match="action"):
        step(PlatformWorldParams(), _state(2), [[np.nan, 0.0], [0.0, 0.0]])
