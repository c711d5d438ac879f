"""Fisher information and Cramér–Rao bounds for bearings-only target motion analysis.

The "covariance analysis" rewards of the platform-manoeuvre environments. All functions are
batched over leading axes (scenarios, candidate manoeuvres), vectorised numpy.

Measurement information of one bearing with standard deviation σ (rad)::

    I(x) = Hᵀ H / σ²,      H = ∂β/∂x = (Δy, −Δx, 0, 0) / r²

Deterministic target (q̃ = 0), state ``x₀`` at reference time ``t₀``; bearing ``k`` sees the
state ``x_k = Φ_k x₀`` with ``Φ_k = F(t_k − t₀)``, so the batch Fisher information is
(Van Trees 1968; Ristic, Arulampalam & Gordon 2004, §6.2)::

    J(t₀) = J_prior + Σ_k Φ_kᵀ I(x_k) Φ_k,      CRLB = J⁻¹

Information moves between reference times exactly: ``J(t₁) = Φᵀ⁻¹ J(t₀) Φ⁻¹`` with
``Φ = F(t₁ − t₀)``; an incremental update adds one bearing's ``Φ_kᵀ I Φ_k``.

Random target (q̃ > 0): posterior CRLB recursion for linear-Gaussian dynamics with additive
noise (Tichavský, Muravchik & Nehorai 1998, eq. 21 specialised)::

    J_{k+1} = (Q + F J_k⁻¹ Fᵀ)⁻¹ + E[I(x_{k+1})]

computed as ``(I + J̄ Q)⁻¹ J̄`` with ``J̄ = F⁻ᵀ J_k F⁻¹`` (:func:`predict_information`, also the
bound at any time between bearings), which needs no inverse of a possibly singular ``J_k``
or ``Q`` (it reduces to pure transport when ``q̃ = 0``). The expectation is over
the true trajectories: pass the per-trajectory information averaged over Monte Carlo runs,
or that of one deterministic trajectory.

Without a platform manoeuvre the bearings are invariant to scaling the relative
trajectory, so ``J`` (without prior) is singular with null vector
``(x₀ − p₀, v − v_p)`` (Nardone & Aidala 1981); :func:`observability` measures it, and
:func:`crlb` returns ``inf`` for the bound elements it touches.

Square-root (covariance) form of the same recursion (theory §7.8). When the information
holds a full-rank prior the bound is finite in exact arithmetic, and it is better carried as
a square root ``L`` of the bound ``P = J⁻¹ = L Lᵀ``: inverting ``J`` (or thresholding its
eigenvalues) loses everything once the spread of ``P`` spans more than the float range
(bearing noise of 1e-6 rad against a 10-km range prior; steps of 1e5 s). By the matrix
inversion lemma the recursion above is the Kalman covariance (Riccati) recursion with the
bearing gradient ``H`` at the true state::

    P̄ = F P Fᵀ + Q,      P⁺ = (P̄⁻¹ + Hᵀ H / σ²)⁻¹ = P̄ − P̄ Hᵀ (H P̄ Hᵀ + σ²)⁻¹ H P̄

:func:`predict_bound_factor` and :func:`update_bound_factor` carry ``L`` through it by
orthogonal triangularisation (QR of the stacked square roots), so ``P`` stays symmetric
positive semi-definite by construction and the bound's spread is resolved to the square root
of the float precision it would need as a matrix; :func:`factor_position_rms_bound` and
:func:`factor_range_bound` read the bounds off ``L`` as sums of squares (never negative).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sensorgym.trackers.bearings import kernels
from sensorgym.trackers.bearings.models import (
    STATE_DIM,
    bearing_jacobian,
    cv_transition,
    cwna_covariance,
    cwna_covariance_factor,
)
from sensorgym.trackers.kernel_args import kernel_array
from sensorgym.trackers.validation import finite_array

FloatArray = NDArray[np.float64]


def _sym(A: FloatArray) -> FloatArray:
    return 0.5 * (A + np.swapaxes(A, -1, -2))


def _check_sigma(sigma: ArrayLike) -> FloatArray:
    s = finite_array(sigma, "sigma")
    if np.any(s <= 0.0):
        raise ValueError("sigma: bearing noise standard deviation must be positive")
    return s


def bearing_information(
    target_state: ArrayLike, platform_position: ArrayLike, sigma: ArrayLike
) -> FloatArray:
    """Fisher information ``I = Hᵀ H / σ²`` ``(..., 4, 4)`` of one bearing at the true state."""
    H = bearing_jacobian(target_state, platform_position)
    s = _check_sigma(sigma)
    # I = Hᵀ σ⁻² H
    return H[..., :, None] * H[..., None, :] / (s[..., None, None] ** 2)


def transport_information(J: ArrayLike, dt: ArrayLike) -> FloatArray:
    """Information about the state at ``t + dt`` given information ``J`` about the state at ``t``.

    ``J' = F⁻ᵀ J F⁻¹`` with ``F = F(dt)`` (exact for the deterministic CV model).
    """
    J = finite_array(J, "J", tail=(STATE_DIM, STATE_DIM))
    Finv = cv_transition(-np.asarray(dt, dtype=np.float64))
    return _sym(np.swapaxes(Finv, -1, -2) @ J @ Finv)


def add_bearing_information(
    J: ArrayLike,
    x_ref: ArrayLike,
    t_ref: float,
    t_k: ArrayLike,
    platform_position: ArrayLike,
    sigma: ArrayLike,
) -> FloatArray:
    """Incremental batch-FIM update: ``J + Φ_kᵀ I(Φ_k x_ref) Φ_k``, ``Φ_k = F(t_k − t_ref)``.

    ``J`` is information about the (deterministic) state ``x_ref`` at ``t_ref``; ``t_k`` and
    ``platform_position`` ``(..., 2)`` describe the new bearing. Broadcasting over candidates
    is the intended use: one ``J`` and many candidate platform positions.
    """
    J = finite_array(J, "J", tail=(STATE_DIM, STATE_DIM))
    x_ref = finite_array(x_ref, "x_ref", tail=(STATE_DIM,))
    Phi = cv_transition(np.asarray(t_k, dtype=np.float64) - float(t_ref))
    xk = np.einsum("...ij,...j->...i", Phi, x_ref)
    # H_k Φ_k is the sensitivity of β_k to x_ref
    g = np.einsum("...i,...ij->...j", bearing_jacobian(xk, platform_position), Phi)
    s = _check_sigma(sigma)
    return J + g[..., :, None] * g[..., None, :] / (s[..., None, None] ** 2)


def batch_information(
    x_ref: ArrayLike,
    t_ref: float,
    times: ArrayLike,
    platform_positions: ArrayLike,
    sigma: ArrayLike,
    prior_information: ArrayLike | None = None,
) -> FloatArray:
    """Batch Fisher information ``J(t_ref) = J_prior + Σ_k Φ_kᵀ I(x_k) Φ_k`` (deterministic target).

    ``x_ref`` ``(..., 4)`` is the true state at ``t_ref``; ``times`` ``(K,)`` and
    ``platform_positions`` ``(..., K, 2)`` the bearing times and platform positions; ``sigma``
    broadcasts against ``(..., K)``. Returns ``(..., 4, 4)``.
    """
    x_ref = finite_array(x_ref, "x_ref", tail=(STATE_DIM,))
    times = finite_array(times, "times")
    p = finite_array(platform_positions, "platform_positions", tail=(2,))
    if times.ndim != 1 or p.shape[-2] != times.shape[0]:
        raise ValueError(f"platform_positions: expected (..., {times.shape[0]}, 2), got {p.shape}")
    Phi = cv_transition(times - float(t_ref))  # (K, 4, 4)
    xk = np.einsum("kij,...j->...ki", Phi, x_ref)
    g = np.einsum("...ki,kij->...kj", bearing_jacobian(xk, p), Phi)
    s = np.broadcast_to(_check_sigma(sigma), g.shape[:-1])
    J = np.einsum("...ki,...kj->...ij", g / s[..., None], g / s[..., None])
    if prior_information is not None:
        J = J + finite_array(prior_information, "prior_information", tail=(STATE_DIM, STATE_DIM))
    return _sym(J)


def predict_information(J: ArrayLike, dt: float, q_tilde: float) -> FloatArray:
    """Information about the state ``dt ≥ 0`` seconds later under CWNA process noise ``q̃``.

    ``(Q + F J⁻¹ Fᵀ)⁻¹ = (I + J̄ Q)⁻¹ J̄`` with ``J̄ = F⁻ᵀ J F⁻¹``; works for singular ``J`` (no
    information yet) and ``q̃ = 0`` (pure transport). Use it with :func:`crlb` and the helpers
    below for the bound at any time between (or after) bearings.
    """
    if not np.isfinite(dt) or dt < 0.0:
        raise ValueError(f"dt: must be finite and >= 0, got {dt}")
    Jbar = transport_information(J, dt)
    Q = cwna_covariance(dt, q_tilde)
    # (Q + F J⁻¹ Fᵀ)⁻¹ = (I + J̄ Q)⁻¹ J̄
    return _sym(np.linalg.solve(np.eye(STATE_DIM) + Jbar @ Q, Jbar))


def posterior_information(
    J0: ArrayLike, times: ArrayLike, measurement_information: ArrayLike, q_tilde: float
) -> FloatArray:
    """Posterior CRLB recursion (Tichavský et al. 1998) over ``K`` bearings.

    ``J0`` ``(..., 4, 4)``: prior information about the state at ``times[0]`` *before* the first
    bearing; ``measurement_information`` ``(..., K, 4, 4)``: ``E[I(x_k)]`` at each bearing
    (use :func:`bearing_information` on the true states, averaged over runs if random).
    Returns the filtering information ``J_k`` ``(..., K, 4, 4)`` after bearing ``k``::

        J_0 ← J0 + E[I_0],   J_{k+1} = (I + J̄ Q)⁻¹ J̄ + E[I_{k+1}],   J̄ = F⁻ᵀ J_k F⁻¹
    """
    J = finite_array(J0, "J0", tail=(STATE_DIM, STATE_DIM))
    times = finite_array(times, "times")
    Im = finite_array(measurement_information, "measurement_information", tail=(STATE_DIM,) * 2)
    K = times.shape[0]
    if Im.shape[-3] != K:
        raise ValueError(f"measurement_information: expected (..., {K}, 4, 4), got {Im.shape}")
    batch = np.broadcast_shapes(J.shape[:-2], Im.shape[:-3])
    out = np.empty((*batch, K, STATE_DIM, STATE_DIM))
    J = J + Im[..., 0, :, :]
    out[..., 0, :, :] = J
    for k in range(1, K):
        J = predict_information(J, times[k] - times[k - 1], q_tilde) + Im[..., k, :, :]
        out[..., k, :, :] = J
    return out


def crlb(J: ArrayLike, *, rcond: float = 1e-12) -> FloatArray:
    """Bound ``P = J⁻¹`` ``(..., 4, 4)``; unobservable directions give ``inf`` (documented).

    Information is first scaled to unit diagonal; eigenvalues below ``rcond`` times the largest
    count as zero, and every bound element touching such a direction is set to ``inf``.

    Meant for information without a full-rank prior (batch estimates), where such directions
    are truly unobservable. Information that holds a full-rank prior has a finite bound, but
    a badly scaled one (spread beyond ~1e12) would be declared unobservable here: carry its
    bound in square-root form instead (:func:`predict_bound_factor`,
    :func:`update_bound_factor`), as the platform-manoeuvre environment does.
    """
    J = finite_array(J, "J", tail=(STATE_DIM, STATE_DIM))
    d = np.sqrt(np.clip(np.diagonal(J, axis1=-2, axis2=-1), 1e-300, None))
    Js = J / (d[..., :, None] * d[..., None, :])
    w, V = np.linalg.eigh(_sym(Js))
    ok = w > rcond * np.max(w, axis=-1, keepdims=True)
    winv = np.where(ok, 1.0 / np.where(ok, w, 1.0), 0.0)
    Ps = np.einsum("...ik,...k,...jk->...ij", V, winv, V)
    P = Ps / (d[..., :, None] * d[..., None, :])
    # any weight on a null direction makes that element unbounded
    null_weight = np.einsum("...ik,...k->...i", V**2, (~ok).astype(float))
    bad = null_weight > 1e-6
    return np.where(bad[..., :, None] | bad[..., None, :], np.inf, P)


def observability(J: ArrayLike) -> FloatArray:
    """Smallest over largest eigenvalue of the diagonally scaled information ``(...,)``.

    ≈ 0 (≲ 1e-12) means some state direction is unobservable (no platform manoeuvre).
    """
    J = finite_array(J, "J", tail=(STATE_DIM, STATE_DIM))
    d = np.sqrt(np.clip(np.diagonal(J, axis1=-2, axis2=-1), 1e-300, None))
    w = np.linalg.eigvalsh(_sym(J / (d[..., :, None] * d[..., None, :])))
    return w[..., 0] / w[..., -1]


def position_rms_bound(P: ArrayLike) -> FloatArray:
    """Position RMS bound ``√(P_xx + P_yy)`` (m), ``(...,)``."""
    P = np.asarray(P, dtype=np.float64)
    return np.sqrt(P[..., 0, 0] + P[..., 1, 1])


def velocity_rms_bound(P: ArrayLike) -> FloatArray:
    """Velocity RMS bound ``√(P_ẋẋ + P_ẏẏ)`` (m/s), ``(...,)``."""
    P = np.asarray(P, dtype=np.float64)
    return np.sqrt(P[..., 2, 2] + P[..., 3, 3])


def range_bound(
    P: ArrayLike, target_position: ArrayLike, platform_position: ArrayLike
) -> FloatArray:
    """Range standard-deviation bound ``σ_r = √(g P_pos gᵀ)``, ``g = (Δx, Δy)/r`` (m)."""
    P = np.asarray(P, dtype=np.float64)
    d = finite_array(target_position, "target_position", tail=(2,)) - finite_array(
        platform_position, "platform_position", tail=(2,)
    )
    g = d / np.hypot(d[..., 0], d[..., 1])[..., None]
    with np.errstate(invalid="ignore"):
        var = np.einsum("...i,...ij,...j->...", g, P[..., :2, :2], g)
    # 0·inf from an unobservable direction is unbounded, not NaN
    return np.sqrt(np.where(np.isnan(var), np.inf, var))


def relative_range_bound(
    P: ArrayLike, target_position: ArrayLike, platform_position: ArrayLike
) -> FloatArray:
    """Relative range bound ``σ_r / r`` (dimensionless)."""
    d = np.asarray(target_position, dtype=np.float64) - np.asarray(
        platform_position, dtype=np.float64
    )
    return range_bound(P, target_position, platform_position) / np.hypot(d[..., 0], d[..., 1])


# --- square-root (covariance) form ------------------------------------------------------------


def covariance_square_root(P: ArrayLike) -> FloatArray:
    """The lower-triangular square root ``L`` ``(..., 4, 4)`` of a covariance ``P = L Lᵀ``
    (Cholesky, of the lower triangle; compiled: :func:`.kernels.psd_square_root`).

    Pivots below zero can only be rounding of a positive semi-definite ``P`` built in floating
    point (a moment-matched mixture whose spread spans many decades); they count as zero, with
    their column, so ``L Lᵀ`` equals ``P`` to rounding and is positive semi-definite.
    """
    P = finite_array(P, "P", tail=(STATE_DIM, STATE_DIM))
    L = np.empty(P.shape)
    kernels.psd_square_root_batch(
        np.ascontiguousarray(P).reshape(-1, STATE_DIM, STATE_DIM),
        L.reshape(-1, STATE_DIM, STATE_DIM),
    )
    return L


def predict_bound_factor(L: ArrayLike, dt: float, q_tilde: float) -> FloatArray:
    """Square root of the predicted bound ``P̄ = F P Fᵀ + Q`` (``dt ≥ 0`` s, CWNA ``q̃``).

    ``L`` ``(..., 4, 4)`` is a square root of ``P``; the result is ``F L`` when ``q̃ = 0``,
    else the triangular factor of ``[F L, G]`` (``G Gᵀ = Q``, closed form) by QR. Equivalent
    to :func:`predict_information` on ``J = P⁻¹``, without an inverse.
    """
    if not np.isfinite(dt) or dt < 0.0:
        raise ValueError(f"dt: must be finite and >= 0, got {dt}")
    L = finite_array(L, "L", tail=(STATE_DIM, STATE_DIM))
    cwna_covariance_factor(dt, q_tilde)  # checks q̃
    out = np.empty(L.shape)
    # P̄ = [F L, G][F L, G]ᵀ = Rᵀ R with [F L, G]ᵀ = Q R  (compiled: kernels.bound_predict)
    kernels.bound_predict_batch(
        np.ascontiguousarray(L).reshape(-1, STATE_DIM, STATE_DIM),
        float(dt),
        float(q_tilde),
        out.reshape(-1, STATE_DIM, STATE_DIM),
    )
    return out


def update_bound_factor(
    L: ArrayLike, target_state: ArrayLike, platform_position: ArrayLike, sigma: ArrayLike
) -> FloatArray:
    """Square root of the bound after one bearing at the true state,
    ``P⁺ = (P̄⁻¹ + Hᵀ H / σ²)⁻¹``, from a square root ``L`` of ``P̄``.

    With ``n̂ = (Δy, −Δx)/r`` the unit normal to the line of sight (so ``H = n̂ᵀ/r``), the
    pre-array ``M = [[r σ, n̂ᵀ L_pos], [0, L]]`` has ``M Mᵀ = [[r²S, r H P̄], [r P̄ Hᵀ, P̄]]``;
    triangularising it (``Mᵀ = Q R``, ``M Q = Rᵀ``) leaves the Schur complement
    ``P̄ − P̄ Hᵀ S⁻¹ H P̄ = P⁺`` as ``Rᵀ[1:, 1:] (Rᵀ[1:, 1:])ᵀ``. Rows in metres keep the
    pre-array well scaled. ``target_state`` ``(..., 4)``, ``platform_position`` ``(..., 2)``
    and ``sigma`` broadcast against ``L``'s batch.
    """
    L = finite_array(L, "L", tail=(STATE_DIM, STATE_DIM))
    x = finite_array(target_state, "target_state", tail=(STATE_DIM,))
    p = finite_array(platform_position, "platform_position", tail=(2,))
    s = _check_sigma(sigma)
    d = x[..., :2] - p
    r = np.hypot(d[..., 0], d[..., 1])
    if np.any(r == 0.0):
        raise ValueError("target_state: position coincides with the platform")
    batch = np.broadcast_shapes(L.shape[:-2], d.shape[:-1], s.shape)
    out = np.empty((*batch, STATE_DIM, STATE_DIM))
    # triangularise the pre-array [[r σ, n̂ᵀ L_pos], [0, L]]  (compiled: kernels.bound_update)
    kernels.bound_update_batch(
        kernel_array(L, out.shape).reshape(-1, STATE_DIM, STATE_DIM),
        kernel_array(x, (*batch, STATE_DIM)).reshape(-1, STATE_DIM),
        kernel_array(p, (*batch, 2)).reshape(-1, 2),
        kernel_array(s, batch).reshape(-1),
        out.reshape(-1, STATE_DIM, STATE_DIM),
    )
    return out


def factor_position_rms_bound(L: ArrayLike) -> FloatArray:
    """Position RMS bound ``√(P_xx + P_yy)`` (m) of ``P = L Lᵀ``: the norm of ``L``'s position
    rows, ``(...,)``."""
    L = np.ascontiguousarray(L, dtype=np.float64)
    out = np.empty(L.shape[:-2])
    kernels.position_rms_batch(L.reshape(-1, STATE_DIM, STATE_DIM), out.reshape(-1))
    return out


def factor_range_bound(
    L: ArrayLike, target_position: ArrayLike, platform_position: ArrayLike
) -> FloatArray:
    """Range standard-deviation bound ``σ_r = ‖gᵀ L_pos‖``, ``g = (Δx, Δy)/r`` (m), of
    ``P = L Lᵀ`` (:func:`range_bound` on the square root)."""
    L = np.asarray(L, dtype=np.float64)
    t = finite_array(target_position, "target_position", tail=(2,))
    p = finite_array(platform_position, "platform_position", tail=(2,))
    batch = np.broadcast_shapes(L.shape[:-2], t.shape[:-1], p.shape[:-1])
    out = np.empty(batch)
    # compiled: kernels.range_sigma
    kernels.range_sigma_batch(
        kernel_array(L, (*batch, STATE_DIM, STATE_DIM)).reshape(-1, STATE_DIM, STATE_DIM),
        kernel_array(t, (*batch, 2)).reshape(-1, 2),
        kernel_array(p, (*batch, 2)).reshape(-1, 2),
        out.reshape(-1),
    )
    return out
