"""Least-squares conjugation of direction vectors from n receivers (SPEC §2.2, §5.2).

Receiver 1 is the reference frame. Receiver ``k`` (``k = 2..n``) reports the unit vector
``a_k`` in its own frame at time ``t_k``; ``c_k = P_k a_k`` is that direction in frame 1 and
``Δt_k = t_k − t_1`` its delay. For one object moving with velocity ``V`` and acceleration
``V̇`` (frame 1, at ``t_1``) the conjugation equations are (000 eq. 4–5, 003 eq. 1–3)::

    r_1 a_1 − r_k c_k + V Δt_k + V̇ Δt_k²/2 − b_k = e_k ,      k = 2..n

stacked as ``A X − B = E`` with ``X = (r_1, …, r_n, V, V̇)`` (003 eq. 4)::

    row block k:  [ a_1 | −c_k in column k | Δt_k I₃ | Δt_k²/2 I₃ ]      B block k: b_k

Motion order 0 keeps only the ranges (3(n−1) equations, n unknowns), order 1 adds ``V``
(needs n ≥ 3), order 2 adds ``V̇`` (needs n ≥ 5, 003 §5.2 table).

Solution (003 eq. 6–7)::

    X̂ = (AᵀWA)⁻¹ AᵀW B ,   J = (AX̂ − B)ᵀ W (AX̂ − B) ,   Q = σ_e² (AᵀWA)⁻¹

with ``W = diag(w_1 w_k I₃)`` from received powers (identity when no powers are given).
Weights are read as inverse relative variances: block ``k``'s error has variance
``σ_e²/(w_1 w_k)``, under which ``Q`` is the exact covariance of ``X̂``.

Conditioning. Every result carries the Frobenius condition number
``κ_F(A) = ‖A‖_F ‖A⁺‖_F = √(tr(AᵀWA) · tr((AᵀWA)⁻¹))`` (of the weighted matrix), which is
cheap for every path and bounds the spectral one: ``κ₂ ≤ κ_F ≤ p κ₂`` (``p`` unknowns).
Where ``κ_F > cond_max`` the system is solved through the Moore–Penrose pseudo-inverse with
singular values below ``s_max / cond_max`` dropped (000 eq. 11, "A⁺ if ill-conditioned"); the
flag ``used_pinv`` says where. That fallback is finite: the minimum-norm solution, its
covariance ``σ_e² A⁺A⁺ᵀ`` describing only the observable directions. Fully degenerate
geometry (parallel lines of sight, coplanar LOS with velocity, equal or zero delays) lands
there instead of producing NaN.

Accuracy models. ``Q`` is the papers' model: i.i.d. error of variance ``σ_e²`` on every
component of ``e_k``. Real direction errors are angular (zero along each line of sight,
``σ_e ≈ r σ_ang`` across it); for them see :mod:`.stereo_accuracy`.

Fast paths. n = 2 order 0 and n = 3 order 1 (the systems of papers 000/003) are solved in
closed form: the first by the 2×2 normal equations, the second by eliminating the velocity
(``Δt_3·block 2 − Δt_2·block 3``), which leaves a 3×3 system in the ranges solved by
Cramer's rule with triple products. Both agree with the generic SVD path to rounding and
hand any element whose ``κ_F`` exceeds ``cond_max`` to it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .validation import finite_array, unit_vectors

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

#: default switch to the pseudo-inverse branch (SPEC §11.2 item 14 suggests 1e6 for κ₂;
#: κ_F ≤ p κ₂, so 1e7 keeps well-conditioned 6×6 systems off the fallback)
DEFAULT_COND_MAX = 1e7

#: number of unknowns in X beyond the n ranges, per motion order
_MOTION_UNKNOWNS = {0: 0, 1: 3, 2: 6}
#: smallest n for which the motion order is determined (003 §5.2 table)
_MIN_RECEIVERS = {0: 2, 1: 3, 2: 5}


@dataclass(frozen=True)
class ConjugationSolution:
    """Least-squares solution of ``A X − B = E`` for a batch of problems (leading axes ``...``)."""

    ranges: FloatArray
    """``(..., n)`` slant ranges ``r̂_1 … r̂_n`` at the receivers' fix times, metres."""
    position: FloatArray
    """``(..., 3)`` object position ``M̂_1 = r̂_1 a_1`` in frame 1 at ``t_1``, metres."""
    velocity: FloatArray | None
    """``(..., 3)`` velocity ``V̂_1`` in frame 1, m/s; ``None`` for motion order 0."""
    acceleration: FloatArray | None
    """``(..., 3)`` acceleration ``V̇_1`` in frame 1, m/s²; ``None`` below motion order 2."""
    residual: FloatArray
    """``(...)`` weighted squared conjugation error ``J = ‖E‖²_W`` (000 eq. 9, 003 eq. 5), m²."""
    covariance: FloatArray
    """``(..., p, p)`` covariance ``σ_e² (AᵀWA)⁻¹`` of ``X = (r, V, V̇)`` under the papers' model."""
    condition: FloatArray
    """``(...)`` Frobenius condition number ``κ_F`` of the (weighted) matrix ``A``."""
    used_pinv: BoolArray
    """``(...)`` True where the pseudo-inverse fallback produced the solution."""

    @property
    def conjugation_error(self) -> FloatArray:
        """``‖E‖ = √J``, metres (003 §5.4 thresholds the norm, not its square)."""
        return np.sqrt(self.residual)

    @property
    def range_sigma(self) -> FloatArray:
        """``(..., n)`` standard deviations of the ranges, ``√diag(Q)[:n]``, metres."""
        n = self.ranges.shape[-1]
        return np.sqrt(np.diagonal(self.covariance, axis1=-2, axis2=-1)[..., :n])


