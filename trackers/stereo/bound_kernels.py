"""Compiled position information and bound of :mod:`.information`, one point at a time.

The formulas and constants are those of :mod:`.information` (theory §4.1–4.3), for the envs'
fused step kernels; the batched numpy functions there remain the reference (and are tested
equal to these to rounding). A 3×3 symmetric matrix is held as its six distinct entries
``(xx, yy, zz, xy, xz, yz)``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from sensorgym.trackers.stereo.information import CONDITION, MIN_RANGE


@njit(inline="always")
def add_line_of_sight(G, u, r, sigma):
    """``G + (I − u uᵀ)/(σ² r²)`` (one receiver's term of ``I(M)``, range floored at
    ``MIN_RANGE``)."""
    rr = max(r, MIN_RANGE)
    w = 1.0 / (sigma * rr) ** 2
    return (
        G[0] + w * (1.0 - u[0] * u[0]),
        G[1] + w * (1.0 - u[1] * u[1]),
        G[2] + w * (1.0 - u[2] * u[2]),
        G[3] - w * (u[0] * u[1]),
        G[4] - w * (u[0] * u[2]),
        G[5] - w * (u[1] * u[2]),
    )


@njit(inline="always")
def position_sigma3(G, sigma):
    """``σ √tr G⁻¹`` where observable (``det G > CONDITION (tr G)³``), else ``+inf``.

    ``tr G⁻¹ = (C_xx + C_yy + C_zz)/det G`` with ``C`` the diagonal cofactors.
    """
    xx, yy, zz, xy, xz, yz = G
    cxx = yy * zz - yz * yz
    cyy = xx * zz - xz * xz
    czz = xx * yy - xy * xy
    det = xx * cxx - xy * (xy * zz - yz * xz) + xz * (xy * yz - yy * xz)
    tr = xx + yy + zz
    if not det > CONDITION * tr**3:
        return np.inf
    return sigma * np.sqrt(max((cxx + cyy + czz) / det, 0.0))


@njit(inline="always")
def log_ratio_reward1(sigma_pos, sigma_ref, clip):
    """``clip(ln(σ_ref/σ_pos), −R, R)``; ``+R`` for ``σ_pos = 0``, ``−R`` for inf or NaN."""
    if not np.isfinite(sigma_pos):
        return -clip
    if not sigma_pos > 0.0:
        return clip
    return min(max(np.log(sigma_ref) - np.log(sigma_pos), -clip), clip)
