"""Position information from lines of sight: the maths every stereo env, rule and tracker shares.

Angle-noise model (theory §4.1–4.3): receiver ``k`` measures the line of sight ``u_k`` to a point
``M`` at range ``r_k`` with isotropic angular noise ``σ_k``. The Fisher information of ``M`` is

    I(M) = Σ_k m_k (I − u_k u_kᵀ) / (σ_k² r_k²)

(``m_k`` = 1 where receiver ``k`` sees the point), its inverse the Cramér–Rao bound; the
position RMS bound is ``σ_pos = √tr I⁻¹``. The information is singular when fewer than two
receivers see the point or their lines of sight are parallel; :func:`observable` is the one
test of that, ``det I > CONDITION · (tr I)³`` (scale-free: ``det/tr³`` is a product of
eigenvalue ratios).

These functions are batched over leading axes, mask-aware and *unchecked*: they never raise on
degenerate geometry, which an environment must score, not refuse. Their documented fallbacks:
:func:`position_sigma` is ``+inf`` where the position is unobservable, and
:func:`log_ratio_reward` maps that to the finite ``−R``; a zero line of sight (a point at the
receiver, no direction) gives that receiver the information ``I/(σ² r²)`` at the floored range,
so it must be masked out (the environments never count such a view).

A noisy fix can pass the observability test although the true geometry is singular: receivers
(nearly) at one place see a point along (nearly) one line, their noisy lines of sight cross
where the receivers stand, and the information at that fix's own (tiny) ranges is regular.
:func:`fix_in_front` is the second test a tracker applies: the fix must lie at least
``MIN_FIX_RANGE`` in front of every receiver that sees it. The checked public API of
:mod:`.accuracy` (``position_information``, ``position_crlb``) validates its inputs and calls
these.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

#: the information is regular where ``det I > CONDITION · (tr I)³``
CONDITION = 1e-12
#: ranges are floored at this (m) so that a receiver on the point gives finite information
MIN_RANGE = 1e-9
#: largest clip ``R`` of :func:`log_ratio_reward` an env accepts: sums of ``±R`` over drones and
#: episodes stay finite
MAX_REWARD_CLIP = 1e6
#: a fix is trusted only if it lies at least this far (m) in front of every receiver that sees
#: it, along that receiver's line of sight (:func:`fix_in_front`)
MIN_FIX_RANGE = 1e-2


def position_information(
    los: ArrayLike, ranges: ArrayLike, sigma: ArrayLike = 1.0, mask: ArrayLike | None = None
) -> FloatArray:
    """``I = Σ_k m_k (I − u_k u_kᵀ) / (σ_k² r_k²)`` ``(..., 3, 3)``, 1/m² (``σ`` in rad).

    ``los (..., n, 3)`` unit lines of sight in one frame, ``ranges (..., n)`` m, ``sigma``
    scalar or ``(..., n)`` rad, ``mask (..., n)`` bool (None: every receiver). With the default
    ``σ = 1`` it is the geometry part ``G`` of ``I = G/σ²`` (equal noise at every receiver).
    Leading axes broadcast.
    """
    u = np.asarray(los, dtype=np.float64)
    r = np.maximum(np.asarray(ranges, dtype=np.float64), MIN_RANGE)
    w = 1.0 / (np.broadcast_to(sigma, r.shape) * r) ** 2
    if mask is not None:
        w = np.asarray(mask, dtype=bool) * w
    proj = np.eye(3) - u[..., :, None] * u[..., None, :]
    # I = Σ_k w_k Π_k,  Π_k = I − u_k u_kᵀ
    return np.einsum("...k,...kij->...ij", w, proj)


def observable(information: ArrayLike, mask: ArrayLike | None = None) -> BoolArray:
    """Where the position is observable ``(...)``: ``det I > CONDITION · (tr I)³`` and, with a
    ``mask (..., n)``, at least two receivers see the point."""
    info = np.asarray(information, dtype=np.float64)
    tr = np.trace(info, axis1=-2, axis2=-1)
    regular = np.linalg.det(info) > CONDITION * tr**3
    if mask is None:
        return regular
    return (np.sum(np.asarray(mask, dtype=bool), axis=-1) >= 2) & regular


def position_sigma(information: ArrayLike, ok: ArrayLike, sigma: float = 1.0) -> FloatArray:
    """Position RMS bound ``σ √tr I⁻¹`` ``(...)`` (m) where ``ok``; ``+inf`` elsewhere (the
    documented value of an unobservable position). ``sigma`` scales a geometry part
    ``G = σ² I`` (pass the information itself with the default 1)."""
    info = np.asarray(information, dtype=np.float64)
    good = np.asarray(ok, dtype=bool)
    safe = np.where(good[..., None, None], info, np.eye(3))
    tr = np.trace(np.linalg.inv(safe), axis1=-2, axis2=-1)
    return np.where(good, sigma * np.sqrt(np.maximum(tr, 0.0)), np.inf)


def log_ratio_reward(sigma_pos: ArrayLike, sigma_ref: float, clip: float) -> FloatArray:
    """``clip(ln(σ_ref / σ_pos), −R, R)`` elementwise (theory §11.1): ``+R`` for an exact fix
    (``σ_pos = 0``), ``−R`` where ``σ_pos`` is ``inf`` or NaN (no fix) — always finite."""
    s = np.asarray(sigma_pos, dtype=np.float64)
    finite = np.isfinite(s)
    positive = finite & (s > 0.0)
    log_ratio = np.log(sigma_ref) - np.log(np.where(positive, s, 1.0))
    return np.where(positive, np.clip(log_ratio, -clip, clip), np.where(finite, clip, -clip))


def weighted_fix(
    origins: ArrayLike,
    los: ArrayLike,
    mask: ArrayLike | None = None,
    sigma: ArrayLike = 1.0,
    iterations: int = 2,
) -> tuple[FloatArray, FloatArray, BoolArray]:
    """The position fix efficient to first order under angle noise (theory §4.2).

    Minimises ``Σ_k m_k ‖Π_k (M − o_k)‖² / (σ_k² r_k²)``, the perpendicular miss of ``M`` from
    each line of sight weighted by its information: for fixed ranges the normal equations are
    ``I M = Σ_k w_k Π_k o_k`` with ``I`` of :func:`position_information`; the ranges start at 1
    (the unweighted midpoint) and are refreshed from the fix ``iterations − 1`` times.
    Noise-free directions give the exact intersection whatever the weights.

    ``origins (..., n, 3)`` m and ``los (..., n, 3)`` unit vectors in one frame, ``mask (..., n)``
    bool (None: every receiver), ``sigma`` scalar or ``(..., n)`` rad. Returns
    ``(M (..., 3), I (..., 3, 3) at the final ranges, ok (...))``; where ``ok`` is False (fewer
    than two views, parallel lines of sight) ``M`` is zero and must not be used.
    """
    o = np.asarray(origins, dtype=np.float64)
    u = np.asarray(los, dtype=np.float64)
    if iterations < 1:
        raise ValueError(f"iterations: must be at least 1, got {iterations}")
    batch = np.broadcast_shapes(o.shape[:-1], u.shape[:-1])
    s = np.ones(batch, dtype=bool) if mask is None else np.asarray(mask, dtype=bool)
    o = np.broadcast_to(o, (*s.shape, 3))
    proj = np.eye(3) - u[..., :, None] * u[..., None, :]
    r = np.ones(s.shape)
    M = np.zeros((*s.shape[:-1], 3))
    ok = np.zeros(s.shape[:-1], dtype=bool)
    for _ in range(iterations):
        info = position_information(u, r, sigma, s)
        ok = observable(info, s)
        w = s / (np.broadcast_to(sigma, r.shape) * r) ** 2
        # (Σ w_k Π_k) M = Σ w_k Π_k o_k
        rhs = np.einsum("...k,...kij,...kj->...i", w, proj, o)
        safe = np.where(ok[..., None, None], info, np.eye(3))
        M = np.where(ok[..., None], np.linalg.solve(safe, rhs[..., None])[..., 0], 0.0)
        r = np.maximum(np.linalg.norm(M[..., None, :] - o, axis=-1), MIN_RANGE)
    info = position_information(u, r, sigma, s)
    return M, info, ok & observable(info, s)


def fix_in_front(
    fix: ArrayLike,
    origins: ArrayLike,
    los: ArrayLike,
    mask: ArrayLike | None = None,
    min_range: float = MIN_FIX_RANGE,
) -> BoolArray:
    """Where a fix is in front of its receivers ``(...)``: ``u_k · (M − o_k) > min_range`` for
    every receiver ``k`` that sees it (``mask``, None: every receiver).

    ``fix (..., 3)``, ``origins (..., n, 3)`` and unit ``los (..., n, 3)`` in one frame, m. A
    fix behind a receiver, on it or within ``min_range`` of it (non-positive or tiny ranges
    along the measured line of sight) is what near-parallel lines of sight from (nearly)
    co-located receivers give; it must not be trusted even where :func:`observable` holds.
    """
    M = np.asarray(fix, dtype=np.float64)
    o = np.asarray(origins, dtype=np.float64)
    u = np.asarray(los, dtype=np.float64)
    ahead = np.einsum("...ki,...ki->...k", u, M[..., None, :] - o) > min_range
    if mask is not None:
        ahead = ahead | ~np.asarray(mask, dtype=bool)
    return np.all(ahead, axis=-1)
