"""Compiled primitives of the stereo trackers: the one copy of each formula (theory §4, §11.3).

Small numba functions over one object at a time — lines of sight, the masked position
information, the observability test, the weighted least-squares fix and its in-front test, the
position bound and the log-ratio reward, the constant-velocity Kalman predict/update and the
angles of a unit vector. The batched public functions of :mod:`.information` and :mod:`.kalman`
loop over their batch in compiled code and call these; the environments' fused steps (e.g.
:mod:`sensorgym.envs.stereo_pointing.kernels`) call the same ones. Every function works on
array views it is given (no allocation on the regular paths), never raises and keeps the
documented fallbacks of the public functions.

3×3 systems are solved by Gaussian elimination with partial pivoting (:func:`lu3`,
:func:`lu_solve3`); determinants by cofactors (:func:`det3`). Both are the textbook algorithms
LAPACK runs for these sizes, in another order of operations: results agree with the former
``np.linalg`` forms to round-off (last bits), and every decision (observable, singular) to
round-off at its threshold.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from sensorgym.trackers.geometry import wrap_angle_scalar
from sensorgym.trackers.geometry_kernels import (
    angles_from_unit3 as angles_from_unit,  # noqa: F401  (one copy, re-exported for env kernels)
)
from sensorgym.trackers.geometry_kernels import perturbed_direction3, unit_from_angles3

#: the information is regular where ``det I > CONDITION · (tr I)³``
CONDITION = 1e-12
#: ranges are floored at this (m) so that a receiver on the point gives finite information
MIN_RANGE = 1e-9
#: a fix is trusted only if it lies at least this far (m) in front of every receiver that sees
#: it, along that receiver's line of sight
MIN_FIX_RANGE = 1e-2
#: the innovation covariance ``S`` is singular where an eigenvalue ``λ ≤ RCOND · max|λ|``
RCOND = 1e-13
#: cheap pre-screen of :func:`singular_innovation`: only matrices with a leading principal
#: minor ``≤ SCREEN · ‖S‖^k`` (``k`` = its order) are decomposed
SCREEN = 1e-9

JIT = {"cache": True, "nogil": True, "error_model": "numpy", "boundscheck": False}
#: small primitives are inlined into their callers: each separately compiled function costs
#: about 0.3 s of cold compile time (the fused step's fell from 19 s to 10 s)
INLINE = {**JIT, "inline": "always"}


# ---------------------------------------------------------------- scalars and small algebra


@njit(**INLINE)
def clip(x, lo, hi):
    """``np.clip`` of one value (NaN stays NaN)."""
    if x < lo:
        return lo
    if x > hi:
        return hi
    return x


@njit(**INLINE)
def floor_range(r):
    """``max(r, MIN_RANGE)`` (NaN stays NaN, as ``np.maximum``)."""
    return MIN_RANGE if r < MIN_RANGE else r


@njit(**INLINE)
def wrap_angle(a):
    """``(a + π) mod 2π − π``: the angle in ``[−π, π)`` (theory §2,
    :func:`sensorgym.trackers.geometry.wrap_angle_scalar`)."""
    return wrap_angle_scalar(a)


@njit(**INLINE)
def copy1(src, dst):
    """``dst[:] = src`` (explicit loops: they compile far faster than slice assignment)."""
    for i in range(src.shape[0]):
        dst[i] = src[i]


@njit(**INLINE)
def copy2(src, dst):
    """``dst[:, :] = src``."""
    for i in range(src.shape[0]):
        for j in range(src.shape[1]):
            dst[i, j] = src[i, j]


@njit(**INLINE)
def det3_entries(a00, a01, a02, a10, a11, a12, a20, a21, a22):
    """``det A`` of the 3×3 ``A = [[a00, a01, a02], [a10, a11, a12], [a20, a21, a22]]`` by
    cofactors along the first row (the one copy: :func:`det3`, :func:`symmetric_score`)."""
    return (
        a00 * (a11 * a22 - a12 * a21)
        - a01 * (a10 * a22 - a12 * a20)
        + a02 * (a10 * a21 - a11 * a20)
    )


@njit(**INLINE)
def det3(A):
    """``det A`` of a 3×3 ``A`` by cofactors along the first row (:func:`det3_entries`)."""
    return det3_entries(
        A[0, 0], A[0, 1], A[0, 2], A[1, 0], A[1, 1], A[1, 2], A[2, 0], A[2, 1], A[2, 2]
    )


@njit(**INLINE)
def lu3(A, LU, piv):
    """``P A = L U`` of a 3×3 ``A`` by Gaussian elimination with partial pivoting: ``LU`` gets
    ``U`` on and above the diagonal and the multipliers of ``L`` below, ``piv[i]`` the row
    swapped into row ``i`` at step ``i`` (rows swapped whole, multipliers with them). A zero
    pivot is left in ``U`` (a singular ``A``). The entries are held in locals and written
    once (numba reloads an array after every store: 3–4× slower)."""
    a00, a01, a02 = A[0, 0], A[0, 1], A[0, 2]
    a10, a11, a12 = A[1, 0], A[1, 1], A[1, 2]
    a20, a21, a22 = A[2, 0], A[2, 1], A[2, 2]
    # step 0: pivot, the first largest |a_k0|
    p0 = 0
    if abs(a10) > abs(a00):
        p0 = 1
    if abs(a20) > abs(a10 if p0 == 1 else a00):
        p0 = 2
    if p0 == 1:
        a00, a01, a02, a10, a11, a12 = a10, a11, a12, a00, a01, a02
    elif p0 == 2:
        a00, a01, a02, a20, a21, a22 = a20, a21, a22, a00, a01, a02
    if a00 != 0.0:
        # l_k0 = a_k0 / a_00 ;  a_kc −= l_k0 a_0c
        a10 /= a00
        a11 -= a10 * a01
        a12 -= a10 * a02
        a20 /= a00
        a21 -= a20 * a01
        a22 -= a20 * a02
    # step 1
    p1 = 1
    if abs(a21) > abs(a11):
        p1 = 2
        a10, a11, a12, a20, a21, a22 = a20, a21, a22, a10, a11, a12
    if a11 != 0.0:
        a21 /= a11
        a22 -= a21 * a12
    LU[0, 0], LU[0, 1], LU[0, 2] = a00, a01, a02
    LU[1, 0], LU[1, 1], LU[1, 2] = a10, a11, a12
    LU[2, 0], LU[2, 1], LU[2, 2] = a20, a21, a22
    piv[0], piv[1], piv[2] = p0, p1, 2


@njit(**INLINE)
def lu_solve_column3(LU, piv, x0, x1, x2):
    """``A⁻¹ x`` of one column ``x = (x0, x1, x2)`` from :func:`lu3`'s factors: row swaps,
    then ``L y = P x`` and ``U z = y``; returns ``z`` (in locals, as :func:`lu3`)."""
    p0, p1, p2 = piv[0], piv[1], piv[2]
    # row i swapped with row piv[i], i = 0, 1, 2 in turn
    if p0 == 1:
        x0, x1 = x1, x0
    elif p0 == 2:
        x0, x2 = x2, x0
    if p1 == 0:
        x1, x0 = x0, x1
    elif p1 == 2:
        x1, x2 = x2, x1
    if p2 == 0:
        x2, x0 = x0, x2
    elif p2 == 1:
        x2, x1 = x1, x2
    # forward: y_i = x_i − Σ_{j<i} l_ij y_j
    x1 -= LU[1, 0] * x0
    x2 -= LU[2, 0] * x0 + LU[2, 1] * x1
    # back: z_i = (y_i − Σ_{j>i} u_ij z_j) / u_ii
    x2 /= LU[2, 2]
    x1 = (x1 - LU[1, 2] * x2) / LU[1, 1]
    x0 = (x0 - LU[0, 1] * x1 - LU[0, 2] * x2) / LU[0, 0]
    return x0, x1, x2


@njit(**INLINE)
def lu_solve3(LU, piv, X):
    """``X ← A⁻¹ X`` in place (``X`` of shape ``(3, k)``) from :func:`lu3`'s factors, column
    by column (:func:`lu_solve_column3`)."""
    for c in range(X.shape[1]):
        X[0, c], X[1, c], X[2, c] = lu_solve_column3(LU, piv, X[0, c], X[1, c], X[2, c])


@njit(**INLINE)
def inverse3(A, LU, piv, out):
    """``out = A⁻¹`` of a regular 3×3 ``A`` (scratch ``LU (3, 3)``, ``piv (3,)``)."""
    lu3(A, LU, piv)
    for i in range(3):
        for j in range(3):
            out[i, j] = 1.0 if i == j else 0.0
    lu_solve3(LU, piv, out)


@njit(**INLINE)
def trace_inverse3(A, LU, piv):
    """``tr A⁻¹`` of a regular 3×3 ``A`` (scratch ``LU (3, 3)``, ``piv (3,)``): the diagonal
    of :func:`inverse3`, each entry by the same operations (the solves for the columns of
    ``I``, of which only entry ``c`` of column ``c`` is kept), summed in order."""
    lu3(A, LU, piv)
    d0 = lu_solve_column3(LU, piv, 1.0, 0.0, 0.0)[0]
    d1 = lu_solve_column3(LU, piv, 0.0, 1.0, 0.0)[1]
    d2 = lu_solve_column3(LU, piv, 0.0, 0.0, 1.0)[2]
    return d0 + d1 + d2


@njit(**INLINE)
def trace_inverse3_adjugate(a00, a01, a02, a11, a12, a22, det):
    """``tr A⁻¹ = tr adj A / det A`` of the symmetric 3×3 ``A = [[a00, a01, a02], [a01, a11,
    a12], [a02, a12, a22]]`` of determinant ``det`` (:func:`det3_entries`): the sum of the
    principal 2×2 minors over ``det``. The planners' scores use it
    (:func:`symmetric_score`): a set's value is scored for every receiver that might join
    it, and the determinant is there already, so no factorisation per score in the inner
    loop of :func:`assignment_ascent_batch`. It agrees with :func:`trace_inverse3` (LU) to
    round-off; the env's reward (:func:`position_sigma`) keeps the LU form, so its episodes
    are unchanged."""
    return ((a11 * a22 - a12 * a12) + (a00 * a22 - a02 * a02) + (a00 * a11 - a01 * a01)) / det


# ---------------------------------------------------------------- lines of sight and angles


@njit(**INLINE)
def line_of_sight(o, p, u):
    """Unit line of sight ``u = (p − o)/‖p − o‖`` from ``o`` to ``p`` into ``u (3,)``; returns the
    range ``r = ‖p − o‖``. Within ``MIN_RANGE`` of ``o`` there is no direction: ``u = 0``."""
    d0, d1, d2 = p[0] - o[0], p[1] - o[1], p[2] - o[2]
    r = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    if r > MIN_RANGE:
        u[0], u[1], u[2] = d0 / r, d1 / r, d2 / r
    else:
        u[0], u[1], u[2] = 0.0, 0.0, 0.0
    return r


@njit(**INLINE)
def unit_from_angles(azimuth, elevation, u):
    """``u = (cos ε sin α, sin ε, cos ε cos α)`` (000 eq. 2, theory §2.2) into ``u (3,)``
    (:func:`sensorgym.trackers.geometry_kernels.unit_from_angles3`)."""
    u[0], u[1], u[2] = unit_from_angles3(azimuth, elevation)


@njit(**INLINE)
def perturb_direction(a, z, sigma, out):
    """Isotropic angular noise (``stereo_scene.perturb_directions``) from the standard normal
    draws ``z (3,)``: ``v = a + σ (I − a aᵀ) z``, ``out = v/‖v‖``
    (:func:`sensorgym.trackers.geometry_kernels.perturbed_direction3`); a zero ``a`` stays zero."""
    if a[0] == 0.0 and a[1] == 0.0 and a[2] == 0.0:
        out[0], out[1], out[2] = 0.0, 0.0, 0.0
        return
    out[0], out[1], out[2] = perturbed_direction3(a, z, sigma)


# ---------------------------------------------------------------- information and the fix


@njit(**INLINE)
def projection_entry(u, w, i, j):
    """Entry ``(i, j)`` of ``w Π = w (I − u uᵀ)``: ``w (δ_ij − u_i u_j)``."""
    return w * ((1.0 if i == j else 0.0) - u[i] * u[j])


@njit(**INLINE)
def add_projection(u, w, out):
    """``out += w (I − u uᵀ)`` (:func:`projection_entry`): one line of sight's term ``w Π`` of
    :func:`position_information`."""
    for i in range(3):
        for j in range(3):
            out[i, j] += projection_entry(u, w, i, j)


@njit(**INLINE)
def position_information(u, r, sigma, mask, out):
    """``I = Σ_k m_k (I − u_k u_kᵀ) / (σ_k² r_k²)`` into ``out (3, 3)`` (theory §4.1), ranges
    floored at ``MIN_RANGE``; ``u (n, 3)``, ``r``, ``sigma``, ``mask`` of shape ``(n,)``."""
    for i in range(3):
        for j in range(3):
            out[i, j] = 0.0
    for k in range(u.shape[0]):
        sr = sigma[k] * floor_range(r[k])
        add_projection(u[k], (1.0 if mask[k] else 0.0) * (1.0 / (sr * sr)), out)


@njit(**INLINE)
def well_conditioned(det, tr, views):
    """At least two views and ``det I > CONDITION · (tr I)³`` of the information ``I`` of
    determinant ``det`` and trace ``tr`` (theory §4.3)."""
    return views >= 2 and det > CONDITION * tr**3


@njit(**INLINE)
def observable(info, views):
    """:func:`well_conditioned` of ``info (3, 3)``."""
    tr = info[0, 0] + info[1, 1] + info[2, 2]
    return well_conditioned(det3(info), tr, views)


@njit(**INLINE)
def count_views(mask):
    """Number of receivers that see the point."""
    n = 0
    for k in range(mask.shape[0]):
        if mask[k]:
            n += 1
    return n


@njit(**JIT)
def weighted_fix(o, u, mask, sigma, iterations, M, info, r, rhs, LU, piv):
    """The position fix efficient to first order under angle noise (theory §4.2) into ``M (3,)``,
    its information at the final ranges into ``info (3, 3)``; returns ``ok``.

    ``(Σ_k w_k Π_k) M = Σ_k w_k Π_k o_k`` with ``w_k = m_k/(σ_k r_k)²``, ranges starting at 1
    and refreshed from the fix ``iterations − 1`` times; ``M = 0`` where not observable.
    Scratch: ``r (n,)``, ``rhs (3, 1)``, ``LU (3, 3)``, ``piv (3,)``.
    """
    n = o.shape[0]
    views = count_views(mask)
    for k in range(n):
        r[k] = 1.0
    ok = False
    for _ in range(iterations):
        position_information(u, r, sigma, mask, info)
        ok = observable(info, views)
        rhs[0, 0], rhs[1, 0], rhs[2, 0] = 0.0, 0.0, 0.0
        for k in range(n):
            sr = sigma[k] * r[k]
            w = (1.0 if mask[k] else 0.0) / (sr * sr)
            for i in range(3):
                # Σ_k w_k Π_k o_k
                rhs[i, 0] += w * (
                    o[k, i] - u[k, i] * (u[k, 0] * o[k, 0] + u[k, 1] * o[k, 1] + u[k, 2] * o[k, 2])
                )
        if ok:
            lu3(info, LU, piv)
            lu_solve3(LU, piv, rhs)
            M[0], M[1], M[2] = rhs[0, 0], rhs[1, 0], rhs[2, 0]
        else:
            M[0], M[1], M[2] = 0.0, 0.0, 0.0
        for k in range(n):
            d0, d1, d2 = M[0] - o[k, 0], M[1] - o[k, 1], M[2] - o[k, 2]
            r[k] = floor_range(math.sqrt(d0 * d0 + d1 * d1 + d2 * d2))
    position_information(u, r, sigma, mask, info)
    return ok and observable(info, views)


@njit(**INLINE)
def fix_in_front(M, o, u, mask, min_range):
    """``u_k · (M − o_k) > min_range`` for every receiver ``k`` that sees the fix (theory §4.3)."""
    for k in range(o.shape[0]):
        if mask[k]:
            ahead = (
                u[k, 0] * (M[0] - o[k, 0]) + u[k, 1] * (M[1] - o[k, 1]) + u[k, 2] * (M[2] - o[k, 2])
            )
            if not ahead > min_range:
                return False
    return True


@njit(**INLINE)
def position_sigma(info, ok, sigma, LU, piv, inv):
    """Position RMS bound ``σ √tr I⁻¹`` (m) where ``ok``, ``+inf`` elsewhere (theory §4.1)."""
    if not ok:
        return np.inf
    tr = trace_inverse3(info, LU, piv)
    return sigma * math.sqrt(max(tr, 0.0))


@njit(**INLINE)
def log_ratio_reward(sigma_pos, sigma_ref, clip_r):
    """``clip(ln(σ_ref/σ_pos), −R, R)`` (theory §11.1): ``+R`` for ``σ_pos = 0``, ``−R`` for an
    infinite or NaN ``σ_pos`` (no fix) — always finite."""
    if not math.isfinite(sigma_pos):
        return -clip_r
    if not sigma_pos > 0.0:
        return clip_r
    return clip(math.log(sigma_ref) - math.log(sigma_pos), -clip_r, clip_r)


@njit(**INLINE)
def sin2_between(u, v):
    """``sin²γ = clip(1 − (u · v)², 0, 1)`` of the angle ``γ`` between unit vectors ``u``, ``v``
    (the orthogonality of two lines of sight, theory §10.1 OC-1). The dot product is summed as
    ``(u_x v_x + u_z v_z) + u_y v_y``, the order of the numpy form it replaced (``np.einsum``):
    a rule ranking near-equal scores then decides as before."""
    c = (u[0] * v[0] + u[2] * v[2]) + u[1] * v[1]
    return clip(1.0 - c * c, 0.0, 1.0)


@njit(**JIT)
def assignment_log_det_batch(u, r, sigma, cand, no_fix, out):
    """``Σ_j ln det I_j`` of every candidate assignment of receivers to points (theory §10.1–10.2
    OC-1/OC-2): ``I_j`` the :func:`position_information` of the receivers candidate ``c``
    assigns to point ``j`` (``cand[c, k] = j``), at lines of sight ``u (N, n, m, 3)`` and ranges
    ``r (N, n, m)`` with angle noise ``sigma``. A point given fewer than two receivers, or a
    non-positive ``det I_j``, scores ``−no_fix``. Into ``out (N, C)``."""
    N, n, m = r.shape
    sig = np.full(n, sigma)
    mask = np.empty(n, dtype=np.bool_)
    info = np.empty((3, 3))
    for b in range(N):
        for c in range(cand.shape[0]):
            total = 0.0
            for j in range(m):
                for k in range(n):
                    mask[k] = cand[c, k] == j
                score = -no_fix
                if count_views(mask) >= 2:
                    position_information(u[b, :, j], r[b, :, j], sig, mask, info)
                    det = det3(info)
                    if det > 0.0:
                        score = math.log(det)
                total += score
            out[b, c] = total


@njit(**JIT)
def assignment_orthogonality_batch(u, cand, out):
    """``Σ_j ½ ln max_{k∈S_j} Σ_{l∈S_j} sin²γ_kl`` of every candidate assignment (theory §10.1
    OC-1): ``S_j`` the receivers candidate ``c`` assigns to point ``j`` (``cand[c, k] = j``),
    ``γ_kl`` the angle between their lines of sight ``u (N, n, m, 3)`` (:func:`sin2_between`);
    the sums are floored at ``1e-300`` (an empty ``S_j``; a single receiver scores its own
    ``sin²γ_kk``, zero to round-off). Into ``out (N, C)``."""
    N, n, m = u.shape[0], u.shape[1], u.shape[2]
    for b in range(N):
        for c in range(cand.shape[0]):
            total = 0.0
            for j in range(m):
                best = 0.0
                for k in range(n):
                    if cand[c, k] != j:
                        continue
                    s = 0.0
                    for l in range(n):
                        if cand[c, l] == j:
                            s += sin2_between(u[b, k, j], u[b, l, j])
                    best = max(best, s)
                total += math.log(max(best, 1e-300))
            out[b, c] = 0.5 * total


#: the separable assignment objectives of :func:`assignment_marginals_batch` (its ``kind``):
#: the score of one drone's receivers on one step is ``ln det I`` (``−no_fix`` below two views
#: or at ``det I ≤ 0``, :func:`assignment_log_det_batch`), the information gain
#: ``ln det(λ I + I_S) − 3 ln λ`` over a prior ``λ I``, the env's reward
#: ``clip(ln(σ_ref/σ_pos), −R, R)`` (the planners' return), or the orthogonality
#: ``½ ln max_k Σ_l sin²γ_kl`` (:func:`assignment_orthogonality_batch`)
LOG_DET, GAIN, REWARD, ORTHOGONALITY = 0, 1, 2, 3


@njit(**INLINE)
def set_information(u, w, ready, prior, members, count, skip, extra, info):
    """``info = λ I + Σ_k w_k (I − u_k u_kᵀ)`` (:func:`add_projection`, ``λ = prior``) of the
    receivers ``members[:count]`` without ``skip`` and with ``extra`` (−1: none), each counted
    where ``ready[k]``, added in that order; returns how many were counted. ``u (n, 3)``,
    ``w``/``ready (n,)``, ``info (3, 3)``."""
    for a in range(3):
        for c in range(3):
            info[a, c] = prior if a == c else 0.0
    views = 0
    for i in range(count + 1):
        k = members[i] if i < count else extra
        if k < 0 or k == skip or not ready[k]:
            continue
        views += 1
        add_projection(u[k], w[k], info)
    return views


@njit(**INLINE)
def symmetric_score(kind, i00, i01, i02, i11, i12, i22, views, prior, consts):
    """Score ``kind`` (LOG_DET, GAIN or REWARD, above) of one drone's symmetric information
    ``I = [[i00, i01, i02], [i01, i11, i12], [i02, i12, i22]]`` from ``views`` receivers over
    the prior ``λ = prior``; ``consts`` holds ``no_fix`` (LOG_DET) or ``σ_ref, R`` (REWARD).

    ``det I`` by :func:`det3_entries`; the reward's ``σ_pos² = tr I⁻¹`` by
    :func:`trace_inverse3_adjugate` where :func:`well_conditioned`, ``σ_pos = ∞`` elsewhere
    (theory §4.1, §4.3)."""
    det = det3_entries(i00, i01, i02, i01, i11, i12, i02, i12, i22)
    if kind == LOG_DET:
        return math.log(det) if views >= 2 and det > 0.0 else -consts[0]
    if kind == GAIN:
        return math.log(det) - 3.0 * math.log(prior)
    sigma = np.inf
    if well_conditioned(det, i00 + i11 + i22, views):
        sigma = math.sqrt(max(trace_inverse3_adjugate(i00, i01, i02, i11, i12, i22, det), 0.0))
    return log_ratio_reward(sigma, consts[0], consts[1])


@njit(**INLINE)
def information_score(kind, info, views, prior, consts):
    """:func:`symmetric_score` of ``info (3, 3)`` (its upper triangle)."""
    return symmetric_score(
        kind, info[0, 0], info[0, 1], info[0, 2], info[1, 1], info[1, 2], info[2, 2], views,
        prior, consts,
    )  # fmt: skip


@njit(**INLINE)
def joined_score(kind, info, u, w, views, prior, consts):
    """:func:`symmetric_score` of ``info + w (I − u uᵀ)`` (:func:`add_projection`'s sum of
    :func:`projection_entry`, held in locals) from ``views + 1`` receivers."""
    return symmetric_score(
        kind,
        info[0, 0] + projection_entry(u, w, 0, 0),
        info[0, 1] + projection_entry(u, w, 0, 1),
        info[0, 2] + projection_entry(u, w, 0, 2),
        info[1, 1] + projection_entry(u, w, 1, 1),
        info[1, 2] + projection_entry(u, w, 1, 2),
        info[2, 2] + projection_entry(u, w, 2, 2),
        views + 1,
        prior,
        consts,
    )


@njit(**INLINE)
def orthogonality_score(u, ready, members, count, skip, extra):
    """``½ ln max_k Σ_l sin²γ_kl`` (floored at 1e-300) over the receivers of
    :func:`set_information`'s set (:func:`assignment_orthogonality_batch`)."""
    best = 0.0
    for i in range(count + 1):
        k = members[i] if i < count else extra
        if k < 0 or k == skip or not ready[k]:
            continue
        # Σ_l sin²γ_kl over the set, for the best reference receiver k
        acc = 0.0
        for i2 in range(count + 1):
            l = members[i2] if i2 < count else extra
            if l >= 0 and l != skip and ready[l]:
                acc += sin2_between(u[k], u[l])
        best = max(best, acc)
    return 0.5 * math.log(max(best, 1e-300))


