"""Bearings filters at the edges (issue 10, defects 2, 5 and 7): bad inputs raise a
``ValueError`` naming the argument, documented fallbacks hold, moments stay exact at tiny
angular spreads, and the full-circle course prior is the generator's moments."""

from __future__ import annotations

import numpy as np
import pytest

from sensorgym.trackers.bearings.filters import (
    bearing_prior,
    ckf_update,
    ekf2_update,
    ekf_update,
    polar_moments,
    range_bank_predict,
    range_bank_prior,
    range_bank_update,
)
from sensorgym.trackers.bearings.models import BearingsGaussian, predict

BANK = dict(
    range_min=2_000.0,
    range_max=40_000.0,
    n_members=8,
    speed_mean=5.0,
    speed_sigma=3.0,
    course_mean=0.3,
    course_sigma=np.pi / np.sqrt(12.0),
)


def _bank(z=0.3, sigma=0.02, **kw):
    return range_bank_prior(z, sigma, [0.0, 0.0], 0.0, **{**BANK, **kw})


@pytest.mark.parametrize(
    "kw, name",
    [
        ({"sigma": np.nan}, "sigma"),
        ({"sigma": 0.0}, "sigma"),
        ({"sigma": np.inf}, "sigma"),
        ({"range_mean": 8_000.0, "range_sigma": 0.0}, "range_sigma"),
        ({"range_mean": 8_000.0, "range_sigma": np.nan}, "range_sigma"),
        ({"range_mean": np.inf, "range_sigma": 1_000.0}, "range_mean"),
        ({"range_mean": 8_000.0}, "range_mean, range_sigma"),
        ({"range_min": 5_000.0, "range_max": 5_000.0}, "range_min"),
        ({"n_members": 0}, "n_members"),
        ({"n_members": 2.5}, "n_members"),
        ({"range_density": "flat"}, "range_density"),
        ({"speed_sigma": np.nan}, "speed_sigma"),
        ({"z": np.nan}, "z"),
    ],
)
def test_bank_prior_names_the_bad_argument(kw, name):
    with pytest.raises(ValueError, match=name):
        _bank(**kw)


def test_predicting_back_in_time_raises_naming_the_time():
    s = BearingsGaussian(np.array([0.0, 0.0, 2.0, -1.0]), np.eye(4), 10.0)
    with pytest.raises(ValueError, match=r"t: prediction time 5\.0"):
        predict(s, 5.0, 1e-3)
    with pytest.raises(ValueError, match="t: "):
        predict(s, np.nan, 0.0)
    with pytest.raises(ValueError, match="t: "):
        range_bank_predict(_bank(), -60.0, 0.0)
    assert predict(s, 10.0, 1e-3).P[0, 0] == 1.0  # zero step: unchanged


def test_ckf_with_a_zero_covariance_keeps_the_known_state():
    """A zero covariance is a known state (documented fallback): the update leaves it as is."""
    s = BearingsGaussian(np.array([1000.0, 2000.0, 1.0, 0.0]), np.zeros((4, 4)), 0.0)
    out = ckf_update(s, 0.5, [0.0, 0.0], 0.01)
    np.testing.assert_allclose(out.x, s.x, atol=1e-9)
    np.testing.assert_array_equal(out.P, 0.0)
    bad = BearingsGaussian(s.x, np.diag([1.0, -5.0, 1.0, 1.0]), 0.0)
    with pytest.raises(ValueError, match="P: the covariance is not positive semi-definite"):
        ckf_update(bad, 0.5, [0.0, 0.0], 0.01)
    with pytest.raises(ValueError, match="sigma"):
        ekf_update(s, 0.5, [0.0, 0.0], np.nan)


@pytest.mark.parametrize(
    "args, name",
    [
        ((np.nan, [0.0, 0.0], 0.01), "z"),
        ((0.5, [0.0, np.inf], 0.01), "platform_position"),
        ((0.5, [0.0, 0.0, 0.0], 0.01), "platform_position"),
        ((0.5, [0.0, 0.0], 0.0), "sigma"),
        ((0.5, [0.0, 0.0], np.nan), "sigma"),
    ],
)
def test_ekf2_update_names_the_bad_argument(args, name):
    s = BearingsGaussian(np.array([1000.0, 2000.0, 1.0, 0.0]), np.eye(4), 0.0)
    with pytest.raises(ValueError, match=name):
        ekf2_update(s, *args)


def test_bank_update_names_an_unknown_component():
    with pytest.raises(ValueError, match="component"):
        range_bank_update(_bank(), 0.3, [100.0, 0.0], 0.02, "ukf")


