"""Monte Carlo: empirical covariance of the estimates against the predicted covariance.

Two noise models (theory §4.1, §4.5 CHECK 1–3): the papers' i.i.d. conjugation
error, and independent angular noise on each receiver's direction vector.
"""

from __future__ import annotations

import numpy as np
import pytest

from sensorgym.envs.worlds.stereo_scene import pair_scene, perturb_directions, receivers_around
from sensorgym.trackers.stereo.accuracy import (
    los_angle,
    pair_range_sigma,
    pair_range_sigma_angle_noise,
    position_crlb,
    position_information,
    triangulate_ml,
)
from sensorgym.trackers.stereo.conjugation import solve_conjugation, solve_pair

DRAWS = 20_000


def _whitened(emp: np.ndarray, pred: np.ndarray) -> np.ndarray:
    """``L⁻¹ C_emp L⁻ᵀ`` with ``C_pred = L Lᵀ``: the identity when the covariances agree."""
    L = np.linalg.cholesky(pred)
    Li = np.linalg.inv(L)
    return Li @ emp @ Li.T


def _assert_cov_matches(emp: np.ndarray, pred: np.ndarray, tol: float = 0.05) -> None:
    W = _whitened(emp, pred)
    np.testing.assert_allclose(W, np.eye(len(W)), atol=tol)


@pytest.mark.parametrize("gamma_deg", [30.0, 60.0, 90.0, 120.0, 150.0])
def test_pair_iid_model_covariance(gamma_deg):
    rng = np.random.default_rng(int(gamma_deg))
    scene = pair_scene(np.deg2rad(gamma_deg))
    a = scene.directions
    P, b = scene.relative_poses
    sigma_e = 0.5
    # papers' model: e_k i.i.d. N(0, σ_e² I) on the conjugation equations (through B)
    bn = b[0] + rng.normal(size=(DRAWS, 3)) * sigma_e
    sol = solve_pair(a[0], a[1], P[0], bn, sigma_e=sigma_e)
    emp = np.cov(sol.ranges.T)
    _assert_cov_matches(emp, sol.covariance[0])
    assert np.sqrt(emp[0, 0]) == pytest.approx(
        pair_range_sigma(np.deg2rad(gamma_deg), sigma_e), rel=0.03
    )
    np.testing.assert_allclose(
        sol.ranges.mean(0),
        scene.ranges,
        atol=4 * sigma_e / np.sqrt(DRAWS) / np.sin(np.deg2rad(gamma_deg)),
    )


@pytest.mark.parametrize("geometry", ["orthogonal", "oblique"])
def test_velocity_aware_iid_model_covariance(geometry):
    rng = np.random.default_rng(7)
    T = np.array([0.0, 40.0, 0.0])
    if geometry == "orthogonal":
        d = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    else:
        d = np.array([[0.0, 0.5, 1.0], [1.0, 0.7, 0.2], [-0.6, 0.3, 0.9]])
        d /= np.linalg.norm(d, axis=-1, keepdims=True)
    scene = receivers_around(T, d, np.array([120.0, 90.0, 100.0]), boresight_offset=(1.0, 0.0, 1.0))
    a = scene.directions
    P, b = scene.relative_poses
    dt = np.array([0.1, 0.2])
    bn = b + rng.normal(size=(DRAWS, 2, 3)) * 0.2
    sol = solve_conjugation(a[0], a[1:], P, bn, dt, order=1, sigma_e=0.2)
    X = np.concatenate([sol.ranges, sol.velocity], -1)
    _assert_cov_matches(np.cov(X.T), sol.covariance[0])