@njit(**JIT)
def drone_marginals(kind, u, w, ready, prior, weight, consts, assign, j, rows, out, members, work):
    """Marginal values on drone ``j`` of one scenario under the separable objective of
    :func:`assignment_marginals_batch`: ``out[a] = V_j(S ∪ {k}) − V_j(S ∖ {k})`` for receiver
    ``k = rows[a]``, ``S`` drone ``j``'s receivers under ``assign (n,)`` (−1: not assigned);
    returns ``V_j(S)``. ``u (S, n, m, 3)``, ``w``/``ready (S, n, m)``, ``weight (S,)``,
    ``prior`` drone ``j``'s ``λ``; scratch ``members (n,)``, ``work (2, 3, 3)``.

    Per step, the set's information is summed once; a receiver outside the set adds its term
    to it (the order :func:`set_information` adds them in, so the sum is the same to the
    bit), a receiver inside is summed without. A step where ``k`` does not count, or of
    weight 0, adds nothing to ``out[a]`` and is not scored twice."""
    count = 0
    for k in range(assign.shape[0]):
        if assign[k] == j:
            members[count] = k
            count += 1
    for a in range(rows.shape[0]):
        out[a] = 0.0
    base_info, info = work[0], work[1]
    value = 0.0
    for s in range(u.shape[0]):
        if weight[s] == 0.0:
            continue
        us, ws, rs = u[s, :, j], w[s, :, j], ready[s, :, j]
        views = 0
        if kind == ORTHOGONALITY:
            base = orthogonality_score(us, rs, members, count, -1, -1)
        else:
            views = set_information(us, ws, rs, prior, members, count, -1, -1, base_info)
            base = information_score(kind, base_info, views, prior, consts)
        value += weight[s] * base
        for a in range(rows.shape[0]):
            k = rows[a]
            if not rs[k]:
                continue
            inside = assign[k] == j
            # the set with k minus the set without k, on this step
            if kind == ORTHOGONALITY:
                other = orthogonality_score(
                    us, rs, members, count, k if inside else -1, -1 if inside else k
                )
            elif inside:
                v = set_information(us, ws, rs, prior, members, count, k, -1, info)
                other = information_score(kind, info, v, prior, consts)
            else:
                other = joined_score(kind, base_info, us[k], ws[k], views, prior, consts)
            out[a] += weight[s] * (base - other if inside else other - base)
    return value