# ---------------------------------------------------------------------------------------------
# input handling


def _rotate(P: FloatArray | None, ak: FloatArray) -> FloatArray:
    """``c_k = P_k a_k`` (frame k → frame 1)."""
    if P is None:
        return ak
    return np.einsum("...ij,...j->...i", P, ak)


def _check_rotations(P: ArrayLike | None, name: str) -> FloatArray | None:
    if P is None:
        return None
    P = finite_array(P, name, tail=(3, 3))
    err = np.abs(np.swapaxes(P, -1, -2) @ P - np.eye(3)).max(initial=0.0)
    if err > 1e-6:
        raise ValueError(f"{name}: must hold rotation matrices (max |PᵀP − I| = {err:.3g})")
    return P


def _check_weights(weights: ArrayLike | None, n: int) -> FloatArray | None:
    if weights is None:
        return None
    w = finite_array(weights, "weights")
    if w.ndim == 0 or w.shape[-1] != n:
        raise ValueError(f"weights: expected shape (..., {n}) (one received power per receiver)")
    if np.any(w <= 0.0):
        raise ValueError("weights: received powers must be positive (a zero power is no detection)")
    return w


# ---------------------------------------------------------------------------------------------
# system construction


def build_system(
    a1: FloatArray, c: FloatArray, b: FloatArray, dt: FloatArray | None, order: int
) -> tuple[FloatArray, FloatArray]:
    """``A`` ``(..., 3(n−1), p)`` and ``B`` ``(..., 3(n−1))`` of 003 eq. 4 (general n and order).

    ``a1 (..., 3)``; ``c (..., n−1, 3)`` directions ``P_k a_k`` already in frame 1;
    ``b (..., n−1, 3)``; ``dt (..., n−1)`` delays (ignored for order 0).
    """
    m = c.shape[-2]
    n = m + 1
    p = n + _MOTION_UNKNOWNS[order]
    batch = np.broadcast_shapes(a1.shape[:-1], c.shape[:-2], b.shape[:-2])
    if dt is not None:
        batch = np.broadcast_shapes(batch, dt.shape[:-1])
    A = np.zeros((*batch, m, 3, p))
    # column 1: a_1 in every row block
    A[..., :, :, 0] = a1[..., None, :]
    # column k: −c_k in row block k
    idx = np.arange(m)
    A[..., idx, :, idx + 1] = -np.moveaxis(np.broadcast_to(c, (*batch, m, 3)), -2, 0)
    eye = np.eye(3)
    if order >= 1:
        # velocity columns: Δt_k I₃
        A[..., :, :, n : n + 3] = dt[..., :, None, None] * eye
    if order >= 2:
        # acceleration columns: Δt_k²/2 I₃
        A[..., :, :, n + 3 : n + 6] = (0.5 * dt**2)[..., :, None, None] * eye
    B = np.broadcast_to(b, (*batch, m, 3))
    return A.reshape(*batch, 3 * m, p), B.reshape(*batch, 3 * m)


