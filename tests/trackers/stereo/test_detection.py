"""Paper 003 algebraic (stereo_algebraic003) and algorithmic (stereo_detector003) detectors."""

import numpy as np
import pytest

from sensorgym.envs.worlds.drones import Trajectories
from sensorgym.envs.worlds.scanning import RasterScan
from sensorgym.envs.worlds.stereo import DetectionModel, NoiseModel, ReceiverLayout, simulate
from sensorgym.reproduce.experiments.paper003 import (
    Scenario003,
    algebraic_accuracy,
    algorithmic_cell,
)
from sensorgym.trackers.stereo.algebraic_detection import (
    AlgebraicParams,
    algebraic_multi,
    algebraic_single,
    economical,
)
from sensorgym.trackers.stereo.algorithmic_detection import AlgorithmicParams, detect_algorithmic

AIM = (0.0, 25.0, 0.0)
SCAN = RasterScan(30.0, 30.0, 100, 100, 20.0)


def _labels(det, truth, s):
    N, S = det.members.shape[1:]
    return np.array(
        [[truth[i].source[k][det.members[s, i, k]] for k in range(S)] for i in range(N)]
    )


def test_algebraic_single_noise_free_recovers_position_and_velocity():
    layout = ReceiverLayout.on_circle(50.0, [0.0, 90.0, 180.0], aim=AIM)
    traj = Trajectories.linear([[1.0, 26.0, -1.0]], [[0.1, 0.02, -0.08]])
    per, _ = simulate(np.random.default_rng(0), traj, layout, (SCAN,) * 3, 1, 20.0)
    P, b = layout.relative
    sol = algebraic_single(per[0], P, b, order=1)
    t1 = per[0][0].times[0]
    np.testing.assert_allclose(sol.position, layout.to_frame1(traj.position(t1))[0], atol=1e-6)
    np.testing.assert_allclose(sol.velocity, layout.rotations[0].T @ traj.velocity[0], atol=1e-6)
    # weights do not change a square (n = 3) system
    w = algebraic_single(per[0], P, b, order=1, weighted=True)
    np.testing.assert_allclose(w.position, sol.position, atol=1e-6)
    # ignoring the motion leaves a dynamic error
    assert np.linalg.norm(algebraic_single(per[0], P, b, order=0).position - sol.position) > 1e-3


def test_algebraic_multi_n4_separates_objects():
    layout = ReceiverLayout.on_circle(
        50.0, [0.0, 90.0, 180.0, 270.0], heights=[0, 3, 0, 6], aim=AIM
    )
    traj = Trajectories.linear(
        [[0.0, 25.0, 0.0], [4.0, 27.0, -3.0], [-3.0, 23.0, 4.0]],
        [[0.1, 0.0, 0.05], [-0.05, 0.02, 0.1], [0.08, -0.03, 0.0]],
    )
    per, truth = simulate(
        np.random.default_rng(1), traj, layout, (SCAN,) * 4, 1, 20.0, NoiseModel(angle_sigma=1e-5)
    )
    P, b = layout.relative
    det = algebraic_multi(
        per[0], P, b, 20.0, AlgebraicParams(position_sigma=0.05, velocity_sigma=0.005)
    )
    assert det.m_hat == 3
    for s in range(3):
        lab = _labels(det, truth, s)
        assert np.all(lab == lab[0, 0])


def test_economical_two_periods_two_receivers():
    layout = ReceiverLayout.on_circle(50.0, [0.0, 90.0], aim=AIM)
    traj = Trajectories.linear(
        [[0.0, 25.0, -5.0], [4.0, 27.0, -2.0]], [[0.1, 0.05, 0.3], [-0.2, 0.0, 0.25]]
    )
    per, truth = simulate(np.random.default_rng(2), traj, layout, (SCAN,) * 2, 2, 20.0)
    P, b = layout.relative
    det = economical(
        per, P[0], b[0], 40.0, AlgebraicParams(position_sigma=0.01, velocity_sigma=0.001)
    )
    assert det.m_hat == 2
    for s in range(2):
        lab = _labels(det, truth, s)
        assert np.all(lab == lab[0, 0])
        j = lab[0, 0]
        np.testing.assert_allclose(
            det.positions[s, 0], layout.to_frame1(traj.position(det.times[s, 0]))[j], atol=1e-5
        )