@njit(**JIT)
def assignment_marginals_batch(
    kind, u, w, ready, prior, weight, consts, assign, scenarios, rows, cols, out
):
    """Marginal values of receivers on drones under a separable assignment objective
    ``F(a) = Σ_j V_j({k : a_k = j})``, ``V_j(S) = Σ_s weight_s · score_s(S)`` with the score
    of ``kind`` on each step ``s`` (:func:`information_score`, :func:`orthogonality_score`)
    of the receivers of ``S`` that count there: for row ``i`` — scenario
    ``b = scenarios[i]`` under the assignment ``assign[i] (n,)`` (−1: not assigned) — receiver
    ``k = rows[a]`` and drone ``j = cols[i, c]``, ``out[i, a, c] = V_j(S ∪ {k}) − V_j(S)`` with
    ``S`` drone ``j``'s receivers other than ``k`` (:func:`drone_marginals`). Moving ``k``
    from drone ``j₀`` to ``j`` changes ``F`` by ``out[.., j] − out[.., j₀]``.
    ``u (B, S, n, m, 3)``, ``w``/``ready (B, S, n, m)``, ``prior (B, m)``, ``weight (B, S)``."""
    n = assign.shape[1]
    members = np.empty(n, np.int64)
    column = np.empty(rows.shape[0])
    work = np.empty((2, 3, 3))
    for i in range(scenarios.shape[0]):
        b = scenarios[i]
        for c in range(cols.shape[1]):
            j = cols[i, c]
            drone_marginals(
                kind, u[b], w[b], ready[b], prior[b, j], weight[b], consts, assign[i], j, rows,
                column, members, work,
            )  # fmt: skip
            for a in range(rows.shape[0]):
                out[i, a, c] = column[a]


