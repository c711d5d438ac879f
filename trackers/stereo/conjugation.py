"""Least-squares conjugation of direction vectors from n receivers (theory §3.2–3.3).

Receiver 1 is the reference frame. Receiver ``k`` (``k = 2..n``) reports the unit vector
``a_k`` in its own frame at time ``t_k``; ``c_k = P_k a_k`` is that direction in frame 1 and
``Δt_k = t_k − t_1`` its delay. For one object moving with velocity ``V`` and acceleration
``V̇`` (frame 1, at ``t_1``) the conjugation equations are (000 eq. 4–5, 003 eq. 1–3)::

    r_1 a_1 − r_k c_k + V Δt_k + V̇ Δt_k²/2 − b_k = e_k ,      k = 2..n

stacked as ``A X − B = E`` with ``X = (r_1, …, r_n, V, V̇)`` (003 eq. 4)::

    row block k:  [ a_1 | −c_k in column k | Δt_k I₃ | Δt_k²/2 I₃ ]      B block k: b_k

Motion order 0 keeps only the ranges (3(n−1) equations, n unknowns), order 1 adds ``V``
(needs n ≥ 3), order 2 adds ``V̇`` (needs n ≥ 5, theory §3.3 table).

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
``σ_e ≈ r σ_ang`` across it); for them see :mod:`.accuracy`, and for the n = 3 velocity-aware
solution :func:`velocity_fix_covariance` (exact first order, theory §3.5).

Fast paths. n = 2 order 0 and n = 3 order 1 (the systems of papers 000/003) are solved in
closed form: the first by the 2×2 normal equations, the second by eliminating the velocity
(``Δt_3·block 2 − Δt_2·block 3``), which leaves a 3×3 system in the ranges solved by
Cramer's rule with triple products. Both agree with the generic SVD path to rounding and
hand any element whose ``κ_F`` exceeds ``cond_max`` to it. They are compiled kernels
(:mod:`.conjugation_kernels`) that solve each element in registers with the input checks fused
in: numpy would spend its time on temporaries and transposing copies of ``(..., 3)`` rows.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sensorgym.trackers.kernel_args import kernel_array
from sensorgym.trackers.stereo.conjugation_kernels import (
    pair_kernel,
    triple_velocity_kernel,
    velocity_fix_covariance_kernel,
)
from sensorgym.trackers.validation import check_unit_norms, finite_array, unit_vectors

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

#: default switch to the pseudo-inverse branch (theory §13.14 suggests 1e6 for κ₂;
#: κ_F ≤ p κ₂, so 1e7 keeps well-conditioned 6×6 systems off the fallback)
DEFAULT_COND_MAX = 1e7

_EYE = np.eye(3)
_EYE.flags.writeable = False

#: number of unknowns in X beyond the n ranges, per motion order
_MOTION_UNKNOWNS = {0: 0, 1: 3, 2: 6}
#: smallest n for which the motion order is determined (theory §3.3 table)
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
        """``‖E‖ = √J``, metres (theory §5.5: 003 thresholds the norm, not its square)."""
        return np.sqrt(self.residual)

    @property
    def range_sigma(self) -> FloatArray:
        """``(..., n)`` standard deviations of the ranges, ``√diag(Q)[:n]``, metres."""
        n = self.ranges.shape[-1]
        return np.sqrt(np.diagonal(self.covariance, axis1=-2, axis2=-1)[..., :n])


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


def solve_svd(
    A: FloatArray, B: FloatArray, row_w: FloatArray | None, sigma_e: float, cond_max: float
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, BoolArray]:
    """Weighted least squares ``A X ≈ B`` through the SVD of ``W^½ A`` (row weights ``row_w``,
    ``None``: unweighted), the pseudo-inverse where the condition number exceeds ``cond_max``.
    Returns the solution ``X``, the weighted residual sum of squares ``J``, the covariance
    ``Q = σ_e² (AᵀWA)⁺``, the condition number ``κ`` and whether the pseudo-inverse was used."""
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
# input checks and assembling results


def _check_inputs(
    a1: FloatArray, ak: FloatArray, P: FloatArray | None, b: FloatArray, dt: FloatArray | None
) -> None:
    """Values checks in argument order: finite, unit directions, ``‖P_k a_k‖ = 1``, finite ``b``, ``dt``.

    The solve uses ``P`` only as ``c_k = P_k a_k``, so ``‖P_k a_k‖ = 1`` is exactly what it needs
    of it; a scaled, sheared or NaN ``P`` fails here (a full ``PᵀP = I`` test costs more).
    """
    unit_vectors(a1, "a1")
    unit_vectors(ak, "ak")
    if P is not None:
        c = np.moveaxis(np.einsum("...ij,...j->...i", P, ak), -1, 0)
        check_unit_norms(c, P, "P", "must hold rotation matrices: ‖P_k a_k‖ ≠ 1")
    finite_array(b, "b")
    if dt is not None:
        finite_array(dt, "dt")


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
    X = _broadcast(X, (*shape, X.shape[-1]))
    J, kappa, used_pinv = (_broadcast(x, shape) for x in (J, kappa, used_pinv))
    cov = _broadcast(cov, (*shape, *cov.shape[-2:]))
    ranges = X[..., :n]
    if position is None:
        position = ranges[..., :1] * _broadcast(a1, (*shape, 3))
    return ConjugationSolution(
        ranges=ranges,
        position=position,
        velocity=X[..., n : n + 3] if order >= 1 else None,
        acceleration=X[..., n + 3 : n + 6] if order >= 2 else None,
        residual=J,
        covariance=cov,
        condition=kappa,
        used_pinv=used_pinv,
    )


def _broadcast(x: FloatArray, shape: tuple[int, ...]) -> FloatArray:
    """``np.broadcast_to`` without its cost (several µs) where ``x`` already has the shape."""
    return x if x.shape == shape else np.broadcast_to(x, shape)


def _flat(x: FloatArray, batch: tuple[int, ...], tail: tuple[int, ...]) -> FloatArray:
    """``x`` broadcast to ``(*batch, *tail)`` as a kernel input ``(N, *tail)``
    (:func:`kernel_array`: no copy if it already is one)."""
    return kernel_array(x, (*batch, *tail)).reshape(math.prod(batch), *tail)


def _solve_closed_form(
    a1: FloatArray,
    ak: FloatArray,
    P: FloatArray | None,
    b: FloatArray,
    extra: FloatArray,
    batch: tuple[int, ...],
    order: int,
    w: FloatArray | None,
    sigma_e: float,
    cond_max: float,
    check: bool,
) -> ConjugationSolution:
    """The compiled closed form for n = 2 order 0 (``extra = w_1 w_2``) or n = 3 order 1
    (``extra = Δt``); elements with ``κ_F > cond_max`` re-solved on the generic SVD path."""
    m = ak.shape[-2]
    n, p = m + 1, m + 1 + _MOTION_UNKNOWNS[order]
    kernel = pair_kernel if order == 0 else triple_velocity_kernel
    flat = (
        _flat(a1, batch, (3,)),
        _flat(ak, batch, (m, 3)),
        _flat(_EYE if P is None else P, batch, (m, 3, 3)),
        _flat(b, batch, (m, 3)),
        _flat(extra, batch, extra.shape[len(extra.shape) - (order > 0) :]),
    )
    size = flat[0].shape[0]
    X, J, Q = np.empty((size, p)), np.empty(size), np.empty((size, p, p))
    kappa, position = np.empty(size), np.empty((size, 3))
    code = kernel(*flat, sigma_e**2, check, 0, size, X, J, Q, kappa, position)
    if code:
        _check_inputs(a1, ak, P, b, extra if order > 0 else None)  # raises with the message
        name = ("a1", "ak", "P", "b", "dt")[code - 1]
        raise ValueError(f"{name}: failed the input check (non-finite or non-unit values)")
    used = ~(kappa <= cond_max)
    if used.any():
        a1u, aku, Pu, bu, extra_u = (x[used] for x in flat)
        if not check:  # few elements: an unchecked NaN lands here, so name it rather than
            _check_inputs(a1u, aku, Pu, bu, extra_u if order > 0 else None)  # crash in the SVD
        c = np.einsum("...ij,...j->...i", Pu, aku)
        row_w = None if w is None else np.repeat(extra_u[:, None], 3, axis=-1)
        A, B = build_system(a1u, c, bu, extra_u if order > 0 else None, order)
        Xu, J[used], Q[used], kappa[used], pinv = solve_svd(A, B, row_w, sigma_e, cond_max)
        X[used] = Xu
        position[used] = Xu[:, :1] * a1u
        used[used] = pinv
    return _finalise(
        a1,
        n,
        order,
        X.reshape(*batch, p),
        J.reshape(batch),
        Q.reshape(*batch, p, p),
        kappa.reshape(batch),
        used.reshape(batch),
        position.reshape(*batch, 3),
    )


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
        verify finiteness, unit length of directions and ``‖P_k a_k‖ = 1`` (shapes are always
        checked). On the compiled closed forms the checks are fused into the solve and cost
        little; ``False`` is for arrays known good, e.g. built by the environments (like
        scipy's ``check_finite=False``: a NaN that reaches the SVD is still reported by name,
        one that reaches only ``b`` comes out as NaN).

    All leading axes broadcast; batched results equal one-at-a-time results.
    """
    if order not in _MOTION_UNKNOWNS:
        raise ValueError(f"order: must be 0, 1 or 2, got {order!r}")
    _check_sigma(sigma_e, cond_max)
    a1 = finite_array(a1, "a1", tail=(3,), check=False)
    ak = finite_array(ak, "ak", tail=(3,), check=False)
    if ak.ndim < 2:
        raise ValueError(f"ak: expected shape (..., n-1, 3), got {ak.shape}")
    m = ak.shape[-2]
    n = m + 1
    if n < _MIN_RECEIVERS[order]:
        raise ValueError(
            f"order {order} needs at least {_MIN_RECEIVERS[order]} receivers "
            f"(3(n−1) equations ≥ n + {_MOTION_UNKNOWNS[order]} unknowns), got n = {n}"
        )
    if P is not None:
        P = finite_array(P, "P", tail=(m, 3, 3), check=False)
    b = finite_array(b, "b", tail=(m, 3), check=False)
    if order >= 1:
        if dt is None:
            raise ValueError(f"dt: delays are required for motion order {order}")
        dt = finite_array(dt, "dt", tail=(m,), check=False)
    else:
        dt = None
    w = _check_weights(weights, n)
    shapes = [a1.shape[:-1], ak.shape[:-2], b.shape[:-2]]
    shapes += [x.shape[: x.ndim - t] for x, t in ((P, 3), (dt, 1), (w, 1)) if x is not None]
    try:
        batch = np.broadcast_shapes(*shapes)
    except ValueError:
        raise ValueError(f"inputs: batch shapes {shapes} do not broadcast") from None

    if n == 2 and order == 0:
        scale = 1.0 if w is None else w[..., 0] * w[..., 1]
        return _solve_closed_form(
            a1, ak, P, b, np.asarray(scale), batch, 0, w, sigma_e, cond_max, check_inputs
        )
    if n == 3 and order == 1 and w is None:
        return _solve_closed_form(a1, ak, P, b, dt, batch, 1, None, sigma_e, cond_max, check_inputs)

    if check_inputs:
        _check_inputs(a1, ak, P, b, dt)
    c = ak if P is None else np.einsum("...ij,...j->...i", P, ak)  # receivers 2..n in frame 1
    A, B = build_system(a1, c, b, dt, order)
    try:
        X, J, cov, kappa, used = solve_svd(A, B, _row_weights(w, m), sigma_e, cond_max)
    except np.linalg.LinAlgError:
        _check_inputs(a1, ak, P, b, dt)  # an unchecked NaN or inf: raise naming the argument
        raise
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
    re-solve", 003 step 2.2, theory §5.5). Parallel lines of sight take the pseudo-inverse fallback.
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
    """Paper 000's proposed spatial step (theory §5.3, n = 3).

    ``V̂`` comes from the 6×6 velocity-aware system (000 eq. 10–11); ``r̂_1, r̂_2`` are then
    re-solved from the pair ``(a_1, a_2)`` with ``B̂_2 = b_2 − V̂ Δt_2``, "more stable to matrix
    inversion". Where the 6×6 ``A`` is invertible the re-solve returns the same ``r̂_1``
    (theory §4.5 CHECK 4); it matters on the pseudo-inverse branch. ``r̂_3``, ``covariance``,
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


# ---------------------------------------------------------------------------------------------
# angle noise: exact first-order covariance of the n = 3 velocity-aware solution (theory §3.5)


def _solve_triple(
    a1: ArrayLike,
    ak: ArrayLike,
    P: ArrayLike | None,
    b: ArrayLike,
    dt: ArrayLike,
    cond_max: float,
    check_inputs: bool,
    caller: str,
) -> tuple[ConjugationSolution, tuple[int, ...]]:
    """The solver's ``n = 3`` order-1 solve (its checks and messages), refusing other ``n``."""
    sol = solve_conjugation(a1, ak, P, b, dt, order=1, cond_max=cond_max, check_inputs=check_inputs)
    n = sol.ranges.shape[-1]
    if n != 3:
        raise ValueError(
            f"ak: {caller} is the n = 3 closed form (ak of shape (..., 2, 3)), got n = {n}"
        )
    return sol, sol.residual.shape


