"""Compiled primitives of bearings-only tracking: one element (member, scenario) per call.

The batched public functions of :mod:`.models` (``predict``), :mod:`.filters` (the EKF update and
the range-parameterised EKF bank) and :mod:`.crlb` (the square-root bound recursion and the bounds
read off it) loop these over their flattened batch, and the BearingsManeuver simulation fuses
them into one step kernel (:mod:`sensorgym.envs.bearings_maneuver.kernels`): every formula is
written here once. The simulation's bank (:func:`bank_update`) gives its members the
second-order EKF update (:func:`ekf2_bearing_update`, theory §11.6), whose readable numpy
reference is :func:`sensorgym.trackers.bearings.filters.ekf2_update`; the filters' EKF bank
loops :func:`ekf_bank_update`. The checks of the inputs stay with the public functions; a
kernel trusts its arguments (finite values, a target off the platform).

Conventions (:mod:`.models`): state ``x = (x, y, ẋ, ẏ)`` (m, m/s), bearings from North
clockwise (rad), ``F(T) = [[I, T I], [0, I]]`` and CWNA ``Q(T)``. Arrays are written in place
where the argument says ``out``. The per-member primitives of the hot loop (predict, EKF updates,
moment match) read a member's entries into locals, compute, and write each entry once: numba
cannot tell an output array from an input one, so indexed loops reload after every store
(3–5× slower on 4×4 blocks); the arithmetic, and so every bit, is that of the loops.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numba.extending import register_jitable

from sensorgym.trackers.geometry import wrap_angle_scalar as wrap

_JIT = {"cache": True, "nogil": True, "error_model": "numpy", "boundscheck": False}

STATE_DIM = 4
_TWO_PI = 2.0 * np.pi


# --- the measurement ---------------------------------------------------------------------------


# β = atan2(x_t − x_p, y_t − y_p)  (from North clockwise, theory §2.5)
@njit(**_JIT)
def bearing(tx, ty, px, py):
    """Absolute bearing (rad) of a target at ``(tx, ty)`` from a platform at ``(px, py)`` (East,
    North, m): the one copy, called by :func:`.models.bearing`, the EKF update and the world's
    noisy bearings."""
    return math.atan2(tx - px, ty - py)


@njit(**_JIT)
def bearing_batch(target, platform, out):
    """:func:`bearing` over flat ``target``/``platform (N, 2)`` into ``out (N,)``."""
    for i in range(target.shape[0]):
        out[i] = bearing(target[i, 0], target[i, 1], platform[i, 0], platform[i, 1])


# --- constant-velocity prediction -------------------------------------------------------------


# x⁻ = F x,  P⁻ = F P Fᵀ + Q,  F = F(T), Q = q̃ [[T³/3 I, T²/2 I], [T²/2 I, T I]];  P⁻ symmetrised
@njit(**_JIT)
def cv_predict(x, P, T, q_tilde, x_out, P_out):
    """From ``x (4,)``, ``P (4, 4)`` into ``x_out``, ``P_out`` (which may be ``x``, ``P``:
    in place). Entries are read into locals first and written once (no reloads)."""
    p00, p01, p02, p03, p10, p11, p12, p13 = _rows01(P)
    p20, p21, p22, p23, p30, p31, p32, p33 = _rows23(P)
    x_out[0], x_out[1] = x[0] + T * x[2], x[1] + T * x[3]
    x_out[2], x_out[3] = x[2], x[3]
    # F P: rows i < 2 gain T · row i + 2
    a00, a01, a02, a03 = p00 + T * p20, p01 + T * p21, p02 + T * p22, p03 + T * p23
    a10, a11, a12, a13 = p10 + T * p30, p11 + T * p31, p12 + T * p32, p13 + T * p33
    # (F P) Fᵀ: columns j < 2 gain T · column j + 2
    b00, b01, b10, b11 = a00 + T * a02, a01 + T * a03, a10 + T * a12, a11 + T * a13
    b20, b21, b30, b31 = p20 + T * p22, p21 + T * p23, p30 + T * p32, p31 + T * p33
    q3, q2, q1 = q_tilde * (T**3 / 3.0), q_tilde * (T**2 / 2.0), q_tilde * T
    P_out[0, 0], P_out[1, 1] = b00 + q3, b11 + q3
    P_out[2, 2], P_out[3, 3] = p22 + q1, p33 + q1
    _sym(P_out, 0, 1, b01, b10)
    _sym(P_out, 0, 2, a02 + q2, b20 + q2)
    _sym(P_out, 0, 3, a03, b30)
    _sym(P_out, 1, 2, a12, b21)
    _sym(P_out, 1, 3, a13 + q2, b31 + q2)
    _sym(P_out, 2, 3, p23, p32)


@njit(**_JIT)
def _rows01(P):
    return P[0, 0], P[0, 1], P[0, 2], P[0, 3], P[1, 0], P[1, 1], P[1, 2], P[1, 3]


@njit(**_JIT)
def _rows23(P):
    return P[2, 0], P[2, 1], P[2, 2], P[2, 3], P[3, 0], P[3, 1], P[3, 2], P[3, 3]


# P_ij = P_ji = ½ (a + b): the symmetrised pair (called with constant indices: register_jitable
# types it on plain integers, one compile where a dispatcher compiles one per index pair)
@register_jitable(**_JIT)
def _sym(P, i, j, a, b):
    s = 0.5 * (a + b)
    P[i, j] = s
    P[j, i] = s


# --- EKF bearing updates ----------------------------------------------------------------------


# H = (Δy, −Δx, 0, 0)/r²,  ν = wrap(z − β(x⁻)),  S = max(H P Hᵀ, 0) + σ²,  K = P Hᵀ S⁻¹,
# x⁺ = x⁻ + K ν,  P⁺ = (I − K H) P (I − K H)ᵀ + K σ² Kᵀ (Joseph form, symmetrised)
@njit(**_JIT)
def ekf_bearing_update(x, P, z, px, py, sigma):
    """In place on ``x (4,)`` and ``P (4, 4)``; returns ``(ν, S)``. Entries are read into
    locals first and written once (no reloads, no allocation)."""
    dx = x[0] - px
    dy = x[1] - py
    r2 = dx * dx + dy * dy
    nu = wrap(z - bearing(x[0], x[1], px, py))
    return nu, _gain_update(x, P, nu, dy / r2, -dx / r2, sigma * sigma)


# The Gaussian second-order filter (Bar-Shalom, Li & Kirubarajan 2001, §10.3; theory §7.9): the
# bearing's curvature on the position, B = ∂²β/∂p² = [[−2ΔxΔy, Δx² − Δy²], [Δx² − Δy², 2ΔxΔy]]/r⁴,
# adds its mean to the prediction and its variance to the noise (P_pp: the position block of P⁻):
#   ẑ = β(x⁻) + ½ tr(B P_pp),   R = σ² + max(½ tr(B P_pp B P_pp), 0),   ν = wrap(z − ẑ),
#   S = max(H P Hᵀ, 0) + R,  K = P Hᵀ S⁻¹,  x⁺ = x⁻ + K ν,
#   P⁺ = (I − K H) P (I − K H)ᵀ + K R Kᵀ  (Joseph form, = P − K S Kᵀ; symmetrised)
# numpy reference: sensorgym.trackers.bearings.filters.ekf2_update
@njit(**_JIT)
def ekf2_bearing_update(x, P, z, px, py, sigma):
    """In place on ``x (4,)`` and ``P (4, 4)``; returns ``(ν, S)`` (no allocation)."""
    dx = x[0] - px
    dy = x[1] - py
    r2 = dx * dx + dy * dy
    r4 = r2 * r2
    b00 = -2.0 * dx * dy / r4
    b01 = (dx * dx - dy * dy) / r4
    b11 = 2.0 * dx * dy / r4
    # M = B P_pp
    p00, p01, p10, p11 = P[0, 0], P[0, 1], P[1, 0], P[1, 1]
    m00, m01 = b00 * p00 + b01 * p10, b00 * p01 + b01 * p11
    m10, m11 = b01 * p00 + b11 * p10, b01 * p01 + b11 * p11
    zhat = bearing(x[0], x[1], px, py) + 0.5 * (m00 + m11)
    noise = sigma * sigma + max(0.5 * (m00 * m00 + m01 * m10 + m10 * m01 + m11 * m11), 0.0)
    nu = wrap(z - zhat)
    return nu, _gain_update(x, P, nu, dy / r2, -dx / r2, noise)


# the linear(ised) update of both, with H = (h0, h1, 0, 0) and measurement noise variance R:
# S = max(H P Hᵀ, 0) + R,  K = P Hᵀ S⁻¹,  x⁺ = x⁻ + K ν,  P⁺ = (I − K H) P (I − K H)ᵀ + K R Kᵀ
@njit(**_JIT)
def _gain_update(x, P, nu, h0, h1, R):
    """In place on ``x (4,)`` and ``P (4, 4)``; returns ``S``. Entries are read into locals
    first and written once (no reloads, no allocation)."""
    p00, p01, p02, p03, p10, p11, p12, p13 = _rows01(P)
    p20, p21, p22, p23, p30, p31, p32, p33 = _rows23(P)
    # P Hᵀ
    pht0, pht1 = p00 * h0 + p01 * h1, p10 * h0 + p11 * h1
    pht2, pht3 = p20 * h0 + p21 * h1, p30 * h0 + p31 * h1
    S = max(h0 * pht0 + h1 * pht1, 0.0) + R
    k0, k1, k2, k3 = pht0 / S, pht1 / S, pht2 / S, pht3 / S
    x[0], x[1], x[2], x[3] = x[0] + k0 * nu, x[1] + k1 * nu, x[2] + k2 * nu, x[3] + k3 * nu
    # H P (row), and (A Hᵀ)ᵢ for A = (I − K H) P
    hp0, hp1 = h0 * p00 + h1 * p10, h0 * p01 + h1 * p11
    hp2, hp3 = h0 * p02 + h1 * p12, h0 * p03 + h1 * p13
    ah0 = (p00 - k0 * hp0) * h0 + (p01 - k0 * hp1) * h1
    ah1 = (p10 - k1 * hp0) * h0 + (p11 - k1 * hp1) * h1
    ah2 = (p20 - k2 * hp0) * h0 + (p21 - k2 * hp1) * h1
    ah3 = (p30 - k3 * hp0) * h0 + (p31 - k3 * hp1) * h1
    # P⁺ = A (I − K H)ᵀ + R K Kᵀ, Aᵢⱼ = Pᵢⱼ − kᵢ (H P)ⱼ, then symmetrised
    P[0, 0] = _joseph(p00, k0, hp0, ah0, k0, R)
    P[1, 1] = _joseph(p11, k1, hp1, ah1, k1, R)
    P[2, 2] = _joseph(p22, k2, hp2, ah2, k2, R)
    P[3, 3] = _joseph(p33, k3, hp3, ah3, k3, R)
    _sym(P, 0, 1, _joseph(p01, k0, hp1, ah0, k1, R), _joseph(p10, k1, hp0, ah1, k0, R))
    _sym(P, 0, 2, _joseph(p02, k0, hp2, ah0, k2, R), _joseph(p20, k2, hp0, ah2, k0, R))
    _sym(P, 0, 3, _joseph(p03, k0, hp3, ah0, k3, R), _joseph(p30, k3, hp0, ah3, k0, R))
    _sym(P, 1, 2, _joseph(p12, k1, hp2, ah1, k2, R), _joseph(p21, k2, hp1, ah2, k1, R))
    _sym(P, 1, 3, _joseph(p13, k1, hp3, ah1, k3, R), _joseph(p31, k3, hp1, ah3, k1, R))
    _sym(P, 2, 3, _joseph(p23, k2, hp3, ah2, k3, R), _joseph(p32, k3, hp2, ah3, k2, R))
    return S


# (A (I − K H)ᵀ + R K Kᵀ)ᵢⱼ = (Pᵢⱼ − kᵢ (H P)ⱼ) − (A Hᵀ)ᵢ kⱼ + R kᵢ kⱼ
@njit(**_JIT)
def _joseph(p_ij, k_i, hp_j, ah_i, k_j, R):
    return (p_ij - k_i * hp_j) - ah_i * k_j + R * k_i * k_j


# --- range-parameterised bank -----------------------------------------------------------------


# log wᵢ ← log wᵢ − log Σⱼ wⱼ   (normalised in place, max-shifted)
@njit(**_JIT)
def normalise_log_weights(lw):
    m = lw[0]
    for n in range(1, lw.shape[0]):
        m = max(m, lw[n])
    s = 0.0
    for n in range(lw.shape[0]):
        s += np.exp(lw[n] - m)
    lse = m + np.log(s)
    for n in range(lw.shape[0]):
        lw[n] = lw[n] - lse


# every member: x⁻ = F x, P⁻ = F P Fᵀ + Q; weights unchanged
@njit(**_JIT)
def bank_predict(X, P, T, q_tilde, X_out, P_out):
    """Members ``X (N, 4)``, ``P (N, 4, 4)`` into ``X_out``, ``P_out`` (or in place)."""
    for n in range(X.shape[0]):
        cv_predict(X[n], P[n], T, q_tilde, X_out[n], P_out[n])


# every member: second-order EKF update (ekf2_bearing_update: the first-order EKF over-claims
# by the episode end, theory §11.6);  log wᵢ += log N(νᵢ; 0, Sᵢ) = −½(νᵢ²/Sᵢ + ln 2πSᵢ),
# renormalised. The BearingsManeuver envs' bank.
@njit(**_JIT)
def bank_update(lw, X, P, z, px, py, sigma):
    """In place on ``lw (N,)``, ``X (N, 4)``, ``P (N, 4, 4)``."""
    for n in range(X.shape[0]):
        nu, S = ekf2_bearing_update(X[n], P[n], z, px, py, sigma)
        lw[n] = lw[n] - 0.5 * (nu * nu / S + np.log(_TWO_PI * S))
    normalise_log_weights(lw)


# every member: first-order EKF update (ekf_bearing_update), the weights as bank_update's
@njit(**_JIT)
def ekf_bank_update(lw, X, P, z, px, py, sigma):
    """In place on ``lw (N,)``, ``X (N, 4)``, ``P (N, 4, 4)``."""
    for n in range(X.shape[0]):
        nu, S = ekf_bearing_update(X[n], P[n], z, px, py, sigma)
        lw[n] = lw[n] - 0.5 * (nu * nu / S + np.log(_TWO_PI * S))
    normalise_log_weights(lw)


# moment match: x = Σ wᵢ xᵢ,  P = Σ wᵢ (Pᵢ + (xᵢ − x)(xᵢ − x)ᵀ), symmetrised
@njit(**_JIT)
def bank_estimate(lw, X, P, x_out, P_out, w):
    """Writes ``x_out (4,)``, ``P_out (4, 4)``; ``w (≥ N,)`` is scratch (the weights). The
    sums are kept in locals (no reloads)."""
    N = X.shape[0]
    e0 = e1 = e2 = e3 = 0.0
    for n in range(N):
        wn = np.exp(lw[n])
        w[n] = wn
        e0, e1, e2, e3 = e0 + wn * X[n, 0], e1 + wn * X[n, 1], e2 + wn * X[n, 2], e3 + wn * X[n, 3]
    c00 = c01 = c02 = c03 = c10 = c11 = c12 = c13 = 0.0
    c20 = c21 = c22 = c23 = c30 = c31 = c32 = c33 = 0.0
    for n in range(N):
        wn = w[n]
        d0, d1, d2, d3 = X[n, 0] - e0, X[n, 1] - e1, X[n, 2] - e2, X[n, 3] - e3
        p00, p01, p02, p03, p10, p11, p12, p13 = _rows01(P[n])
        p20, p21, p22, p23, p30, p31, p32, p33 = _rows23(P[n])
        c00 += wn * (p00 + d0 * d0)
        c01 += wn * (p01 + d0 * d1)
        c02 += wn * (p02 + d0 * d2)
        c03 += wn * (p03 + d0 * d3)
        c10 += wn * (p10 + d1 * d0)
        c11 += wn * (p11 + d1 * d1)
        c12 += wn * (p12 + d1 * d2)
        c13 += wn * (p13 + d1 * d3)
        c20 += wn * (p20 + d2 * d0)
        c21 += wn * (p21 + d2 * d1)
        c22 += wn * (p22 + d2 * d2)
        c23 += wn * (p23 + d2 * d3)
        c30 += wn * (p30 + d3 * d0)
        c31 += wn * (p31 + d3 * d1)
        c32 += wn * (p32 + d3 * d2)
        c33 += wn * (p33 + d3 * d3)
    x_out[0], x_out[1], x_out[2], x_out[3] = e0, e1, e2, e3
    P_out[0, 0], P_out[1, 1], P_out[2, 2], P_out[3, 3] = c00, c11, c22, c33
    _sym(P_out, 0, 1, c01, c10)
    _sym(P_out, 0, 2, c02, c20)
    _sym(P_out, 0, 3, c03, c30)
    _sym(P_out, 1, 2, c12, c21)
    _sym(P_out, 1, 3, c13, c31)
    _sym(P_out, 2, 3, c23, c32)


# --- square-root bound ------------------------------------------------------------------------


# P = L Lᵀ, L lower triangular (Cholesky–Banachiewicz): L_jj = √(P_jj − Σ_{k<j} L_jk²),
# L_ij = (P_ij − Σ_{k<j} L_ik L_jk) / L_jj; a pivot that rounding of a positive semi-definite
# P takes to ≤ 0 counts as zero, and so does its column
@njit(**_JIT)
def psd_square_root(P, L):
    """Writes the square root ``L (4, 4)`` of the symmetric ``P (4, 4)`` (lower triangle read)."""
    for j in range(STATE_DIM):
        d = P[j, j]
        for k in range(j):
            d -= L[j, k] * L[j, k]
        ljj = math.sqrt(d) if d > 0.0 else 0.0
        L[j, j] = ljj
        for i in range(j + 1, STATE_DIM):
            s = P[i, j]
            for k in range(j):
                s -= L[i, k] * L[j, k]
            L[i, j] = s / ljj if ljj > 0.0 else 0.0
        for i in range(j):
            L[i, j] = 0.0


@njit(**_JIT)
def psd_square_root_batch(P, L):
    for b in range(P.shape[0]):
        psd_square_root(P[b], L[b])


# ‖v‖ without overflow or underflow: s √Σ(vᵢ/s)², s = maxᵢ |vᵢ|
@njit(**_JIT)
def _scaled_norm(A, j, lo, hi):
    s = 0.0
    for i in range(lo, hi):
        s = max(s, abs(A[i, j]))
    if s == 0.0 or not np.isfinite(s):
        return s
    acc = 0.0
    for i in range(lo, hi):
        v = A[i, j] / s
        acc += v * v
    return s * np.sqrt(acc)


# A = Q R by Householder reflections (LAPACK dgeqr2 conventions: β = −sign(α)‖(α, v)‖);
# the upper triangle of A is left holding R (below it: scratch)
@njit(**_JIT)
def householder_r(A):
    m, n = A.shape
    for j in range(min(m - 1, n)):
        alpha = A[j, j]
        xnorm = _scaled_norm(A, j, j + 1, m)
        if xnorm == 0.0:
            continue
        beta = -math.copysign(math.hypot(alpha, xnorm), alpha)
        tau = (beta - alpha) / beta
        scale = 1.0 / (alpha - beta)
        for i in range(j + 1, m):
            A[i, j] *= scale
        A[j, j] = beta
        # H = I − τ v vᵀ, v = (1, A[j+1:, j]) applied to the columns on the right
        for c in range(j + 1, n):
            w = A[j, c]
            for i in range(j + 1, m):
                w += A[i, j] * A[i, c]
            w *= tau
            A[j, c] -= w
            for i in range(j + 1, m):
                A[i, c] -= w * A[i, j]


# P̄ = F P Fᵀ + Q = [F L, G][F L, G]ᵀ = Rᵀ R with [F L, G]ᵀ = Q R;  L̄ = Rᵀ (= F L when q̃ = 0);
# G = √q̃ [[√(T³/3), 0], [(√3/2)√T, √T/2]] per axis (G Gᵀ = Q)
@njit(**_JIT)
def bound_predict(L, T, q_tilde, out, A):
    """Square root ``out (4, 4)`` of the predicted bound from the square root ``L (4, 4)``;
    ``A (8, 4)`` is scratch."""
    if q_tilde == 0.0:
        for i in range(STATE_DIM):
            for j in range(STATE_DIM):
                out[i, j] = L[i, j] + (T * L[i + 2, j] if i < 2 else 0.0)
        return
    # A = [F L, G]ᵀ
    for i in range(STATE_DIM, 2 * STATE_DIM):
        for j in range(STATE_DIM):
            A[i, j] = 0.0
    for i in range(STATE_DIM):
        for j in range(STATE_DIM):
            A[j, i] = L[i, j] + (T * L[i + 2, j] if i < 2 else 0.0)
    sq = np.sqrt(q_tilde)
    g_pos, g_cross, g_vel = (
        sq * np.sqrt(T**3 / 3.0),
        sq * 0.5 * np.sqrt(3.0 * T),
        sq * 0.5 * np.sqrt(T),
    )
    for i in range(2):
        # G[i, i], G[i + 2, i], G[i + 2, i + 2] as rows 4 + column of Gᵀ
        A[STATE_DIM + i, i] = g_pos
        A[STATE_DIM + i, i + 2] = g_cross
        A[STATE_DIM + i + 2, i + 2] = g_vel
    householder_r(A)
    for i in range(STATE_DIM):
        for j in range(STATE_DIM):
            out[i, j] = A[j, i] if j <= i else 0.0


# P⁺ = (P̄⁻¹ + Hᵀ H/σ²)⁻¹ with H = n̂ᵀ/r, n̂ = (Δy, −Δx)/r: triangularise the pre-array
# M = [[r σ, n̂ᵀ L_pos], [0, L]] (Mᵀ = Q R, M Q = Rᵀ); P⁺ = Rᵀ[1:, 1:] (Rᵀ[1:, 1:])ᵀ
@njit(**_JIT)
def bound_update(L, tx, ty, px, py, sigma, out, A):
    """Square root ``out (4, 4)`` of the bound after one bearing at the true target
    position ``(tx, ty)`` from ``(px, py)``, from the square root ``L (4, 4)`` of ``P̄``;
    ``A (5, 5)`` is scratch."""
    dx = tx - px
    dy = ty - py
    r = math.hypot(dx, dy)
    position_update(L, r * sigma, dy / r, -dx / r, out, A)


# the same pre-array for any position information g gᵀ / a²: P⁺ = (P̄⁻¹ + Hᵀ H)⁻¹, H = gᵀ/a on
# the position (a bearing: a = r σ, g = n̂)
@njit(**_JIT)
def position_update(L, a, g0, g1, out, A):
    """Square root ``out (4, 4)`` of ``(P̄⁻¹ + Hᵀ H)⁻¹`` with ``H = (g0, g1, 0, 0)/a``, from the
    square root ``L (4, 4)`` of ``P̄``; ``A (5, 5)`` is scratch."""
    # A = Mᵀ
    A[0, 0] = a
    for j in range(STATE_DIM):
        A[0, j + 1] = 0.0
    for j in range(STATE_DIM):
        A[j + 1, 0] = g0 * L[0, j] + g1 * L[1, j]
        for i in range(STATE_DIM):
            A[j + 1, i + 1] = L[i, j]
    householder_r(A)
    for i in range(STATE_DIM):
        for j in range(STATE_DIM):
            out[i, j] = A[j + 1, i + 1] if j <= i else 0.0


# Without process noise (q̃ = 0) the state τ before the end is x(t − τ) = Φ(−τ) x(t) exactly, so a
# bearing taken then is the row h = (n̂, −τ n̂)/(r σ) on the final state, and bearings fuse in any
# order: from the bound P_o = L_o L_oᵀ at the end without them (P_o may be singular),
#   P = (P_o⁻¹ + Σ h hᵀ)⁻¹ = L_o N⁻¹ L_oᵀ,  N = I + Σ u uᵀ,  u = L_oᵀ h   (push-through identity)
# N = C Cᵀ is kept as its Cholesky factor, C ← chol(C Cᵀ + u uᵀ) by Givens rotations (dchud:
# never squares the data, so 1e-8-rad bearings on 1e4-m spreads stay exact; C_kk ≥ 1), and
# P = L Lᵀ with L = L_o C⁻ᵀ
@njit(**_JIT)
def late_bearing_information(Lo, tx, ty, px, py, sigma, tau, C, u):
    """Updates the lower-triangular ``C (4, 4)`` to ``chol(C Cᵀ + u uᵀ)`` for the bearing from
    ``(px, py)`` on ``(tx, ty)`` taken ``tau`` (s) before the end, ``u = L_oᵀ h`` from the end's
    square root ``Lo (4, 4)``; ``u (4,)`` is scratch."""
    dx = tx - px
    dy = ty - py
    r = math.hypot(dx, dy)
    a = 1.0 / (r * r * sigma)
    h0, h1 = dy * a, -dx * a
    h2, h3 = -tau * h0, -tau * h1
    for j in range(STATE_DIM):
        u[j] = Lo[0, j] * h0 + Lo[1, j] * h1 + Lo[2, j] * h2 + Lo[3, j] * h3
    # a Givens rotation of (column k of C, u) onto C_kk = ‖(C_kk, u_k)‖ for each k in turn
    for k in range(STATE_DIM):
        rk = math.sqrt(C[k, k] * C[k, k] + u[k] * u[k])
        cos, sin = C[k, k] / rk, u[k] / rk
        C[k, k] = rk
        for i in range(k + 1, STATE_DIM):
            cik = C[i, k]
            C[i, k] = cos * cik + sin * u[i]
            u[i] = cos * u[i] - sin * cik


@njit(**_JIT)
def late_update_root(Lo, C, out):
    """Square root ``out (4, 4)`` of ``L_o (C Cᵀ)⁻¹ L_oᵀ``: each row ``l`` of ``L_o`` solves
    ``C xᵀ = lᵀ`` by forward substitution."""
    for i in range(STATE_DIM):
        for j in range(STATE_DIM):
            s = Lo[i, j]
            for k in range(j):
                s -= C[j, k] * out[i, k]
            out[i, j] = s / C[j, j]


# √(P_xx + P_yy) = ‖L_pos‖ (the position rows of L)
@njit(**_JIT)
def position_rms(L):
    s = 0.0
    for i in range(2):
        for j in range(STATE_DIM):
            s += L[i, j] * L[i, j]
    return np.sqrt(s)


# σ_r = ‖gᵀ L_pos‖, g = (Δx, Δy)/r
@njit(**_JIT)
def range_sigma(L, tx, ty, px, py):
    dx = tx - px
    dy = ty - py
    r = math.hypot(dx, dy)
    g0 = dx / r
    g1 = dy / r
    s = 0.0
    for j in range(STATE_DIM):
        v = g0 * L[0, j] + g1 * L[1, j]
        s += v * v
    return np.sqrt(s)


# m(P) = √(P_xx + P_yy) ("position") or σ_r/r ("relative range", from the origin platform),
# clipped to [floor, 1/floor]
@njit(**_JIT)
def accuracy(relative_range, L, tx, ty, px, py, floor):
    if relative_range:
        m = range_sigma(L, tx, ty, px, py) / math.hypot(tx - px, ty - py)
    else:
        m = position_rms(L)
    return min(max(m, floor), 1.0 / floor)


# --- flattened batches (what the public numpy-facing functions call) -------------------------


@njit(**_JIT)
def cv_predict_batch(X, P, T, q_tilde):
    for b in range(X.shape[0]):
        cv_predict(X[b], P[b], T, q_tilde, X[b], P[b])


@njit(**_JIT)
def ekf_update_batch(X, P, z, pos, sigma, nu, S):
    for b in range(X.shape[0]):
        nu[b], S[b] = ekf_bearing_update(X[b], P[b], z[b], pos[b, 0], pos[b, 1], sigma)


@njit(**_JIT)
def ekf2_update_batch(X, P, z, pos, sigma, nu, S):
    for b in range(X.shape[0]):
        nu[b], S[b] = ekf2_bearing_update(X[b], P[b], z[b], pos[b, 0], pos[b, 1], sigma)


@njit(**_JIT)
def bank_update_batch(lw, X, P, z, pos, sigma):
    for b in range(X.shape[0]):
        bank_update(lw[b], X[b], P[b], z[b], pos[b, 0], pos[b, 1], sigma)


@njit(**_JIT)
def ekf_bank_update_batch(lw, X, P, z, pos, sigma):
    for b in range(X.shape[0]):
        ekf_bank_update(lw[b], X[b], P[b], z[b], pos[b, 0], pos[b, 1], sigma)


@njit(**_JIT)
def bank_estimate_batch(lw, X, P, x_out, P_out):
    w = np.empty(X.shape[1])
    for b in range(X.shape[0]):
        bank_estimate(lw[b], X[b], P[b], x_out[b], P_out[b], w)


@njit(**_JIT)
def bound_predict_batch(L, T, q_tilde, out):
    A = np.empty((2 * STATE_DIM, STATE_DIM))
    for b in range(L.shape[0]):
        bound_predict(L[b], T, q_tilde, out[b], A)


@njit(**_JIT)
def bound_update_batch(L, target, pos, sigma, out):
    A = np.empty((STATE_DIM + 1, STATE_DIM + 1))
    for b in range(L.shape[0]):
        bound_update(L[b], target[b, 0], target[b, 1], pos[b, 0], pos[b, 1], sigma[b], out[b], A)


@njit(**_JIT)
def position_rms_batch(L, out):
    for b in range(L.shape[0]):
        out[b] = position_rms(L[b])


@njit(**_JIT)
def range_sigma_batch(L, target, pos, out):
    for b in range(L.shape[0]):
        out[b] = range_sigma(L[b], target[b, 0], target[b, 1], pos[b, 0], pos[b, 1])


@njit(**_JIT)
def accuracy_batch(relative_range, L, target, origin, floor, out):
    for b in range(L.shape[0]):
        out[b] = accuracy(
            relative_range, L[b], target[b, 0], target[b, 1], origin[b, 0], origin[b, 1], floor
        )


# --- priors from a first bearing --------------------------------------------------------------


# moments of m (sin a, cos a), m ~ N(m̄, σ_m²) independent of a, δ = a − ā, u = (sin ā, cos ā),
# t = (cos ā, −sin ā), from the angle spread's c₁ = E[cos δ], s₂ = E[sin²δ], Var[cos δ]
# (:func:`sensorgym.trackers.bearings.filters.angle_spread_moments`):
#   E = m̄ c₁ u,   Cov = var_u u uᵀ + var_t t tᵀ,
#   var_u = m̄² Var[cos δ] + σ_m² (1 − s₂),   var_t = (m̄² + σ_m²) s₂
@njit(**_JIT)
def polar_moments(m, sm, a, c1, s2, var_cos, mean, cov):
    """Writes ``mean (2,)`` and ``cov (2, 2)``."""
    c2 = 1.0 - s2
    u0, u1 = math.sin(a), math.cos(a)
    t0, t1 = math.cos(a), -math.sin(a)
    mc = m * c1
    mean[0] = mc * u0
    mean[1] = mc * u1
    var_u = m * m * var_cos + sm * sm * c2
    var_t = (m * m + sm * sm) * s2
    cov[0, 0] = var_u * u0 * u0 + var_t * t0 * t0
    cov[0, 1] = var_u * u0 * u1 + var_t * t0 * t1
    cov[1, 0] = var_u * u1 * u0 + var_t * t1 * t0
    cov[1, 1] = var_u * u1 * u1 + var_t * t1 * t1


# position p + r (sin β, cos β), r ~ N(r̄, σ_r²), β ~ N(z, σ²) (spread factors pos_f);
# velocity s (sin c, cos c), s ~ N(s̄, σ_s²), c about c̄ (spread factors vel_f); x = (p + E_pos,
# E_vel), P = diag(Cov_pos, Cov_vel)   (Ristic §6.3.1)
@njit(**_JIT)
def bearing_prior(z, px, py, r, sr, pos_f, s, ss, c, vel_f, x, P):
    """Writes the prior ``x (4,)``, ``P (4, 4)``; ``pos_f``, ``vel_f`` = ``(c₁, s₂, Var[cos δ])``
    of the bearing and the course spreads."""
    for i in range(STATE_DIM):
        for j in range(STATE_DIM):
            P[i, j] = 0.0
    polar_moments(r, sr, z, pos_f[0], pos_f[1], pos_f[2], x[0:2], P[0:2, 0:2])
    x[0] = px + x[0]
    x[1] = py + x[1]
    polar_moments(s, ss, c, vel_f[0], vel_f[1], vel_f[2], x[2:4], P[2:4, 2:4])


# the bank's members: member n at range r_n (σ_r = sr_n) with log weight lw0_n (the range cells
# of :func:`sensorgym.trackers.bearings.filters.range_bank_cells`), same velocity prior
@njit(**_JIT)
def range_bank_prior(z, px, py, r, sr, lw0, pos_f, s, ss, c, vel_f, lw, X, P):
    """Writes ``lw (N,)``, ``X (N, 4)``, ``P (N, 4, 4)``."""
    for n in range(X.shape[0]):
        lw[n] = lw0[n]
        bearing_prior(z, px, py, r[n], sr[n], pos_f, s, ss, c, vel_f, X[n], P[n])


@njit(**_JIT)
def polar_moments_batch(m, sm, a, factors, mean, cov):
    for b in range(m.shape[0]):
        polar_moments(
            m[b], sm[b], a[b], factors[b, 0], factors[b, 1], factors[b, 2], mean[b], cov[b]
        )


@njit(**_JIT)
def bearing_prior_batch(z, p, r, sr, pos_f, s, ss, c, vel_f, x, P):
    for b in range(z.shape[0]):
        bearing_prior(
            z[b], p[b, 0], p[b, 1], r[b], sr[b], pos_f[b], s[b], ss[b], c[b], vel_f[b], x[b], P[b]
        )