@njit(**JIT)
def assignment_greedy_batch(kind, u, w, ready, prior, weight, consts, bonus, lo, hi, assign):
    """Sequential greedy (:func:`sensorgym.agents.assignment_solver.sequential_greedy`) for
    scenarios ``lo ≤ b < hi``: receivers in index order, each unassigned one (``assign[b, k]
    < 0``) to the drone of largest marginal value (:func:`drone_marginals`) plus
    ``bonus[b, k, j]``, given the receivers assigned before it; ties go to the lowest drone.
    Arrays as :func:`assignment_marginals_batch`; ``assign (B, n)`` is updated in place."""
    n, m = assign.shape[1], u.shape[3]
    members = np.empty(n, np.int64)
    row, column = np.empty(1, np.int64), np.empty(1)
    work = np.empty((2, 3, 3))
    for b in range(lo, hi):
        for k in range(n):
            if assign[b, k] >= 0:
                continue
            row[0] = k
            best, best_value = 0, -np.inf
            for j in range(m):
                drone_marginals(
                    kind, u[b], w[b], ready[b], prior[b, j], weight[b], consts, assign[b], j,
                    row, column, members, work,
                )  # fmt: skip
                value = column[0] + bonus[b, k, j]
                if j == 0 or value > best_value:
                    best, best_value = j, value
            assign[b, k] = best