def velocity_fix_jacobian(
    a1: ArrayLike,
    ak: ArrayLike,
    P: ArrayLike | None,
    b: ArrayLike,
    dt: ArrayLike,
    *,
    cond_max: float = DEFAULT_COND_MAX,
    check_inputs: bool = True,
) -> FloatArray:
    """``(..., 6, 9)`` Jacobian of the ``n = 3`` velocity-aware solution ``(M̂_1, V̂)`` (frame 1)
    with respect to the direction errors ``(n_1, n_2, n_3)`` in frame 1 (theory §3.5).

    Arguments as :func:`solve_conjugation` (``n = 3``; raises as it does). ``n_k`` moves
    ``a_1`` (``k = 1``) or ``c_k = P_k a_k``; a rotation ``P_k`` carries an own-frame error
    ``δa_k`` to ``n_k = P_k δa_k``. Any direction-error covariance ``Σ`` (9×9) then gives
    ``J Σ Jᵀ``. NaN where the solver takes the pseudo-inverse fallback (``used_pinv``: the
    linearisation of a singular system does not exist).

    The readable numpy reference of :func:`velocity_fix_covariance`'s compiled kernel: ``A X = B``
    is square, so ``δA X + A δX = 0`` and, as ``(δA X)_k = r_1 n_1 − r_k n_k``,
    ``δX = A⁻¹ δB`` with ``δB_k = r_k n_k − r_1 n_1``; ``M̂_1 = r̂_1 a_1`` adds ``r_1 n_1``.
    """
    sol, batch = _solve_triple(a1, ak, P, b, dt, cond_max, check_inputs, "velocity_fix_jacobian")
    a1 = _broadcast(np.asarray(a1, dtype=np.float64), (*batch, 3))
    ak = np.asarray(ak, dtype=np.float64)
    c = ak if P is None else np.einsum("...ij,...j->...i", np.asarray(P, dtype=np.float64), ak)
    dt = np.asarray(dt, dtype=np.float64)
    A, _ = build_system(a1, c, np.zeros((2, 3)), dt, 1)
    A = _broadcast(A, (*batch, 6, 6))
    bad = sol.used_pinv
    # A⁻¹ where A is regular (the identity stands in elsewhere; those rows become NaN)
    Ainv = np.linalg.inv(np.where(bad[..., None, None], np.eye(6), A))
    r1, r2, r3 = (sol.ranges[..., k, None, None] * _EYE for k in range(3))
    # δB = D (n_1, n_2, n_3):  block 2 = r_2 n_2 − r_1 n_1 ,  block 3 = r_3 n_3 − r_1 n_1
    zero = np.zeros_like(r1)
    D = np.concatenate(
        [
            np.concatenate([-r1, r2, zero], axis=-1),
            np.concatenate([-r1, zero, r3], axis=-1),
        ],
        axis=-2,
    )
    JX = Ainv @ D  # rows r_1, r_2, r_3, V
    # δM̂_1 = a_1 δr̂_1 + r_1 n_1
    JM = a1[..., :, None] * JX[..., :1, :]
    JM[..., :, :3] += r1
    J = np.concatenate([JM, JX[..., 3:, :]], axis=-2)
    return np.where(bad[..., None, None], np.nan, J)


