"""Exact first-order covariance of the n = 3 velocity-aware solution under angle noise
(theory §3.5, "Angle noise"): kernel, numpy reference, finite differences and Monte Carlo."""

from __future__ import annotations

import numpy as np
import pytest

from sensorgym.envs.worlds.stereo_scene import perturb_directions
from sensorgym.trackers.stereo.conjugation import (
    solve_conjugation,
    velocity_fix_covariance,
    velocity_fix_jacobian,
)
from tests.conftest import random_moving_scene


def _inputs(rng, batch):
    """A random moving scene (rotated receiver frames): ``(a1, ak, P, b, dt)``."""
    scene, a, dt, _, _ = random_moving_scene(rng, 3, batch, order=1)
    P, b = scene.relative_poses
    return a[:, 0], a[:, 1:], P, b, dt


def _direction_covariance(a1, ak, P, sigma):
    """``diag(σ_k² (I − u_k u_kᵀ))`` ``(..., 9, 9)`` of the frame-1 errors ``(n_1, n_2, n_3)``."""
    u = np.concatenate([a1[..., None, :], np.einsum("...kij,...kj->...ki", P, ak)], axis=-2)
    S = np.zeros((*u.shape[:-2], 9, 9))
    for k in range(3):
        proj = np.eye(3) - u[..., k, :, None] * u[..., k, None, :]
        S[..., 3 * k : 3 * k + 3, 3 * k : 3 * k + 3] = sigma[..., k, None, None] ** 2 * proj
    return S


def _relative_error(C, ref):
    """Largest entry error of each ``(6, 6)`` matrix relative to its largest entry."""
    return np.max(np.abs(C - ref), axis=(-2, -1)) / np.max(np.abs(ref), axis=(-2, -1))


def _fix(a1, ak, P, b, dt):
    """``(M̂_1, V̂)`` ``(..., 6)`` of the existing solver."""
    sol = solve_conjugation(a1, ak, P, b, dt, order=1)
    return np.concatenate([sol.position, sol.velocity], axis=-1)