@njit(**JIT)
def _cached_column(kind, u, w, ready, prior, weight, consts, assign, j, rows, members, work,
                   keys, columns, size):  # fmt: skip
    """Row of ``columns`` holding ``V_j(S)`` and the marginals of every receiver on drone
    ``j`` (:func:`drone_marginals`) under ``assign``, computed unless a row of the same drone
    and receiver set (``keys[:size]``: drone, bitmask; ``n ≤ 62``) holds it already; returns
    the row and the new size. Without a key (``n > 62``) the last row is scratch."""
    n = assign.shape[0]
    scratch = columns.shape[0] - 1
    mask = 0
    if n <= 62:
        for k in range(n):
            if assign[k] == j:
                mask |= 1 << k
        for i in range(size):
            if keys[i, 0] == j and keys[i, 1] == mask:
                return i, size
    at = size if n <= 62 and size < scratch else scratch
    columns[at, 0] = drone_marginals(
        kind, u, w, ready, prior, weight, consts, assign, j, rows, columns[at, 1:], members,
        work,
    )  # fmt: skip
    if at == scratch:
        return at, size
    keys[at, 0], keys[at, 1] = j, mask
    return at, size + 1


@njit(**JIT)
def _score_drone(kind, u, w, ready, prior, weight, consts, assign, j, rows, members, work,
                 keys, columns, size, bonus, held, value):  # fmt: skip
    """Drone ``j``'s value ``held[j]`` and every receiver's value of joining it,
    ``value[k, j] = marginal + bonus[k, j]``, from its (cached) column under ``assign``;
    returns the cache's new size."""
    at, size = _cached_column(kind, u, w, ready, prior, weight, consts, assign, j, rows, members,
                              work, keys, columns, size)  # fmt: skip
    held[j] = columns[at, 0]
    for k in range(assign.shape[0]):
        value[k, j] = columns[at, 1 + k] + bonus[k, j]
    return size


