"""One receiver, two drones: aim between two predictions that fit in one field of view
(``sensorgym/StereoPointing-v0``, the ``plan-acquire-share`` rule).

The assignment rules send each receiver to one drone and slew it straight at that drone's
prediction (:func:`~sensorgym.envs.stereo_pointing.simulation.slew_actions`). When another
drone's prediction lies close to it, seen from that receiver, the receiver can hold both: aimed
at the bisector of the two lines of sight, it adds a line of sight to the second drone without
losing the first, and the reward counts every receiver that sees a drone (its Cramér–Rao bound,
theory §4.4). :func:`shared_aims` turns an assignment into such aim points; the margin keeps
both drones inside the field of view despite the tracks' error. Measured on the tuning seeds
(``benchmarks/pointing_sharing.py``, ``benchmarks/results/pointing_sharing.json``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from sensorgym.agents.stereo_pointing import _View
from sensorgym.envs.stereo_pointing.simulation import PointingParams

#: distance along the bisector of the aim point from the receiver, m (any positive value: the
#: slew controller turns the receiver towards the point's direction)
AIM_RANGE = 100.0


@dataclass(frozen=True)
class Sharing:
    """When a receiver aims between its drone and another one. The registered setting was the
    best of four on tuning seeds 500 and 600 (``benchmarks/results/pointing_sharing.json``)."""

    margin: float = 0.5
    """``q``: the two lines of sight must lie closer than the field of view's width less ``2 q``
    times the larger of the two tracks' angular RMS from the receiver (``σ̂/r``)."""
    fraction: float = 0.97
    """``f``: the share of the field of view's full width ``2 fov`` the two may span."""
    max_rms: float = 3.0
    """Largest track RMS position error ``σ̂`` of either drone, m: a worse track is not shared."""

    def __post_init__(self) -> None:
        for name in ("margin", "fraction", "max_rms"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0.0):
                raise ValueError(f"{name}: must be finite and >= 0, got {value!r}")
        if self.fraction > 1.0:
            raise ValueError(f"fraction: at most 1 (the whole field of view), got {self.fraction}")


def shared_aims(
    params: PointingParams, view: _View, target: NDArray[np.int64], sharing: Sharing
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Aim points ``(N, m + n, 3)`` and the index of each receiver's point ``(N, n)`` for
    :func:`~sensorgym.envs.stereo_pointing.simulation.slew_actions`: the drones' predictions,
    then per receiver a point on the bisector of the lines of sight to its drone ``target[:, k]``
    and to the nearest other drone for which ``∠ + 2 q max(σ̂_j/r_kj, σ̂_t/r_kt) < 2 f fov``
    with both tracks' RMS below ``max_rms``; a receiver with no such drone keeps its own
    drone's prediction. A drone on the receiver (no line of sight) is never shared."""
    N, n, m = target.shape[0], params.n_receivers, params.n_drones
    rows, receivers = np.arange(N)[:, None], np.arange(n)[None]
    own = view.los[rows, receivers, target]  # (N, n, 3)
    separation = np.arccos(np.clip(np.einsum("nkc,nkjc->nkj", own, view.los), -1.0, 1.0))
    angular_rms = view.sigma[:, None, :] / view.ranges  # (N, n, m); 0 for no line of sight
    own_rms = np.take_along_axis(angular_rms, target[..., None], axis=2)
    fits = (
        separation + 2.0 * sharing.margin * np.maximum(angular_rms, own_rms)
        < 2.0 * params.fov * sharing.fraction
    )
    fits &= (view.sigma[:, None, :] < sharing.max_rms) & (
        view.sigma[rows, target] < sharing.max_rms
    )[..., None]
    fits &= np.arange(m)[None, None] != target[..., None]
    fits &= np.isfinite(view.ranges) & np.isfinite(
        np.take_along_axis(view.ranges, target[..., None], 2)
    )
    other = np.where(fits, separation, np.inf).argmin(axis=2)  # (N, n)
    bisector = own + view.los[rows, receivers, other]
    bisector /= np.maximum(np.linalg.norm(bisector, axis=-1, keepdims=True), 1e-12)
    aims = params._receivers[None] + AIM_RANGE * bisector
    index = np.where(fits.any(axis=2), m + np.arange(n)[None], target)
    return np.concatenate([view.position, aims], axis=1), index
