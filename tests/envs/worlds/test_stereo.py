"""The simulated stereo world: geometry, raster timing, noise, detection (envs/worlds/stereo)."""

import numpy as np
import pytest

from sensorgym.envs.worlds.drones import GroupSpec, Trajectories, random_group
from sensorgym.envs.worlds.scanning import FixedDelay, RasterScan, ReceiverLayout
from sensorgym.envs.worlds.stereo import DetectionModel, NoiseModel, observe_period, simulate
from sensorgym.trackers.geometry import angles_from_unit
from sensorgym.trackers.stereo.conjugation import solve_conjugation

LAYOUT = ReceiverLayout.on_circle(50.0, [0.0, 90.0, 180.0], aim=(0.0, 25.0, 0.0))


def _still(points):
    p = np.asarray(points, dtype=float)
    return Trajectories.linear(p, np.zeros_like(p))


def test_noise_free_directions_point_at_the_objects():
    traj = Trajectories.linear(
        [[1.0, 24.0, -2.0], [-2.0, 27.0, 1.0]], [[0.3, 0.0, -0.2], [0.0, 0.1, 0.4]]
    )
    fixes, truth = observe_period(
        np.random.default_rng(0), traj, LAYOUT, (RasterScan.paper003(),) * 3, 0, 20.0
    )
    for k, f in enumerate(fixes):
        assert f.count == 2
        for row in range(2):
            j = truth.source[k][row]
            world = traj.position(np.full(2, f.times[row]))[j]
            # recompute independently: R_kᵀ (p − o_k), normalised
            local = LAYOUT.rotations[k].T @ (world - LAYOUT.positions[k])
            np.testing.assert_allclose(f.directions[row], local / np.linalg.norm(local), atol=1e-12)
            np.testing.assert_allclose(truth.fix_positions[k][row], world, atol=1e-12)


def test_raster_time_of_a_still_object_is_its_pixel_time():
    scan = RasterScan.paper003()
    traj = _still([[2.0, 27.0, 1.0]])
    fixes, _ = observe_period(np.random.default_rng(1), traj, LAYOUT, (scan,) * 3, 3, 20.0)
    for k, f in enumerate(fixes):
        az, el = angles_from_unit(f.directions[0])
        col = np.floor((np.rad2deg(az) + 15.0) / 0.3)
        row = np.floor((15.0 - np.rad2deg(el)) / 0.3)
        assert f.times[0] == pytest.approx(60.0 + (row * 100 + col + 0.5) * 2e-3, abs=1e-9), k


def test_moving_object_is_fixed_where_the_scan_meets_it():
    scan = RasterScan.paper003()
    traj = Trajectories.linear([[-3.0, 25.0, 0.0]], [[0.4, 0.05, 0.0]])
    fixes, _ = observe_period(np.random.default_rng(2), traj, LAYOUT, (scan,) * 3, 0, 20.0)
    for f in fixes:
        az, el = angles_from_unit(f.directions[0])
        t, inside = scan.visit_time(az, el)
        assert inside and t == pytest.approx(f.times[0], abs=1e-9)


def test_fixed_delays_and_time_order():
    traj = _still([[0.0, 25.0, 0.0], [2.0, 25.0, 0.0], [0.0, 28.0, 2.0]])
    timings = (FixedDelay(0.0), FixedDelay(0.1), FixedDelay(0.3))
    fixes, _ = observe_period(np.random.default_rng(3), traj, LAYOUT, timings, 2, 1.0)
    for f, d in zip(fixes, (0.0, 0.1, 0.3), strict=True):
        np.testing.assert_allclose(f.times, 2.0 + d)
    # ties are broken at random: the list order does not reveal identity in every seed
    orders = {
        tuple(observe_period(np.random.default_rng(s), traj, LAYOUT, timings, 0, 1.0)[1].source[0])
        for s in range(20)
    }
    assert len(orders) > 1


def test_position_noise_is_one_displacement_seen_by_every_receiver():
    traj = Trajectories.linear([[1.0, 25.0, 0.0]], [[3.0, 1.0, -2.0]])
    timings = (FixedDelay(0.0), FixedDelay(0.1), FixedDelay(0.2))
    fixes, _ = observe_period(
        np.random.default_rng(4), traj, LAYOUT, timings, 0, 1.0, NoiseModel(position_sigma=0.5)
    )
    P, b = LAYOUT.relative
    sol = solve_conjugation(
        fixes[0].directions[0],
        np.stack([fixes[1].directions[0], fixes[2].directions[0]]),
        P,
        b,
        np.array([0.1, 0.2]),
        order=1,
    )
    # the rays are consistent: the velocity-aware solve is exact for the displaced point
    assert sol.residual < 1e-18
    np.testing.assert_allclose(
        sol.velocity, LAYOUT.rotations[0].T @ np.array([3.0, 1.0, -2.0]), atol=1e-8
    )
    true = LAYOUT.rotations[0].T @ (traj.position(0.0)[0] - LAYOUT.positions[0])
    assert 0.0 < np.linalg.norm(sol.position - true) < 3.0


