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
hand any element whose ``κ_F`` exceeds ``cond_max`` to it. They work on component-major
arrays (``(3, ...)``: ``u[0], u[1], u[2]`` are contiguous rows), because numpy reduces a
trailing axis of length 3 an order of magnitude slower than it multiplies rows.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .validation import check_unit_norms, finite_array, unit_vector_components

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

#: default switch to the pseudo-inverse branch (SPEC §11.2 item 14 suggests 1e6 for κ₂;
#: κ_F ≤ p κ₂, so 1e7 keeps well-conditioned 6×6 systems off the fallback)
DEFAULT_COND_MAX = 1e7

#: batch elements per chunk of the n = 3 velocity closed form (cache-sized temporaries)
_CHUNK = 16384

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
# component-major vector algebra: u is (3, ...) with contiguous rows u[0], u[1], u[2]


def _dot(u: FloatArray, v: FloatArray) -> FloatArray:
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]


def _cross(u: FloatArray, v: FloatArray) -> FloatArray:
    return np.stack(
        [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]
    )


def _rotate(P: FloatArray | None, a: FloatArray) -> FloatArray:
    """``c_k = P_k a_k`` (frame k → frame 1) for component-major ``P (3, 3, ...)``, ``a (3, ...)``."""
    if P is None:
        return a
    return np.stack([P[i, 0] * a[0] + P[i, 1] * a[1] + P[i, 2] * a[2] for i in range(3)])


def _broadcast_components(u: FloatArray, lead: int, batch: tuple[int, ...]) -> FloatArray:
    """Broadcast ``u (*lead axes, *own batch)`` to ``(*lead axes, *batch)``."""
    own = u.ndim - lead
    shape = (*u.shape[:lead], *(1,) * (len(batch) - own), *u.shape[lead:])
    return np.broadcast_to(u.reshape(shape), (*u.shape[:lead], *batch))


def _check_weights(weights: ArrayLike | None, n: int) -> FloatArray | None:
    if weights is None:
        return None
    w = finite_array(weights, "weights")
    if w.ndim == 0 or w.shape[-1] != n:
        raise ValueError(f"weights: expected shape (..., {n}) (one received power per receiver)")
    if np.any(w <= 0.0):
        raise ValueError("weights: received powers must be positive (a zero power is no detection)")
    return w


def _check_sigma(sigma_e: float, cond_max: float) -> None:
    if not (np.isfinite(sigma_e) and sigma_e > 0.0):
        raise ValueError(f"sigma_e: must be a positive finite number, got {sigma_e}")
    if not (np.isfinite(cond_max) and cond_max > 1.0):
        raise ValueError(f"cond_max: must be a finite number > 1, got {cond_max}")


# ---------------------------------------------------------------------------------------------
# system construction and the generic solver (any n, any order)


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
# closed forms (component-major inputs)