@pytest.mark.parametrize("dist", ["gaussian", "uniform"])
def test_polar_moments_resolve_tiny_angular_spreads(dist):
    """The cross-line variance ``(m̄² + σ_m²) E[sin²δ]`` is exact to rounding at 1e-8 rad
    (formerly ``1 − E[cos²δ]`` and ``E[·²] − E[·]²`` cancelled it away), and the uniform
    series meets the closed form at its switch (h = 0.1 rad)."""
    m, sm = 12_000.0, 900.0
    for s in (1e-8, 1e-5):
        # bearing North: the cross-line axis is East, so P is diagonal in exact arithmetic
        _, P = polar_moments(m, sm, 0.0, s, dist)
        # E[sin²δ] = σ² (1 − O(σ²)) for both distributions (uniform: h²/3 with h = √3 σ)
        assert P[0, 0] == pytest.approx((m**2 + sm**2) * s**2, rel=1e-9)
        assert P[0, 1] == 0.0 and P[1, 1] > 1e5
    if dist == "uniform":
        lo = polar_moments(m, sm, 0.7, 0.1 / np.sqrt(3.0) * (1 - 1e-12), dist)[1]
        hi = polar_moments(m, sm, 0.7, 0.1 / np.sqrt(3.0) * (1 + 1e-12), dist)[1]
        np.testing.assert_allclose(lo, hi, rtol=1e-9)


def test_full_circle_course_prior_is_the_generator_moments():
    """Course uniform over the circle (``σ_c = π/√3``) and speed ~ U(2, 8): zero mean velocity
    and covariance ``E[s²]/2 · I`` — the moments of the env's target draw."""
    lo, hi = 2.0, 8.0
    mean_s, sd_s = 0.5 * (lo + hi), (hi - lo) / np.sqrt(12.0)
    pr = bearing_prior(
        0.4, 0.02, [0.0, 0.0], 0.0, range_mean=9_000.0, range_sigma=1_000.0,
        speed_mean=mean_s, speed_sigma=sd_s, course_mean=1.234,
        course_sigma=np.pi / np.sqrt(3.0), course_distribution="uniform",
    )  # fmt: skip
    np.testing.assert_allclose(pr.velocity, 0.0, atol=1e-12)
    np.testing.assert_allclose(pr.P[2:, 2:], (mean_s**2 + sd_s**2) / 2 * np.eye(2), rtol=1e-12)
    rng = np.random.default_rng(0)
    s, c = rng.uniform(lo, hi, 200_000), rng.uniform(-np.pi, np.pi, 200_000)
    v = np.stack([s * np.sin(c), s * np.cos(c)], -1)
    np.testing.assert_allclose(np.cov(v.T), pr.P[2:, 2:], rtol=0.02, atol=0.05)
    # a known speed (σ_s = 0) is allowed: the course spread keeps the velocity covariance full
    known = bearing_prior(
        0.4, 0.02, [0.0, 0.0], 0.0, range_mean=9_000.0, range_sigma=1_000.0, speed_mean=4.0,
        speed_sigma=0.0, course_mean=0.0, course_sigma=np.pi / np.sqrt(3.0),
        course_distribution="uniform",
    )  # fmt: skip
    np.testing.assert_allclose(known.P[2:, 2:], 8.0 * np.eye(2), rtol=1e-12)


def test_uniform_range_density_weights_members_by_their_cell():
    """``range_density="uniform"``: weights ∝ cell width, so the mixture's range moments are
    those of a uniform range over the span; the default stays log-uniform (equal weights)."""
    lo, hi = 5_000.0, 20_000.0
    flat = _bank(range_min=lo, range_max=hi, range_density="uniform")
    r = np.hypot(*flat.members.x[..., :2].T)
    w = flat.weights
    assert w[-1] / w[0] == pytest.approx(r[-1] / r[0], rel=1e-9)
    est = flat.estimate()
    u = np.array([np.sin(0.3), np.cos(0.3)])
    assert est.position @ u == pytest.approx(0.5 * (lo + hi), rel=0.01)
    assert u @ est.P[:2, :2] @ u == pytest.approx((hi - lo) ** 2 / 12.0, rel=0.02)
    np.testing.assert_allclose(_bank(range_min=lo, range_max=hi).weights, 1.0 / 8.0)


@pytest.mark.parametrize("component", ["ekf", "ekf2"])
def test_bank_updates_stay_finite_with_nearly_noise_free_bearings(component):
    """σ = 1e-8 rad against kilometres of range spread: the innovation variance never drops
    below σ² (rounding below zero counts as zero), so weights stay finite."""
    bank = _bank(sigma=1e-8, range_density="uniform", course_sigma=np.pi / np.sqrt(3.0))
    p = np.zeros(2)
    target = np.array([6_000.0 * np.sin(0.3), 6_000.0 * np.cos(0.3), 3.0, -2.0])
    for k in range(1, 20):
        p = p + np.array([300.0, 100.0 * (-1) ** k])
        target = target + np.r_[60.0 * target[2:], 0.0, 0.0]
        bank = range_bank_predict(bank, 60.0 * k, 0.0)
        z = np.arctan2(target[0] - p[0], target[1] - p[1])
        bank = range_bank_update(bank, z, p, 1e-8, component)
        assert np.all(np.isfinite(bank.log_weights) | (bank.log_weights == -np.inf))
        assert np.all(np.isfinite(bank.estimate().P))
