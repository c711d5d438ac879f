"""The headroom of a benchmark: each episode's true upper bound and the normalised score.

An env with a proven bound on an episode's return (theory §11.3.1 for StereoPointing, §11.4.1
for StereoPlacement, §11.5.1 for StereoScanning, §11.8.1 for GimbalTracking) names it in :data:`EPISODE_BOUNDS`: a function
``episode_bound(params, state) -> (B,)`` of the batched simulator state an episode starts in,
which no policy's return on that episode can exceed. The platform-manoeuvre envs' bound is
the hindsight optimum (theory §11.2.1), computed once every policy has played the episode
(:data:`HINDSIGHT_BOUNDS`, :func:`add_hindsight_bounds`). The benchmark keeps each episode's
bound beside its return (:func:`~sensorgym.train.evaluation.evaluate`) and reports, per
policy,

* the bound's mean over the policy's episodes;
* the normalised score: per episode ``(R − R₀)/(B − R₀)``, averaged, with its normal 95 %
  half-width, where ``R₀`` is the env's passive rule on the same episode
  (:data:`PASSIVE_RULES`): 0 plays as the passive rule, 1 reaches the bound;
* the share of the headroom above the best rule the policy closes,
  ``(R̄ − R̄_best)/(B̄ − R̄_best)``.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Any

import numpy as np

#: env id → ``"module:function"`` of its episode bound
EPISODE_BOUNDS: dict[str, str] = {
    "sensorgym/StereoPointing-v0": "sensorgym.envs.stereo_pointing.bound:episode_bound",
    "sensorgym/StereoPointingCrowded-v0": "sensorgym.envs.stereo_pointing.bound:episode_bound",
    "sensorgym/StereoPlacement-v0": "sensorgym.envs.stereo_placement.bound:episode_bound",
    "sensorgym/StereoScanning-v0": "sensorgym.envs.stereo_scanning.bound:episode_bound",
    "sensorgym/GimbalTracking-v0": "sensorgym.envs.gimbal_tracking.bound:episode_bound",
}

#: env id → ``"module:function"`` of a bound computed after the policies have played: the
#: hindsight optimum of each episode (theory §11.2.1), started from every policy's own actions
#: on it, so that it is at least each one's return by construction. The function takes
#: ``(params, seed, keys, played, steps)`` (``played[p][e]``: policy ``p``'s actions on episode
#: ``e``) and returns ``(bound, gain)`` per episode.
HINDSIGHT_BOUNDS: dict[str, str] = {
    "sensorgym/BearingsManeuver-v0": "sensorgym.envs.bearings_maneuver.bound:benchmark_bounds",
    "sensorgym/BearingsManeuverBook-v0": "sensorgym.envs.bearings_maneuver.bound:benchmark_bounds",
}

#: env id → the rule that does nothing (score 0 of the normalised score)
PASSIVE_RULES: dict[str, str] = {
    "sensorgym/BearingsManeuver-v0": "straight-course",
    "sensorgym/BearingsManeuverBook-v0": "straight-course",
    "sensorgym/StereoPointing-v0": "hold-still",
    "sensorgym/StereoPointingCrowded-v0": "hold-still",
    "sensorgym/StereoPlacement-v0": "hold-position",
    "sensorgym/StereoScanning-v0": "full-sweep",
    "sensorgym/GimbalTracking-v0": "hold-still",
}

#: an episode whose bound exceeds the passive rule's return by less than this has no headroom:
#: it is left out of the normalised score (the ratio is undefined there)
MIN_HEADROOM = 1e-9


def episode_bound_of(env_id: str, params: Any) -> Callable[[Any], np.ndarray] | None:
    """The bound of ``env_id`` at ``params`` as a function of the batched start state, or
    ``None`` for an env without one."""
    entry = EPISODE_BOUNDS.get(env_id)
    if entry is None:
        return None
    module, _, name = entry.partition(":")
    fn = getattr(importlib.import_module(module), name)
    return lambda state: fn(params, state)


def add_hindsight_bounds(
    env_id: str, params: Any, seed: int, results: dict[str, dict[str, Any]]
) -> dict[str, Any] | None:
    """For an env of :data:`HINDSIGHT_BOUNDS`: each episode's bound, from every policy's
    recorded ``actions`` (``score(..., record_actions=True)``, one stream per episode, so all
    played the same episodes: their ``keys`` agree), written into every result as ``bounds``;
    the ``actions`` and ``keys`` are removed. Returns a summary (the optimiser's gain over the
    best start, mean and largest), or ``None`` for another env."""
    import gymnasium

    entry = HINDSIGHT_BOUNDS.get(env_id)
    if entry is None or not results:
        return None
    names = list(results)
    keys = [tuple(k) for k in results[names[0]]["keys"]]
    for name in names:
        if [tuple(k) for k in results[name]["keys"]] != keys:
            raise RuntimeError(f"{env_id}: {name} played other episodes than {names[0]}")
    module, _, fn = entry.partition(":")
    compute = getattr(importlib.import_module(module), fn)
    steps = int(gymnasium.spec(env_id).max_episode_steps)
    played = [results[name]["actions"] for name in names]
    bound, gain = compute(params, seed, keys, played, steps)
    for name in names:
        r = results[name]
        del r["actions"], r["keys"]
        r["bounds"] = [float(b) for b in bound]
    return {"method": "hindsight optimum", "gain_mean": float(np.mean(gain)),
            "gain_max": float(np.max(gain))}  # fmt: skip


def bound_violations(result: dict[str, Any], tolerance: float = 1e-6) -> list[int]:
    """The episodes (indices) of one policy's result whose return exceeds its bound by more
    than ``tolerance`` of ``max(|bound|, 1)`` (float32 rewards summed in float64)."""
    if "bounds" not in result:
        return []
    r = np.asarray(result["returns"], dtype=np.float64)
    b = np.asarray(result["bounds"], dtype=np.float64)
    slack = tolerance * np.maximum(np.abs(b), 1.0)
    return [int(i) for i in np.flatnonzero(r > b + slack)]


def headroom(
    results: dict[str, dict[str, Any]], passive: str | None, best: str | None
) -> dict[str, dict[str, Any]]:
    """Per policy of ``results`` with per-episode ``bounds``: ``bound`` (their mean),
    ``normalised`` and ``normalised_ci95`` (the mean of ``(R − R₀)/(B − R₀)`` over the
    episodes with headroom, ``R₀`` the ``passive`` rule's return on the same episode, and its
    normal 95 % half-width), ``episodes_with_headroom``, and ``closes`` (the share of the
    headroom above the ``best`` rule's mean that the policy's mean closes; ``None`` for the
    best rule itself or without one). Empty when the env has no bound or the passive rule
    was not scored."""
    if passive is None or "bounds" not in results.get(passive, {}):
        return {}
    r0 = np.asarray(results[passive]["returns"], dtype=np.float64)
    out: dict[str, dict[str, Any]] = {}
    for name, res in results.items():
        if "bounds" not in res or len(res["returns"]) != r0.size:
            continue
        r = np.asarray(res["returns"], dtype=np.float64)
        b = np.asarray(res["bounds"], dtype=np.float64)
        room = b - r0
        keep = room > MIN_HEADROOM
        z = (r[keep] - r0[keep]) / room[keep]
        std = float(z.std(ddof=1)) if z.size > 1 else 0.0
        closes = None
        if best is not None and name != best and "bounds" in results.get(best, {}):
            gap = float(np.mean(b) - results[best]["mean"])
            closes = float((res["mean"] - results[best]["mean"]) / gap) if gap > 0 else None
        out[name] = {
            "bound": float(np.mean(b)),
            "normalised": float(z.mean()) if z.size else None,
            "normalised_ci95": float(1.96 * std / np.sqrt(z.size)) if z.size else None,
            "episodes_with_headroom": int(z.size),
            "closes": closes,
        }
    return out