def test_algorithmic_noise_free_detects_every_object_exactly():
    layout = ReceiverLayout.on_circle(50.0, [0.0, 90.0], aim=(0.0, 10.0, 0.0))
    traj = Trajectories.linear(
        [[0.0, 10.0, 0.0], [4.0, 12.0, -3.0], [-3.0, 8.0, 4.0]],
        [[1.0, 0.0, 0.5], [-0.5, 0.2, 1.0], [0.8, -0.3, 0.0]],
    )
    scan = RasterScan(30.0, 30.0, 100, 100, 1.0)
    per, truth = simulate(np.random.default_rng(3), traj, layout, (scan,) * 2, 6, 1.0)
    P, b = layout.relative
    det = detect_algorithmic(
        per, P[0], b[0], AlgorithmicParams(sigma_e=0.01, sigma_position=0.05, max_delay=1.0)
    )
    assert det.m_hat == 3
    for s in range(3):
        lab = _labels(det, truth, s)
        assert np.all(lab == lab[0, 0])
        j = lab[0, 0]
        t = det.times[s, -1]
        np.testing.assert_allclose(
            det.positions[s, -1], layout.to_frame1(traj.position(np.full(3, t))[j]), atol=0.05
        )


def test_algorithmic_survives_a_missed_period():
    layout = ReceiverLayout.on_circle(50.0, [0.0, 90.0], aim=(0.0, 10.0, 0.0))
    traj = Trajectories.linear([[0.0, 10.0, 0.0]], [[1.0, 0.0, 0.5]])
    scan = RasterScan(30.0, 30.0, 100, 100, 1.0)
    per, _ = simulate(np.random.default_rng(4), traj, layout, (scan,) * 2, 5, 1.0)
    empty = type(per[2][0])(np.zeros((0, 3)), np.zeros(0), np.zeros(0))
    per[2] = (empty, per[2][1])
    P, b = layout.relative
    det = detect_algorithmic(
        per, P[0], b[0], AlgorithmicParams(sigma_e=0.01, sigma_position=0.05, max_delay=1.0)
    )
    assert det.m_hat == 1
    assert det.members[0, 2].tolist() == [-1, -1] and np.all(det.members[0, [0, 1, 3, 4]] == 0)


def test_noise_derived_parameters():
    p = AlgorithmicParams(sigma_e=0.05, sigma_position=1.0, period=1.0, gate=4.0)
    assert p.c[0] == pytest.approx(20.0) and p.alpha == (8.0, 12.0)
    with pytest.raises(ValueError):
        AlgorithmicParams(beam=0)


@pytest.mark.slow
def test_rt10_rt11_velocity_term_and_close_layout():
    sc = Scenario003()
    v2 = algebraic_accuracy(np.random.default_rng(5), sc, 2, 150)
    v1 = algebraic_accuracy(np.random.default_rng(6), sc, 1, 50)
    assert v2["error_3_params"] > 2.5 * v2["error_6_params"]
    assert v1["error_6_params"] > 5 * v2["error_6_params"]


@pytest.mark.slow
def test_rt12_detection_probability_falls_with_m():
    sc = Scenario003()
    p2 = algorithmic_cell(np.random.default_rng(7), sc, 2, 5, 150, False)["p_m"]
    p5 = algorithmic_cell(np.random.default_rng(8), sc, 5, 5, 150, False)["p_m"]
    assert p2 >= 0.95 and p5 < p2


def test_algorithmic_rejects_false_fixes():
    layout = ReceiverLayout.on_circle(50.0, [0.0, 90.0], aim=(0.0, 10.0, 0.0))
    traj = Trajectories.linear(
        [[0.0, 10.0, 0.0], [4.0, 12.0, -3.0], [-3.0, 8.0, 4.0]],
        [[1.0, 0.0, 0.5], [-0.5, 0.2, 1.0], [0.8, -0.3, 0.0]],
    )
    scan = RasterScan(30.0, 30.0, 100, 100, 1.0)
    sigma = np.deg2rad(0.03)
    P, b = layout.relative
    params = AlgorithmicParams(sigma_e=50 * sigma, sigma_position=0.1, max_delay=1.0)
    for seed in range(5):
        per, truth = simulate(
            np.random.default_rng(seed),
            traj,
            layout,
            (scan,) * 2,
            6,
            1.0,
            NoiseModel(angle_sigma=sigma),
            DetectionModel(false_rate=3.0),
        )
        det = detect_algorithmic(per, P[0], b[0], params)
        assert det.m_hat == 3
        for s in range(3):
            lab = _labels(det, truth, s)
            assert lab[0, 0] >= 0 and np.all(lab == lab[0, 0])


