"""One receiver, two drones: aim between two predictions that fit in one field of view
(``sensorgym/StereoPointing-v0``, the ``plan-acquire-share`` rule).

The assignment rules send each receiver to one drone and slew it straight at that drone's
prediction (:func:`~sensorgym.envs.stereo_pointing.simulation.slew_actions`). When another
drone's prediction lies close to it, seen from that receiver, the receiver can hold both: aimed
at the bisector of the two lines of sight, it adds a line of sight to the second drone without
losing the first, and the reward counts every receiver that sees a drone (its Cramér–Rao bound,
theory §4.4). :func:`shared_aims` turns an assignment into such aim points; the margin keeps
both drones inside the field of view despite the tracks' error. Measured on the tuning seeds
(``research/stereo_pointing/pointing_sharing.py``, ``research/stereo_pointing/results/pointing_sharing.json``).

A state-dependent decision per receiver found no room beyond this static test on the tuning
seeds, neither by hand nor learned by ARS (``research/stereo_pointing/README.md``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from sensorgym.agents.stereo_pointing import RuleView
from sensorgym.envs.stereo_pointing.simulation import PointingParams

#: distance along the bisector of the aim point from the receiver, m (any positive value: the
#: slew controller turns the receiver towards the point's direction)
AIM_RANGE = 100.0


@dataclass(frozen=True)
class Sharing:
    """When a receiver aims between its drone and another one. The default is the best of the
    six settings measured on tuning seeds 500 and 600 (``research/stereo_pointing/results/pointing_sharing.json``;
    the registered rule used ``fraction = 0.97``, the best of the first four, until the finer
    settings measured since scored higher)."""

    margin: float = 0.5
    """``q``: the two lines of sight must lie closer than the field of view's width less ``2 q``
    times the larger of the two tracks' angular RMS from the receiver (``σ̂/r``)."""
    fraction: float = 1.0
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


def share_logits(
    params: PointingParams, view: RuleView, target: NDArray[np.int64], sharing: Sharing
) -> NDArray[np.float64]:
    """How well each drone fits beside each receiver's own one, ``(N, n, m)``: positive exactly
    when the rule of :func:`shared_aims` may share receiver ``k``'s drone ``target[:, k]`` with
    drone ``j``. The smallest of three slacks, each zero at its threshold: the fit margin
    ``(2 f fov − ∠ − 2 q max(σ̂_j/r_kj, σ̂_t/r_kt)) / (2 fov)`` and, per track, ``(max_rms −
    σ̂) / max_rms``; ``−inf`` for the own drone and a drone on the receiver or with the own drone
    on it (no line of sight). The one formula of the rule's test."""
    rows = np.arange(target.shape[0])[:, None]
    _, separation = _separation(view, target)
    angular_rms = view.sigma[:, None, :] / view.ranges  # (N, n, m); 0 for no line of sight
    own_rms = np.take_along_axis(angular_rms, target[..., None], axis=2)
    width = 2.0 * params.fov
    fit = (
        width * sharing.fraction
        - separation
        - 2.0 * sharing.margin * np.maximum(angular_rms, own_rms)
    ) / width
    scale = sharing.max_rms if sharing.max_rms > 0.0 else 1.0
    partner_track = (sharing.max_rms - view.sigma[:, None, :]) / scale  # (N, 1, m)
    own_track = (sharing.max_rms - view.sigma[rows, target]) / scale  # (N, n)
    logits = np.minimum(np.minimum(fit, partner_track), own_track[..., None])
    return np.where(_shareable(view, target), logits, -np.inf)


def _separation(
    view: RuleView, target: NDArray[np.int64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Each receiver's line of sight to its own drone ``(N, n, 3)`` and its angle to the line
    of sight to every drone ``(N, n, m)``, rad."""
    rows, receivers = np.arange(target.shape[0])[:, None], np.arange(target.shape[1])[None]
    own = view.los[rows, receivers, target]
    return own, np.arccos(np.clip(np.einsum("nkc,nkjc->nkj", own, view.los), -1.0, 1.0))


def _shareable(view: RuleView, target: NDArray[np.int64]) -> NDArray[np.bool_]:
    """``(N, n, m)``: drone ``j`` is another drone than receiver ``k``'s own, and the receiver
    has a line of sight to both (neither predicted on it)."""
    m = view.ranges.shape[2]
    other = np.arange(m)[None, None] != target[..., None]
    return (
        other
        & np.isfinite(view.ranges)
        & np.isfinite(np.take_along_axis(view.ranges, target[..., None], 2))
    )


def aims_between(
    params: PointingParams, view: RuleView, target: NDArray[np.int64], logits: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Aim points ``(N, m + n, 3)`` and each receiver's point index ``(N, n)`` for
    :func:`~sensorgym.envs.stereo_pointing.simulation.slew_actions`: the drones' predictions,
    then per receiver the bisector of the lines of sight to its drone ``target[:, k]`` and to
    the nearest (smallest angle) other drone ``j`` with ``logits[:, k, j] > 0``; a receiver
    with none keeps its drone's prediction. Drones :func:`_shareable` excludes never count."""
    N, n, m = target.shape[0], params.n_receivers, params.n_drones
    if logits.shape != (N, n, m):
        raise ValueError(f"logits: expected shape {(N, n, m)}, got {logits.shape}")
    rows, receivers = np.arange(N)[:, None], np.arange(n)[None]
    own, separation = _separation(view, target)
    fits = (logits > 0.0) & _shareable(view, target)
    other = np.where(fits, separation, np.inf).argmin(axis=2)  # (N, n)
    bisector = own + view.los[rows, receivers, other]
    bisector /= np.maximum(np.linalg.norm(bisector, axis=-1, keepdims=True), 1e-12)
    aims = params._receivers[None] + AIM_RANGE * bisector
    index = np.where(fits.any(axis=2), m + np.arange(n)[None], target)
    return np.concatenate([view.position, aims], axis=1), index


def shared_aims(
    params: PointingParams, view: RuleView, target: NDArray[np.int64], sharing: Sharing
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Aim points ``(N, m + n, 3)`` and the index of each receiver's point ``(N, n)`` for
    :func:`~sensorgym.envs.stereo_pointing.simulation.slew_actions`: the drones' predictions,
    then per receiver a point on the bisector of the lines of sight to its drone ``target[:, k]``
    and to the nearest other drone for which ``∠ + 2 q max(σ̂_j/r_kj, σ̂_t/r_kt) < 2 f fov``
    with both tracks' RMS below ``max_rms`` (:func:`share_logits` positive); a receiver with no
    such drone keeps its own drone's prediction. A drone on the receiver (no line of sight) is
    never shared."""
    return aims_between(params, view, target, share_logits(params, view, target, sharing))
