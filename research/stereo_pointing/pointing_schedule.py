"""Tune the ``plan-schedule`` rule of ``sensorgym/StereoPointingCrowded-v0`` (issue 37, item 1).

``python research/stereo_pointing/pointing_schedule.py [--seeds 500 600] [--episodes 128] [--jobs 2]`` scores
``plan-search`` and settings of :class:`~sensorgym.agents.stereo_pointing_schedule.PlanSchedule`
on the benchmark's own scenarios (:func:`sensorgym.train.benchmark.score`, the episodes of
``sensorgym benchmark --seed S --n-envs 64``), each paired episode by episode to
``plan-search``:

* ``off``: the schedule never forces a hand-over (``reach`` so small that every drone counts as
  already lost): the exhaustive acquisition-weighted plan over all 81 assignments, with
  ``plan-search``'s aiming. It separates what the schedule adds from what the exhaustive
  search adds (``plan-search`` plans through the polynomial search at 81 > 32 assignments,
  without the acquisition weight);
* ``reach`` × ``lead`` (:class:`~sensorgym.agents.stereo_pointing_schedule.Schedule`): when a
  drifting drone is handed a pair.

Writes ``research/stereo_pointing/results/pointing_schedule.json``: per seed and setting the mean return, its
95 % half-width, the paired difference to ``plan-search`` and the share of drone-steps without
a fix. Tuning seeds only (a held-out seed, 10000 and up, is refused).
"""

from __future__ import annotations

import argparse
import json
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

ENV_ID = "sensorgym/StereoPointingCrowded-v0"
RESULTS = Path(__file__).resolve().parent / "results" / "pointing_schedule.json"
BASE = "plan-search"
#: (reach, lead) of the schedule; reach 1e-9: never forced ("off")
SETTINGS: tuple[tuple[float, float], ...] = (
    (1e-9, 0.0),
    (1.0, 0.0),
    (1.0, 3.0),
    (2.0, 3.0),
    (0.5, 3.0),
)


def name_of(reach: float, lead: float) -> str:
    return "off" if reach < 1e-6 else f"reach={reach:g},lead={lead:g}"


def factory(reach: float, lead: float) -> Any:
    """The rule factory of one setting: the registered ``plan-schedule`` with that schedule."""
    from sensorgym.agents import stereo_pointing_schedule as sched
    from sensorgym.agents import stereo_pointing_search as search
    from sensorgym.agents import stereo_pointing_sharing as sharing

    return lambda params, _: sched.PlanSchedule(
        params,
        acquisition=True,
        sharing=sharing.Sharing(),
        cue_steps=1,
        search=search.EpipolarSearch(),
        schedule=sched.Schedule(reach=reach, lead=lead),
    )


def run(task: tuple[int, int, str, float | None, float | None]) -> dict[str, Any]:
    """Score one setting (or ``plan-search``) on one seed."""
    from sensorgym.agents.registry import RULES
    from sensorgym.train.benchmark import PolicySpec, score

    seed, episodes, name, reach, lead = task
    if name != BASE:
        RULES[ENV_ID][name] = factory(reach, lead)
    start = time.perf_counter()
    out = score(ENV_ID, PolicySpec("rule", name), episodes, min(episodes, 64), seed)
    return {
        "seed": seed,
        "setting": name,
        "reach": reach,
        "lead": lead,
        "returns": list(map(float, out["returns"])),
        "no_fix_share": float(np.mean(out["tails"]["no_fix_share"])),
        "seconds": time.perf_counter() - start,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[500, 600])
    ap.add_argument("--episodes", type=int, default=128)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", type=Path, default=RESULTS)
    args = ap.parse_args()
    if any(s >= 10_000 for s in args.seeds):
        raise SystemExit("seeds: tuning seeds only (< 10000); 10000 and up are held out")
    from sensorgym.train.benchmark import paired_difference

    tasks: list[Any] = [(s, args.episodes, BASE, None, None) for s in args.seeds]
    tasks += [(s, args.episodes, name_of(r, q), r, q) for s in args.seeds for r, q in SETTINGS]
    # every finished task is appended to a cache beside the output, so a stopped sweep resumes
    cache = args.out.with_suffix(".partial.jsonl")
    done = [json.loads(x) for x in cache.read_text().splitlines()] if cache.exists() else []
    have = {(r["seed"], r["setting"], r["returns"].__len__()) for r in done}
    todo = [task for task in tasks if (task[0], task[2], task[1]) not in have]
    cache.parent.mkdir(parents=True, exist_ok=True)
    with ProcessPoolExecutor(args.jobs) as pool:
        for r in pool.map(run, todo):
            with cache.open("a") as f:
                f.write(json.dumps(r) + "\n")
            done.append(r)
            print(f"seed {r['seed']} {r['setting']}: {np.mean(r['returns']):.2f}", flush=True)
    results = [r for r in done if len(r["returns"]) == args.episodes and r["seed"] in args.seeds]
    base = {r["seed"]: np.array(r["returns"]) for r in results if r["setting"] == BASE}
    rows = []
    for r in results:
        x = np.array(r["returns"])
        d = paired_difference(x, base[r["seed"]])
        rows.append(
            {
                **{k: r[k] for k in ("seed", "setting", "reach", "lead")},
                "mean": float(x.mean()),
                "ci95": float(1.96 * x.std(ddof=1) / np.sqrt(len(x))),
                f"paired_minus_{BASE}": d["mean"],
                "paired_ci95": d["ci95"],
                "episodes_above": float((x - base[r["seed"]] > 1e-9).mean()),
                "episodes_below": float((x - base[r["seed"]] < -1e-9).mean()),
                "no_fix_share": r["no_fix_share"],
                "seconds_per_episode": r["seconds"] / len(x),
            }
        )
        print(
            f"seed {r['seed']:>4} {r['setting']:<22} {x.mean():9.2f} ± {rows[-1]['ci95']:5.2f}"
            f"  paired {d['mean']:+7.2f} ± {d['ci95']:5.2f}  unfixed {r['no_fix_share']:.3f}",
            flush=True,
        )
    args.out.parent.mkdir(parents=True, exist_ok=True)
    record = {
        "env": ENV_ID,
        "episodes": args.episodes,
        "seeds": args.seeds,
        "n_envs": min(args.episodes, 64),
        "rows": rows,
    }
    args.out.write_text(json.dumps(record, indent=1) + "\n")
    cache.unlink()
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
