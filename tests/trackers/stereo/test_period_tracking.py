"""Paper 000 trackers (stereo_tracker000) and the Table 1-2 reproduction (AT-9, AT-10)."""

import numpy as np
import pytest

from sensorgym.envs.worlds.drones import Trajectories
from sensorgym.envs.worlds.stereo import FixedDelay, NoiseModel, ReceiverLayout, simulate
from sensorgym.reproduce.experiments.paper000 import Scenario000, run_cell
from sensorgym.trackers.stereo.conjugation import solve_proposed
from sensorgym.trackers.stereo.period_tracking import (
    AlternativeParams,
    ProposedParams,
    proposed_candidates,
    track_alternative,
    track_proposed,
)

LAYOUT = ReceiverLayout.on_circle(120.0, [0.0, 90.0, 270.0], aim=(0.0, 40.0, 0.0))
TRAJ = Trajectories.linear(
    [[0.0, 40.0, 0.0], [3.0, 41.0, -2.0], [-2.0, 38.0, 3.0]],
    [[10.0, 2.0, -5.0], [10.0, 2.0, -5.0], [10.0, 2.0, -5.0]],
)


def test_proposed_noise_free_recovers_objects_and_association():
    timings = (FixedDelay(0.0), FixedDelay(0.1), FixedDelay(0.2))
    per, truth = simulate(np.random.default_rng(0), TRAJ, LAYOUT, timings, 5, 1.0)
    P, b = LAYOUT.relative
    det = track_proposed(per, P, b, ProposedParams(position_sigma=0.01))
    assert det.m_hat == 3
    pos, vel, t = det.latest()
    for s in range(3):
        labels = {int(truth[i].source[k][det.members[s, i, k]]) for i in range(5) for k in range(3)}
        assert len(labels) == 1
        j = labels.pop()
        np.testing.assert_allclose(
            pos[s], LAYOUT.to_frame1(TRAJ.position(np.full(3, t[s]))[j]), atol=1e-7
        )
        np.testing.assert_allclose(vel[s], LAYOUT.rotations[0].T @ TRAJ.velocity[j], atol=1e-7)


def test_alternative_noise_free_without_delay_is_exact():
    layout = LAYOUT.subset([0, 1])
    per, truth = simulate(
        np.random.default_rng(1), TRAJ, layout, (FixedDelay(0.0), FixedDelay(0.0)), 4, 1.0
    )
    P, b = layout.relative
    det = track_alternative(per, P[0], b[0], AlternativeParams(position_sigma=0.01, max_delay=0.0))
    assert det.m_hat == 3
    pos, vel, t = det.latest()
    for s in range(3):
        j = int(truth[-1].source[0][det.members[s, -1, 0]])
        np.testing.assert_allclose(
            pos[s], LAYOUT.to_frame1(TRAJ.position(np.full(3, t[s]))[j]), atol=1e-6
        )
        np.testing.assert_allclose(vel[s], LAYOUT.rotations[0].T @ TRAJ.velocity[j], atol=1e-6)


def test_alternative_dynamic_error_grows_with_delay():
    layout = LAYOUT.subset([0, 1])
    P, b = layout.relative
    one = Trajectories.linear(TRAJ.start[:1], TRAJ.velocity[:1])
    err = []
    for d in (0.1, 0.25):
        per, _ = simulate(
            np.random.default_rng(2), one, layout, (FixedDelay(0.0), FixedDelay(d)), 5, 1.0
        )
        det = track_alternative(per, P[0], b[0], AlternativeParams(max_delay=d))
        pos, _, t = det.latest()
        err.append(np.linalg.norm(pos[0] - LAYOUT.to_frame1(one.position(t[0]))[0]))
    assert err[1] / err[0] == pytest.approx(2.5, rel=0.15)


def test_batched_candidates_equal_one_at_a_time():
    timings = (FixedDelay(0.0), FixedDelay(0.1), FixedDelay(0.3))
    per, _ = simulate(
        np.random.default_rng(3), TRAJ, LAYOUT, timings, 1, 1.0, NoiseModel(angle_sigma=1e-3)
    )
    P, b = LAYOUT.relative
    cand = proposed_candidates(per[0], P, b, ProposedParams(max_speed=1e9))
    assert cand.members.shape[0] > 0
    for row, (j1, j2, j3) in enumerate(cand.members):
        f = per[0]
        sol = solve_proposed(
            f[0].directions[j1],
            np.stack([f[1].directions[j2], f[2].directions[j3]]),
            P,
            b,
            np.array([f[1].times[j2], f[2].times[j3]]) - f[0].times[j1],
        )
        np.testing.assert_allclose(cand.position[row], sol.position, atol=1e-9)
        np.testing.assert_allclose(cand.velocity[row], sol.velocity, atol=1e-9)


def test_noise_derived_thresholds():
    p = ProposedParams(position_sigma=0.1)
    assert p.delta == pytest.approx(4.03 * np.sqrt(2) * 0.1, rel=0.01)
    a = AlternativeParams(position_sigma=0.1, max_speed=40.0, max_delay=0.25)
    assert a.eps_J == pytest.approx((4.03 * np.sqrt(2) * 0.1 + 10.0) ** 2, rel=0.01)
    with pytest.raises(ValueError):
        ProposedParams(position_sigma=0.0)


@pytest.mark.slow
def test_at9_proposed_maxwell_errors_for_both_delays():
    """AT-9 / RT-2 (reduced runs): d_avg ∈ [0.14, 0.18], σ_d ∈ [0.055, 0.08]."""
    for k, delays in enumerate(((0.1, 0.2), (0.3, 0.4))):
        o = run_cell(np.random.default_rng(10 + k), Scenario000(), "proposed", 1, delays, 300)
        assert 0.14 <= o["d_avg"] <= 0.18 and 0.055 <= o["d_std"] <= 0.08
        assert o["pr_m"] >= 0.95


@pytest.mark.slow
def test_at10_alternative_ratio_and_detection_trend():
    """AT-10 / RT-3, RT-4 (reduced runs): d ratio ∈ [2.2, 2.8] and Pr_m falls with Δt."""
    o = [
        run_cell(np.random.default_rng(20 + k), Scenario000(), "alternative", 1, (d,), 400)
        for k, d in enumerate((0.1, 0.25))
    ]
    assert 2.2 <= o[1]["d_avg"] / o[0]["d_avg"] <= 2.8
    assert o[1]["pr_m"] < o[0]["pr_m"]


def test_reproduction_does_not_depend_on_worker_count():
    from sensorgym.reproduce.experiments.paper000 import reproduce

    one = reproduce(runs=4, seed=1, jobs=1)
    two = reproduce(runs=4, seed=1, jobs=2)
    assert one["cells"] == two["cells"]
    assert {c["id"] for c in one["checks"]} == {"RT-2", "RT-3", "RT-4", "RT-5"}
