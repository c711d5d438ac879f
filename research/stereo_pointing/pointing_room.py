"""How far is ``plan-search`` from the instantaneous bound when receivers are scarce? A probe
of ``sensorgym/StereoPointing-v0`` layouts on tuning seeds (issue 13, the owner's option 2).

``python research/stereo_pointing/pointing_room.py [--seeds 500 600] [--episodes 128]`` writes
``research/stereo_pointing/results/pointing_room.json``.

At the defaults (4 receivers, 2 drones: two receivers per drone) no pairing policy can gain much
over ``plan-search`` (``research/stereo_pointing/pointing_rollout.py``). With fewer receivers than two per
drone, pointing becomes a scheduling problem: which drones are fixed now, which wait, and when
a receiver can hold two drones at once. This probe plays ``plan-search`` at several layouts
(``n_receivers``, ``n_drones``) and sums, on the same episodes, the instantaneous bound of
:func:`sensorgym.envs.stereo_pointing.bound.step_bound` (the best mean drone reward any
pointing could give at each instant on the true drones, with no slew limit and no tracking
error; theory §11.3.1). The gap between
the two is an upper bound on what any policy could gain; it is not reachable (the bound knows
the truth and ignores slewing and search), but where it is small no learner has room, and
where it is large a learner might. It also counts the drones ``plan-search`` never fixes.

**Is it only the rule's tuning?** ``plan-search``'s two settings, its planning horizon and its
hysteresis (``keep_bonus``), were chosen at the defaults. At each scarce layout the probe also
plays ``plan-search`` over a grid of both (:data:`RETUNE`) on the same scenarios, paired with
the rule as registered: the most a retuned rule gains there.
"""

from __future__ import annotations

import dataclasses
import itertools
import time
from pathlib import Path
from typing import Any

import numpy as np
from pointing_rollout import EARLY_STEPS, bound_rows, plan_search
from pointing_sharing import paired_fields, tuning_args, write_rows

from sensorgym.agents.stereo_pointing_horizon import PlanHorizon
from sensorgym.envs.stereo_pointing.simulation import PointingParams
from sensorgym.train.evaluation import evaluate, make_sb3_env

RESULTS = Path(__file__).resolve().parent / "results" / "pointing_room.json"
#: ``(n_receivers, n_drones)``: the defaults first, then fewer receivers than two per drone
#: (the bound enumerates ``(2^m − 1)^n`` pointings, so the layouts stay small)
LAYOUTS = ((4, 2), (3, 2), (4, 3), (3, 3))
#: ``plan-search``'s planning horizon (steps) and hysteresis (``keep_bonus``) tried at the
#: scarce layouts; the registered rule is ``(100, 0.3)``
RETUNE = tuple(itertools.product((100, 50, 30, 15), (0.3, 0.1, 0.0, 1.0)))


def retune_rows(n: int, m: int, seed: int, episodes: int) -> list[dict[str, Any]]:
    """``plan-search`` at every setting of :data:`RETUNE` on ``episodes`` scenarios of
    ``seed``, paired with the registered setting (the first)."""
    env = make_sb3_env("sensorgym/StereoPointing-v0", 16, seed, n_receivers=n, n_drones=m)
    rule = plan_search(PointingParams(n_receivers=n, n_drones=m))
    rows, base = [], np.zeros(0)
    for horizon, keep in RETUNE:
        tuned: PlanHorizon = dataclasses.replace(rule, horizon=horizon, keep_bonus=keep)
        returns = np.asarray(evaluate(tuned, env, episodes, seed).returns)
        base = returns if not base.size else base
        rows.append({
            "probe": "retune", "n_receivers": n, "n_drones": m, "seed": seed, "horizon": horizon,
            "keep_bonus": keep, "mean_return": float(returns.mean()),
            **paired_fields(returns, base, "registered"),
        })  # fmt: skip
    best = max(rows, key=lambda r: r["paired_minus_registered"])
    print(
        f"{n} receivers, {m} drones, seed {seed}: best retuning (horizon {best['horizon']},"
        f" keep {best['keep_bonus']}) {best['paired_minus_registered']:+.1f}"
        f" ± {best['paired_ci95']:.1f} over the registered plan-search",
        flush=True,
    )
    return rows


def main() -> None:
    args = tuning_args(__doc__, RESULTS, [500, 600], episodes=128)
    start = time.perf_counter()
    rows, retuned = [], []
    for n, m in LAYOUTS:
        rule = plan_search(PointingParams(n_receivers=n, n_drones=m))
        for seed in args.seeds:
            r = bound_rows(rule, seed, args.episodes)
            e = EARLY_STEPS
            rows.append({
                "probe": "bound", "n_receivers": n, "n_drones": m, **r,
                "gap": r["instant_bound"] - r["rule_return"],
                f"gap_after_{e}_steps": r["bound_after"] - r["rule_after"],
                "never_fixed_share": r["never_fixed_drones"] / (args.episodes * m),
            })  # fmt: skip
            print(
                f"{n} receivers, {m} drones, seed {seed}: plan-search {r['rule_return']:.1f},"
                f" instantaneous bound {r['instant_bound']:.1f} (gap {rows[-1]['gap']:.1f}),"
                f" drones never fixed {rows[-1]['never_fixed_share']:.1%}",
                flush=True,
            )
            if n < 2 * m:  # fewer receivers than two per drone
                retuned += retune_rows(n, m, seed, args.episodes)
    settings = {
        "seeds": args.seeds,
        "episodes": args.episodes,
        "rule": "plan-search",
        "layouts": [list(x) for x in LAYOUTS],
        "retune": [list(x) for x in RETUNE],
    }
    write_rows(args.out, settings, rows + retuned, start)


if __name__ == "__main__":
    main()