@pytest.mark.parametrize("gamma_deg", [30.0, 60.0, 90.0, 150.0])
def test_pair_angle_noise_range_error(gamma_deg):
    """LS pair under angular noise: σ[r̂_1] = σ √(r_2² + r_1² cos²γ)/sin γ (first order)."""
    rng = np.random.default_rng(100 + int(gamma_deg))
    r1, r2, sigma = 150.0, 120.0, 1e-3
    scene = pair_scene(np.deg2rad(gamma_deg), r1, r2)
    a = scene.directions
    P, b = scene.relative_poses
    an = perturb_directions(np.broadcast_to(a, (DRAWS, 2, 3)), sigma, rng)
    sol = solve_pair(an[:, 0], an[:, 1], P[0], b[0])
    predicted = pair_range_sigma_angle_noise(r1, r2, np.deg2rad(gamma_deg), sigma)
    assert sol.ranges[:, 0].std() == pytest.approx(predicted, rel=0.03)
    # the papers' σ_e/sin γ with σ_e = r_2 σ is optimistic away from 90°
    if gamma_deg != 90.0:
        assert predicted > pair_range_sigma(np.deg2rad(gamma_deg), r2 * sigma) * 1.05


@pytest.mark.parametrize("n,spread", [(2, 30.0), (2, 150.0), (3, 90.0), (4, 60.0)])
def test_ml_triangulation_attains_fisher_bound(n, spread):
    rng = np.random.default_rng(n * 1000 + int(spread))
    az = np.deg2rad(spread) * np.arange(n) / max(n - 1, 1)
    el = np.deg2rad(np.linspace(10.0, 35.0, n))
    d = np.stack([np.cos(el) * np.sin(az), np.sin(el), np.cos(el) * np.cos(az)], -1)
    scene = receivers_around(np.array([0.0, 50.0, 0.0]), d, np.linspace(80.0, 160.0, n))
    sigma = np.linspace(5e-4, 1.5e-3, n)
    u = scene.world_los
    un = perturb_directions(np.broadcast_to(u, (DRAWS, n, 3)), sigma, rng)
    M, cov = triangulate_ml(scene.origins, un, sigma)
    crlb = position_crlb(u, scene.ranges, sigma)
    _assert_cov_matches(np.cov(M.T), crlb, tol=0.06)
    np.testing.assert_allclose(cov.mean(0), crlb, rtol=0.02, atol=1e-12)
    np.testing.assert_allclose(M.mean(0), scene.target, atol=0.05)


def test_fisher_information_closed_form_and_orthogonality_optimum():
    # I(M) = Σ (I − u uᵀ)/(σ² r²); two orthogonal LOS at equal range give the smallest trace(CRLB)
    r = np.array([100.0, 100.0])
    gammas = np.deg2rad(np.linspace(20.0, 160.0, 29))
    u1 = np.array([0.0, 0.0, 1.0])
    u2 = np.stack([np.sin(gammas), np.zeros_like(gammas), np.cos(gammas)], -1)
    los = np.stack([np.broadcast_to(u1, u2.shape), u2], -2)
    info = position_information(los, r, 1e-3)
    expected = sum(
        (np.eye(3) - np.einsum("...i,...j->...ij", los[:, k], los[:, k])) / (1e-3 * 100.0) ** 2
        for k in range(2)
    )
    np.testing.assert_allclose(info, expected, rtol=1e-12)
    # the in-plane (x, z) error is what the geometry controls; y is fixed by both receivers
    xz = np.linalg.inv(info)[:, [0, 2]][:, :, [0, 2]]
    best = gammas[np.argmin(np.trace(xz, axis1=1, axis2=2))]
    assert np.rad2deg(best) == pytest.approx(90.0, abs=1e-6)
    assert np.allclose(los_angle(los[:, 0], los[:, 1]), gammas)


def test_parallel_lines_of_sight_have_no_position_bound():
    u = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]])
    with pytest.raises(ValueError, match="parallel"):
        position_crlb(u, [100.0, 120.0], 1e-3)
    with pytest.raises(ValueError, match="parallel"):
        triangulate_ml([[0.0, 0.0, 0.0], [0.0, 0.0, 10.0]], u)
    with pytest.raises(ValueError, match="gamma"):
        pair_range_sigma(0.0, 1.0)
