"""StereoScanning-v0: the checkers, determinism, vector/single equivalence, geometry, covariance."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from pettingzoo.test import parallel_api_test, parallel_seed_test

import sensorgym.envs  # noqa: F401  (registers the ids)
from sensorgym.envs import stereo_scanning
from sensorgym.envs.stereo_scanning import kernels
from sensorgym.envs.stereo_scanning import simulation as sim
from sensorgym.envs.stereo_scanning.simulation import ScanningParams
from sensorgym.trackers.stereo.conjugation import solve_conjugation, velocity_fix_covariance

ENV_ID = "sensorgym/StereoScanning-v0"
FULL = np.array([0.0, 0.0, 1.0] * 3, dtype=np.float32)


def test_gymnasium_check_env_passes():
    check_env(gym.make(ENV_ID).unwrapped, skip_render_check=True)


def test_sb3_check_env_passes():
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    sb3_check_env(gym.make(ENV_ID), warn=True)


@pytest.mark.parametrize(
    "make",
    [
        lambda: stereo_scanning.parallel_env(max_episode_steps=25),
        lambda: stereo_scanning.parallel_env(clutter_rate=1.0, max_episode_steps=15),
    ],
)
def test_pettingzoo_api_and_seed_tests_pass(make):
    parallel_api_test(make(), num_cycles=30)
    parallel_seed_test(make, num_cycles=30)


def _episode(seed: int, steps: int = 30):
    env = gym.make(ENV_ID)
    obs, _ = env.reset(seed=seed)
    out = [obs]
    rewards = []
    rng = np.random.default_rng(seed)
    for _ in range(steps):
        obs, r, term, trunc, _ = env.step(rng.uniform(-1, 1, 9).astype(np.float32))
        out.append(obs)
        rewards.append(r)
        if term or trunc:
            break
    return np.array(out), np.array(rewards)


def test_same_seed_same_episode():
    o1, r1 = _episode(3)
    o2, r2 = _episode(3)
    np.testing.assert_array_equal(o1, o2)
    np.testing.assert_array_equal(r1, r2)
    assert np.all(np.isfinite(o1)) and np.all(np.isfinite(r1))


def test_vector_env_equals_single_envs_scenario_by_scenario():
    params = ScanningParams()
    rng_b = np.random.default_rng(5)
    batch = sim.reset(params, rng_b, 4)
    singles = [
        sim.start(params, batch.drone_position[i : i + 1], batch.drone_velocity[i : i + 1],
                  batch.drone_acceleration[i : i + 1], batch.enter[i : i + 1])
        for i in range(4)
    ]  # fmt: skip
    actions = np.random.default_rng(1).uniform(-1, 1, (12, 4, 3, 3))
    for a in actions:
        # the same noise draws scenario by scenario: noise off, so only geometry matters
        p0 = ScanningParams(noise_per_width=0.0)
        batch, rb, _ = sim.step(p0, batch, a, np.random.default_rng(0))
        for i in range(4):
            singles[i], ri, _ = sim.step(p0, singles[i], a[i : i + 1], np.random.default_rng(0))
            assert ri[0] == rb[i]
            np.testing.assert_array_equal(sim.observe(p0, singles[i])[0], sim.observe(p0, batch)[i])


def test_full_sweep_tracks_most_drones_and_earns_more_than_looking_away():
    params = ScanningParams()
    rng = np.random.default_rng(0)
    B = 64
    s = sim.reset(params, rng, B)
    full = np.broadcast_to(np.array([0.0, 0.0, 1.0]), (B, 3, 3)).copy()
    away = np.broadcast_to(np.array([1.0, -1.0, -1.0]), (B, 3, 3)).copy()
    s2 = s
    ra, rb, present, tracked = 0.0, 0.0, 0.0, 0.0
    for k in range(15):
        s, r1, _ = sim.step(params, s, full, rng)
        s2, r2, _ = sim.step(params, s2, away, rng)
        if k >= 3:
            ra, rb = ra + r1.mean(), rb + r2.mean()
            present += s.parts[:, 0].sum()
            tracked += s.parts[:, 1].sum()
    assert tracked / present > 0.7
    assert ra > rb + 10


def test_noiseless_fixes_point_exactly_at_the_drones_at_their_fix_times():
    params = ScanningParams(noise_per_width=0.0, close_drones=0, late_drones=0)
    s = sim.reset(params, np.random.default_rng(2), 8)
    prev = s
    s, _, _ = sim.step(
        params, s, np.broadcast_to(FULL.reshape(3, 3), (8, 3, 3)), np.random.default_rng(0)
    )
    checked = 0
    for i in range(8):
        for k in range(3):
            for f in range(s.fix_count[i, k]):
                j = s.fix_drone[i, k, f]
                dt = s.fix_time[i, k, f] - prev.t[i]
                truth = (prev.drone_position[i, j] + prev.drone_velocity[i, j] * dt
                         + 0.5 * prev.drone_acceleration[i, j] * dt**2)  # fmt: skip
                u = truth - params.receivers[k]
                np.testing.assert_allclose(s.fix_world[i, k, f], u / np.linalg.norm(u), atol=1e-12)
                checked += 1
    assert checked > 30
    # noiseless confirmed tracks sit on the drones after a few periods
    for _ in range(4):
        s, _, _ = sim.step(
            params, s, np.broadcast_to(FULL.reshape(3, 3), (8, 3, 3)), np.random.default_rng(0)
        )
    ok = s.assigned >= 0
    assert ok.sum() > 10
    assert np.all(s.drone_sigma[ok] < 1e-6)


def test_candidate_covariance_matches_monte_carlo_and_the_generic_solver():
    """Candidates of one drone under angle noise: the spreads of the fixed position and
    velocity follow the triple's exact first-order covariance (theory §3.5), and the track's
    ``(σ_pos, σ_vel)`` are the square roots of the traces of the library's
    ``velocity_fix_covariance`` on the same fixes."""
    params = ScanningParams(n_drones=1, close_drones=0, late_drones=0, noise_per_width=2e-3,
                            max_acceleration=0.0, climb_rate=(0.0, 0.0))  # fmt: skip
    B = 3000
    p = np.broadcast_to(np.array([5.0, 45.0, -3.0]), (B, 1, 3)).copy()
    v = np.broadcast_to(np.array([4.0, 0.0, 2.0]), (B, 1, 3)).copy()
    s = sim.start(params, p, v, np.zeros((B, 1, 3)), np.zeros((B, 1)))
    rng = np.random.default_rng(11)
    action = np.broadcast_to(np.array([0.0, 0.0, -0.6]), (B, 3, 3)).copy()
    s1, _, _ = sim.step(params, s, action, rng)
    s2, _, _ = sim.step(params, s1, action, rng)
    # tentative tracks after period 1 hold each scenario's single candidate
    row = np.argmax(s1.track_status > 0, axis=1)
    idx = np.arange(B)
    assert np.all(s1.track_status[idx, row] == kernels.TENTATIVE)
    t_fix = s1.track_t[idx, row]
    truth = p[:, 0] + v[:, 0] * t_fix[:, None]
    err = s1.track_x[idx, row, :3] - truth
    predicted = s1.track_sigma[idx, row, 0]
    ratio = np.sqrt(np.mean(np.sum(err**2, -1))) / np.mean(predicted)
    assert 0.9 < ratio < 1.1
    # the velocity too (the papers' i.i.d. σ_e² (AᵀA)⁻¹ put σ_vel 10–45 % too small)
    verr = s1.track_x[idx, row, 3:] - v[:, 0]
    vratio = np.sqrt(np.mean(np.sum(verr**2, -1))) / np.mean(s1.track_sigma[idx, row, 1])
    assert 0.9 < vratio < 1.1
    # the kernel's spreads are the library's covariance of the same fixes
    P, b = params.relative
    u = np.stack([s1.fix_world[0, k, 0] for k in range(3)])
    a_local = np.einsum("kjc,kj->kc", params.rotations, u)
    dt = np.array(
        [s1.fix_time[0, 1, 0] - s1.fix_time[0, 0, 0], s1.fix_time[0, 2, 0] - s1.fix_time[0, 0, 0]]
    )
    sig = 2e-3 * s1.sectors[0, :, 2]
    C = velocity_fix_covariance(a_local[0], a_local[1:], P, b, dt, sig)
    expected = np.sqrt([np.trace(C[:3, :3]), np.trace(C[3:, 3:])])
    np.testing.assert_allclose(s1.track_sigma[0, row[0]], expected, rtol=1e-9)
    # and the solution they belong to is the generic solver's
    sol = solve_conjugation(a_local[0], a_local[1:], P, b, dt, order=1)
    R1 = params.rotations[0]  # world = O_1 + R_1ᵀ (frame 1)
    world = np.concatenate([params.receivers[0] + R1.T @ sol.position, R1.T @ sol.velocity])
    np.testing.assert_allclose(s1.track_x[0, row[0]], world, rtol=1e-9, atol=1e-9)
    assert s2.batch_size == B


def test_a_wider_sector_fixes_coarser():
    assert kernels.sector_sigma(1.0, 1e-3, 0.0) == pytest.approx(
        10 * kernels.sector_sigma(0.1, 1e-3, 0.0)
    )


def test_termination_once_every_drone_has_left():
    params = ScanningParams(n_drones=1, close_drones=0, late_drones=0, drone_speed=(30.0, 30.0),
                            max_acceleration=0.0)  # fmt: skip
    s = sim.reset(params, np.random.default_rng(0), 4)
    done = np.zeros(4, bool)
    for _ in range(20):
        s, r, term = sim.step(params, s, np.zeros((4, 3, 3)), np.random.default_rng(0))
        done |= term
        assert np.all(np.isfinite(r))
    assert done.all()


@pytest.mark.parametrize(
    "fields, match",
    [
        ({"receiver_azimuths": (0.0, 1.0)}, "receiver_azimuths"),
        ({"scan_offsets": (0.0, 0.9, 0.5)}, "scan_offsets"),
        ({"sector_width": (0.5, 0.1)}, "sector_width"),
        ({"tracker": "kalman"}, "tracker"),
        ({"period": -1.0}, "period"),
        ({"noise_per_width": float("nan")}, "noise_per_width"),
        ({"close_drones": 4}, "close_drones"),
        ({"raster_lines": 0}, "raster_lines"),
        ({"fit_false_alarm": 0.0}, "fit_false_alarm"),
        ({"fit_false_alarm": 1.0}, "fit_false_alarm"),
    ],
)
def test_bad_params_name_the_field(fields, match):
    with pytest.raises(ValueError, match=match):
        ScanningParams(**fields)


def test_bad_actions_raise():
    env = gym.make(ENV_ID)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="action"):
        env.step(np.full(9, np.nan, np.float32))
    with pytest.raises(ValueError, match="action"):
        env.step(np.zeros(4, np.float32))
    s = sim.reset(ScanningParams(), np.random.default_rng(0), 2)
    with pytest.raises(ValueError, match="action"):
        sim.step(ScanningParams(), s, np.zeros((2, 5)), np.random.default_rng(0))
    with pytest.raises(ValueError, match="drone_position"):
        sim.start(
            ScanningParams(),
            np.zeros((2, 3, 3)),
            np.zeros((2, 4, 3)),
            np.zeros((2, 4, 3)),
            np.zeros((2, 4)),
        )


def test_rgb_array_frames():
    env = gym.make(ENV_ID, render_mode="rgb_array")
    env.reset(seed=1)
    for _ in range(4):
        env.step(FULL)
    frame = env.render()
    assert frame.dtype == np.uint8 and frame.ndim == 3 and frame.shape[2] == 3
    assert frame.std() > 0


@pytest.mark.parametrize(
    "tracker, share", [("proposed", 0.85), ("alternative", 0.7), ("algorithmic", 0.85)]
)
def test_every_tracker_finds_the_drones_under_the_full_sweep(tracker, share):
    params = ScanningParams(tracker=tracker, close_drones=0)
    rng = np.random.default_rng(4)
    B = 48
    s = sim.reset(params, rng, B)
    full = np.broadcast_to(np.array([0.0, 0.0, 1.0]), (B, 3, 3)).copy()
    present = tracked = 0.0
    for k in range(12):
        s, r, _ = sim.step(params, s, full, rng)
        assert np.all(np.isfinite(r))
        if k >= 4:
            present += s.parts[:, 0].sum()
            tracked += s.parts[:, 1].sum()
    assert tracked / present > share


def _noiseless_errors(tracker: str) -> np.ndarray:
    params = ScanningParams(tracker=tracker, noise_per_width=0.0, close_drones=0,
                            late_drones=0, max_acceleration=0.0)  # fmt: skip
    rng = np.random.default_rng(6)
    B = 16
    s = sim.reset(params, rng, B)
    full = np.broadcast_to(np.array([0.0, 0.0, 1.0]), (B, 3, 3)).copy()
    for _ in range(8):
        prev = s
        s, _, _ = sim.step(params, s, full, rng)
    errors = []
    for i in range(B):
        for j in range(params.n_drones):
            q = s.assigned[i, j]
            if q < 0 or s.track_t[i, q] < prev.t[i]:
                continue
            dt = s.track_t[i, q] - prev.t[i]
            truth = prev.drone_position[i, j] + prev.drone_velocity[i, j] * dt
            errors.append(np.linalg.norm(s.track_x[i, q, :3] - truth))
    return np.array(errors)


def test_algorithmic_tracker_compensates_the_scan_delay():
    """Paper 003's detector re-solves each pair with the track's motion (B̂_2 = b_2 − V Δt_2):
    without noise its error is a fraction of the alternative's dynamic error (a₁·V) Δt, which
    ignores the delay; what is left is the first, uncompensated fixes' share of the averaged
    velocity."""
    algorithmic, alternative = _noiseless_errors("algorithmic"), _noiseless_errors("alternative")
    assert algorithmic.size > 20 and alternative.size > 20
    assert np.median(algorithmic) < 0.25
    assert np.median(alternative) > 4 * np.median(algorithmic)