def _row_weights(weights: FloatArray | None, m: int) -> FloatArray | None:
    """Diagonal of ``W``: ``w_1 w_k`` repeated over the three rows of block k (003 eq. 7)."""
    if weights is None:
        return None
    wk = weights[..., :1] * weights[..., 1:]
    return np.repeat(wk, 3, axis=-1).reshape(*wk.shape[:-1], 3 * m)


# ---------------------------------------------------------------------------------------------
# generic solver (any n, any order)


def _solve_svd(
    A: FloatArray, B: FloatArray, row_w: FloatArray | None, sigma_e: float, cond_max: float
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, BoolArray]:
    """Weighted least squares through the SVD of ``W^½ A``; pseudo-inverse where ill-conditioned."""
    if row_w is not None:
        sw = np.sqrt(row_w)
        A = A * sw[..., :, None]
        B = B * sw
    U, s, Vt = np.linalg.svd(A, full_matrices=False)
    s_max = s[..., :1]
    with np.errstate(divide="ignore"):
        inv_s = np.where(s > 0.0, 1.0 / np.where(s > 0.0, s, 1.0), np.inf)
        # κ_F = √(Σ s² · Σ 1/s²)
        kappa = np.sqrt(np.sum(s**2, axis=-1) * np.sum(inv_s**2, axis=-1))
    used_pinv = ~(kappa <= cond_max)
    # A⁺: drop singular values below s_max/cond_max where the fallback runs (000 eq. 11)
    keep = ~used_pinv[..., None] | (s > s_max / cond_max)
    inv_s = np.where(keep, inv_s, 0.0)
    # X̂ = V diag(1/s) Uᵀ B
    UtB = np.einsum("...ji,...j->...i", U, B)
    X = np.einsum("...ji,...j->...i", Vt, inv_s * UtB)
    # Q = σ_e² V diag(1/s²) Vᵀ
    cov = sigma_e**2 * np.einsum("...ki,...k,...kj->...ij", Vt, inv_s**2, Vt)
    E = np.einsum("...ij,...j->...i", A, X) - B
    J = np.sum(E**2, axis=-1)
    return X, J, cov, kappa, used_pinv


# ---------------------------------------------------------------------------------------------
# closed forms


