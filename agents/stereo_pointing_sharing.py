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

A learned policy decides per receiver instead (``pointing-plan`` with ``share_bits``): its
logit is the rule's :func:`share_logits` at the receiver's :func:`share_partner` plus a linear
term of :func:`share_features`, :func:`share_inputs` collects both and :func:`decided_aims`
aims by the decisions; zero weights are the rule. Whether a state-dependent decision can beat
the best static setting at all was probed on the tuning seeds
(``research/stereo_pointing/pointing_sharing_state.py``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sensorgym.agents.stereo_pointing import _View
from sensorgym.envs.stereo_pointing.simulation import PointingParams
from sensorgym.trackers.stereo.information import observable, position_information, position_sigma

#: distance along the bisector of the aim point from the receiver, m (any positive value: the
#: slew controller turns the receiver towards the point's direction)
AIM_RANGE = 100.0


@dataclass(frozen=True)
class Sharing:
    """When a receiver aims between its drone and another one. The default is the best of the
    six settings measured on tuning seeds 500 and 600 (``research/stereo_pointing/results/pointing_sharing.json``;
    the registered rule used ``fraction = 0.97``, the best of the first four, until the finer
    settings measured since scored about 0.2 higher)."""

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
    params: PointingParams, view: _View, target: NDArray[np.int64], sharing: Sharing
) -> NDArray[np.float64]:
    """How well each drone fits beside each receiver's own one, ``(N, n, m)``: positive exactly
    when the rule of :func:`shared_aims` may share receiver ``k``'s drone ``target[:, k]`` with
    drone ``j``. The smallest of three slacks, each zero at its threshold: the fit margin
    ``(2 f fov − ∠ − 2 q max(σ̂_j/r_kj, σ̂_t/r_kt)) / (2 fov)`` and, per track, ``(max_rms −
    σ̂) / max_rms``; ``−inf`` for the own drone and a drone on the receiver or with the own drone
    on it (no line of sight). The one formula of the rule's test; a learned policy adds its
    term to it (:func:`share_features`)."""
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
    view: _View, target: NDArray[np.int64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Each receiver's line of sight to its own drone ``(N, n, 3)`` and its angle to the line
    of sight to every drone ``(N, n, m)``, rad."""
    rows, receivers = np.arange(target.shape[0])[:, None], np.arange(target.shape[1])[None]
    own = view.los[rows, receivers, target]
    return own, np.arccos(np.clip(np.einsum("nkc,nkjc->nkj", own, view.los), -1.0, 1.0))


def _shareable(view: _View, target: NDArray[np.int64]) -> NDArray[np.bool_]:
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
    params: PointingParams, view: _View, target: NDArray[np.int64], logits: NDArray[np.float64]
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
    params: PointingParams, view: _View, target: NDArray[np.int64], sharing: Sharing
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Aim points ``(N, m + n, 3)`` and the index of each receiver's point ``(N, n)`` for
    :func:`~sensorgym.envs.stereo_pointing.simulation.slew_actions`: the drones' predictions,
    then per receiver a point on the bisector of the lines of sight to its drone ``target[:, k]``
    and to the nearest other drone for which ``∠ + 2 q max(σ̂_j/r_kj, σ̂_t/r_kt) < 2 f fov``
    with both tracks' RMS below ``max_rms`` (:func:`share_logits` positive); a receiver with no
    such drone keeps its own drone's prediction. A drone on the receiver (no line of sight) is
    never shared."""
    return aims_between(params, view, target, share_logits(params, view, target, sharing))


#: names of :func:`share_features`' last axis, in order
SHARE_FEATURES = (
    "bias",
    "partner_receivers",
    "own_receivers",
    "partner_rms",
    "own_rms",
    "slack",
    "angular_rms",
    "sees_own",
    "sees_partner",
    "time_left",
    "partner_gain",
)
#: cap of the ``partner_gain`` feature (a drone that no receiver fixes without ``k``)
GAIN_CAP = 5.0
#: track RMS (m) at which the RMS features saturate at 1
RMS_SCALE = 10.0


def share_features(
    params: PointingParams, view: _View, target: NDArray[np.int64], time_left: NDArray[Any]
) -> NDArray[np.float64]:
    """What a policy may weigh, beside :func:`share_logits`, to decide whether receiver ``k``
    shares its drone ``t = target[:, k]`` with drone ``j``: ``(N, n, m, F)``, the names in
    :data:`SHARE_FEATURES`, each of order 1. 1; how many *other* receivers are sent to ``j``,
    and to ``t``; ``min(σ̂, RMS_SCALE) / RMS_SCALE`` of ``j``'s and of ``t``'s track; the
    geometric slack ``(2 fov − ∠) / (2 fov)`` (no margin); the larger angular RMS of the two
    tracks from ``k`` over ``2 fov`` (capped at 10), the unit of the rule's margin; whether
    ``k`` saw ``t``, and ``j``, on the last step; the fraction ``time_left (N,)`` of the episode
    left; ``partner_gain``, ``ln(σ_without / σ_with)`` of drone ``j``'s position bound from the
    other receivers sent to it without and with ``k``'s line of sight (theory §4.4, at the
    predicted positions; in ``[0, GAIN_CAP]``, the cap where they alone do not fix it): the
    reward ``k`` adds to ``j`` while it sees both. Read off the observation and the step count
    only."""
    N, n, m = target.shape[0], params.n_receivers, params.n_drones
    left = np.asarray(time_left, dtype=np.float64)
    if left.shape != (N,):
        raise ValueError(f"time_left: expected shape ({N},), got {left.shape}")
    rows, receivers = np.arange(N)[:, None], np.arange(n)[None]
    sent = (target[..., None] == np.arange(m)[None, None]).astype(np.float64)  # (N, n, m)
    partner = sent.sum(axis=1, keepdims=True) - sent  # other receivers sent to j
    own = np.take_along_axis(partner, target[..., None], axis=2)  # other receivers sent to t
    rms = np.minimum(view.sigma, RMS_SCALE) / RMS_SCALE  # (N, m)
    _, separation = _separation(view, target)
    width = 2.0 * params.fov
    angular = view.sigma[:, None, :] / view.ranges
    angular = np.maximum(angular, np.take_along_axis(angular, target[..., None], axis=2))
    sees_own = view.seen[rows, receivers, target]
    shape = (N, n, m)
    return np.stack(
        [
            np.ones(shape),
            partner,
            np.broadcast_to(own, shape),
            np.broadcast_to(rms[:, None, :], shape),
            np.broadcast_to(rms[rows, target][..., None], shape),
            (width - separation) / width,
            np.minimum(angular / width, 10.0),
            np.broadcast_to(sees_own[..., None], shape),
            view.seen,
            np.broadcast_to(left[:, None, None], shape),
            _partner_gain(view, target),
        ],
        axis=-1,
    )


def _partner_gain(view: _View, target: NDArray[np.int64]) -> NDArray[np.float64]:
    """``(N, n, m)``: ``ln(σ_without / σ_with)`` of drone ``j``'s position bound (theory §4.4)
    from the receivers other than ``k`` sent to it, without and with ``k``'s line of sight,
    in ``[0, GAIN_CAP]``; 0 for ``k``'s own drone."""
    N, n, m = view.ranges.shape
    sent = target[..., None] == np.arange(m)[None, None]  # (N, n', m)
    others = sent.transpose(0, 2, 1)[:, None] & ~np.eye(n, dtype=bool)[None, :, None]
    receiver = np.broadcast_to(np.eye(n, dtype=bool)[None, :, None], (N, n, m, n))
    los = view.los.transpose(0, 2, 1, 3)[:, None]  # (N, 1, m, n', 3)
    ranges = np.where(np.isfinite(view.ranges), view.ranges, 1.0).transpose(0, 2, 1)[:, None]
    visible = np.isfinite(view.ranges).transpose(0, 2, 1)[:, None]

    def bound(mask: NDArray[np.bool_]) -> NDArray[np.float64]:
        mask = mask & visible
        info = position_information(los, ranges, 1.0, mask)
        return position_sigma(info, observable(info, mask))

    without, with_k = bound(others), bound(others | receiver)
    with np.errstate(divide="ignore", invalid="ignore"):
        gain = np.log(without / with_k)
    gain = np.where(np.isfinite(with_k), np.nan_to_num(gain, nan=0.0, posinf=GAIN_CAP), 0.0)
    gain = np.clip(gain, 0.0, GAIN_CAP)
    return np.where(sent, 0.0, gain)


def share_partner(
    view: _View, target: NDArray[np.int64], logits: NDArray[np.float64]
) -> NDArray[np.int64]:
    """The drone ``(N, n)`` receiver ``k`` would share its own with: the one
    :func:`aims_between` picks for ``logits`` (the nearest with a positive logit) or, when none
    is positive, the nearest other drone in sight; ``-1`` when no other drone is in sight."""
    _, separation = _separation(view, target)
    shareable = _shareable(view, target)
    fits = shareable & (logits > 0.0)
    near_fit = np.where(fits, separation, np.inf).argmin(axis=2)
    near = np.where(shareable, separation, np.inf).argmin(axis=2)
    partner = np.where(fits.any(axis=2), near_fit, near)
    return np.where(shareable.any(axis=2), partner, -1)


#: per receiver, the inputs of a learned share decision: the rule's logit, then the features
SHARE_INPUTS = ("rule_logit", *SHARE_FEATURES)
#: the rule's logit as an input is clipped to ``[LOGIT_FLOOR, 1]`` (its sign kept)
LOGIT_FLOOR = -10.0


def share_inputs(
    params: PointingParams,
    view: _View,
    target: NDArray[np.int64],
    sharing: Sharing,
    time_left: NDArray[Any],
) -> NDArray[np.float64]:
    """``(N, n, len(SHARE_INPUTS))``: per receiver, the rule's :func:`share_logits` (clipped to
    ``[LOGIT_FLOOR, 1]``) and :func:`share_features` with its :func:`share_partner`; the floor
    and zero features where no other drone is in sight. A learned decision shares exactly when
    the logit plus its term is positive (zero term: the rule of :func:`shared_aims`)."""
    logits = share_logits(params, view, target, sharing)
    partner = share_partner(view, target, logits)
    at = np.maximum(partner, 0)[..., None]
    rule = np.take_along_axis(logits, at, axis=2)[..., 0]
    feats = np.take_along_axis(share_features(params, view, target, time_left), at[..., None], 2)
    none = partner < 0
    rule = np.where(none, LOGIT_FLOOR, np.clip(rule, LOGIT_FLOOR, 1.0))
    feats = np.where(none[..., None], 0.0, feats[:, :, 0])
    return np.concatenate([rule[..., None], feats], axis=-1)


def decided_aims(
    params: PointingParams,
    view: _View,
    target: NDArray[np.int64],
    sharing: Sharing,
    share: NDArray[Any],
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """:func:`aims_between` where receiver ``k`` shares with its :func:`share_partner` exactly
    when ``share[:, k]`` (``(N, n)``, 0/1): with ``share`` the rule's own decisions (its
    logit at the partner positive) the aims are :func:`shared_aims`'."""
    share = np.asarray(share)
    if share.shape != target.shape:
        raise ValueError(f"share: expected shape {target.shape}, got {share.shape}")
    partner = share_partner(view, target, share_logits(params, view, target, sharing))
    m = params.n_drones
    chosen = (np.arange(m)[None, None] == partner[..., None]) & (share[..., None] > 0)
    return aims_between(params, view, target, np.where(chosen, 1.0, -1.0))
