"""How far is ``plan-search`` from the instantaneous bound when receivers are scarce? A probe
of ``sensorgym/StereoPointing-v0`` layouts on tuning seeds (issue 13, the owner's option 2).

``python benchmarks/pointing_room.py [--seeds 500 600] [--episodes 128]`` writes
``benchmarks/results/pointing_room.json``.

At the defaults (4 receivers, 2 drones: two receivers per drone) no pairing policy can gain much
over ``plan-search`` (``benchmarks/pointing_rollout.py``). With fewer receivers than two per
drone, pointing becomes a scheduling problem: which drones are fixed now, which wait, and when
a receiver can hold two drones at once. This probe plays ``plan-search`` at several layouts
(``n_receivers``, ``n_drones``) and sums, on the same episodes, the instantaneous bound of
:func:`pointing_rollout.instant_bound` (the best mean drone reward any pointing could give at
each instant on the true drones, with no slew limit and no tracking error). The gap between
the two is an upper bound on what any policy could gain; it is not reachable (the bound knows
the truth and ignores slewing and search), but where it is small no learner has room, and
where it is large a learner might. It also counts the drones ``plan-search`` never fixes.
"""

from __future__ import annotations

import time
from pathlib import Path

from pointing_rollout import EARLY_STEPS, bound_rows, plan_search
from pointing_sharing import tuning_args, write_rows

from sensorgym.envs.stereo_pointing.simulation import PointingParams

RESULTS = Path(__file__).resolve().parent / "results" / "pointing_room.json"
#: ``(n_receivers, n_drones)``: the defaults first, then fewer receivers than two per drone
#: (the bound enumerates ``(2^m − 1)^n`` pointings, so the layouts stay small)
LAYOUTS = ((4, 2), (3, 2), (4, 3), (3, 3))


def main() -> None:
    args = tuning_args(__doc__, RESULTS, [500, 600], episodes=128)
    start = time.perf_counter()
    rows = []
    for n, m in LAYOUTS:
        rule = plan_search(PointingParams(n_receivers=n, n_drones=m))
        for seed in args.seeds:
            r = bound_rows(rule, seed, args.episodes)
            e = EARLY_STEPS
            rows.append({
                "n_receivers": n, "n_drones": m, **r,
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
    settings = {
        "seeds": args.seeds,
        "episodes": args.episodes,
        "rule": "plan-search",
        "layouts": [list(x) for x in LAYOUTS],
    }
    write_rows(args.out, settings, rows, start)


if __name__ == "__main__":
    main()
