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

Each formula is written once, as a compiled primitive of :mod:`.kernels`; the functions here
broadcast their inputs, flatten the batch and loop over it in compiled code. (The numpy forms
:func:`position_sigma` and :func:`log_ratio_reward` kept until issue 11 rounded differently
from the compiled ones in the last bits — LAPACK's inverse, numpy's SIMD logarithm — within
1e-13 relative; no recorded episode passes through them any more.)
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sensorgym.trackers.kernel_args import kernel_array
from sensorgym.trackers.stereo import kernels
from sensorgym.trackers.stereo.kernels import CONDITION, MIN_FIX_RANGE, MIN_RANGE

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

__all__ = [
    "CONDITION",
    "MAX_REWARD_CLIP",
    "MIN_FIX_RANGE",
    "MIN_RANGE",
    "fix_in_front",
    "log_ratio_reward",
    "observable",
    "position_information",
    "position_sigma",
    "weighted_fix",
]

#: largest clip ``R`` of :func:`log_ratio_reward` an env accepts: sums of ``±R`` over drones and
#: episodes stay finite
MAX_REWARD_CLIP = 1e6


def _flat(value: ArrayLike, shape: tuple[int, ...], dtype=np.float64) -> np.ndarray:
    """``value`` broadcast to ``shape`` as a kernel input (:func:`kernel_array`), the batch axes
    ``shape[:-k]`` flattened by the caller's reshape."""
    return kernel_array(value, shape, dtype)


def _views(mask: ArrayLike | None, shape: tuple[int, ...]) -> np.ndarray:
    """``mask`` broadcast to ``shape`` (None: every receiver sees) as C-contiguous bools."""
    if mask is None:
        return np.ones(shape, dtype=bool)
    return _flat(mask, shape, bool)


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
    r = np.asarray(ranges, dtype=np.float64)
    s, m = np.asarray(sigma, dtype=np.float64), None if mask is None else np.asarray(mask, bool)
    batch = np.broadcast_shapes(u.shape[:-1], r.shape, s.shape, () if m is None else m.shape)
    n = batch[-1]
    out = np.empty((*batch[:-1], 3, 3))
    kernels.position_information_batch(
        _flat(u, (*batch, 3)).reshape(-1, n, 3),
        _flat(r, batch).reshape(-1, n),
        _flat(s, batch).reshape(-1, n),
        _views(m, batch).reshape(-1, n),
        out.reshape(-1, 3, 3),
    )
    return out


def observable(information: ArrayLike, mask: ArrayLike | None = None) -> BoolArray:
    """Where the position is observable ``(...)``: ``det I > CONDITION · (tr I)³`` and, with a
    ``mask (..., n)``, at least two receivers see the point."""
    info = np.asarray(information, dtype=np.float64)
    if mask is None:
        batch = info.shape[:-2]
        views = np.full(batch, 3, dtype=np.int64)  # no mask: the determinant test alone
    else:
        m = np.asarray(mask, dtype=bool)
        batch = np.broadcast_shapes(info.shape[:-2], m.shape[:-1])
        views = np.broadcast_to(np.sum(m, axis=-1), batch)
    out = np.empty(batch, dtype=bool)
    kernels.observable_batch(
        _flat(info, (*batch, 3, 3)).reshape(-1, 3, 3),
        _flat(views, batch, np.int64).reshape(-1),
        out.reshape(-1),
    )
    return out


def position_sigma(information: ArrayLike, ok: ArrayLike, sigma: float = 1.0) -> FloatArray:
    """Position RMS bound ``σ √tr I⁻¹`` ``(...)`` (m) where ``ok``; ``+inf`` elsewhere (the
    documented value of an unobservable position). ``sigma`` scales a geometry part
    ``G = σ² I`` (pass the information itself with the default 1)."""
    info = np.asarray(information, dtype=np.float64)
    good = np.asarray(ok, dtype=bool)
    batch = np.broadcast_shapes(info.shape[:-2], good.shape)
    out = np.empty(batch)
    # σ √tr I⁻¹ (kernels.position_sigma)
    kernels.position_sigma_batch(
        _flat(info, (*batch, 3, 3)).reshape(-1, 3, 3),
        _flat(good, batch, bool).reshape(-1),
        np.full(out.size, float(sigma)),
        out.reshape(-1),
    )
    return out


def log_ratio_reward(sigma_pos: ArrayLike, sigma_ref: float, clip: float) -> FloatArray:
    """``clip(ln(σ_ref / σ_pos), −R, R)`` elementwise (theory §11.1): ``+R`` for an exact fix
    (``σ_pos = 0``), ``−R`` where ``σ_pos`` is ``inf`` or NaN (no fix) — always finite."""
    s = np.asarray(sigma_pos, dtype=np.float64)
    out = np.empty(s.shape)
    # clip(ln σ_ref − ln σ_pos, −R, R)  (kernels.log_ratio_reward)
    kernels.log_ratio_reward_batch(
        np.ascontiguousarray(s).reshape(-1), float(sigma_ref), float(clip), out.reshape(-1)
    )
    return out


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
    if iterations < 1:
        raise ValueError(f"iterations: must be at least 1, got {iterations}")
    o = np.asarray(origins, dtype=np.float64)
    u = np.asarray(los, dtype=np.float64)
    s, m = np.asarray(sigma, dtype=np.float64), None if mask is None else np.asarray(mask, bool)
    batch = np.broadcast_shapes(o.shape[:-1], u.shape[:-1], s.shape, () if m is None else m.shape)
    n = batch[-1]
    M = np.empty((*batch[:-1], 3))
    info = np.empty((*batch[:-1], 3, 3))
    ok = np.empty(batch[:-1], dtype=bool)
    kernels.weighted_fix_batch(
        _flat(o, (*batch, 3)).reshape(-1, n, 3),
        _flat(u, (*batch, 3)).reshape(-1, n, 3),
        _views(m, batch).reshape(-1, n),
        _flat(s, batch).reshape(-1, n),
        int(iterations),
        M.reshape(-1, 3),
        info.reshape(-1, 3, 3),
        ok.reshape(-1),
    )
    return M, info, ok


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
    m = None if mask is None else np.asarray(mask, dtype=bool)
    batch = np.broadcast_shapes(
        (*M.shape[:-1], 1), o.shape[:-1], u.shape[:-1], () if m is None else m.shape
    )
    n = batch[-1]
    out = np.empty(batch[:-1], dtype=bool)
    kernels.fix_in_front_batch(
        _flat(M, (*batch[:-1], 3)).reshape(-1, 3),
        _flat(o, (*batch, 3)).reshape(-1, n, 3),
        _flat(u, (*batch, 3)).reshape(-1, n, 3),
        _views(m, batch).reshape(-1, n),
        float(min_range),
        out.reshape(-1),
    )
    return out
