"""Room the assignment rules of ``sensorgym/StereoPointing-v0`` leave: one receiver, two drones.

``python benchmarks/pointing_sharing.py [--seeds 500 600] [--episodes 256]`` plays the same
seeded scenarios with ``plan-acquire`` and with ``plan-acquire`` whose receivers aim, when they
can, between the drone they are sent to and another one: a receiver whose lines of sight to two
predicted drones are closer than the field of view's width (less a margin for the tracks'
uncertainty) slews onto their bisector instead, so that one receiver fixes both. The
assignment rules never do this: their slew controller aims at one prediction. Writes
``benchmarks/results/pointing_sharing.json``: per setting the paired difference to
``plan-acquire`` (per episode, the same scenarios and noise) and the share of receiver-steps
that aimed between two drones.

A probe, not a registered rule: it measures how much return fine pointing holds beyond the
choice of assignment (issue 13). Tuning seeds only (never 10000 or 31337).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from sensorgym.agents.stereo_pointing import _view
from sensorgym.agents.stereo_pointing_horizon import PlanHorizon
from sensorgym.envs.stereo_pointing import simulation
from sensorgym.envs.stereo_pointing.simulation import (
    PointingParams,
    observed_pointing,
    slew_actions,
)

RESULTS = Path(__file__).resolve().parent / "results" / "pointing_sharing.json"
EPISODE_STEPS = 150

#: (margin in the tracks' angular RMS, fraction of the field of view's width, largest track RMS
#: in m): the settings measured
SETTINGS = ((1.0, 0.9, 0.5), (1.0, 1.0, 0.5), (1.0, 0.9, 3.0), (0.5, 0.97, 3.0))


def shared_targets(
    params: PointingParams,
    obs: np.ndarray,
    target: np.ndarray,
    margin: float,
    fraction: float,
    max_sigma: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Aim points ``(B, m + n, 3)`` and per-receiver indices into them ``(B, n)``: the drones'
    predictions, then per receiver the bisector of its drone and the nearest other drone
    that fits in its field of view with both predictions (``sep + 2 q σ_ang < 2 f fov``, both
    tracks' RMS below ``max_sigma``); the receiver keeps its drone's prediction otherwise."""
    v = _view(params, obs.astype(np.float64))
    _, _, points = observed_pointing(params, obs)
    B, n, m = target.shape[0], params.n_receivers, params.n_drones
    rows = np.arange(B)[:, None]
    recv = np.arange(n)[None]
    u_own = v.los[rows, recv, target]  # (B, n, 3)
    cos_sep = np.einsum("bkc,bkjc->bkj", u_own, v.los)
    sep = np.arccos(np.clip(cos_sep, -1.0, 1.0))  # (B, n, m)
    ang_sigma = v.sigma[:, None, :] / v.ranges  # (B, n, m)
    own_sigma = np.take_along_axis(ang_sigma, target[..., None], axis=2)
    fits = sep + margin * 2.0 * np.maximum(ang_sigma, own_sigma) < 2.0 * params.fov * fraction
    fits &= (v.sigma[:, None, :] < max_sigma) & (v.sigma[rows, target] < max_sigma)[..., None]
    fits &= np.arange(m)[None, None] != target[..., None]
    fits &= np.isfinite(v.ranges)
    other = np.where(fits, sep, np.inf).argmin(axis=2)  # (B, n)
    share = fits.any(axis=2)
    bisector = u_own + v.los[rows, recv, other]
    bisector /= np.maximum(np.linalg.norm(bisector, axis=-1, keepdims=True), 1e-12)
    aims = params._receivers[None] + 100.0 * bisector  # a point along the bisector
    index = np.where(share, m + np.arange(n)[None], target)
    return np.concatenate([points, aims], axis=1), index


def play(params: PointingParams, seed: int, batch: int, setting: tuple | None) -> tuple:
    """Returns ``(returns (B,), share of receiver-steps aimed between two drones)``."""
    rule = PlanHorizon(params, acquisition=True)
    rng = np.random.default_rng(seed)
    state = simulation.reset(params, rng, batch)
    obs = simulation.observe(params, state)
    total, shared = np.zeros(batch), 0
    for t in range(EPISODE_STEPS):
        target = rule.assign(obs, np.full(batch, t))
        azimuth, elevation, points = observed_pointing(params, obs)
        if setting is not None:
            points, target = shared_targets(params, obs, target, *setting)
            shared += int((target >= params.n_drones).sum())
        action = slew_actions(params, azimuth, elevation, points, target)
        state, reward, _ = simulation.step(params, state, action, rng)
        obs = simulation.observe(params, state)
        total += reward
    return total, shared / (batch * EPISODE_STEPS * params.n_receivers)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[500, 600])
    ap.add_argument("--episodes", type=int, default=256)
    ap.add_argument("--out", type=Path, default=RESULTS)
    args = ap.parse_args()
    if any(s >= 10_000 for s in args.seeds):
        raise SystemExit("seeds: tuning seeds only (< 10000); 10000 and up are held out")
    params = PointingParams()
    start = time.perf_counter()
    rows = []
    for seed in args.seeds:
        base, _ = play(params, seed, args.episodes, None)
        for setting in SETTINGS:
            returns, share = play(params, seed, args.episodes, setting)
            d = returns - base
            rows.append({
                "seed": seed,
                "margin_sigmas": setting[0], "fov_fraction": setting[1], "max_track_rms_m": setting[2],
                "plan_acquire": float(base.mean()),
                "shared": float(returns.mean()),
                "paired_minus_plan_acquire": float(d.mean()),
                "paired_ci95": float(1.96 * d.std(ddof=1) / np.sqrt(d.size)),
                "episodes_above": float((d > 1e-9).mean()),
                "episodes_below": float((d < -1e-9).mean()),
                "receiver_steps_shared": share,
            })  # fmt: skip
            r = rows[-1]
            print(f"seed {seed} q {setting[0]} f {setting[1]} σmax {setting[2]}: "
                  f"{r['shared']:.2f} vs {r['plan_acquire']:.2f}, paired "
                  f"{r['paired_minus_plan_acquire']:+.2f} ± {r['paired_ci95']:.2f}, "
                  f"shared {share:.3%} of receiver-steps")  # fmt: skip
    out = {
        "settings": {
            "env": "sensorgym/StereoPointing-v0",
            "rule": "plan-acquire",
            "episodes": args.episodes,
            "seconds": round(time.perf_counter() - start, 1),
        },
        "rows": rows,
    }
    args.out.write_text(json.dumps(out, indent=1) + "\n")


if __name__ == "__main__":
    main()