@njit(**JIT)
def assignment_ascent_batch(kind, u, w, ready, prior, weight, consts, starts, bonus, max_moves,
                            min_rise, lo, hi, out):  # fmt: skip
    """Coordinate-wise ascent (:func:`sensorgym.agents.assignment_solver.improve`) of
    ``F(a) + Σ_k bonus[b, k, a_k]`` from every start ``starts[t, b] (n,)``, for scenarios
    ``lo ≤ b < hi``: while some receiver can move to another drone and raise the objective by
    more than ``min_rise``, make the move that raises it most (the first in receiver-major
    order on ties), at most ``max_moves`` moves; then the end of the highest objective,
    less ``min_rise · t`` (the first start on ties), into ``out[b] (n,)``. Arrays as
    :func:`assignment_marginals_batch`.

    Only the two drones a move touches are re-scored, and every drone's column (its value and
    the marginals of all receivers on it, :func:`drone_marginals`) is kept per receiver set
    within a scenario: an ascent that comes back to a set, or another start's ascent passing
    through it, reads it instead of scoring it again."""
    T, n, m = starts.shape[0], starts.shape[2], u.shape[3]
    rows = np.arange(n)
    members = np.empty(n, np.int64)
    work = np.empty((2, 3, 3))
    # every column one scenario may need: T starts × (m + two per move), plus the scratch row
    cap = T * (m + 2 * max_moves) + 1
    keys = np.empty((cap, 2), np.int64)
    columns = np.empty((cap, n + 1))
    value = np.empty((n, m))
    held = np.empty(m)
    a = np.empty(n, np.int64)
    for b in range(lo, hi):
        size = np.int64(0)  # not a literal: _score_drone compiles once
        best_score = -np.inf
        for t in range(T):
            for k in range(n):
                a[k] = starts[t, b, k]
            for j in range(m):
                size = _score_drone(kind, u[b], w[b], ready[b], prior[b, j], weight[b], consts,
                                    a, j, rows, members, work, keys, columns, size,
                                    bonus[b], held, value)  # fmt: skip
            for _ in range(max_moves):
                # the move of largest rise (receiver-major, first on ties)
                mk, mj, rise = 0, 0, -np.inf
                for k in range(n):
                    here = value[k, a[k]]
                    for j in range(m):
                        r = value[k, j] - here
                        if r > rise:
                            mk, mj, rise = k, j, r
                if not rise > min_rise:
                    break
                j0 = a[mk]
                a[mk] = mj
                for j in (j0, mj):
                    size = _score_drone(kind, u[b], w[b], ready[b], prior[b, j], weight[b],
                                        consts, a, j, rows, members, work, keys, columns,
                                        size, bonus[b], held, value)  # fmt: skip
            score = 0.0
            for j in range(m):
                score += held[j]
            for k in range(n):
                score += bonus[b, k, a[k]]
            score -= min_rise * t
            if t == 0 or score > best_score:
                best_score = score
                for k in range(n):
                    out[b, k] = a[k]


# ---------------------------------------------------------------- constant-velocity Kalman filter


@njit(**INLINE)
def cv_prior(position, velocity, sigma_p, sigma_v, x, P):
    """Track started from a cue (:mod:`.kalman`): mean ``x = (p, v)``, covariance
    ``P = diag(σ_p², σ_p², σ_p², σ_v², σ_v², σ_v²)``."""
    for i in range(3):
        x[i] = position[i]
        x[i + 3] = velocity[i]
    for i in range(6):
        for j in range(6):
            P[i, j] = 0.0
        P[i, i] = sigma_p**2 if i < 3 else sigma_v**2


