"""Throughput of the conjugation solvers: problems solved per second, one at a time and batched.

Run: ``.venv/bin/python benchmarks/triangulation.py [--batch 100000] [--repeat 5]``. Prints a table
and writes ``benchmarks/results/triangulation.json``. Targets (issue 2, 2-core machine, batched):
≥ 10 M two-receiver problems/s and ≥ 2 M three-receiver velocity problems/s.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from timing import RESULTS, best_rate, write_results

from sensorgym.trackers.geometry import look_at_rotation, relative_pose
from sensorgym.trackers.stereo.conjugation import solve_conjugation

TARGETS = {"n=2 order 0": 10e6, "n=3 order 1": 2e6}


def make_problems(n: int, order: int, batch: int, seed: int = 0) -> tuple:
    rng = np.random.default_rng(seed)
    T = rng.normal(size=(batch, 3)) * 20.0 + np.array([0.0, 40.0, 120.0])
    V = rng.normal(size=(batch, 3)) * 8.0 * (order > 0)
    o = rng.normal(size=(batch, n, 3)) * 70.0
    R = look_at_rotation(o, T[:, None, :])
    t = np.concatenate([np.zeros((batch, 1)), rng.uniform(0.05, 0.6, (batch, n - 1))], 1)
    u = T[:, None, :] + V[:, None, :] * t[..., None] - o
    u /= np.linalg.norm(u, axis=-1, keepdims=True)
    a = np.einsum("bkji,bkj->bki", R, u)
    P, b = relative_pose(R[:, :1], o[:, :1], R[:, 1:], o[:, 1:])
    return a[:, 0], a[:, 1:], P, b, (t[:, 1:] if order else None)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--batch", type=int, default=100_000)
    parser.add_argument("--single", type=int, default=2_000, help="problems timed one at a time")
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--out", type=Path, default=RESULTS / "triangulation.json")
    args = parser.parse_args()

    cases = [
        ("n=2 order 0", 2, 0, "closed form"),
        ("n=3 order 1", 3, 1, "velocity eliminated"),
        ("n=3 order 0", 3, 0, "generic SVD"),
        ("n=4 order 1", 4, 1, "generic SVD"),
        ("n=5 order 2", 5, 2, "generic SVD"),
    ]
    rows = []
    for name, n, order, path in cases:
        a1, ak, P, b, dt = make_problems(n, order, args.batch)

        def batched(_, a1=a1, ak=ak, P=P, b=b, dt=dt, order=order):
            solve_conjugation(a1, ak, P, b, dt, order=order)

        def unchecked(_, a1=a1, ak=ak, P=P, b=b, dt=dt, order=order):
            solve_conjugation(a1, ak, P, b, dt, order=order, check_inputs=False)

        k = args.single

        def single(_, a1=a1, ak=ak, P=P, b=b, dt=dt, order=order, k=k):
            for i in range(k):
                solve_conjugation(
                    a1[i], ak[i], P[i], b[i], None if dt is None else dt[i], order=order
                )

        r_batch = best_rate(batched, args.batch, args.repeat)
        r_unchecked = best_rate(unchecked, args.batch, args.repeat)
        r_single = best_rate(single, k, max(1, args.repeat // 2))
        target = TARGETS.get(name)
        rows.append(
            {
                "case": name,
                "path": path,
                "single_per_s": r_single,
                "batched_per_s": r_batch,
                "batched_unchecked_per_s": r_unchecked,
                "batch": args.batch,
                "target_batched_per_s": target,
                "meets_target": None if target is None else bool(r_batch >= target),
            }
        )

    header = (
        f"{'case':<13} {'path':<20} {'one at a time /s':>17} {'batched /s':>14} "
        f"{'unchecked /s':>14} {'target':>10}  ok"
    )
    print(header)
    print("-" * len(header))
    for r in rows:
        tgt = (
            "" if r["target_batched_per_s"] is None else f"{r['target_batched_per_s'] / 1e6:.0f} M"
        )
        ok = "" if r["meets_target"] is None else ("yes" if r["meets_target"] else "NO")
        print(
            f"{r['case']:<13} {r['path']:<20} {r['single_per_s']:>17,.0f} "
            f"{r['batched_per_s']:>14,.0f} {r['batched_unchecked_per_s']:>14,.0f} {tgt:>10}  {ok}"
        )
    print("batched: default call with input checks; unchecked: check_inputs=False")
    write_results(args.out, rows, batch=args.batch, single=args.single, repeat=args.repeat)


if __name__ == "__main__":
    main()
