"""Paper 002 (theory §7): eq. (1)-(3) construction, exact 4-bearing fix (AT-7), block smoothing."""

from __future__ import annotations

import numpy as np
import pytest

from sensorgym.reproduce.experiments.paper002 import Paper002Scenario, ideal_result, noisy_result
from sensorgym.trackers.bearings.four_bearings import (
    block_base_bearings,
    fictitious_bearing_fix,
    fictitious_relative_track,
    literal_refinement,
    paper_construction,
    tan_beta,
)

KMH = 1.0 / 3.6


def _scenario(vp_kmh, rng=None, target_course=None, delta=90.0):
    """Platform along bearing 1 at vp, then perpendicular to bearing 2 at 2·vp (≥ 20 km/h)."""
    if target_course is None:
        target_course = np.deg2rad(300.0)
    b0 = np.deg2rad(30.0) if rng is None else rng.uniform(-np.pi, np.pi)
    T0 = 30e3 * np.array([np.sin(b0), np.cos(b0)])
    VT = 40 * KMH * np.array([np.sin(target_course), np.cos(target_course)])
    t = np.arange(6) * delta
    u1 = T0 / np.linalg.norm(T0)
    M = [np.zeros(2), vp_kmh * KMH * u1 * delta, 2 * vp_kmh * KMH * u1 * delta]
    z = lambda k: np.arctan2(*(T0 + VT * t[k] - M[k]))  # noqa: E731
    h = z(1) - np.pi / 2
    v1 = max(2 * vp_kmh, 20) * KMH * np.array([np.sin(h), np.cos(h)])
    for _ in range(3):
        M.append(M[-1] + v1 * delta)
    M = np.array(M)
    return t, M, np.array([z(k) for k in range(6)]), T0, VT


@pytest.mark.parametrize("vp", [0.0, 20.0, 40.0])
def test_four_bearing_fix_is_exact(vp):
    # AT-7: exact (< 1 m) for uniformly moving platforms at 0-40 km/h with the theory §7.3 turn
    t, M, z, T0, VT = _scenario(vp)
    for D in (50e3, 10e3):
        fix = fictitious_bearing_fix(t[:4], M[:4], z[:4], D)
        assert np.linalg.norm(fix.position_at(t[3]) - (T0 + VT * t[3])) < 1e-6
        np.testing.assert_allclose(fix.velocity, VT, atol=1e-9)
        np.testing.assert_allclose(fix.scale * D, 30e3, rtol=1e-12)
    fix6 = fictitious_bearing_fix(t, M, z, 50e3)
    assert np.linalg.norm(fix6.position_at(t[5]) - (T0 + VT * t[5])) < 1e-6
    lit = literal_refinement(fix, t[3:], M[3:], z[3:])
    assert np.linalg.norm(lit.position_at(t[5]) - (T0 + VT * t[5])) < 1e-6
    np.testing.assert_allclose(lit.velocity, VT, atol=1e-9)


@pytest.mark.parametrize("vp", [0.0, 20.0, 40.0])
def test_equation_1_construction_matches_direct_solve(vp):
    # eq. (1)-(3) with Q = π − β give AB′ = B′C′, and B′ equals the direct solve's F₂
    _, M, z, *_ = _scenario(vp)
    for D in (50e3, 20e3, 45e3):
        track = paper_construction(M[:3], z[:3], np.array(D))
        AB = np.linalg.norm(track.B_prime - track.A)
        BC = np.linalg.norm(track.C_prime - track.B_prime)
        assert abs(AB - BC) < 1e-7 * AB
        F1, dF = fictitious_relative_track(z[:3], np.array(D))
        np.testing.assert_allclose(track.B_prime, M[1] + F1 + dF, atol=1e-6)
        np.testing.assert_allclose(
            np.tan(track.beta), tan_beta(track.c1, track.c2, track.alpha1, track.alpha2)
        )


def test_common_origin_reduces_to_tan_a1_minus_2_tan_a2():
    # theory §7.2 special case: c_k = D cot α_k gives tan β = tan α₁ − 2 tan α₂, independent of D
    rng = np.random.default_rng(0)
    a1, a2 = rng.uniform(0.3, 1.4, 2)
    for D in (1.0, 7.0, 1e4):
        tb = tan_beta(D / np.tan(a1), D / np.tan(a2), a1, a2)
        np.testing.assert_allclose(tb, np.tan(a1) - 2 * np.tan(a2), rtol=1e-12)