@njit(**JIT)
def cv_predict(x, P, dt, q, x_out, P_out):
    """``x⁻ = F x``, ``P⁻ = F P Fᵀ + Q`` (theory §4.2, :mod:`.kalman`), blockwise with
    ``F = [[I, dt I], [0, I]]``, ``Q = q [[dt³/3 I, dt²/2 I], [dt²/2 I, dt I]]``:
    ``P⁻_pp = P_pp + dt (P_vp + P_pv) + dt² P_vv``, ``P⁻_pv = P_pv + dt P_vv``, ``P⁻_vv = P_vv``
    plus ``Q``. ``x_out``/``P_out`` may not alias ``x``/``P``."""
    q_pp, q_pv, q_vv = q * (dt**3 / 3.0), q * (dt**2 / 2.0), q * dt
    for i in range(3):
        x_out[i] = x[i] + dt * x[i + 3]
        x_out[i + 3] = x[i + 3]
        for j in range(3):
            pv = P[i, j + 3] + dt * P[i + 3, j + 3]
            vp = P[i + 3, j] + dt * P[i + 3, j + 3]
            P_out[i, j] = P[i, j] + dt * P[i + 3, j] + dt * pv
            P_out[i, j + 3] = pv
            P_out[i + 3, j] = vp
            P_out[i + 3, j + 3] = P[i + 3, j + 3]
        P_out[i, i] += q_pp
        P_out[i, i + 3] += q_pv
        P_out[i + 3, i] += q_pv
        P_out[i + 3, i + 3] += q_vv


@njit(**JIT)
def eigh3(S, lam, V):
    """Eigenvalues ``lam (3,)`` (ascending) and orthonormal eigenvectors (columns of ``V``) of a
    symmetric 3×3 ``S`` by cyclic Jacobi rotations: ``A ← Jᵀ A J`` zeroes ``a_pq`` with
    ``t = tan θ`` the smaller root of ``t² + 2τt − 1 = 0``, ``τ = (a_qq − a_pp)/(2 a_pq)``, until
    the off-diagonal part is below ``1e-17 ‖S‖_F`` (eigenvalue errors at round-off, Weyl)."""
    A = np.empty((3, 3))
    copy2(S, A)
    fro = 0.0
    for i in range(3):
        for j in range(3):
            V[i, j] = 1.0 if i == j else 0.0
            fro += S[i, j] * S[i, j]
    for _ in range(50):
        off = A[0, 1] * A[0, 1] + A[0, 2] * A[0, 2] + A[1, 2] * A[1, 2]
        if off <= 1e-34 * fro:
            break
        for p in range(2):
            for q in range(p + 1, 3):
                if A[p, q] == 0.0:
                    continue
                tau = (A[q, q] - A[p, p]) / (2.0 * A[p, q])
                if abs(tau) > 1e150:
                    t = 0.5 / tau
                else:
                    t = (1.0 if tau >= 0.0 else -1.0) / (abs(tau) + math.sqrt(1.0 + tau * tau))
                c = 1.0 / math.sqrt(1.0 + t * t)
                sn = t * c
                for k in range(3):  # columns p, q: A J
                    akp, akq = A[k, p], A[k, q]
                    A[k, p], A[k, q] = c * akp - sn * akq, sn * akp + c * akq
                for k in range(3):  # rows p, q: Jᵀ (A J)
                    apk, aqk = A[p, k], A[q, k]
                    A[p, k], A[q, k] = c * apk - sn * aqk, sn * apk + c * aqk
                for k in range(3):  # V J
                    vkp, vkq = V[k, p], V[k, q]
                    V[k, p], V[k, q] = c * vkp - sn * vkq, sn * vkp + c * vkq
    for i in range(3):
        lam[i] = A[i, i]
    # ascending order (insertion sort on 3), columns of V with them
    for i in range(1, 3):
        j = i
        while j > 0 and lam[j - 1] > lam[j]:
            lam[j - 1], lam[j] = lam[j], lam[j - 1]
            for k in range(3):
                t = V[k, j - 1]
                V[k, j - 1] = V[k, j]
                V[k, j] = t
            j -= 1


@njit(**JIT)
def singular_innovation(S):
    """Whether the symmetric 3×3 ``S`` is singular to working precision: ``λ_min ≤ RCOND ·
    max|λ|`` (:mod:`.kalman`); only matrices with a leading minor of order ``k`` at most
    ``SCREEN · ‖S‖^k`` (Frobenius) are decomposed (Sylvester's criterion)."""
    norm = 0.0
    for i in range(3):
        for j in range(3):
            norm += S[i, j] * S[i, j]
    norm = math.sqrt(norm)
    m1 = S[0, 0]
    m2 = S[0, 0] * S[1, 1] - S[0, 1] * S[1, 0]
    m3 = det3(S)
    if m1 > SCREEN * norm and m2 > SCREEN * norm**2 and m3 > SCREEN * norm**3:
        return False
    lam, V = np.empty(3), np.empty((3, 3))
    eigh3(S, lam, V)
    return lam[0] <= RCOND * max(abs(lam[0]), abs(lam[2]))


@njit(**JIT)
def pseudo_gain(P, S, K):
    """Gain ``K (6, 3)`` for singular ``S``: ``P Hᵀ S⁺`` plus the null-space projector
    ``N = I − S S⁺`` of ``S`` on the position rows (there the fix is taken as it is)."""
    lam, V = np.empty(3), np.empty((3, 3))
    eigh3(S, lam, V)
    top = max(abs(lam[0]), abs(lam[2]))
    pinv = np.zeros((3, 3))
    null = np.zeros((3, 3))
    for e in range(3):
        keep = lam[e] > RCOND * top
        for i in range(3):
            for j in range(3):
                # S⁺ = V diag(1/λ kept) Vᵀ,  N = V diag(not kept) Vᵀ
                if keep:
                    pinv[i, j] += V[i, e] * (1.0 / lam[e]) * V[j, e]
                else:
                    null[i, j] += V[i, e] * V[j, e]
    for i in range(6):
        for j in range(3):
            acc = 0.0
            for k in range(3):
                acc += P[k, i] * pinv[k, j]
            K[i, j] = acc + (null[i, j] if i < 3 else 0.0)