def test_angle_noise_statistics():
    traj = _still([[0.0, 25.0, 0.0]])
    sigma = np.deg2rad(0.5)
    rng = np.random.default_rng(5)
    az = [
        angles_from_unit(
            observe_period(
                rng, traj, LAYOUT, (FixedDelay(),) * 3, 0, 1.0, NoiseModel(angle_sigma=sigma)
            )[0][0].directions[0]
        )[0]
        for _ in range(500)
    ]
    assert np.std(az) == pytest.approx(sigma, rel=0.15)


def test_missed_detections_and_false_fixes():
    traj = _still([[0.0, 25.0, 0.0]] * 1)
    rng = np.random.default_rng(6)
    det = DetectionModel(p_detect=0.5, false_rate=2.0)
    counts, trues = [], []
    for _ in range(400):
        fixes, truth = observe_period(rng, traj, LAYOUT, (FixedDelay(),) * 3, 0, 1.0, detection=det)
        counts.append(np.sum(truth.source[0] < 0))
        trues.append(np.sum(truth.source[0] == 0))
        assert np.all((fixes[0].powers >= 0) & (fixes[0].powers <= 1))
        assert np.all(np.isnan(truth.fix_positions[0][truth.source[0] < 0]))
    assert np.mean(counts) == pytest.approx(2.0, abs=0.25)
    assert np.mean(trues) == pytest.approx(0.5, abs=0.08)


def test_out_of_sector_objects_are_not_fixed_and_poses_are_inputs():
    traj = _still([[0.0, 25.0, 0.0]])
    away = ReceiverLayout.on_circle(
        50.0, [0.0, 90.0, 180.0], aim=(0.0, 25.0, 200.0), centre=(0.0, 0.0, 0.0)
    )
    f_away, _ = observe_period(
        np.random.default_rng(7), traj, away, (RasterScan(period=1.0),) * 3, 0, 1.0
    )
    f_on, _ = observe_period(
        np.random.default_rng(7), traj, LAYOUT, (RasterScan(period=1.0),) * 3, 0, 1.0
    )
    assert f_away[1].count == 0 and f_on[1].count == 1


def test_seeded_simulation_is_reproducible():
    spec = GroupSpec(centre=(0.0, 25.0, 0.0), speed=(1.0, 2.0))
    runs = []
    for _ in range(2):
        rng = np.random.default_rng(8)
        traj = random_group(rng, 3, spec)
        per, _ = simulate(
            rng, traj, LAYOUT, (RasterScan(period=1.0),) * 3, 3, 1.0, NoiseModel(angle_sigma=1e-3)
        )
        runs.append(np.concatenate([f.directions.ravel() for p in per for f in p]))
    np.testing.assert_array_equal(runs[0], runs[1])


def test_random_group_separation_and_validation():
    traj = random_group(
        np.random.default_rng(9), 5, GroupSpec(centre=(0, 0, 0), spread=5, min_separation=3)
    )
    d = np.linalg.norm(traj.start[:, None] - traj.start[None], axis=-1)
    assert d[np.triu_indices(5, 1)].min() >= 3.0
    with pytest.raises(ValueError, match="rotations"):
        ReceiverLayout(np.ones((2, 3, 3)), np.zeros((2, 3)))
    with pytest.raises(ValueError, match="timings"):
        observe_period(np.random.default_rng(0), traj, LAYOUT, (FixedDelay(),), 0, 1.0)
    with pytest.raises(ValueError, match="delay"):
        FixedDelay(-1.0)


def test_accelerating_paths_and_local_frames():
    traj = Trajectories(np.zeros((1, 3)), np.array([[1.0, 0.0, 0.0]]), np.array([[0.0, 2.0, 0.0]]))
    np.testing.assert_allclose(traj.position(2.0), [[2.0, 4.0, 0.0]])
    np.testing.assert_allclose(traj.velocity_at(2.0), [[1.0, 4.0, 0.0]])
    p = np.array([1.0, 26.0, -2.0])
    local = LAYOUT.to_local(np.broadcast_to(p, (3, 3)))
    P, b = LAYOUT.relative
    # M_1 = P_k M_k + b_k (theory §2.1)
    for k in (1, 2):
        np.testing.assert_allclose(local[0], P[k - 1] @ local[k] + b[k - 1], atol=1e-12)


def test_false_fixes_are_timed_by_the_raster():
    traj = _still([[0.0, 25.0, 0.0]])
    scan = RasterScan(period=1.0)
    det = DetectionModel(false_rate=5.0, false_fov_deg=20.0)
    fixes, _ = observe_period(
        np.random.default_rng(11), traj, LAYOUT, (scan,) * 3, 2, 1.0, detection=det
    )
    for f in fixes:
        az, el = angles_from_unit(f.directions)
        t, inside = scan.visit_time(az, el)
        assert np.all(inside)
        np.testing.assert_allclose(f.times, 2.0 + t, atol=1e-12)
        assert np.all(np.diff(f.times) >= 0.0)