def test_per_period_poses_equal_static_poses():
    layout = ReceiverLayout.on_circle(50.0, [0.0, 90.0], aim=(0.0, 10.0, 0.0))
    traj = Trajectories.linear(
        [[0.0, 10.0, 0.0], [4.0, 12.0, -3.0]], [[1.0, 0.0, 0.5], [-0.5, 0.2, 1.0]]
    )
    scan = RasterScan(30.0, 30.0, 100, 100, 1.0)
    per, _ = simulate(
        np.random.default_rng(9), traj, layout, (scan,) * 2, 4, 1.0, NoiseModel(angle_sigma=1e-4)
    )
    P, b = layout.relative
    params = AlgorithmicParams(sigma_e=0.01, sigma_position=0.05, max_delay=1.0)
    static = detect_algorithmic(per, P[0], b[0], params)
    moving = detect_algorithmic(per, np.repeat(P[:1], 4, 0), np.repeat(b[:1], 4, 0), params)
    np.testing.assert_array_equal(static.members, moving.members)
    np.testing.assert_allclose(static.positions, moving.positions)


def test_whitened_index_weights_only_the_transverse_part():
    from sensorgym.trackers.stereo.algorithmic_detection import _norm

    u = np.array([[0.0, 0.0, 1.0]])
    d = np.array([[3.0, 0.0, 4.0]])
    assert _norm(d, u, 1.0)[0] == pytest.approx(5.0)
    assert _norm(d, u, 2.0)[0] == pytest.approx(np.hypot(4.0, 6.0))
    p = AlgorithmicParams(sigma_position=1.0, sigma_transverse=0.05)
    assert p.transverse_gain == pytest.approx(20.0)
    assert AlgorithmicParams().transverse_gain == 1.0


def test_batched_continuation_equals_group_by_group():
    from dataclasses import replace

    from sensorgym.trackers.stereo.algorithmic_detection import _births, _continue
    from sensorgym.trackers.stereo.association import combinations

    layout = ReceiverLayout.on_circle(50.0, [0.0, 90.0], aim=(0.0, 10.0, 0.0))
    traj = Trajectories.linear(
        [[0.0, 10.0, 0.0], [4.0, 12.0, -3.0], [-3.0, 8.0, 4.0]],
        [[1.0, 0.0, 0.5], [-0.5, 0.2, 1.0], [0.8, -0.3, 0.0]],
    )
    scan = RasterScan(30.0, 30.0, 100, 100, 1.0)
    per, _ = simulate(
        np.random.default_rng(12), traj, layout, (scan,) * 2, 2, 1.0, NoiseModel(angle_sigma=1e-3)
    )
    P, b = layout.relative
    prm = replace(
        AlgorithmicParams(sigma_e=0.5, sigma_position=2.0, max_delay=1.0, gate=50.0), beam=None
    )
    pairs0 = combinations([per[0][0].count, per[0][1].count])
    groups = _births(per[0][0], per[0][1], pairs0, P[0], b[0], 0, 2, prm)
    pairs1 = combinations([per[1][0].count, per[1][1].count])
    batch, gi, ci = _continue(groups, per[1][0], per[1][1], pairs1, P[0], b[0], 1, prm)
    assert len(gi) > 3
    rows = {}
    for g in range(groups.score.shape[0]):
        one, _, cj = _continue(
            groups.take(np.array([g])), per[1][0], per[1][1], pairs1, P[0], b[0], 1, prm
        )
        for r, c in enumerate(cj):
            rows[(g, int(c))] = (one.score[r], one.M1[r], one.V1[r])
    assert len(rows) == len(gi)
    for r, (g, c) in enumerate(zip(gi, ci, strict=True)):
        s, M, V = rows[(int(g), int(c))]
        assert batch.score[r] == pytest.approx(s, rel=1e-12)
        np.testing.assert_allclose(batch.M1[r], M, rtol=1e-12)
        np.testing.assert_allclose(batch.V1[r], V, rtol=1e-12)


def test_reproduction_runs_end_to_end_and_reports_every_target():
    from sensorgym.reproduce.experiments.paper003 import format_report, reproduce

    res = reproduce(runs=3, algorithmic_runs=2, jobs=1)
    assert {c["id"] for c in res["checks"]} == {"RT-10", "RT-11", "RT-12", "RT-13", "ext"}
    assert all(c["status"] in ("matched", "missed") for c in res["checks"])
    assert all(c["reason"] for c in res["checks"] if c["status"] == "missed")
    assert "Targets (theory §12)" in format_report(res)