@njit(**JIT)
def cv_update(x, P, z, R, x_out, P_out, S, K, LU, piv, work):
    """Kalman update with the position fix ``z (3,)`` of covariance ``R (3, 3)`` (:mod:`.kalman`):
    ``S = P_pp + R``, ``K = P Hᵀ S⁻¹`` (the pseudo-inverse gain where ``S`` is singular),
    ``x = x + K (z − p)``, ``P = P − K S Kᵀ`` symmetrised. Scratch ``S (3, 3)``, ``K (6, 3)``,
    ``LU (3, 3)``, ``piv (3,)``, ``work (3, 6)``; the outputs may not alias the inputs."""
    for i in range(3):
        for j in range(3):
            S[i, j] = P[i, j] + R[i, j]
    if singular_innovation(S):
        pseudo_gain(P, S, K)
    else:
        # Kᵀ = S⁻¹ P_{p·}
        lu3(S, LU, piv)
        for i in range(3):
            for j in range(6):
                work[i, j] = P[i, j]
        lu_solve3(LU, piv, work)
        for i in range(6):
            for j in range(3):
                K[i, j] = work[j, i]
    e0, e1, e2 = z[0] - x[0], z[1] - x[1], z[2] - x[2]
    for i in range(6):
        x_out[i] = x[i] + (K[i, 0] * e0 + K[i, 1] * e1 + K[i, 2] * e2)
    # P − K S Kᵀ
    for i in range(6):
        ks0 = K[i, 0] * S[0, 0] + K[i, 1] * S[1, 0] + K[i, 2] * S[2, 0]
        ks1 = K[i, 0] * S[0, 1] + K[i, 1] * S[1, 1] + K[i, 2] * S[2, 1]
        ks2 = K[i, 0] * S[0, 2] + K[i, 1] * S[1, 2] + K[i, 2] * S[2, 2]
        for j in range(6):
            P_out[i, j] = P[i, j] - (ks0 * K[j, 0] + ks1 * K[j, 1] + ks2 * K[j, 2])
    for i in range(6):
        for j in range(i + 1, 6):
            s = 0.5 * (P_out[i, j] + P_out[j, i])
            P_out[i, j] = s
            P_out[j, i] = s


# ---------------------------------------------------------------- batched loops of the public API
# (flat batch ``N`` on the leading axis; the public functions broadcast and reshape)


@njit(**JIT)
def position_information_batch(u, r, sigma, mask, out):
    """:func:`position_information` over ``u (N, n, 3)``, ``r``/``sigma``/``mask (N, n)``."""
    for b in range(u.shape[0]):
        position_information(u[b], r[b], sigma[b], mask[b], out[b])


@njit(**JIT)
def observable_batch(info, views, out):
    """:func:`observable` over ``info (N, 3, 3)`` with ``views (N,)``."""
    for b in range(info.shape[0]):
        out[b] = observable(info[b], views[b])


@njit(**JIT)
def position_sigma_batch(info, ok, sigma, out):
    """:func:`position_sigma` over ``info (N, 3, 3)``, ``ok``/``sigma (N,)``."""
    LU, piv, inv = np.empty((3, 3)), np.empty(3, np.int64), np.empty((3, 3))
    for b in range(info.shape[0]):
        out[b] = position_sigma(info[b], ok[b], sigma[b], LU, piv, inv)


@njit(**JIT)
def log_ratio_reward_batch(sigma_pos, sigma_ref, clip_r, out):
    """:func:`log_ratio_reward` over a flat ``sigma_pos (N,)``."""
    for b in range(sigma_pos.shape[0]):
        out[b] = log_ratio_reward(sigma_pos[b], sigma_ref, clip_r)


@njit(**JIT)
def weighted_fix_batch(o, u, mask, sigma, iterations, M, info, ok):
    """:func:`weighted_fix` over ``o``/``u (N, n, 3)``, ``mask``/``sigma (N, n)``."""
    r = np.empty(o.shape[1])
    rhs, LU, piv = np.empty((3, 1)), np.empty((3, 3)), np.empty(3, np.int64)
    for b in range(o.shape[0]):
        ok[b] = weighted_fix(
            o[b], u[b], mask[b], sigma[b], iterations, M[b], info[b], r, rhs, LU, piv
        )


@njit(**JIT)
def fix_in_front_batch(M, o, u, mask, min_range, out):
    """:func:`fix_in_front` over ``M (N, 3)``, ``o``/``u (N, n, 3)``, ``mask (N, n)``."""
    for b in range(M.shape[0]):
        out[b] = fix_in_front(M[b], o[b], u[b], mask[b], min_range)


@njit(**JIT)
def cv_prior_batch(position, velocity, sigma_p, sigma_v, x, P):
    """:func:`cv_prior` over ``position``/``velocity (N, 3)``."""
    for b in range(position.shape[0]):
        cv_prior(position[b], velocity[b], sigma_p, sigma_v, x[b], P[b])


@njit(**JIT)
def cv_predict_batch(x, P, dt, q, x_out, P_out):
    """:func:`cv_predict` over ``x (N, 6)``, ``P (N, 6, 6)``."""
    for b in range(x.shape[0]):
        cv_predict(x[b], P[b], dt, q, x_out[b], P_out[b])


@njit(**JIT)
def singular_innovation_batch(S, out):
    """:func:`singular_innovation` over ``S (N, 3, 3)``."""
    for b in range(S.shape[0]):
        out[b] = singular_innovation(S[b])


@njit(**JIT)
def cv_update_batch(x, P, z, R, mask, x_out, P_out):
    """:func:`cv_update` over ``x (N, 6)``, ``P (N, 6, 6)``, ``z (N, 3)``, ``R (N, 3, 3)``
    where ``mask (N,)``; elsewhere the track is copied unchanged."""
    S, K, LU = np.empty((3, 3)), np.empty((6, 3)), np.empty((3, 3))
    piv, work = np.empty(3, np.int64), np.empty((3, 6))
    for b in range(x.shape[0]):
        if mask[b]:
            cv_update(x[b], P[b], z[b], R[b], x_out[b], P_out[b], S, K, LU, piv, work)
        else:
            copy1(x[b], x_out[b])
            copy2(P[b], P_out[b])
