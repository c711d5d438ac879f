"""Room the assignment rules of ``sensorgym/StereoPointing-v0`` leave: one receiver, two drones.

``python research/stereo_pointing/pointing_sharing.py [--seeds 500 600] [--episodes 256]`` plays the same
seeded scenarios with ``plan-acquire`` and with ``plan-acquire`` whose receivers aim, when they
can, between the drone they are sent to and another one
(:func:`sensorgym.agents.stereo_pointing_sharing.shared_aims`; the ``plan-acquire-share``
rule was registered with the fourth setting, the best of the first four; the last two,
measured afterwards, are finer steps around it, and the fifth, the best of all six, is its
default since): a receiver whose lines of sight to two
predicted drones are closer than the field of view's width (less a margin for the tracks'
uncertainty) slews onto their bisector instead, so that one receiver fixes both. The
assignment rules never do this: their slew controller aims at one prediction. Writes
``research/stereo_pointing/results/pointing_sharing.json``: per setting the paired difference to
``plan-acquire`` (per episode, the same scenarios and noise) and the share of receiver-steps
that aimed between two drones.

It measured how much return fine pointing holds beyond the choice of assignment (issue 13),
and chose the rule's setting. Tuning seeds only (never 10000 or 31337).
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from sensorgym.agents.stereo_pointing import rule_view
from sensorgym.agents.stereo_pointing_horizon import PlanHorizon
from sensorgym.agents.stereo_pointing_sharing import Sharing, shared_aims
from sensorgym.envs.stereo_pointing import simulation
from sensorgym.envs.stereo_pointing.simulation import PointingParams, slew_actions
from sensorgym.train.benchmark import paired_difference

RESULTS = Path(__file__).resolve().parent / "results" / "pointing_sharing.json"
EPISODE_STEPS = 150

#: (margin in the tracks' angular RMS, fraction of the field of view's width, largest track RMS
#: in m): the settings measured
SETTINGS = (
    (1.0, 0.9, 0.5), (1.0, 1.0, 0.5), (1.0, 0.9, 3.0), (0.5, 0.97, 3.0), (0.5, 1.0, 3.0),
    (0.25, 1.0, 6.0),
)  # fmt: skip


def play(params: PointingParams, seed: int, batch: int, aim: Callable | None) -> tuple:
    """``plan-acquire``'s assignments on ``batch`` scenarios of ``seed``, each receiver aimed by
    ``aim(view, target, t) → (points, target)`` for ``slew_actions`` (``None``: straight at its
    drone). Returns ``(returns (B,), share of receiver-steps aimed between two drones)``."""
    rule = PlanHorizon(params, acquisition=True)
    rng = np.random.default_rng(seed)
    state = simulation.reset(params, rng, batch)
    obs = simulation.observe(params, state)
    total, shared = np.zeros(batch), 0
    for t in range(EPISODE_STEPS):
        view = rule_view(params, obs.astype(np.float64))
        target = rule.choose(view, np.full(batch, t))
        points = view.position
        if aim is not None:
            points, target = aim(view, target, t)
            shared += int((target >= params.n_drones).sum())
        action = slew_actions(params, view.azimuth, view.elevation, points, target)
        state, reward, _ = simulation.step(params, state, action, rng)
        obs = simulation.observe(params, state)
        total += reward
    return total, shared / (batch * EPISODE_STEPS * params.n_receivers)


def setting_aim(params: PointingParams, setting: tuple) -> Callable:
    """``play``'s ``aim`` of the rule's :func:`shared_aims` at ``setting = (q, f, max_rms)``."""
    sharing = Sharing(*setting)
    return lambda view, target, t: shared_aims(params, view, target, sharing)


def paired_fields(returns: np.ndarray, base: np.ndarray, against: str) -> dict[str, float]:
    """A results row's fields of the per-episode difference ``returns − base`` (the same
    scenarios and noise): its mean (``paired_minus_<against>``), 95 % half-width
    (:func:`sensorgym.train.benchmark.paired_difference`) and the shares of episodes above and
    below."""
    stats, d = paired_difference(returns, base), returns - base
    return {
        f"paired_minus_{against}": stats["mean"],
        "paired_ci95": stats["ci95"],
        "episodes_above": float((d > 1e-9).mean()),
        "episodes_below": float((d < -1e-9).mean()),
    }


def tuning_args(
    doc: str,
    results: Path,
    seeds: list[int],
    ap: argparse.ArgumentParser | None = None,
    episodes: int = 256,
) -> argparse.Namespace:
    """The command line of a probe on tuning seeds (``--seeds``, ``--episodes`` with default
    ``episodes``, ``--out``; ``ap`` may hold more arguments); a held-out seed (10000 and up) is
    refused."""
    ap = ap or argparse.ArgumentParser(description=doc.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=seeds)
    ap.add_argument("--episodes", type=int, default=episodes)
    ap.add_argument("--out", type=Path, default=results)
    args = ap.parse_args()
    if any(s >= 10_000 for s in args.seeds):
        raise SystemExit("seeds: tuning seeds only (< 10000); 10000 and up are held out")
    return args


def main() -> None:
    args = tuning_args(__doc__, RESULTS, [500, 600])
    params = PointingParams()
    start = time.perf_counter()
    rows = []
    for seed in args.seeds:
        base, _ = play(params, seed, args.episodes, None)
        for setting in SETTINGS:
            returns, share = play(params, seed, args.episodes, setting_aim(params, setting))
            rows.append({
                "seed": seed,
                "margin_sigmas": setting[0], "fov_fraction": setting[1], "max_track_rms_m": setting[2],
                "plan_acquire": float(base.mean()),
                "shared": float(returns.mean()),
                **paired_fields(returns, base, "plan_acquire"),
                "receiver_steps_shared": share,
            })  # fmt: skip
            r = rows[-1]
            print(f"seed {seed} q {setting[0]} f {setting[1]} σmax {setting[2]}: "
                  f"{r['shared']:.2f} vs {r['plan_acquire']:.2f}, paired "
                  f"{r['paired_minus_plan_acquire']:+.2f} ± {r['paired_ci95']:.2f}, "
                  f"shared {share:.3%} of receiver-steps")  # fmt: skip
    write_rows(args.out, {"rule": "plan-acquire", "episodes": args.episodes}, rows, start)


def write_rows(path: Path, settings: dict, rows: list, start: float) -> None:
    """A probe's results file: its settings (the env, ``settings``, the seconds since
    ``start``) and its rows."""
    settings = {"env": "sensorgym/StereoPointing-v0", **settings}
    settings["seconds"] = round(time.perf_counter() - start, 1)
    path.write_text(json.dumps({"settings": settings, "rows": rows}, indent=1) + "\n")


if __name__ == "__main__":
    main()
