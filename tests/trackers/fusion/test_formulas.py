"""Paper 004 closed forms: eqs. (9), (10), (12), (13) and recurrence (11) (theory §9.4, §12.6 AT-8)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.special import erf

from sensorgym.trackers.fusion.detection_probability import (
    axis_holding_probability,
    combined_detection_parameter,
    detection_parameter,
    detection_probability,
)
from sensorgym.trackers.fusion.variance import (
    generalised_detection_parameter_sq,
    relative_variance_history,
    relative_variance_step,
    stationary_relative_variance,
    steps_to_stationarity,
    tracking_error,
)


def laplace_phi0(x: np.ndarray) -> np.ndarray:
    """Φ₀(x) = (2π)^{-1/2} ∫₀ˣ exp(−t²/2) dt, written independently via erf."""
    return 0.5 * erf(np.asarray(x) / np.sqrt(2.0))


def test_eq9_matches_paper_values_rt14() -> None:
    # AT-8 / RT-14: F = 0.01 -> P(q = 1, 2, 3, 5, 7) (theory §9.4)
    P = detection_probability([1.0, 2.0, 3.0, 5.0, 7.0], 0.01)
    np.testing.assert_allclose(P[:4], [0.0924, 0.3721, 0.7497, 0.9962], atol=1e-4)
    assert P[4] > 0.999998
    assert abs(float(detection_probability(3.0, 0.01)) - 0.7497) < 1e-4


def test_eq9_equals_laplace_form_as_printed() -> None:
    q = np.linspace(-2.0, 9.0, 45)[:, None]
    F = np.array([1e-4, 1e-3, 0.01, 0.1, 0.3])[None, :]
    # Φ₀⁻¹(0.5 − F) found by bisection on the independent Φ₀, not via scipy.stats
    lo, hi = np.full(F.shape, -10.0), np.full(F.shape, 10.0)
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        too_big = laplace_phi0(mid) > 0.5 - F
        hi, lo = np.where(too_big, mid, hi), np.where(too_big, lo, mid)
    printed = 0.5 + laplace_phi0(q - 0.5 * (lo + hi))
    np.testing.assert_allclose(detection_probability(q, F), printed, atol=1e-12)


def test_eq13_inverts_eq9() -> None:
    q = np.linspace(-1.0, 7.0, 33)
    for F in (1e-3, 0.01, 0.2):
        q_back = detection_parameter(detection_probability(q, F), F)
        np.testing.assert_allclose(q_back, q, atol=1e-9)
    P = np.array([0.05, 0.5, 0.7497, 0.99])
    P_back = detection_probability(detection_parameter(P, 0.01), 0.01)
    np.testing.assert_allclose(P_back, P, rtol=1e-12)


def test_bad_probabilities_rejected() -> None:
    with pytest.raises(ValueError, match="false_alarm"):
        detection_probability(3.0, 0.0)
    with pytest.raises(ValueError, match="probability"):
        detection_parameter(1.0, 0.01)
    with pytest.raises(ValueError, match="q"):
        detection_probability(np.nan, 0.01)


def test_eq10_combination_rules() -> None:
    q = np.array([[3.0, 4.0], [1.0, 1.0]])
    np.testing.assert_allclose(combined_detection_parameter(q), [5.0, np.sqrt(2.0)])
    np.testing.assert_allclose(combined_detection_parameter(q, rule="sum"), [7.0, 2.0])
    # several weak channels reach the detection quality of one strong channel
    four_weak = combined_detection_parameter(np.full(4, 2.5))
    assert detection_probability(four_weak, 0.01) > 0.99 > detection_probability(2.5, 0.01)
    with pytest.raises(ValueError, match="rule"):
        combined_detection_parameter(q, rule="max")  # type: ignore[arg-type]


def test_eq12_axis_holding() -> None:
    sigma = np.array([0.5, 1.0, 2.0])
    Pc = axis_holding_probability(2.0, 4.0, sigma)
    expected = (2 * laplace_phi0(2.0 / (2 * sigma))) * (2 * laplace_phi0(4.0 / (2 * sigma)))
    np.testing.assert_allclose(Pc, expected, rtol=1e-12)
    assert np.all(np.diff(Pc) < 0.0)


def test_eq12_matches_monte_carlo_of_the_axis_inside_the_projection() -> None:
    # independent N(0, σ²) errors in the two planes, object g × v centred on the line of sight
    rng = np.random.default_rng(12)
    g, v, sigma = 3.0, 1.5, 1.1
    err = rng.normal(0.0, sigma, size=(200_000, 2))
    inside = np.mean((np.abs(err[:, 0]) <= g / 2) & (np.abs(err[:, 1]) <= v / 2))
    assert abs(inside - float(axis_holding_probability(g, v, sigma))) < 0.004  # ≈ 4σ of MC


def test_stationary_variance_is_fixed_point_of_both_forms() -> None:
    rng = np.random.default_rng(4)
    P = rng.uniform(0.0, 1.0, 200)
    z2 = rng.uniform(0.0, 60.0, 200)
    R = rng.uniform(0.0, 0.999, 200)
    for form in ("mixture", "information"):
        d = stationary_relative_variance(P, z2, R, form)
        assert np.all((d > 0.0) & (d <= 1.0))
        np.testing.assert_allclose(relative_variance_step(d, P, z2, R, form), d, rtol=1e-10)
        # the recurrence converges to it from the prior
        far = relative_variance_history(P, z2, np.minimum(R, 0.95), 3000, form)[-1]
        np.testing.assert_allclose(
            far, stationary_relative_variance(P, z2, np.minimum(R, 0.95), form), rtol=1e-9
        )
    # no detection: no information, the variance stays at the prior
    assert float(stationary_relative_variance(0.0, 10.0, 0.99)) == pytest.approx(1.0)


def test_rt15_steps_to_stationarity() -> None:
    # theory §9.4 [D,V]: R = 0.99, z² = q²/2, 5 % of δ_∞: (a) 20, 9, 5, 3; (b) 15, 8, 4, 3
    q = np.array([2.0, 3.0, 5.0, 7.0])
    P = detection_probability(q, 0.01)
    z2 = generalised_detection_parameter_sq(q)
    np.testing.assert_array_equal(steps_to_stationarity(P, z2, 0.99, "mixture"), [20, 9, 5, 3])
    np.testing.assert_array_equal(steps_to_stationarity(P, z2, 0.99, "information"), [15, 8, 4, 3])


def test_rt16_tracking_error_at_one_km() -> None:
    # theory §9.5: (11a), z² = q²/2, θ₀ = 5 mrad, L = 1 km -> 1.99, 1.31, 0.88, 0.71, 0.56 m
    q = np.array([2.0, 3.0, 5.0, 7.0, 10.0])
    d = stationary_relative_variance(
        detection_probability(q, 0.01), generalised_detection_parameter_sq(q), 0.99
    )
    np.testing.assert_allclose(
        tracking_error(d, 5e-3, 1000.0), [1.99, 1.31, 0.88, 0.71, 0.56], atol=0.006
    )
    assert np.all(np.diff(tracking_error(d, 5e-3, 1000.0)) < 0.0)
