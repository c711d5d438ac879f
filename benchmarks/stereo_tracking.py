"""Speed of the stereo trackers: one period and a whole N = 5 run for m = 1..10 objects.

Targets (issue 3): n = 3, m = 10, N = 5 in under 1 s; m = 5 in under 100 ms. Scenes are paper
000's (receivers on a 120 m arc, objects a few metres apart, σ_x = 0.1 m) for the alternative
(n = 2) and proposed (n = 3) trackers, and the same objects seen by a raster-scanning pair
(0.03° angle noise) for paper 003's algorithmic detector (n = 2). Each time is the median of
``--repeats`` seeded scenes; the simulation is excluded.

Run: ``.venv/bin/python benchmarks/stereo_tracking.py`` (writes
``benchmarks/results/stereo_tracking.json``).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from timing import RESULTS, write_results

from sensorgym.envs.worlds.drones import GroupSpec, random_group
from sensorgym.envs.worlds.scanning import FixedDelay, RasterScan
from sensorgym.envs.worlds.stereo import NoiseModel, ReceiverLayout, simulate
from sensorgym.trackers.stereo.algorithmic_detection import AlgorithmicParams, detect_algorithmic
from sensorgym.trackers.stereo.period_tracking import track_alternative, track_proposed

LAYOUT = ReceiverLayout.on_circle(120.0, [0.0, 90.0, 270.0], aim=(0.0, 40.0, 0.0))
GROUP = GroupSpec(
    centre=(0.0, 40.0, 0.0), spread=6.0, min_separation=2.0, speed=(9.0, 36.0), shared_velocity=True
)


def _scene(rng, m, tracker, N):
    traj = random_group(rng, m, GROUP)
    if tracker == "proposed":
        timings = (FixedDelay(0.0), FixedDelay(0.1), FixedDelay(0.2))
        per, _ = simulate(rng, traj, LAYOUT, timings, N, 1.0, NoiseModel(position_sigma=0.1))
        return per, LAYOUT
    layout = LAYOUT.subset([0, 1])
    if tracker == "alternative":
        timings = (FixedDelay(0.0), FixedDelay(0.1))
        per, _ = simulate(rng, traj, layout, timings, N, 1.0, NoiseModel(position_sigma=0.1))
    else:
        scan = RasterScan(30.0, 30.0, 100, 100, 1.0)
        per, _ = simulate(
            rng, traj, layout, (scan, scan), N, 1.0, NoiseModel(angle_sigma=np.deg2rad(0.03))
        )
    return per, layout


def _run(tracker, per, layout):
    P, b = layout.relative
    if tracker == "proposed":
        return track_proposed(per, P, b)
    if tracker == "alternative":
        return track_alternative(per, P[0], b[0])
    params = AlgorithmicParams(
        sigma_e=120 * np.deg2rad(0.03), sigma_position=0.2, max_speed=40.0, max_delay=1.0
    )
    return detect_algorithmic(per, P[0], b[0], params)


def measure(tracker: str, m: int, repeats: int, seed: int) -> dict:
    """Median wall time of one period (N = 1; N = 2 for the alternative, halved) and of N = 5."""
    out = {}
    for label, N in (("period", 2 if tracker == "alternative" else 1), ("run_N5", 5)):
        times = []
        for r in range(repeats):
            per, layout = _scene(np.random.default_rng([seed, m, r]), m, tracker, N)
            t0 = time.perf_counter()
            det = _run(tracker, per, layout)
            times.append((time.perf_counter() - t0) / (2 if N == 2 else 1))
        out[label] = float(np.median(times))
        out[f"m_hat_{label}"] = det.m_hat
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=RESULTS / "stereo_tracking.json")
    args = parser.parse_args()
    rows = []
    print(f"{'tracker':<12} {'n':>2} {'m':>3} {'period, ms':>11} {'N=5 run, ms':>12}")
    for tracker, n in (("alternative", 2), ("algorithmic", 2), ("proposed", 3)):
        for m in range(1, 11):
            r = measure(tracker, m, args.repeats, args.seed)
            rows.append({"tracker": tracker, "n": n, "m": m, **r})
            print(
                f"{tracker:<12} {n:>2} {m:>3} {1e3 * r['period']:>11.2f} {1e3 * r['run_N5']:>12.2f}"
            )
    prop = {r["m"]: r["run_N5"] for r in rows if r["tracker"] == "proposed"}
    targets = {
        "n3_m10_N5_under_1s": prop[10] < 1.0,
        "n3_m5_N5_under_100ms": prop[5] < 0.1,
    }
    print("targets:", targets)
    write_results(
        args.out, {"rows": rows, "targets": targets}, repeats=args.repeats, seed=args.seed
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