def _pair_closed_form(
    a1: FloatArray, c2: FloatArray, b2: FloatArray, scale: FloatArray | float, sigma_e: float
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """n = 2, order 0 (000 eq. 7–8) via ``AᵀA = [[1, −g], [−g, 1]]``, ``g = a_1·c_2 = cos γ``."""
    g = np.sum(a1 * c2, axis=-1)
    s2 = 1.0 - g * g  # det AᵀA = sin²γ
    p1 = np.sum(a1 * b2, axis=-1)  # (Aᵀb)_1 = a_1·b
    p2 = np.sum(c2 * b2, axis=-1)  # (Aᵀb)_2 = −c_2·b
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / s2
        # R̂ = (AᵀA)⁻¹Aᵀb = [[1, g], [g, 1]] (a_1·b, −c_2·b) / sin²γ
        r1 = (p1 - g * p2) * inv
        r2 = (g * p1 - p2) * inv
        # κ_F = √(tr AᵀA · tr (AᵀA)⁻¹) = 2/sin γ
        kappa = 2.0 * np.sqrt(inv)
    ranges = np.stack([r1, r2], axis=-1)
    # Q = σ_e²/(w sin²γ) [[1, cos γ], [cos γ, 1]]   (000 eq. 12)
    q = sigma_e**2 * inv / scale
    cov = np.empty((*q.shape, 2, 2))
    cov[..., 0, 0] = cov[..., 1, 1] = q
    cov[..., 0, 1] = cov[..., 1, 0] = q * g
    return ranges, cov, kappa, s2


def _triple_velocity_closed_form(
    a1: FloatArray, c: FloatArray, b: FloatArray, dt: FloatArray, sigma_e: float
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """n = 3, order 1 (000 eq. 10–11, 003 eq. 4): eliminate ``V`` and solve the 3×3 range system.

    ``Δt_3·(block 2) − Δt_2·(block 3)`` removes ``V``:
    ``r_1 (Δt_3 − Δt_2) a_1 − r_2 Δt_3 c_2 + r_3 Δt_2 c_3 = Δt_3 b_2 − Δt_2 b_3`` (SPEC §2.2).
    The 6×6 inverse (for ``Q`` and ``κ_F``) is the same solve applied to the six unit vectors.
    """
    c2, c3 = c[..., 0, :], c[..., 1, :]
    d2, d3 = dt[..., 0:1], dt[..., 1:2]
    # columns u_i of the reduced matrix M = [(Δt_3 − Δt_2) a_1, −Δt_3 c_2, Δt_2 c_3]
    u1 = (d3 - d2) * a1
    u2 = -d3 * c2
    u3 = d2 * c3
    x23, x31, x12 = np.cross(u2, u3), np.cross(u3, u1), np.cross(u1, u2)
    det = np.sum(u1 * x23, axis=-1)  # det M = u_1·(u_2 × u_3)
    # rows of M⁻¹ are (u_2×u_3, u_3×u_1, u_1×u_2)/det (Cramer)
    with np.errstate(divide="ignore", invalid="ignore"):
        Minv = np.stack([x23, x31, x12], axis=-2) / det[..., None, None]
    # R̂ = M⁻¹ (Δt_3 B_2 − Δt_2 B_3) applied to B and to the columns of the 6×6 identity:
    # K maps the stacked right-hand side (B_2, B_3) to the ranges: K = M⁻¹ [Δt_3 I, −Δt_2 I]
    K = np.concatenate([d3[..., None] * Minv, -d2[..., None] * Minv], axis=-1)  # (..., 3, 6)
    # V̂ = [Δt_2 (B_2 − r_1 a_1 + r_2 c_2) + Δt_3 (B_3 − r_1 a_1 + r_3 c_3)] / (Δt_2² + Δt_3²)
    # as a linear map of (B_2, B_3): V = L (B_2, B_3) with L = ([Δt_2 I, Δt_3 I] − G K)/(Δt_2²+Δt_3²)
    norm = d2 * d2 + d3 * d3
    G = np.stack([-(d2 + d3) * a1, d2 * c2, d3 * c3], axis=-1)  # V-numerator coefficients of r
    eye = np.eye(3)
    L = (np.concatenate([d2[..., None] * eye, d3[..., None] * eye], axis=-1) + G @ K) / norm[
        ..., None
    ]
    Ainv = np.concatenate([K, L], axis=-2)  # (..., 6, 6) = A⁻¹
    X = np.einsum("...ij,...j->...i", Ainv, b.reshape(*b.shape[:-2], 6))
    # Q = σ_e² A⁻¹ A⁻ᵀ
    cov = sigma_e**2 * (Ainv @ np.swapaxes(Ainv, -1, -2))
    # ‖A‖_F² = 2‖a_1‖² + ‖c_2‖² + ‖c_3‖² + 3(Δt_2² + Δt_3²)
    trace_ata = 4.0 + 3.0 * np.sum(dt * dt, axis=-1)
    trace_inv = np.sum(Ainv * Ainv, axis=(-2, -1))
    with np.errstate(invalid="ignore"):
        kappa = np.sqrt(trace_ata * trace_inv)
    return X, cov, kappa, det


# ---------------------------------------------------------------------------------------------
# public solvers


def _finalise(
    a1: FloatArray,
    n: int,
    order: int,
    X: FloatArray,
    J: FloatArray,
    cov: FloatArray,
    kappa: FloatArray,
    used_pinv: BoolArray,
) -> ConjugationSolution:
    # every field carries the full batch shape, even where it depends on a broadcast input only
    shape = np.broadcast_shapes(X.shape[:-1], J.shape, cov.shape[:-2], kappa.shape, used_pinv.shape)
    X = np.broadcast_to(X, (*shape, X.shape[-1]))
    J, kappa, used_pinv = (np.broadcast_to(x, shape) for x in (J, kappa, used_pinv))
    cov = np.broadcast_to(cov, (*shape, *cov.shape[-2:]))
    a1 = np.broadcast_to(a1, (*shape, 3))
    ranges = X[..., :n]
    return ConjugationSolution(
        ranges=ranges,
        position=ranges[..., :1] * a1,
        velocity=X[..., n : n + 3] if order >= 1 else None,
        acceleration=X[..., n + 3 : n + 6] if order >= 2 else None,
        residual=J,
        covariance=cov,
        condition=kappa,
        used_pinv=used_pinv,
    )


def _check_sigma(sigma_e: float, cond_max: float) -> None:
    if not (np.isfinite(sigma_e) and sigma_e > 0.0):
        raise ValueError(f"sigma_e: must be a positive finite number, got {sigma_e}")
    if not (np.isfinite(cond_max) and cond_max > 1.0):
        raise ValueError(f"cond_max: must be a finite number > 1, got {cond_max}")


def solve_conjugation(
    a1: ArrayLike,
    ak: ArrayLike,
    P: ArrayLike | None,
    b: ArrayLike,
    dt: ArrayLike | None = None,
    *,
    order: int = 0,
    weights: ArrayLike | None = None,
    sigma_e: float = 1.0,
    cond_max: float = DEFAULT_COND_MAX,
) -> ConjugationSolution:
    """Solve the conjugation system of n receivers for ranges (and velocity, acceleration).

    Parameters
    ----------
    a1
        ``(..., 3)`` unit vector of receiver 1 (frame 1), fixed at ``t_1``.
    ak
        ``(..., n−1, 3)`` unit vectors of receivers ``2..n`` in their own frames.
    P
        ``(..., n−1, 3, 3)`` rotations frame k → frame 1, or ``None`` for aligned frames.
    b
        ``(..., n−1, 3)`` base vectors ``O_1 → O_k`` in frame 1, metres.
    dt
        ``(..., n−1)`` delays ``Δt_k = t_k − t_1``, seconds; required for ``order ≥ 1``.
    order
        0: ranges only; 1: + velocity (n ≥ 3); 2: + acceleration (n ≥ 5).
    weights
        ``(..., n)`` positive received powers ``w_k`` (003 eq. 7), or ``None``.
    sigma_e
        standard deviation of each component of ``e_k``, metres (scales ``covariance``).
    cond_max
        ``κ_F`` above which the pseudo-inverse fallback runs.

    All leading axes broadcast; batched results equal one-at-a-time results.
    """
    if order not in _MOTION_UNKNOWNS:
        raise ValueError(f"order: must be 0, 1 or 2, got {order!r}")
    _check_sigma(sigma_e, cond_max)
    a1 = unit_vectors(a1, "a1")
    ak = unit_vectors(ak, "ak")
    if ak.ndim < 2:
        raise ValueError(f"ak: expected shape (..., n-1, 3), got {ak.shape}")
    m = ak.shape[-2]
    n = m + 1
    if n < _MIN_RECEIVERS[order]:
        raise ValueError(
            f"order {order} needs at least {_MIN_RECEIVERS[order]} receivers "
            f"(3(n−1) equations ≥ n + {_MOTION_UNKNOWNS[order]} unknowns), got n = {n}"
        )
    P = _check_rotations(P, "P")
    b = finite_array(b, "b", tail=(m, 3))
    if order >= 1:
        if dt is None:
            raise ValueError(f"dt: delays are required for motion order {order}")
        dt = finite_array(dt, "dt", tail=(m,))
    else:
        dt = None
    w = _check_weights(weights, n)
    c = _rotate(P, ak)

    if n == 2 and order == 0:
        return _solve_pair_checked(a1, c[..., 0, :], b[..., 0, :], w, sigma_e, cond_max)
    if n == 3 and order == 1 and w is None:
        return _solve_triple_velocity_checked(a1, c, b, dt, sigma_e, cond_max)

    A, B = build_system(a1, c, b, dt, order)
    X, J, cov, kappa, used = _solve_svd(A, B, _row_weights(w, m), sigma_e, cond_max)
    return _finalise(np.broadcast_to(a1, (*X.shape[:-1], 3)), n, order, X, J, cov, kappa, used)


def _generic_fallback(
    mask: BoolArray,
    a1: FloatArray,
    c: FloatArray,
    b: FloatArray,
    dt: FloatArray | None,
    order: int,
    row_w: FloatArray | None,
    sigma_e: float,
    cond_max: float,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, BoolArray]:
    """Run the SVD path on the elements selected by ``mask`` (ill-conditioned closed forms)."""
    shape = mask.shape

    def pick(x: FloatArray | None, tail: int) -> FloatArray | None:
        if x is None:
            return None
        return np.broadcast_to(x, (*shape, *x.shape[x.ndim - tail :]))[mask]

    A, B = build_system(pick(a1, 1), pick(c, 2), pick(b, 2), pick(dt, 1), order)
    return _solve_svd(A, B, pick(row_w, 1), sigma_e, cond_max)


def _patch(
    used: BoolArray, fast: tuple[FloatArray, ...], fallback: tuple[FloatArray, ...]
) -> tuple[FloatArray, ...]:
    """Copies of the closed-form outputs with the fallback's values where ``used``."""
    flat = used.reshape(-1)
    out = []
    for f, g in zip(fast, fallback, strict=True):
        shape = np.shape(f)
        f = np.array(f, copy=True).reshape(flat.size, *shape[used.ndim :])
        f[flat] = g
        out.append(f.reshape(shape))
    return tuple(out)


def _solve_pair_checked(
    a1: FloatArray,
    c2: FloatArray,
    b2: FloatArray,
    w: FloatArray | None,
    sigma_e: float,
    cond_max: float,
) -> ConjugationSolution:
    scale = 1.0 if w is None else w[..., 0] * w[..., 1]
    with np.errstate(divide="ignore", invalid="ignore"):  # degenerate elements go to the fallback
        ranges, cov, kappa, _ = _pair_closed_form(a1, c2, b2, scale, sigma_e)
    shape = ranges.shape[:-1]
    cov, kappa = np.broadcast_to(cov, (*shape, 2, 2)), np.broadcast_to(kappa, shape)
    a1 = np.broadcast_to(a1, (*shape, 3))
    c2 = np.broadcast_to(c2, (*shape, 3))
    b2 = np.broadcast_to(b2, (*shape, 3))
    # J = ‖r_1 a_1 − r_2 c_2 − b_2‖² · w_1 w_2   (000 eq. 9)
    E = ranges[..., :1] * a1 - ranges[..., 1:] * c2 - b2
    J = np.sum(E * E, axis=-1) * scale
    used = ~(kappa <= cond_max)
    kappa = np.where(used, np.inf, kappa)
    if np.any(used):
        row_w = None if w is None else np.repeat((w[..., 0] * w[..., 1])[..., None], 3, axis=-1)
        X, Jf, covf, kf, uf = _generic_fallback(
            used, a1, c2[..., None, :], b2[..., None, :], None, 0, row_w, sigma_e, cond_max
        )
        ranges, J, cov, kappa, pinv = _patch(
            used, (ranges, J, cov, kappa, used), (X, Jf, covf, kf, uf)
        )
        used = pinv.astype(bool)
    return _finalise(a1, 2, 0, ranges, J, cov, kappa, used)


def _solve_triple_velocity_checked(
    a1: FloatArray, c: FloatArray, b: FloatArray, dt: FloatArray, sigma_e: float, cond_max: float
) -> ConjugationSolution:
    with np.errstate(divide="ignore", invalid="ignore"):  # degenerate elements go to the fallback
        X, cov, kappa, _ = _triple_velocity_closed_form(a1, c, b, dt, sigma_e)
    shape = X.shape[:-1]
    cov, kappa = np.broadcast_to(cov, (*shape, 6, 6)), np.broadcast_to(kappa, shape)
    used = ~(kappa <= cond_max)
    # square system: J = 0 up to rounding; computed honestly from the residual
    a1b = np.broadcast_to(a1, (*shape, 3))
    cb = np.broadcast_to(c, (*shape, 2, 3))
    bb = np.broadcast_to(b, (*shape, 2, 3))
    dtb = np.broadcast_to(dt, (*shape, 2))
    E = (
        X[..., None, :1] * a1b[..., None, :]
        - X[..., 1:3, None] * cb
        + dtb[..., :, None] * X[..., None, 3:6]
        - bb
    )
    J = np.sum(E * E, axis=(-2, -1))
    if np.any(used):
        Xf, Jf, covf, kf, uf = _generic_fallback(used, a1b, cb, bb, dtb, 1, None, sigma_e, cond_max)
        X, J, cov, kappa, pinv = _patch(used, (X, J, cov, kappa, used), (Xf, Jf, covf, kf, uf))
        used = pinv.astype(bool)
    return _finalise(a1b, 3, 1, X, J, cov, kappa, used)


def solve_pair(
    a1: ArrayLike,
    a2: ArrayLike,
    P2: ArrayLike | None,
    b2: ArrayLike,
    dt2: ArrayLike | None = None,
    velocity: ArrayLike | None = None,
    *,
    sigma_e: float = 1.0,
    cond_max: float = DEFAULT_COND_MAX,
) -> ConjugationSolution:
    """Two-receiver ranges (000 eq. 7–9), optionally motion-compensated.

    ``a1, a2 (..., 3)`` unit vectors in their own frames, ``P2 (..., 3, 3)`` or ``None``,
    ``b2 (..., 3)``. With a known ``velocity`` ``(..., 3)`` (frame 1) and delay ``dt2`` the
    displacement is moved to the right-hand side: ``B̂_2 = b_2 − V Δt_2`` (000 §"range
    re-solve", 003 §5.4 step 2.2). Parallel lines of sight take the pseudo-inverse fallback.
    """
    _check_sigma(sigma_e, cond_max)
    a1 = unit_vectors(a1, "a1")
    a2 = unit_vectors(a2, "a2")
    P2 = _check_rotations(P2, "P2")
    b2 = finite_array(b2, "b2", tail=(3,))
    if (velocity is None) != (dt2 is None):
        raise ValueError("velocity and dt2: give both (motion compensation) or neither")
    if velocity is not None:
        v = finite_array(velocity, "velocity", tail=(3,))
        d = finite_array(dt2, "dt2")
        # B̂_2 = b_2 − V̂ Δt_2
        b2 = b2 - v * d[..., None]
    return _solve_pair_checked(a1, _rotate(P2, a2), b2, None, sigma_e, cond_max)


def solve_proposed(
    a1: ArrayLike,
    ak: ArrayLike,
    P: ArrayLike | None,
    b: ArrayLike,
    dt: ArrayLike,
    *,
    sigma_e: float = 1.0,
    cond_max: float = DEFAULT_COND_MAX,
) -> ConjugationSolution:
    """Paper 000's proposed spatial step (SPEC §2.4, n = 3).

    ``V̂`` comes from the 6×6 velocity-aware system (000 eq. 10–11); ``r̂_1, r̂_2`` are then
    re-solved from the pair ``(a_1, a_2)`` with ``B̂_2 = b_2 − V̂ Δt_2``, "more stable to matrix
    inversion". Where the 6×6 ``A`` is invertible the re-solve returns the same ``r̂_1``
    (SPEC §9 CHECK 4); it matters on the pseudo-inverse branch. ``r̂_3``, ``covariance``,
    ``condition`` and ``used_pinv`` are those of the 6×6 system.
    """
    full = solve_conjugation(a1, ak, P, b, dt, order=1, sigma_e=sigma_e, cond_max=cond_max)
    ak = np.asarray(ak, dtype=np.float64)
    pair = solve_pair(
        a1,
        ak[..., 0, :],
        None if P is None else np.asarray(P, dtype=np.float64)[..., 0, :, :],
        np.asarray(b, dtype=np.float64)[..., 0, :],
        np.asarray(dt, dtype=np.float64)[..., 0],
        full.velocity,
        sigma_e=sigma_e,
        cond_max=cond_max,
    )
    ranges = np.concatenate([pair.ranges, full.ranges[..., 2:]], axis=-1)
    return ConjugationSolution(
        ranges=ranges,
        position=pair.position,
        velocity=full.velocity,
        acceleration=None,
        residual=full.residual,
        covariance=full.covariance,
        condition=full.condition,
        used_pinv=full.used_pinv,
    )
