"""Compiled closed forms of the two conjugation systems the papers solve (theory §3.2), and
the velocity-aware system of any n.

n = 2 order 0 (000 eq. 7–9, 12) and n = 3 order 1 (000 eq. 10–11, 003 eq. 4) are solved
element by element in registers by numba kernels: no temporaries, no transposing copies, the
input checks fused into the same pass. :func:`velocity_kernel` solves order 1 for any n ≥ 3
through the normal equations with the ranges ``r_2 … r_n`` eliminated (``O(n)`` per solve):
the receiver-placement env's step at more than three receivers; the generic solver
:func:`~.conjugation.solve_conjugation` keeps its SVD path for those sizes (no squared
condition number). :func:`velocity_fix_covariance_kernel` gives the exact first-order covariance
of the n = 3 velocity-aware solution under angle noise. Each kernel works on a half-open range
``[lo, hi)`` of a flat batch and releases the GIL (callers may run parts of a batch on their
own threads). At batch 1e5 on one core of the 2-core reference machine they solve about 38 M
two-receiver and 13 M three-receiver velocity problems per second
(``benchmarks/triangulation.py``).

The system, its weighting and ``κ_F`` are defined in :mod:`.conjugation`, whose generic SVD solver
is the reference the solving kernels are tested against (the covariance kernel's is
:func:`~.conjugation.velocity_fix_jacobian`). A solving kernel returns 0, or the
1-based index of the first argument (in call order) whose input check failed; the caller then
re-runs the ordinary validators on that argument for the message. Degenerate geometry is not an
input error: it gives ``κ_F = inf`` or NaN there and the caller re-solves those elements on the
pseudo-inverse path.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

Array = NDArray[np.float64]

#: tolerance on unit length (|‖v‖² − 1| ≤ 2·atol ≈ |‖v‖ − 1| ≤ atol), as in ``validation``
UNIT_ATOL = 1e-6

_JIT = {"cache": True, "nogil": True, "error_model": "numpy", "boundscheck": False}

#: n = 3 closed form: ``|det M|`` below this fraction of ``‖u_1‖‖u_2‖‖u_3‖`` (the volume of the
#: unit-scaled columns; then ``κ₂(M) ≳ 1e10`` > any sensible ``cond_max``) is left to the SVD
SINGULAR_VOLUME = 1e-10


@njit(inline="always")
def _dot(u, v):
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]


@njit(inline="always")
def _cross(u, v):
    return (u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0])


@njit(inline="always")
def _vec(x, i):
    """Row ``x[i]`` of an ``(N, 3)`` array as a register tuple."""
    return (x[i, 0], x[i, 1], x[i, 2])


@njit(inline="always")
def _rotate(P, i, k, a):
    """``c_k = P_k a_k`` (frame k → frame 1) for ``P (N, m, 3, 3)``."""
    return (
        P[i, k, 0, 0] * a[0] + P[i, k, 0, 1] * a[1] + P[i, k, 0, 2] * a[2],
        P[i, k, 1, 0] * a[0] + P[i, k, 1, 1] * a[1] + P[i, k, 1, 2] * a[2],
        P[i, k, 2, 0] * a[0] + P[i, k, 2, 1] * a[1] + P[i, k, 2, 2] * a[2],
    )


@njit(inline="always")
def _not_unit(u):
    """True unless ``u`` is finite with ``|‖u‖² − 1| ≤ 2·atol`` (NaN fails every comparison)."""
    return not (abs(_dot(u, u) - 1.0) <= 2.0 * UNIT_ATOL)


@njit(inline="always")
def _not_finite(u):
    return not (np.isfinite(u[0]) and np.isfinite(u[1]) and np.isfinite(u[2]))


@njit(**_JIT)
def pair_kernel(
    a1: Array,
    a2: Array,
    P: Array,
    b: Array,
    scale: Array,
    sigma2: float,
    check: bool,
    lo: int,
    hi: int,
    X: Array,
    J: Array,
    Q: Array,
    kappa: Array,
    position: Array,
) -> int:
    """n = 2, order 0 for elements ``lo..hi−1``.

    Inputs ``a1 (N, 3)``, ``a2 (N, 1, 3)``, ``P (N, 1, 3, 3)``, ``b (N, 1, 3)``, ``scale (N,)``
    ``= w_1 w_2``; outputs ``X (N, 2)``, ``J (N,)``, ``Q (N, 2, 2)``, ``κ_F (N,)``,
    ``M̂_1 (N, 3)``. With ``AᵀA = [[1, −g], [−g, 1]]``, ``g = a_1·c_2 = cos γ``.
    """
    for i in range(lo, hi):
        a = _vec(a1, i)
        c = _rotate(P, i, 0, (a2[i, 0, 0], a2[i, 0, 1], a2[i, 0, 2]))
        bb = (b[i, 0, 0], b[i, 0, 1], b[i, 0, 2])
        if check:
            if _not_unit(a):
                return 1
            if _not_unit((a2[i, 0, 0], a2[i, 0, 1], a2[i, 0, 2])):
                return 2
            if _not_unit(c):  # ‖P_k a_k‖ = 1 is all the solve needs of P
                return 3
            if _not_finite(bb):
                return 4
        g = _dot(a, c)
        p1 = _dot(a, bb)  # (Aᵀb)_1 = a_1·b
        p2 = _dot(c, bb)  # (Aᵀb)_2 = −c_2·b
        # 1/det AᵀA = 1/sin²γ
        inv = 1.0 / (1.0 - g * g)
        # R̂ = (AᵀA)⁻¹Aᵀb = [[1, g], [g, 1]] (a_1·b, −c_2·b) / sin²γ
        r1 = (p1 - g * p2) * inv
        r2 = (g * p1 - p2) * inv
        # E = r_1 a_1 − r_2 c_2 − b ;  J = w_1 w_2 ‖E‖²   (000 eq. 9)
        e = (
            r1 * a[0] - r2 * c[0] - bb[0],
            r1 * a[1] - r2 * c[1] - bb[1],
            r1 * a[2] - r2 * c[2] - bb[2],
        )
        J[i] = _dot(e, e) * scale[i]
        # Q = σ_e²/(w_1 w_2 sin²γ) [[1, cos γ], [cos γ, 1]]   (000 eq. 12)
        q = sigma2 / scale[i] * inv
        Q[i, 0, 0] = Q[i, 1, 1] = q
        Q[i, 0, 1] = Q[i, 1, 0] = q * g
        # κ_F = √(tr AᵀA · tr (AᵀA)⁻¹) = 2/sin γ
        kappa[i] = 2.0 * np.sqrt(inv)
        X[i, 0], X[i, 1] = r1, r2
        position[i, 0], position[i, 1], position[i, 2] = r1 * a[0], r1 * a[1], r1 * a[2]
    return 0


@njit(inline="always")
def _triple_inverse(a, c2, c3, d2, d3):
    """``(ok, M⁻¹)`` of the ``n = 3`` system's ``M = [(Δt_3 − Δt_2) a_1, −Δt_3 c_2, Δt_2 c_3]``
    (theory §3.5) as a 3-tuple of rows, by Cramer: the rows are ``(u_2×u_3, u_3×u_1, u_1×u_2)
    / det M``, ``det M = u_1·(u_2×u_3)``. ``ok`` is False (and ``M⁻¹`` zeros) for (near-)
    coplanar columns, where det M is rounding noise and so is the Cramer inverse, whose κ_F
    could then look small (parallel unit vectors give ``u_2×u_3 ~ det ~ 1e-18``)."""
    u1 = ((d3 - d2) * a[0], (d3 - d2) * a[1], (d3 - d2) * a[2])
    u2 = (-d3 * c2[0], -d3 * c2[1], -d3 * c2[2])
    u3 = (d2 * c3[0], d2 * c3[1], d2 * c3[2])
    x23 = _cross(u2, u3)
    det = _dot(u1, x23)
    scale = np.sqrt(_dot(u1, u1) * _dot(u2, u2) * _dot(u3, u3))
    if not np.abs(det) > SINGULAR_VOLUME * scale:
        zero = (0.0, 0.0, 0.0)
        return False, (zero, zero, zero)
    inv_det = 1.0 / det
    x31 = _cross(u3, u1)
    x12 = _cross(u1, u2)
    Mi = (
        (x23[0] * inv_det, x23[1] * inv_det, x23[2] * inv_det),
        (x31[0] * inv_det, x31[1] * inv_det, x31[2] * inv_det),
        (x12[0] * inv_det, x12[1] * inv_det, x12[2] * inv_det),
    )
    return True, Mi


@njit(**_JIT)
def triple_velocity_kernel(
    a1: Array,
    ak: Array,
    P: Array,
    b: Array,
    dt: Array,
    sigma2: float,
    check: bool,
    lo: int,
    hi: int,
    X: Array,
    J: Array,
    Q: Array,
    kappa: Array,
    position: Array,
) -> int:
    """n = 3, order 1 for elements ``lo..hi−1``: velocity eliminated, Cramer on the ranges.

    Inputs ``a1 (N, 3)``, ``ak (N, 2, 3)``, ``P (N, 2, 3, 3)``, ``b (N, 2, 3)``, ``dt (N, 2)``;
    outputs ``X (N, 6)``, ``J (N,)``, ``Q (N, 6, 6)``, ``κ_F (N,)``, ``M̂_1 (N, 3)``.

    ``Δt_3·(block 2) − Δt_2·(block 3)`` removes ``V``:
    ``r_1 (Δt_3 − Δt_2) a_1 − r_2 Δt_3 c_2 + r_3 Δt_2 c_3 = Δt_3 b_2 − Δt_2 b_3 = d`` (theory §3.5),
    ``M R = d`` solved by Cramer's rule; then ``V̂`` is the least-squares fit of both blocks,
    ``V̂ = (Δt_2 b_2 + Δt_3 b_3 + G R)/Δ²`` with ``Δ² = Δt_2² + Δt_3²`` and ``G`` the columns
    ``(−(Δt_2+Δt_3) a_1, Δt_2 c_2, Δt_3 c_3)``. As a map of ``(b_2, b_3)`` this is
    ``A⁻¹ = [[M⁻¹ [Δt_3 I, −Δt_2 I]], [[Δt_2 I + Δt_3 H, Δt_3 I − Δt_2 H]/Δ²]]``, ``H = G M⁻¹``,
    whence (by multiplying out) ``Q = σ_e² A⁻¹A⁻ᵀ`` has the blocks
    ``Q_rr = Δ² M⁻¹M⁻ᵀ``, ``Q_rV = M⁻¹Hᵀ``, ``Q_VV = (I + H Hᵀ)/Δ²`` and
    ``‖A⁻¹‖_F² = Δ² ‖M⁻¹‖_F² + (3 + ‖H‖_F²)/Δ²``.
    """
    for i in range(lo, hi):
        a = _vec(a1, i)
        x2 = (ak[i, 0, 0], ak[i, 0, 1], ak[i, 0, 2])
        x3 = (ak[i, 1, 0], ak[i, 1, 1], ak[i, 1, 2])
        c2 = _rotate(P, i, 0, x2)
        c3 = _rotate(P, i, 1, x3)
        b2 = (b[i, 0, 0], b[i, 0, 1], b[i, 0, 2])
        b3 = (b[i, 1, 0], b[i, 1, 1], b[i, 1, 2])
        d2, d3 = dt[i, 0], dt[i, 1]
        if check:
            if _not_unit(a):
                return 1
            if _not_unit(x2) or _not_unit(x3):
                return 2
            if _not_unit(c2) or _not_unit(c3):
                return 3
            if _not_finite(b2) or _not_finite(b3):
                return 4
            if not (np.isfinite(d2) and np.isfinite(d3)):
                return 5
        # Δt_3·(block 2) − Δt_2·(block 3):  M R = d,  M = [(Δt_3 − Δt_2) a_1, −Δt_3 c_2, Δt_2 c_3]
        ok, Mi = _triple_inverse(a, c2, c3, d2, d3)
        if not ok:
            # (near-)coplanar columns: κ_F = inf hands the element to the caller's SVD path,
            # which measures κ_F properly
            kappa[i] = np.inf
            continue
        # R̂ = M⁻¹ d,  d = Δt_3 b_2 − Δt_2 b_3
        d = (d3 * b2[0] - d2 * b3[0], d3 * b2[1] - d2 * b3[1], d3 * b2[2] - d2 * b3[2])
        r1, r2, r3 = _dot(Mi[0], d), _dot(Mi[1], d), _dot(Mi[2], d)
        # V̂ = (Δt_2 (b_2 − r_1 a_1 + r_2 c_2) + Δt_3 (b_3 − r_1 a_1 + r_3 c_3)) / Δ²
        delta2 = d2 * d2 + d3 * d3
        # G columns (−(Δt_2+Δt_3) a_1, Δt_2 c_2, Δt_3 c_3), so V̂ = (Δt_2 b_2 + Δt_3 b_3 + G R̂)/Δ²
        g1 = (-(d2 + d3) * a[0], -(d2 + d3) * a[1], -(d2 + d3) * a[2])
        g2 = (d2 * c2[0], d2 * c2[1], d2 * c2[2])
        g3 = (d3 * c3[0], d3 * c3[1], d3 * c3[2])
        V = (
            (d2 * b2[0] + d3 * b3[0] + g1[0] * r1 + g2[0] * r2 + g3[0] * r3) / delta2,
            (d2 * b2[1] + d3 * b3[1] + g1[1] * r1 + g2[1] * r2 + g3[1] * r3) / delta2,
            (d2 * b2[2] + d3 * b3[2] + g1[2] * r1 + g2[2] * r2 + g3[2] * r3) / delta2,
        )
        # E_k = r_1 a_1 − r_k c_k + Δt_k V − b_k ;  J = ‖E_2‖² + ‖E_3‖²
        J2 = 0.0
        J3 = 0.0
        for j in range(3):
            e2 = r1 * a[j] - r2 * c2[j] + d2 * V[j] - b2[j]
            e3 = r1 * a[j] - r3 * c3[j] + d3 * V[j] - b3[j]
            J2 += e2 * e2
            J3 += e3 * e3
        J[i] = J2 + J3
        # H = G M⁻¹ :  H[j][k] = Σ_m G[j][m] M⁻¹[m][k]
        H = (
            (
                g1[0] * Mi[0][0] + g2[0] * Mi[1][0] + g3[0] * Mi[2][0],
                g1[0] * Mi[0][1] + g2[0] * Mi[1][1] + g3[0] * Mi[2][1],
                g1[0] * Mi[0][2] + g2[0] * Mi[1][2] + g3[0] * Mi[2][2],
            ),
            (
                g1[1] * Mi[0][0] + g2[1] * Mi[1][0] + g3[1] * Mi[2][0],
                g1[1] * Mi[0][1] + g2[1] * Mi[1][1] + g3[1] * Mi[2][1],
                g1[1] * Mi[0][2] + g2[1] * Mi[1][2] + g3[1] * Mi[2][2],
            ),
            (
                g1[2] * Mi[0][0] + g2[2] * Mi[1][0] + g3[2] * Mi[2][0],
                g1[2] * Mi[0][1] + g2[2] * Mi[1][1] + g3[2] * Mi[2][1],
                g1[2] * Mi[0][2] + g2[2] * Mi[1][2] + g3[2] * Mi[2][2],
            ),
        )
        frob_mi = 0.0
        frob_h = 0.0
        for j in range(3):
            frob_mi += _dot(Mi[j], Mi[j])
            frob_h += _dot(H[j], H[j])
            for k in range(3):
                # Q_rV = M⁻¹ Hᵀ
                Q[i, j, 3 + k] = Q[i, 3 + k, j] = sigma2 * _dot(Mi[j], H[k])
            for k in range(j, 3):
                # Q_rr = Δ² M⁻¹ M⁻ᵀ ;  Q_VV = (I + H Hᵀ)/Δ²
                Q[i, j, k] = Q[i, k, j] = sigma2 * delta2 * _dot(Mi[j], Mi[k])
                hh = _dot(H[j], H[k]) + (1.0 if j == k else 0.0)
                Q[i, 3 + j, 3 + k] = Q[i, 3 + k, 3 + j] = sigma2 * hh / delta2
        # κ_F² = ‖A‖_F² ‖A⁻¹‖_F²,  ‖A‖_F² = 2‖a_1‖² + ‖c_2‖² + ‖c_3‖² + 3Δ² ,
        # ‖A⁻¹‖_F² = Δ² ‖M⁻¹‖_F² + (3 + ‖H‖_F²)/Δ²
        kappa[i] = np.sqrt((4.0 + 3.0 * delta2) * (delta2 * frob_mi + (3.0 + frob_h) / delta2))
        X[i, 0], X[i, 1], X[i, 2] = r1, r2, r3
        X[i, 3], X[i, 4], X[i, 5] = V[0], V[1], V[2]
        position[i, 0], position[i, 1], position[i, 2] = r1 * a[0], r1 * a[1], r1 * a[2]
    return 0


#: :func:`velocity_kernel` solves the normal equations, which square the condition number; an
#: element whose ``κ_F`` exceeds this is left to the caller's SVD path (``κ_F = inf``), where the
#: normal equations would lose more than some 8 of the 16 digits
NORMAL_EQUATIONS_COND = 1e4


@njit(inline="always")
def _cholesky_inverse4(w, s, l, o):
    """``S⁻¹`` of a symmetric ``(4, 4)`` ``S`` through its Cholesky factor ``L``; False where
    ``S`` is not positive definite to rounding (a pivot ≤ 1e-14 of its diagonal). ``S``, ``L``
    and the result are row-major blocks of the flat scratch ``w`` at offsets ``s``, ``l`` and
    ``o`` (a reshaped view would cost a helper call and a reference count per solve)."""
    for j in range(4):
        d = w[s + 5 * j]
        for k in range(j):
            d -= w[l + 4 * j + k] * w[l + 4 * j + k]
        if not d > 1e-14 * abs(w[s + 5 * j]):
            return False
        w[l + 5 * j] = np.sqrt(d)
        for i in range(j + 1, 4):
            x = w[s + 4 * i + j]
            for k in range(j):
                x -= w[l + 4 * i + k] * w[l + 4 * j + k]
            w[l + 4 * i + j] = x / w[l + 5 * j]
    # L⁻¹ in place of the upper triangle's mirror: W = L⁻¹ (lower), then S⁻¹ = Wᵀ W
    for j in range(4):
        w[o + 5 * j] = 1.0 / w[l + 5 * j]
        for i in range(j + 1, 4):
            x = 0.0
            for k in range(j, i):
                x -= w[l + 4 * i + k] * w[o + 4 * k + j]
            w[o + 4 * i + j] = x / w[l + 5 * i]
    for i in range(4):
        for j in range(i, 4):
            x = 0.0
            for k in range(j, 4):
                x += w[o + 4 * k + i] * w[o + 4 * k + j]
            w[l + 4 * i + j] = x  # (S⁻¹)_ij, i ≤ j, kept in L's upper triangle
    for i in range(4):
        for j in range(i, 4):
            w[o + 4 * i + j] = w[o + 4 * j + i] = w[l + 4 * i + j]
    return True


@njit(**_JIT)
def velocity_kernel(a1: Array, ak: Array, P: Array, b: Array, dt: Array, sigma2: float,
                    check: bool, lo: int, hi: int, X: Array, J: Array, Q: Array, kappa: Array,
                    position: Array) -> int:  # fmt: skip
    """Any n ≥ 3, order 1 for elements ``lo..hi−1``: the normal equations, the ranges
    ``r_2 … r_n`` eliminated (``O(n)`` per solve, ``O(n²)`` for ``Q``).

    Inputs ``a1 (N, 3)``, ``ak (N, m, 3)``, ``P (N, m, 3, 3)``, ``b (N, m, 3)``, ``dt (N, m)``
    (``m = n − 1``); outputs ``X (N, n+3)``, ``J (N,)``, ``Q (N, n+3, n+3)``, ``κ_F (N,)``,
    ``M̂_1 (N, 3)``; arguments and return code as :func:`triple_velocity_kernel`.

    ``AᵀA`` is an arrow matrix: ``r_k`` (k ≥ 2) meets only itself (``D_k = ‖c_k‖²``) and the
    four shared unknowns ``y = (r_1, V)``, through ``g_k = (−a_1·c_k, −Δt_k c_k)``. With
    ``S = E − Σ_k g_k g_kᵀ/D_k`` (``E = [[m‖a_1‖², Σ Δt_k a_1ᵀ], [Σ Δt_k a_1, Σ Δt_k² I]]``) the
    Schur complement: ``y = S⁻¹ (h_y − Σ_k g_k h_k/D_k)``, ``r_k = (h_k − g_k·y)/D_k`` (``h = AᵀB``)
    and ``(AᵀA)⁻¹`` has the blocks ``S⁻¹``, ``−S⁻¹g_k/D_k`` and
    ``δ_kl/D_k + g_kᵀS⁻¹g_l/(D_k D_l)``; ``κ_F = √(tr AᵀA · tr (AᵀA)⁻¹)``. Elements with
    ``κ_F > NORMAL_EQUATIONS_COND`` (or a singular ``S``) get ``κ_F = inf``: the caller's SVD
    path solves them.
    """
    m = ak.shape[1]
    work = np.empty(velocity_work(m))
    for i in range(lo, hi):
        code = velocity_element(i, m, a1, ak, P, b, dt, sigma2, check, X, J, Q, kappa,
                                position, work, np.bool_(True))  # fmt: skip
        if code:
            return code
    return 0


@njit(**_JIT)
def velocity_work(m: int) -> int:
    """Floats of scratch :func:`velocity_element` needs for ``m = n − 1`` receivers past the
    first."""
    return 13 * m + 56


@njit(inline="always")
def velocity_element(i: int, m: int, a1: Array, ak: Array, P: Array, b: Array, dt: Array,
                     sigma2: float, check: bool, X: Array, J: Array, Q: Array, kappa: Array,
                     position: Array, work: Array, full_q: bool) -> int:  # fmt: skip
    """Element ``i`` of :func:`velocity_kernel` for the first ``m`` receivers past the first
    (``m ≤ ak.shape[1]``: a caller may keep arrays sized for the most receivers and fill only
    the first rows; ``X``, ``Q`` are written in their first ``m + 4`` entries), on the caller's
    scratch ``work`` (at least :func:`velocity_work` floats: a caller solving one system at a
    time allocates nothing). With ``full_q`` false only ``Q``'s block of the shared unknowns
    ``(r_1, V)`` (rows and columns ``0, n, n+1, n+2``) is written."""
    n = m + 1
    # flat blocks of ``work`` (a reshaped view would cost a helper call and a reference count
    # per solve): c_k (m, 3) from 0, g_k (m, 4) from og, D_k, h_k (m,), S⁻¹g_k (m, 4), then the
    # (4, 4) S, its Cholesky factor L and S⁻¹, h_y (4,), y (4,)
    og, oD, oh, osg = 3 * m, 7 * m, 8 * m, 9 * m
    oS = 13 * m
    oL, oSi, ohy, oy = oS + 16, oS + 32, oS + 48, oS + 52
    a = _vec(a1, i)
    if check and _not_unit(a):
        return 1
    aa = _dot(a, a)
    for k in range(m):
        x = (ak[i, k, 0], ak[i, k, 1], ak[i, k, 2])
        ck = _rotate(P, i, k, x)
        bk = (b[i, k, 0], b[i, k, 1], b[i, k, 2])
        if check:
            if _not_unit(x):
                return 2
            if _not_unit(ck):
                return 3
            if _not_finite(bk):
                return 4
            if not np.isfinite(dt[i, k]):
                return 5
        work[3 * k], work[3 * k + 1], work[3 * k + 2] = ck
    # E, h_y and the trace of AᵀA
    for r in range(4):
        work[ohy + r] = 0.0
        for q in range(4):
            work[oS + 4 * r + q] = 0.0
    trace = 0.0
    for k in range(m):
        d = dt[i, k]
        ck = (work[3 * k], work[3 * k + 1], work[3 * k + 2])
        bk = (b[i, k, 0], b[i, k, 1], b[i, k, 2])
        Dk = _dot(ck, ck)
        work[oD + k] = Dk
        work[oh + k] = -_dot(ck, bk)
        work[og + 4 * k] = -_dot(a, ck)
        work[oS] += aa
        work[ohy] += _dot(a, bk)
        for j in range(3):
            work[og + 4 * k + 1 + j] = -d * ck[j]
            work[oS + 1 + j] += d * a[j]
            work[oS + 5 * (1 + j)] += d * d
            work[ohy + 1 + j] += d * bk[j]
        trace += aa + Dk + 3.0 * d * d
    for j in range(3):
        work[oS + 4 * (1 + j)] = work[oS + 1 + j]
    # S = E − Σ_k g_k g_kᵀ / D_k ;  h_y − Σ_k g_k h_k / D_k
    for k in range(m):
        w = 1.0 / work[oD + k]
        gk = og + 4 * k
        for r in range(4):
            work[ohy + r] -= work[gk + r] * work[oh + k] * w
            for q in range(4):
                work[oS + 4 * r + q] -= work[gk + r] * work[gk + q] * w
    if not _cholesky_inverse4(work, oS, oL, oSi):
        kappa[i] = np.inf
        return 0
    # tr (AᵀA)⁻¹ = tr S⁻¹ + Σ_k (1/D_k + g_kᵀ S⁻¹ g_k / D_k²)
    inv_trace = work[oSi] + work[oSi + 5] + work[oSi + 10] + work[oSi + 15]
    for k in range(m):
        quad = 0.0
        gk = og + 4 * k
        for r in range(4):
            x = 0.0
            for q in range(4):
                x += work[oSi + 4 * r + q] * work[gk + q]
            work[osg + 4 * k + r] = x  # S⁻¹ g_k
            quad += work[gk + r] * x
        Dk = work[oD + k]
        inv_trace += 1.0 / Dk + quad / (Dk * Dk)
    kap = np.sqrt(trace * inv_trace)
    if not kap <= NORMAL_EQUATIONS_COND:
        kappa[i] = np.inf
        return 0
    kappa[i] = kap
    for r in range(4):
        x = 0.0
        for q in range(4):
            x += work[oSi + 4 * r + q] * work[ohy + q]
        work[oy + r] = x
    y = (work[oy], work[oy + 1], work[oy + 2], work[oy + 3])
    # X = (r_1, r_2 … r_n, V): y holds r_1 and V
    X[i, 0] = y[0]
    for j in range(3):
        X[i, n + j] = y[1 + j]
    for k in range(m):
        gk = og + 4 * k
        X[i, 1 + k] = (work[oh + k] - (work[gk] * y[0] + work[gk + 1] * y[1]
                                       + work[gk + 2] * y[2] + work[gk + 3] * y[3])
                       ) / work[oD + k]  # fmt: skip
    # Q = σ_e² (AᵀA)⁻¹ in X's order (y ↦ columns 0, n, n+1, n+2)
    for r in range(4):
        ir = 0 if r == 0 else n + r - 1
        for q in range(4):
            iq = 0 if q == 0 else n + q - 1
            Q[i, ir, iq] = sigma2 * work[oSi + 4 * r + q]
        if not full_q:
            continue
        for k in range(m):
            Q[i, ir, 1 + k] = Q[i, 1 + k, ir] = -sigma2 * work[osg + 4 * k + r] / work[oD + k]
    for k in range(m if full_q else 0):
        sk = osg + 4 * k
        for l in range(k, m):
            gl = og + 4 * l
            x = (work[gl] * work[sk] + work[gl + 1] * work[sk + 1] + work[gl + 2] * work[sk + 2]
                 + work[gl + 3] * work[sk + 3])  # fmt: skip
            x /= work[oD + k] * work[oD + l]
            if k == l:
                x += 1.0 / work[oD + k]
            Q[i, 1 + k, 1 + l] = Q[i, 1 + l, 1 + k] = sigma2 * x
    # E_k = r_1 a_1 − r_k c_k + Δt_k V − b_k ;  J = Σ_k ‖E_k‖²
    total = 0.0
    r1 = X[i, 0]
    for k in range(m):
        rk, d = X[i, 1 + k], dt[i, k]
        for j in range(3):
            e = r1 * a[j] - rk * work[3 * k + j] + d * X[i, n + j] - b[i, k, j]
            total += e * e
    J[i] = total
    position[i, 0], position[i, 1], position[i, 2] = r1 * a[0], r1 * a[1], r1 * a[2]
    return 0


@njit(inline="always")
def velocity_fix_element(a, c2, c3, d2, d3, r1, r2, r3, s1, s2, s3, position_var, C, i, work):
    """Exact first-order covariance of the ``n = 3`` velocity-aware solution ``(M̂_1, V̂)``
    under angle noise (theory §3.5, "Angle noise"), written to ``C[i]`` ``(6, 6)``; False (and
    NaN) where ``M`` is singular to rounding (as :func:`triple_velocity_kernel`).

    ``a``, ``c2``, ``c3`` are the unit directions in frame 1 (3-tuples), ``d2``, ``d3`` the
    delays, ``r1 … r3`` the solved ranges, ``s1 … s3`` the angular standard deviations ``σ_k``
    (rad), ``position_var`` paper 000's shared apparent-position variance ``σ_x²`` (it moves
    ``M̂_1`` by itself and leaves ``V̂`` alone); ``work`` is a ``(9, 3)`` scratch.

    A direction error ``n_k`` (``u_1 = a_1``, ``u_k = c_k``) enters block ``k`` of ``A X = B``
    as ``δB_k = r_k n_k − r_1 n_1``. Through ``A⁻¹`` of :func:`triple_velocity_kernel` (``m`` the
    first row of ``M⁻¹``, ``H = G M⁻¹``, ``g = Δt_3 − Δt_2``, ``Δ² = Δt_2² + Δt_3²``)::

        δd = Σ_k β_k n_k ,   β = (−g r_1, Δt_3 r_2, −Δt_2 r_3)      (δ of Δt_3 B_2 − Δt_2 B_3)
        δM̂_1 = r_1 n_1 + a_1 mᵀ δd                                   (M̂_1 = r̂_1 a_1)
        δV̂ = (Σ_k γ_k n_k + H δd) / Δ² ,   γ = (−(Δt_2 + Δt_3) r_1, Δt_2 r_2, Δt_3 r_3)

    so ``(δM̂_1, δV̂) = Σ_k T_k n_k`` with the ``6×3`` blocks ``T_k = [α_k I + β_k a_1 mᵀ ;
    (γ_k I + β_k H)/Δ²]`` (``α = (r_1, 0, 0)``). With ``n_k ~ N(0, σ_k² (I − u_k u_kᵀ))``
    independent::

        C = Σ_k σ_k² (T_k T_kᵀ − w_k w_kᵀ) + σ_x² diag(I₃, 0) ,    w_k = T_k u_k

    The numpy reference is :func:`~.conjugation.velocity_fix_jacobian` (``J Σ Jᵀ``).
    """
    g = d3 - d2
    ok, Mi = _triple_inverse(a, c2, c3, d2, d3)
    if not ok:
        for j in range(6):
            for k in range(6):
                C[i, j, k] = np.nan
        return False
    m = Mi[0]
    # H = G M⁻¹ in work[6:9], G columns (−(Δt_2 + Δt_3) a_1, Δt_2 c_2, Δt_3 c_3)
    for j in range(3):
        gj = (-(d2 + d3) * a[j], d2 * c2[j], d3 * c3[j])
        for k in range(3):
            work[6 + j, k] = gj[0] * Mi[0][k] + gj[1] * Mi[1][k] + gj[2] * Mi[2][k]
    inv_delta2 = 1.0 / (d2 * d2 + d3 * d3)
    for j in range(6):
        for k in range(6):
            C[i, j, k] = 0.0
    for alpha, beta, gamma, s, u in (
        (r1, -g * r1, -(d2 + d3) * r1, s1, a),
        (0.0, d3 * r2, d2 * r2, s2, c2),
        (0.0, -d2 * r3, d3 * r3, s3, c3),
    ):
        # T_k in work[0:6]: rows α e_j + β a_j m (position), (γ e_j + β H_j)/Δ² (velocity)
        for j in range(3):
            for k in range(3):
                eye = 1.0 if j == k else 0.0
                work[j, k] = alpha * eye + beta * a[j] * m[k]
                work[3 + j, k] = (gamma * eye + beta * work[6 + j, k]) * inv_delta2
        s2k = s * s
        # C += σ_k² (T_k T_kᵀ − w_k w_kᵀ),  w_k = T_k u_k: the projector I − u_k u_kᵀ
        for j in range(6):
            wj = work[j, 0] * u[0] + work[j, 1] * u[1] + work[j, 2] * u[2]
            for k in range(j + 1):
                wk = work[k, 0] * u[0] + work[k, 1] * u[1] + work[k, 2] * u[2]
                tt = work[j, 0] * work[k, 0] + work[j, 1] * work[k, 1] + work[j, 2] * work[k, 2]
                C[i, j, k] += s2k * (tt - wj * wk)
    for j in range(6):
        if j < 3:
            C[i, j, j] += position_var
        for k in range(j):
            C[i, k, j] = C[i, j, k]
    return True


@njit(**_JIT)
def velocity_fix_covariance_kernel(
    a1: Array,
    ak: Array,
    P: Array,
    dt: Array,
    ranges: Array,
    sigma: Array,
    position_var: float,
    lo: int,
    hi: int,
    C: Array,
) -> None:
    """:func:`velocity_fix_element` for elements ``lo..hi−1``: inputs ``a1 (N, 3)``,
    ``ak (N, 2, 3)``, ``P (N, 2, 3, 3)``, ``dt (N, 2)``, the solved ``ranges (N, 3)`` and
    ``sigma (N, 3)`` (rad); output ``C (N, 6, 6)`` of ``(M̂_1, V̂)`` in frame 1. Inputs are
    not checked (the caller has solved them with :func:`triple_velocity_kernel`)."""
    work = np.empty((9, 3))
    for i in range(lo, hi):
        c2 = _rotate(P, i, 0, (ak[i, 0, 0], ak[i, 0, 1], ak[i, 0, 2]))
        c3 = _rotate(P, i, 1, (ak[i, 1, 0], ak[i, 1, 1], ak[i, 1, 2]))
        velocity_fix_element(
            _vec(a1, i),
            c2,
            c3,
            dt[i, 0],
            dt[i, 1],
            ranges[i, 0],
            ranges[i, 1],
            ranges[i, 2],
            sigma[i, 0],
            sigma[i, 1],
            sigma[i, 2],
            position_var,
            C,
            i,
            work,
        )
