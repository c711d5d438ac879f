"""Does a *state-dependent* sharing decision beat the best static one? (issue 13, StereoPointing)

``python research/stereo_pointing/pointing_sharing_state.py [--seeds 500] [--episodes 256]`` plays the same
seeded scenarios with ``plan-acquire`` (the assignment) whose receivers share as the best
static setting of :class:`~sensorgym.agents.stereo_pointing_sharing.Sharing` measured on the
tuning seeds (margin 0.5, fraction 1.0, tracks below 3 m; ``research/stereo_pointing/pointing_sharing.py``)
and with hand-made state-dependent variants of it: the static test gated, or widened, by what
the observation says (:func:`share_features`: how many other receivers the partner drone and
the own drone have, whether the receiver sees both, the time left). Every variant is a logit rule fed to
:func:`~sensorgym.agents.stereo_pointing_sharing.aims_between`, the one aiming of the rule.
Writes ``research/stereo_pointing/results/pointing_sharing_state.json``: per variant the paired difference
to the static setting (per episode, the same scenarios and noise) with its 95 % interval.

A learned sharing policy (the share bits ``pointing-plan`` took before issue 38 removed them;
``pointing_share_ars.py``) only pays if some state-dependent decision beats the static frontier
by an interval above zero; this probe is that check. The features it weighs,
:func:`share_features`, lived in ``sensorgym.agents.stereo_pointing_sharing`` until then and are
kept here as they were. Tuning seeds only (never 10000 or 31337).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from pointing_sharing import EPISODE_STEPS, paired_fields, play, tuning_args, write_rows

from sensorgym.agents.stereo_pointing import RuleView
from sensorgym.agents.stereo_pointing_sharing import (
    Sharing,
    _separation,
    aims_between,
    share_logits,
)
from sensorgym.envs.stereo_pointing.simulation import PointingParams
from sensorgym.trackers.stereo.information import observable, position_information, position_sigma

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
    params: PointingParams, view: RuleView, target: NDArray[np.int64], time_left: NDArray[Any]
) -> NDArray[np.float64]:
    """What a policy may weigh, beside
    :func:`~sensorgym.agents.stereo_pointing_sharing.share_logits`, to decide whether receiver
    ``k`` shares its drone ``t = target[:, k]`` with drone ``j``: ``(N, n, m, F)``, the names in
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


def _partner_gain(view: RuleView, target: NDArray[np.int64]) -> NDArray[np.float64]:
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


RESULTS = Path(__file__).resolve().parent / "results" / "pointing_sharing_state.json"
#: the best static setting on tuning seeds 500 and 600 (q, f, max_rms)
STATIC = Sharing(0.5, 1.0, 3.0)
#: a wide test: no margin, the whole field of view, any track below 1 km
WIDE = Sharing(0.0, 1.0, 1000.0)
#: between the two: a quarter margin, tracks below 6 m
MID = Sharing(0.25, 1.0, 6.0)
F = {name: i for i, name in enumerate(SHARE_FEATURES)}


def _gate(base: Sharing, cond: Callable) -> Callable:
    """The static test of ``base``, only where ``cond(features)``."""

    def rule(params, view, target, feats):
        return np.where(cond(feats), share_logits(params, view, target, base), -1.0)

    return rule


def _widen(wide: Sharing, cond: Callable) -> Callable:
    """The static test of :data:`STATIC`, or that of ``wide`` where ``cond(features)``."""

    def rule(params, view, target, feats):
        logits = share_logits(params, view, target, STATIC)
        extra = np.where(cond(feats), share_logits(params, view, target, wide), -1.0)
        return np.maximum(logits, extra)

    return rule


def _f(name: str) -> Callable:
    return lambda x: x[..., F[name]]