def _tangents(u):
    """Two unit vectors ``(2, ..., 3)`` spanning the plane across each unit ``u``."""
    helper = np.where(np.abs(u[..., :1]) < 0.9, [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    t1 = np.cross(u, helper)
    t1 /= np.linalg.norm(t1, axis=-1, keepdims=True)
    return np.stack([t1, np.cross(u, t1)])


# --- the compiled kernel against its numpy reference and against the solver ---------------------


def test_kernel_equals_numpy_reference(rng):
    """``C`` of the kernel is ``J Σ Jᵀ + σ_x² diag(I, 0)`` with the numpy ``J`` (rounding)."""
    a1, ak, P, b, dt = _inputs(rng, 200)
    sigma = rng.uniform(1e-4, 3e-3, size=(200, 3))
    C = velocity_fix_covariance(a1, ak, P, b, dt, sigma, position_sigma=0.1)
    J = velocity_fix_jacobian(a1, ak, P, b, dt)
    ref = J @ _direction_covariance(a1, ak, P, sigma) @ np.swapaxes(J, -1, -2)
    ref[:, :3, :3] += 0.1**2 * np.eye(3)
    assert _relative_error(C, ref).max() < 1e-10
    np.testing.assert_array_equal(C, np.swapaxes(C, -1, -2))
    assert np.all(np.linalg.eigvalsh(C) > 0.0)


def test_equals_finite_difference_jacobian_of_the_solver(rng):
    """``C = J Σ Jᵀ`` with ``J`` central differences of :func:`solve_conjugation`'s ``(M̂_1, V̂)``
    under rotations of each own-frame direction by ``±ε`` about two axes across it.

    ``ε = 1e-6`` rad: truncation ``O(ε²)`` and rounding ``~1e-16 X/ε`` both stay below 1e-8 of
    ``C``'s largest entry (measured: 1.5e-10); the tolerance is 1e-7.
    """
    batch, eps = 20, 1e-6
    a1, ak, P, b, dt = _inputs(rng, batch)
    sigma = rng.uniform(1e-4, 3e-3, size=(batch, 3))
    a = np.concatenate([a1[:, None], ak], axis=1)  # own frames (frame 1 for receiver 1)
    C_fd = np.zeros((batch, 6, 6))
    for k in range(3):
        for t in _tangents(a[:, k]):
            rows = []
            for sign in (1.0, -1.0):
                moved = a.copy()
                # an exact rotation by ±ε keeps the direction a unit vector
                moved[:, k] = np.cos(eps) * a[:, k] + sign * np.sin(eps) * t
                rows.append(_fix(moved[:, 0], moved[:, 1:], P, b, dt))
            col = (rows[0] - rows[1]) / (2.0 * eps)  # ∂(M̂_1, V̂)/∂(angle about t)
            # two orthonormal tangents: Σ_t col colᵀ = J_k (I − u_k u_kᵀ) J_kᵀ
            C_fd += sigma[:, k, None, None] ** 2 * col[:, :, None] * col[:, None, :]
    C = velocity_fix_covariance(a1, ak, P, b, dt, sigma)
    err = _relative_error(C, C_fd)
    assert err.max() < 1e-7, err.max()


# --- Monte Carlo: the exact covariance holds, the i.i.d. one is too small -----------------------

#: a fixed geometry (aligned frames, metres, m/s, s) on which the i.i.d. form is clearly off:
#: receivers 150 m apart on the ground, the object 200 m up, delays 0.12 s and 0.45 s
_ORIGINS = np.array([[0.0, 0.0, 0.0], [150.0, 0.0, 0.0], [0.0, 150.0, 0.0]])
_M1 = np.array([40.0, 40.0, 200.0])
_V = np.array([5.0, -8.0, 3.0])
_DT = np.array([0.12, 0.45])


def _fixed_geometry():
    """Noise-free own-frame directions ``a (3, 3)`` and base vectors ``b (2, 3)``: receiver k
    fixes the object at ``t_k``, at ``M_1 + V Δt_k``."""
    t = np.concatenate([[0.0], _DT])
    u = _M1 + _V * t[:, None] - _ORIGINS
    return u / np.linalg.norm(u, axis=-1, keepdims=True), _ORIGINS[1:] - _ORIGINS[0]


def test_monte_carlo_matches_exact_covariance_and_iid_form_is_too_small():
    """20,000 seeded draws of angle noise (σ = 1e-4, 2e-4, 1.5e-4 rad) on the three directions,
    each solved by :func:`solve_conjugation`.

    Whitened by the exact ``C`` (``W = L⁻¹ S L⁻ᵀ``, ``C = L Lᵀ``) the sample covariance ``S``
    is ``I`` up to sampling error: standard error ``√(2/N) = 0.010`` on the diagonal and
    ``1/√N = 0.007`` off it; tolerance 0.05 on every entry (5–7 SE). The mean NEES is 6 with
    standard error ``√(12/N) = 0.024``; tolerance ±0.1 (measured: max ``|W − I|`` 0.015, NEES
    6.020). The papers' ``σ_e² (AᵀA)⁻¹`` with ``σ_e² = mean((σ_k r̂_k)²)`` (the StereoScanning
    tracker's form) puts ``tr C_VV`` 1.82 × too small here (``tr C_MM`` 1.48 ×); the sample
    velocity variance is within 3 % of the exact one (measured 0.9 %, standard error about
    0.7 %) and exceeds the i.i.d. one by more than 1.6 × (measured 1.84 ×).
    """
    n_draws = 20_000
    sigma = np.array([1e-4, 2e-4, 1.5e-4])
    a, b = _fixed_geometry()
    truth = _fix(a[0], a[1:], None, b, _DT)
    np.testing.assert_allclose(truth, np.concatenate([_M1, _V]), rtol=1e-12, atol=1e-9)
    C = velocity_fix_covariance(a[0], a[1:], None, b, _DT, sigma)

    rng = np.random.default_rng(20240535)
    noisy = perturb_directions(np.broadcast_to(a, (n_draws, 3, 3)), sigma, rng)
    err = _fix(noisy[:, 0], noisy[:, 1:], None, b, _DT) - truth
    S = err.T @ err / n_draws  # the truth is known: no mean to subtract

    L = np.linalg.cholesky(C)
    W = np.linalg.solve(L, np.linalg.solve(L, S).T)
    assert np.max(np.abs(W - np.eye(6))) < 0.05, W
    nees = np.mean(np.sum(err * np.linalg.solve(C, err.T).T, axis=-1))
    assert abs(nees - 6.0) < 0.1, nees

    sol = solve_conjugation(a[0], a[1:], None, b, _DT, order=1)
    sigma_e2 = np.mean((sigma * sol.ranges) ** 2)
    iid_vel = sigma_e2 * np.trace(sol.covariance[3:, 3:])
    exact_vel = np.trace(C[3:, 3:])
    sample_vel = np.trace(S[3:, 3:])
    assert 1.75 < exact_vel / iid_vel < 1.9
    assert abs(sample_vel / exact_vel - 1.0) < 0.03
    assert sample_vel / iid_vel > 1.6


# --- options, batching, degenerate geometry and bad inputs ----------------------------------------


def test_position_sigma_moves_the_position_block_only(rng):
    a1, ak, P, b, dt = _inputs(rng, 5)
    C0 = velocity_fix_covariance(a1, ak, P, b, dt, 1e-3)
    C1 = velocity_fix_covariance(a1, ak, P, b, dt, 1e-3, position_sigma=0.2)
    extra = np.zeros((6, 6))
    extra[:3, :3] = 0.04 * np.eye(3)
    np.testing.assert_allclose(C1 - C0, np.broadcast_to(extra, C0.shape), atol=1e-12)


def test_one_receivers_noise_scales_its_own_term(rng):
    """``C`` is linear in ``σ_k²``: the three single-receiver terms add up to the whole."""
    a1, ak, P, b, dt = _inputs(rng, 8)
    sigma = np.array([1e-3, 2e-3, 3e-3])
    parts = [
        velocity_fix_covariance(a1, ak, P, b, dt, sigma * (np.arange(3) == k)) for k in range(3)
    ]
    whole = velocity_fix_covariance(a1, ak, P, b, dt, sigma)
    assert _relative_error(sum(parts), whole).max() < 1e-12
    # receiver 1's error enters both equation blocks: its term moves the velocity too
    assert np.all(np.trace(parts[0][:, 3:, 3:], axis1=-2, axis2=-1) > 0.0)


def test_batched_and_broadcast_equal_looped(rng):
    a1, ak, P, b, dt = _inputs(rng, 6)
    sigma = rng.uniform(1e-4, 1e-3, size=(6, 3))
    C = velocity_fix_covariance(a1, ak, P, b, dt, sigma)
    assert C.shape == (6, 6, 6)
    for i in range(6):
        one = velocity_fix_covariance(a1[i], ak[i], P[i], b[i], dt[i], sigma[i])
        np.testing.assert_array_equal(one, C[i])
    # a 2-D batch, and a scalar or per-receiver σ broadcast over it
    C2 = velocity_fix_covariance(
        a1.reshape(2, 3, 3), ak.reshape(2, 3, 2, 3), P.reshape(2, 3, 2, 3, 3),
        b.reshape(2, 3, 2, 3), dt.reshape(2, 3, 2), sigma.reshape(2, 3, 3),
    )  # fmt: skip
    np.testing.assert_array_equal(C2.reshape(6, 6, 6), C)
    same = velocity_fix_covariance(a1, ak, P, b, dt, np.full(3, 5e-4))
    np.testing.assert_array_equal(same, velocity_fix_covariance(a1, ak, P, b, dt, 5e-4))
    # one geometry (no batch axis) against a batch of base vectors
    Cb = velocity_fix_covariance(a1[0], ak[0], P[0], np.stack([b[0], b[0]]), dt[0], 5e-4)
    np.testing.assert_array_equal(Cb[0], Cb[1])


@pytest.mark.parametrize("dt", [[0.0, 0.2], [0.2, 0.2]])
def test_singular_geometry_gives_nan_where_the_solver_falls_back(rng, dt):
    """Zero or equal delays, or coplanar lines of sight: ``A`` is singular, the solver takes the
    pseudo-inverse and the first-order covariance does not exist (NaN), element by element."""
    a1, ak, P, b, good_dt = _inputs(rng, 3)
    dts = good_dt.copy()
    dts[1] = dt
    sol = solve_conjugation(a1, ak, P, b, dts, order=1)
    np.testing.assert_array_equal(sol.used_pinv, [False, True, False])
    C = velocity_fix_covariance(a1, ak, P, b, dts, 1e-3)
    J = velocity_fix_jacobian(a1, ak, P, b, dts)
    assert np.all(np.isnan(C[1])) and np.all(np.isnan(J[1]))
    assert np.all(np.isfinite(C[[0, 2]])) and np.all(np.isfinite(J[[0, 2]]))
    # coplanar: receiver 3 looks along receiver 1's line of sight (frames aligned)
    a, base = _fixed_geometry()
    flat = a.copy()
    flat[2] = a[0]
    assert np.all(np.isnan(velocity_fix_covariance(flat[0], flat[1:], None, base, _DT, 1e-3)))


def test_bad_inputs_raise_as_the_solver(rng):
    a1, ak, P, b, dt = _inputs(rng, 2)

    def both(**kw):
        """The solver's message, and the same from both new functions."""
        args = {"a1": a1, "ak": ak, "P": P, "b": b, "dt": dt} | kw
        with pytest.raises(ValueError) as solver:
            solve_conjugation(*args.values(), order=1)
        for f, extra in ((velocity_fix_covariance, (1e-3,)), (velocity_fix_jacobian, ())):
            with pytest.raises(ValueError) as ours:
                f(*args.values(), *extra)
            assert str(ours.value) == str(solver.value)
        return str(solver.value)

    assert "a1: contains NaN" in both(a1=np.full_like(a1, np.nan))
    assert "ak: direction vectors must have unit length" in both(ak=1.01 * ak)
    assert "b: expected shape" in both(b=b[..., :2])
    assert "dt: contains NaN" in both(dt=np.full_like(dt, np.inf))
    assert "P: must hold rotation" in both(P=2 * P)
    assert "inputs: batch shapes" in both(a1=np.concatenate([a1, a1, a1]))
    assert "dt: delays are required" in both(dt=None)
    assert "at least 3 receivers" in both(ak=ak[:, :1], P=P[:, :1], b=b[:, :1], dt=dt[:, :1])
    # the closed form is n = 3 only; σ must be a non-negative scalar or one per receiver
    scene, a, dt4, _, _ = random_moving_scene(rng, 4, 2, order=1)
    P4, b4 = scene.relative_poses
    with pytest.raises(ValueError, match=r"n = 3 closed form.*got n = 4"):
        velocity_fix_covariance(a[:, 0], a[:, 1:], P4, b4, dt4, 1e-3)
    with pytest.raises(ValueError, match=r"n = 3 closed form.*got n = 4"):
        velocity_fix_jacobian(a[:, 0], a[:, 1:], P4, b4, dt4)
    for bad, match in (
        (-1e-3, "sigma_ang: must be non-negative"),
        (np.nan, "sigma_ang: contains NaN"),
        (np.full(2, 1e-3), r"sigma_ang: expected a scalar or shape \(\.\.\., 3\)"),
        (np.full((5, 3), 1e-3), "sigma_ang: shape .* does not broadcast"),
    ):
        with pytest.raises(ValueError, match=match):
            velocity_fix_covariance(a1, ak, P, b, dt, bad)
    with pytest.raises(ValueError, match="position_sigma"):
        velocity_fix_covariance(a1, ak, P, b, dt, 1e-3, position_sigma=-0.1)
