"""The frozen ``plan-schedule`` rules of ``sensorgym/StereoPointingCrowded-v0`` on the held-out
seed, once (issue 37, item 1): evaluation only, after ``research/stereo_pointing/pointing_schedule.py`` chose
their settings on tuning seeds.

``python research/stereo_pointing/pointing_schedule_heldout.py [--episodes 256] [--jobs 2]`` scores
``plan-search`` and the registered rules named in :data:`RULES` on seed 10000
(:func:`sensorgym.train.benchmark.score` with 64 scenarios per batch: the benchmark's episodes
at that batch, not the 16 of ``sensorgym benchmark``'s default, whose streams differ), and writes
``research/stereo_pointing/results/pointing_schedule_heldout.json``: each rule's mean, its 95 % half-width,
its paired difference to ``plan-search`` and its wall-clock per agent step.
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
SEED = 10_000
BASE = "plan-search"
RULES = (BASE, "plan-schedule", "plan-search-exhaustive")
RESULTS = Path(__file__).resolve().parent / "results" / "pointing_schedule_heldout.json"
EPISODE_STEPS = 150


def run(task: tuple[str, int]) -> dict[str, Any]:
    from sensorgym.train.benchmark import PolicySpec, score

    name, episodes = task
    start = time.perf_counter()
    out = score(ENV_ID, PolicySpec("rule", name), episodes, 64, SEED)
    seconds = time.perf_counter() - start
    return {"rule": name, "returns": list(map(float, out["returns"])), "seconds": seconds}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--episodes", type=int, default=256)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", type=Path, default=RESULTS)
    args = ap.parse_args()
    from sensorgym.train.benchmark import paired_difference

    with ProcessPoolExecutor(args.jobs) as pool:
        results = list(pool.map(run, [(name, args.episodes) for name in RULES]))
    base = np.array(results[0]["returns"])
    rows = []
    for r in results:
        x = np.array(r["returns"])
        d = paired_difference(x, base)
        rows.append(
            {
                "rule": r["rule"],
                "mean": float(x.mean()),
                "ci95": float(1.96 * x.std(ddof=1) / np.sqrt(len(x))),
                f"paired_minus_{BASE}": d["mean"],
                "paired_ci95": d["ci95"],
                "better": d["better"],
                "worse": d["worse"],
                # one process, 64 scenarios per batched call, shared CPUs: an upper bound
                "ms_per_scenario_step": 1e3 * r["seconds"] / (len(x) * EPISODE_STEPS),
            }
        )
        print(json.dumps(rows[-1]), flush=True)
    record = {"env": ENV_ID, "seed": SEED, "episodes": args.episodes, "n_envs": 64, "rows": rows}
    args.out.write_text(json.dumps(record, indent=1) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