#: name → logit rule ``(params, view, target, features) → (N, n, m)``
VARIANTS: dict[str, Callable] = {
    "static (0.5, 1.0, 3)": _gate(STATIC, lambda x: np.ones(x.shape[:-1], bool)),
    "static, partner has <= 1 other receiver": _gate(STATIC, lambda x: _f("partner_receivers")(x) <= 1),
    "static, partner has >= 2 other receivers": _gate(STATIC, lambda x: _f("partner_receivers")(x) >= 2),
    "static, own drone has >= 2 other receivers": _gate(STATIC, lambda x: _f("own_receivers")(x) >= 2),
    "static, not (own has 1 other and partner >= 2)": _gate(
        STATIC, lambda x: ~((_f("own_receivers")(x) == 1) & (_f("partner_receivers")(x) >= 2))
    ),
    "static, receiver sees its own drone": _gate(STATIC, lambda x: _f("sees_own")(x) > 0),
    "static or wide where partner has <= 1 other": _widen(WIDE, lambda x: _f("partner_receivers")(x) <= 1),
    "static or mid where partner has <= 1 other": _widen(MID, lambda x: _f("partner_receivers")(x) <= 1),
    "static or wide where partner <= 1 and own >= 2 others": _widen(
        WIDE, lambda x: (_f("partner_receivers")(x) <= 1) & (_f("own_receivers")(x) >= 2)
    ),
    "static or wide where the receiver sees both": _widen(
        WIDE, lambda x: (_f("sees_own")(x) > 0) & (_f("sees_partner")(x) > 0)
    ),
    "static or mid in the last 20 % of the episode": _widen(MID, lambda x: _f("time_left")(x) < 0.2),
    "static or wide in the last 10 % of the episode": _widen(WIDE, lambda x: _f("time_left")(x) < 0.1),
    "static, partner gain > 0.05": _gate(STATIC, lambda x: _f("partner_gain")(x) > 0.05),
    "static, partner gain > 0.1": _gate(STATIC, lambda x: _f("partner_gain")(x) > 0.1),
    "static, partner gain > 0.2": _gate(STATIC, lambda x: _f("partner_gain")(x) > 0.2),
    "static or mid where partner gain > 0.2": _widen(MID, lambda x: _f("partner_gain")(x) > 0.2),
    "static or mid where partner gain > 0.4": _widen(MID, lambda x: _f("partner_gain")(x) > 0.4),
    "static or wide where partner gain > 0.4": _widen(WIDE, lambda x: _f("partner_gain")(x) > 0.4),
}  # fmt: skip


def rule_aim(params: PointingParams, rule: Callable) -> Callable:
    """``pointing_sharing.play``'s ``aim`` of a share decision ``rule(params, view, target,
    features) → (N, n) bool`` on :func:`share_features`, aimed by :func:`aims_between`."""

    def aim(view, target, t):
        left = np.full(target.shape[0], (EPISODE_STEPS - t) / EPISODE_STEPS)
        feats = share_features(params, view, target, left)
        return aims_between(params, view, target, rule(params, view, target, feats))

    return aim


def main() -> None:
    args = tuning_args(__doc__, RESULTS, [500])
    params = PointingParams()
    start = time.perf_counter()
    rows = []
    for seed in args.seeds:
        plain, _ = play(params, seed, args.episodes, None)
        static = rule_aim(params, VARIANTS["static (0.5, 1.0, 3)"])
        base, _ = play(params, seed, args.episodes, static)
        for name, rule in VARIANTS.items():
            returns, share = play(params, seed, args.episodes, rule_aim(params, rule))
            rows.append({
                "seed": seed,
                "variant": name,
                "plan_acquire": float(plain.mean()),
                "static": float(base.mean()),
                "variant_return": float(returns.mean()),
                **paired_fields(returns, base, "static"),
                "receiver_steps_shared": share,
            })  # fmt: skip
            r = rows[-1]
            print(f"seed {seed} {name}: {r['variant_return']:.3f} vs static {r['static']:.3f}, "
                  f"paired {r['paired_minus_static']:+.3f} ± {r['paired_ci95']:.3f}, "
                  f"shared {share:.3%}", flush=True)  # fmt: skip
    settings = {
        "assignment": "plan-acquire",
        "static": [STATIC.margin, STATIC.fraction, STATIC.max_rms],
        "wide": [WIDE.margin, WIDE.fraction, WIDE.max_rms],
        "mid": [MID.margin, MID.fraction, MID.max_rms],
        "episodes": args.episodes,
    }
    write_rows(args.out, settings, rows, start)


if __name__ == "__main__":
    main()