def _pair_closed_form(
    a: FloatArray,
    c: FloatArray,
    b: FloatArray,
    scale: FloatArray | float,
    sigma_e: float,
    out: FloatArray | None = None,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """n = 2, order 0 (000 eq. 7–8) via ``AᵀA = [[1, −g], [−g, 1]]``, ``g = a_1·c_2 = cos γ``.

    Returns ``X (2, ...)``, ``J``, ``Q (2, 2, ...)`` (written into ``out`` when given), ``κ_F``.
    """
    g = _dot(a, c)
    p1 = _dot(a, b)  # (Aᵀb)_1 = a_1·b
    p2 = _dot(c, b)  # (Aᵀb)_2 = −c_2·b
    # 1/det AᵀA = 1/sin²γ
    inv = 1.0 / (1.0 - g * g)
    # R̂ = (AᵀA)⁻¹Aᵀb = [[1, g], [g, 1]] (a_1·b, −c_2·b) / sin²γ
    r1 = (p1 - g * p2) * inv
    r2 = (g * p1 - p2) * inv
    # E = r_1 a_1 − r_2 c_2 − b ;  J = w_1 w_2 ‖E‖²   (000 eq. 9)
    E = r1 * a - r2 * c - b
    J = _dot(E, E) * scale
    # Q = σ_e²/(w_1 w_2 sin²γ) [[1, cos γ], [cos γ, 1]]   (000 eq. 12)
    q = (sigma_e**2 / scale) * inv
    qg = q * g
    # κ_F = √(tr AᵀA · tr (AᵀA)⁻¹) = 2/sin γ
    kappa = 2.0 * np.sqrt(inv)
    Q = np.empty((2, 2, *J.shape)) if out is None else out
    Q[0, 0] = Q[1, 1] = q
    Q[0, 1] = Q[1, 0] = qg
    return np.stack([r1, r2]), J, Q, kappa


def _triple_velocity_closed_form(
    a: FloatArray,
    c2: FloatArray,
    c3: FloatArray,
    b2: FloatArray,
    b3: FloatArray,
    d2: FloatArray,
    d3: FloatArray,
    sigma_e: float,
    out: FloatArray | None = None,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """n = 3, order 1 (000 eq. 10–11, 003 eq. 4): eliminate ``V`` and solve the 3×3 range system.

    ``Δt_3·(block 2) − Δt_2·(block 3)`` removes ``V``:
    ``r_1 (Δt_3 − Δt_2) a_1 − r_2 Δt_3 c_2 + r_3 Δt_2 c_3 = Δt_3 b_2 − Δt_2 b_3 = d`` (SPEC §2.2),
    ``M R = d`` solved by Cramer's rule; then ``V̂`` is the least-squares fit of both blocks,
    ``V̂ = (Δt_2 b_2 + Δt_3 b_3 + G R)/Δ²`` with ``Δ² = Δt_2² + Δt_3²`` and ``G`` the columns
    ``(−(Δt_2+Δt_3) a_1, Δt_2 c_2, Δt_3 c_3)``. As a map of ``(b_2, b_3)`` this is
    ``A⁻¹ = [[M⁻¹ [Δt_3 I, −Δt_2 I]], [[Δt_2 I + Δt_3 H, Δt_3 I − Δt_2 H]/Δ²]]``, ``H = G M⁻¹``,
    whence (by multiplying out) ``Q = σ_e² A⁻¹A⁻ᵀ`` has the blocks
    ``Q_rr = Δ² M⁻¹M⁻ᵀ``, ``Q_rV = M⁻¹Hᵀ``, ``Q_VV = (I + H Hᵀ)/Δ²`` and
    ``‖A⁻¹‖_F² = Δ² ‖M⁻¹‖_F² + (3 + ‖H‖_F²)/Δ²``. Returns ``X (6, ...)``, ``J``,
    ``Q (6, 6, ...)`` (written into ``out`` when given), ``κ_F``.
    """
    # columns of M = [(Δt_3 − Δt_2) a_1, −Δt_3 c_2, Δt_2 c_3]
    u1, u2, u3 = (d3 - d2) * a, -d3 * c2, d2 * c3
    # rows of M⁻¹ = (u_2×u_3, u_3×u_1, u_1×u_2) / det M   (Cramer), det M = u_1·(u_2×u_3)
    x23 = _cross(u2, u3)
    inv_det = 1.0 / _dot(u1, x23)
    Mi = [x23 * inv_det, _cross(u3, u1) * inv_det, _cross(u1, u2) * inv_det]  # Mi[row][col]
    # R̂ = M⁻¹ d
    d = d3 * b2 - d2 * b3
    r = [_dot(Mi[k], d) for k in range(3)]
    # V̂ = (Δt_2 (b_2 − r_1 a_1 + r_2 c_2) + Δt_3 (b_3 − r_1 a_1 + r_3 c_3)) / Δ²
    delta2 = d2 * d2 + d3 * d3
    V = (d2 * b2 + d3 * b3 - (d2 + d3) * r[0] * a + d2 * r[1] * c2 + d3 * r[2] * c3) / delta2
    # E_k = r_1 a_1 − r_k c_k + Δt_k V − b_k ;  J = ‖E_2‖² + ‖E_3‖²
    E2 = r[0] * a - r[1] * c2 + d2 * V - b2
    E3 = r[0] * a - r[2] * c3 + d3 * V - b3
    J = _dot(E2, E2) + _dot(E3, E3)
    # H = G M⁻¹ : H[i][j] = Σ_m G[i][m] M⁻¹[m][j]
    Gcols = (-(d2 + d3) * a, d2 * c2, d3 * c3)
    H = [[sum(Gcols[m][i] * Mi[m][j] for m in range(3)) for j in range(3)] for i in range(3)]
    s2 = sigma_e**2
    Q = np.empty((6, 6, *J.shape)) if out is None else out
    for i in range(3):
        for j in range(3):
            # Q_rV = M⁻¹ Hᵀ
            Q[i, 3 + j] = Q[3 + j, i] = s2 * sum(Mi[i][k] * H[j][k] for k in range(3))
        for j in range(i, 3):
            # Q_rr = Δ² M⁻¹ M⁻ᵀ ;  Q_VV = (I + H Hᵀ)/Δ²
            Q[i, j] = Q[j, i] = s2 * delta2 * _dot(Mi[i], Mi[j])
            hh = sum(H[i][k] * H[j][k] for k in range(3)) + (1.0 if i == j else 0.0)
            Q[3 + i, 3 + j] = Q[3 + j, 3 + i] = s2 * hh / delta2
    # κ_F² = ‖A‖_F² ‖A⁻¹‖_F², ‖A‖_F² = 2‖a_1‖² + ‖c_2‖² + ‖c_3‖² + 3Δ²
    frob_mi = sum(_dot(Mi[k], Mi[k]) for k in range(3))
    frob_h = sum(H[i][j] ** 2 for i in range(3) for j in range(3))
    kappa = np.sqrt((4.0 + 3.0 * delta2) * (delta2 * frob_mi + (3.0 + frob_h) / delta2))
    X = np.stack([r[0], r[1], r[2], V[0], V[1], V[2]])
    return X, J, Q, kappa


def _pool() -> ThreadPoolExecutor:
    """Two worker threads (numpy releases the GIL inside its loops), created on first use."""
    global _POOL
    if _POOL is None:
        _POOL = ThreadPoolExecutor(max_workers=min(2, os.cpu_count() or 1))
    return _POOL


_POOL: ThreadPoolExecutor | None = None


def _in_chunks(
    closed_form: Callable[..., tuple[FloatArray, FloatArray, FloatArray, FloatArray]],
    inputs: tuple[FloatArray, ...],
    p: int,
    sigma_e: float,
    chunk: int = _CHUNK,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """An elementwise closed form over cache-sized chunks of a large batch, two chunks at a time.

    The closed forms make tens to hundreds of temporaries; in chunks of :data:`_CHUNK` they stay
    in cache, and as numpy releases the GIL two threads use both cores. Each chunk writes its
    own slice of full-size component-major outputs, so the result does not depend on the
    threading. ``inputs`` share the batch shape of the last one (component axes lead).
    """
    shape = inputs[-1].shape
    size = int(np.prod(shape))
    flat = [x.reshape(*x.shape[: x.ndim - len(shape)], size) for x in inputs]
    X, J, Q, kappa = np.empty((p, size)), np.empty(size), np.empty((p, p, size)), np.empty(size)

    def work(lo: int) -> None:
        sl = slice(lo, lo + chunk)
        # errstate is per thread: degenerate elements are handled by the fallback
        with np.errstate(divide="ignore", invalid="ignore"):
            Xc, Jc, _, kc = closed_form(*(x[..., sl] for x in flat), sigma_e, out=Q[..., sl])
        X[:, sl], J[sl], kappa[sl] = Xc, Jc, kc

    for _ in _pool().map(work, range(0, size, chunk)):
        pass
    return X.reshape(p, *shape), J.reshape(shape), Q.reshape(p, p, *shape), kappa.reshape(shape)


# ---------------------------------------------------------------------------------------------
# assembling results


def _finalise(
    a1: FloatArray,
    n: int,
    order: int,
    X: FloatArray,
    J: FloatArray,
    cov: FloatArray,
    kappa: FloatArray,
    used_pinv: BoolArray,
    position: FloatArray | None = None,
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
        position=ranges[..., :1] * a1 if position is None else position,
        velocity=X[..., n : n + 3] if order >= 1 else None,
        acceleration=X[..., n + 3 : n + 6] if order >= 2 else None,
        residual=J,
        covariance=cov,
        condition=kappa,
        used_pinv=used_pinv,
    )


def _closed_form_result(
    a1: FloatArray,
    a1c: FloatArray,
    n: int,
    order: int,
    fast: tuple[FloatArray, FloatArray, FloatArray, FloatArray],
    system: tuple[FloatArray, FloatArray, FloatArray, FloatArray | None, FloatArray | None],
    sigma_e: float,
    cond_max: float,
) -> ConjugationSolution:
    """Component-major closed-form outputs → result; elements with ``κ_F > cond_max`` re-solved
    on the generic pseudo-inverse path. ``system = (a1, c, b, dt, row_w)`` in ``(..., 3)`` form."""
    X, J, Q, kappa = fast
    shape = np.broadcast_shapes(X.shape[1:], J.shape, kappa.shape)
    X = np.moveaxis(np.broadcast_to(X, (X.shape[0], *shape)), 0, -1)
    # Q is one contiguous (p, p, ...) block, returned as a (..., p, p) view: row writes are
    # fast, strided writes into a batch-first array are not
    p = Q.shape[0]
    cov = np.moveaxis(np.broadcast_to(Q, (p, p, *shape)).reshape(p * p, *shape), 0, -1)
    cov = cov.reshape(*shape, p, p)
    J, kappa = np.broadcast_to(J, shape), np.broadcast_to(kappa, shape)
    used = ~(kappa <= cond_max)
    if np.any(used):
        picked = [
            None if x is None else np.broadcast_to(x, (*shape, *x.shape[x.ndim - t :]))[used]
            for x, t in zip(system, (1, 2, 2, 1, 1), strict=True)
        ]
        A, B = build_system(*picked[:4], order)
        fallback = _solve_svd(A, B, picked[4], sigma_e, cond_max)
        X, J, cov, kappa, used = (np.array(x, copy=True) for x in (X, J, cov, kappa, used))
        X[used], J[used], cov[used], kappa[used], used[used] = fallback
    # M̂_1 = r̂_1 a_1 from the contiguous components (a (N, 1) × (N, 3) broadcast is slow)
    position = np.moveaxis(X[..., 0] * a1c, 0, -1)
    return _finalise(a1, n, order, X, J, cov, kappa, used, position)


# ---------------------------------------------------------------------------------------------
# public solvers


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
    check_inputs: bool = True,
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
    check_inputs
        verify finiteness, unit length of directions and orthonormality of ``P`` (shapes are
        always checked). Pass ``False`` only for arrays known good, e.g. built by the
        environments; it saves about a third of the time of the closed forms.

    All leading axes broadcast; batched results equal one-at-a-time results.
    """
    if order not in _MOTION_UNKNOWNS:
        raise ValueError(f"order: must be 0, 1 or 2, got {order!r}")
    _check_sigma(sigma_e, cond_max)
    chk = check_inputs
    a1, a1c = unit_vector_components(a1, "a1", check=chk)
    ak, akc = unit_vector_components(ak, "ak", check=chk)
    if ak.ndim < 2:
        raise ValueError(f"ak: expected shape (..., n-1, 3), got {ak.shape}")
    m = ak.shape[-2]
    n = m + 1
    if n < _MIN_RECEIVERS[order]:
        raise ValueError(
            f"order {order} needs at least {_MIN_RECEIVERS[order]} receivers "
            f"(3(n−1) equations ≥ n + {_MOTION_UNKNOWNS[order]} unknowns), got n = {n}"
        )
    # P enters only through c_k = P_k a_k and is checked there (below). With several
    # receivers their matrices interleave in memory and one transposing copy beats strided
    # reads of the nine rows; with one receiver the strided view is faster (measured)
    Pc = None
    if P is not None:
        P = finite_array(P, "P", tail=(3, 3), check=False)
        Pc = np.moveaxis(P, (-2, -1), (0, 1))
        if m > 1:
            Pc = np.ascontiguousarray(Pc)
    b = finite_array(b, "b", tail=(m, 3), check=chk)
    if order >= 1:
        if dt is None:
            raise ValueError(f"dt: delays are required for motion order {order}")
        dt = finite_array(dt, "dt", tail=(m,), check=chk)
    else:
        dt = None
    w = _check_weights(weights, n)
    batch = np.broadcast_shapes(a1.shape[:-1], ak.shape[:-2], b.shape[:-2])
    if Pc is not None:
        batch = np.broadcast_shapes(batch, Pc.shape[2:-1])
    if dt is not None:
        batch = np.broadcast_shapes(batch, dt.shape[:-1])
        dt = np.broadcast_to(dt, (*batch, m))
    # component-major with the receiver axis in front of the batch, so that every row used by
    # the closed forms is contiguous: (3, ...), (3, m, ...), (3, 3, m, ...), (m, ...)
    a1c = _broadcast_components(a1c, 1, batch)
    akc = _broadcast_components(np.moveaxis(akc, -1, 1), 2, batch)
    if Pc is not None:
        Pc = _broadcast_components(np.moveaxis(Pc, -1, 2), 3, batch)
    cc = np.ascontiguousarray(_rotate(Pc, akc))  # receivers 2..n in frame 1
    if chk and Pc is not None:
        # the solve uses P only as c_k = P_k a_k, so ‖P_k a_k‖ = 1 is exactly what it needs;
        # a scaled, sheared or NaN P fails here (a full PᵀP = I test costs a third of the solve)
        check_unit_norms(cc, P, "P", "must hold rotation matrices: ‖P_k a_k‖ ≠ 1")
    bc = np.ascontiguousarray(_broadcast_components(np.moveaxis(b, (-1, -2), (0, 1)), 2, batch))
    c = np.moveaxis(cc, (0, 1), (-1, -2))
    if dt is not None:
        dtc = np.ascontiguousarray(np.moveaxis(dt, -1, 0))

    with np.errstate(divide="ignore", invalid="ignore"):  # degenerate elements go to the fallback
        if n == 2 and order == 0:
            scale = np.broadcast_to(1.0 if w is None else w[..., 0] * w[..., 1], batch)
            inputs = (a1c, cc[:, 0], bc[:, 0], scale)
            if scale.size > _CHUNK:
                # few temporaries: one half per thread beats cache-sized chunks
                half = -(-scale.size // 2)
                fast = _in_chunks(_pair_closed_form, inputs, 2, sigma_e, max(_CHUNK, half))
            else:
                fast = _pair_closed_form(*inputs, sigma_e)
            row_w = None if w is None else np.repeat(scale[..., None], 3, axis=-1)
            return _closed_form_result(
                a1, a1c, 2, 0, fast, (a1, c, b, None, row_w), sigma_e, cond_max
            )
        if n == 3 and order == 1 and w is None:
            inputs = (a1c, cc[:, 0], cc[:, 1], bc[:, 0], bc[:, 1], dtc[0], dtc[1])
            if dtc[0].size > _CHUNK:
                fast = _in_chunks(_triple_velocity_closed_form, inputs, 6, sigma_e)
            else:
                fast = _triple_velocity_closed_form(*inputs, sigma_e)
            return _closed_form_result(a1, a1c, 3, 1, fast, (a1, c, b, dt, None), sigma_e, cond_max)

    A, B = build_system(a1, c, b, dt, order)
    X, J, cov, kappa, used = _solve_svd(A, B, _row_weights(w, m), sigma_e, cond_max)
    return _finalise(a1, n, order, X, J, cov, kappa, used)


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
    b2 = finite_array(b2, "b2", tail=(3,))
    if (velocity is None) != (dt2 is None):
        raise ValueError("velocity and dt2: give both (motion compensation) or neither")
    if velocity is not None:
        v = finite_array(velocity, "velocity", tail=(3,))
        d = finite_array(dt2, "dt2")
        # B̂_2 = b_2 − V̂ Δt_2
        b2 = b2 - v * d[..., None]
    a2 = np.asarray(a2, dtype=np.float64)
    return solve_conjugation(
        a1,
        a2[..., None, :],
        None if P2 is None else np.asarray(P2, dtype=np.float64)[..., None, :, :],
        b2[..., None, :],
        sigma_e=sigma_e,
        cond_max=cond_max,
    )


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