def test_uncorrected_course_is_biased_only_for_moving_platform():
    # theory §13.25: the fictitious track is parallel to the true one only for vp = 0
    errors = {}
    for vp in (0.0, 40.0):
        t, M, z, _, VT = _scenario(vp)
        _, dF = fictitious_relative_track(z[:3], np.array(50e3))
        U_f = dF / (t[1] - t[0]) + (M[1] - M[0]) / (t[1] - t[0])
        cos = U_f @ VT / np.linalg.norm(U_f) / np.linalg.norm(VT)
        errors[vp] = np.degrees(np.arccos(np.clip(abs(cos), -1, 1)))
    assert errors[0.0] < 1e-6
    assert errors[40.0] > 3.0


def test_batched_fix_equals_looped():
    rng = np.random.default_rng(4)
    cases = [_scenario(vp, rng, rng.uniform(-np.pi, np.pi)) for vp in (10.0, 25.0, 35.0)]
    t = cases[0][0]
    M = np.stack([c[1] for c in cases])
    z = np.stack([c[2] for c in cases])
    batched = fictitious_bearing_fix(t, M, z, np.array([50e3, 40e3, 60e3]))
    for i, D in enumerate((50e3, 40e3, 60e3)):
        one = fictitious_bearing_fix(t, M[i], z[i], D)
        np.testing.assert_allclose(batched.position[i], one.position)
        np.testing.assert_allclose(batched.velocity[i], one.velocity)


def test_no_turn_makes_range_unobservable():
    t, M, z, T0, VT = _scenario(20.0)
    v0 = (M[1] - M[0]) / (t[1] - t[0])
    M_straight = M[0] + np.outer(t, v0)
    z_straight = np.arctan2(*(T0 + np.outer(t, VT) - M_straight).T)
    with pytest.raises(ValueError, match="unobservable"):
        fictitious_bearing_fix(t[:4], M_straight[:4], z_straight[:4], 50e3)
    with pytest.raises(ValueError, match="equal"):
        fictitious_bearing_fix(t[[0, 1, 3, 4]], M[:4], z[:4], 50e3)
    bent = M.copy()
    bent[2] += [30.0, 0.0]
    with pytest.raises(ValueError, match="uniformly"):
        fictitious_bearing_fix(t[:4], bent[:4], z[:4], 50e3)


@pytest.mark.parametrize("degree", [1, 2])
def test_block_smoothing_exact_and_noise_gain(degree):
    t = 2.0 * np.arange(1, 91)
    coef = [0.3, 2e-3, -4e-6]
    truth = sum(c * t**i for i, c in enumerate(coef[: degree + 1]))
    tb, base, gain = block_base_bearings(t, truth, 45, degree)
    np.testing.assert_allclose(tb, [90.0, 180.0])
    np.testing.assert_allclose(base, truth[[44, 89]], atol=1e-12)
    rng = np.random.default_rng(5)
    sigma = 0.01
    noisy = truth + sigma * rng.standard_normal((20_000, t.size))
    _, b, _ = block_base_bearings(t, noisy, 45, degree)
    np.testing.assert_allclose(np.std(b - truth[[44, 89]], axis=0), gain * sigma, rtol=0.03)
    # bearings across ±π are unwrapped before the fit
    wrapped = np.angle(np.exp(1j * (np.pi - 0.02 + 1e-3 * t)))
    _, bw, _ = block_base_bearings(t, wrapped, 45, 1)
    np.testing.assert_allclose(np.cos(bw - (np.pi - 0.02 + 1e-3 * t[[44, 89]])), 1.0)


def test_reproduction_rt8_and_rt9_reduced():
    scn = Paper002Scenario()
    ideal = ideal_result(scn)
    assert max(ideal["position_error_m"].values()) < 50.0
    assert abs(ideal["start_range_m"] - ideal["true_start_range_m"]) < 1.0
    noisy = noisy_result(scn, 30, seed=1)
    rows = noisy["rows"]
    pre = rows["preliminary (base 4)"]["median_position"]
    assert rows["ML on base bearings 1-6"]["median_position"] < pre
    assert rows["no smoothing (raw, base 4)"]["median_position"] > 1.5 * pre  # "large errors"
    sweep = list(noisy["speed_sweep_median_position_m"].values())
    assert sweep[0] > sweep[1] > sweep[2]  # OC-5: longer baseline, smaller errors
    assert (
        rows["ML on raw bearings (9 min)"]["median_position"]
        < rows["ML on raw bearings (6 min)"]["median_position"]
    )