def velocity_fix_covariance(
    a1: ArrayLike,
    ak: ArrayLike,
    P: ArrayLike | None,
    b: ArrayLike,
    dt: ArrayLike,
    sigma_ang: ArrayLike,
    *,
    position_sigma: float = 0.0,
    cond_max: float = DEFAULT_COND_MAX,
    check_inputs: bool = True,
) -> FloatArray:
    """Exact first-order covariance ``(..., 6, 6)`` of the ``n = 3`` velocity-aware solution
    ``(M̂_1, V̂)`` (frame 1, metres and m/s) under angle noise (theory §3.5, "Angle noise").

    Arguments ``a1 … dt``, ``cond_max`` and ``check_inputs`` as :func:`solve_conjugation` with
    ``n = 3``, ``order = 1`` (the estimate itself is that solve's ``position`` and
    ``velocity``); it raises as the solver does. ``sigma_ang`` scalar or ``(..., 3)``: the
    isotropic angular standard deviation ``σ_k`` of each receiver's direction, radians
    (``n_k ~ N(0, σ_k² (I − u_k u_kᵀ))``, independent, across the line of sight only);
    ``position_sigma`` paper 000's shared apparent-position error ``σ_x`` (§4.1), which moves
    ``M̂_1`` by itself and leaves ``V̂`` alone::

        C = J diag(σ_k² (I − u_k u_kᵀ)) Jᵀ + σ_x² diag(I₃, 0)

    with ``J`` of :func:`velocity_fix_jacobian`, in closed form per element
    (:func:`~.conjugation_kernels.velocity_fix_element`). Unlike the papers'
    ``σ_e² (AᵀA)⁻¹`` (``covariance``), it keeps receiver 1's error shared by both equation
    blocks and each error across its own line of sight; the i.i.d. form with
    ``σ_e² = mean((σ_k r_k)²)`` understates the velocity variance (theory §3.5). NaN where
    the solver takes the pseudo-inverse fallback (``used_pinv``).
    """
    sol, batch = _solve_triple(a1, ak, P, b, dt, cond_max, check_inputs, "velocity_fix_covariance")
    s = finite_array(sigma_ang, "sigma_ang")
    if s.ndim and s.shape[-1] not in (1, 3):
        raise ValueError(
            f"sigma_ang: expected a scalar or shape (..., 3) (one σ per receiver), got {s.shape}"
        )
    if np.any(s < 0.0):
        raise ValueError("sigma_ang: must be non-negative")
    if not (np.isfinite(position_sigma) and position_sigma >= 0.0):
        raise ValueError(f"position_sigma: must be finite and non-negative, got {position_sigma}")
    s = s[..., None] if s.ndim == 0 else s
    try:
        sigma = _flat(s, batch, (3,))
    except ValueError:
        raise ValueError(
            f"sigma_ang: shape {s.shape} does not broadcast to the batch {batch}"
        ) from None
    size = sigma.shape[0]
    C = np.empty((size, 6, 6))
    velocity_fix_covariance_kernel(
        _flat(np.asarray(a1, dtype=np.float64), batch, (3,)),
        _flat(np.asarray(ak, dtype=np.float64), batch, (2, 3)),
        _flat(_EYE if P is None else np.asarray(P, dtype=np.float64), batch, (2, 3, 3)),
        _flat(np.asarray(dt, dtype=np.float64), batch, (2,)),
        _flat(sol.ranges, batch, (3,)),
        sigma,
        float(position_sigma) ** 2,
        0,
        size,
        C,
    )
    C = C.reshape(*batch, 6, 6)
    C[sol.used_pinv] = np.nan
    return C
