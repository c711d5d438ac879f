"""Throughput of the bearings-only core: bounds, filter updates and the world step, batched.

Run: ``.venv/bin/python benchmarks/bearings.py [--batch 10000] [--repeat 5]``. Prints a table of
scenario-steps per second (one scenario advanced by one bearing) with ``--batch`` scenarios
stepped at once, and writes ``benchmarks/results/bearings.json``.

What the environments need: a greedy information-gain policy scores every candidate manoeuvre
per step (incremental Fisher update + bound), and every env step runs one filter update.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from timing import RESULTS, best_rate, write_results

from sensorgym.envs.worlds.platform import PlatformWorldParams, PlatformWorldState, step
from sensorgym.trackers.bearings.crlb import (
    add_bearing_information,
    batch_information,
    crlb,
    position_rms_bound,
    predict_information,
    range_bound,
)
from sensorgym.trackers.bearings.filters import (
    bearing_prior,
    ckf_update,
    ekf_update,
    range_bank_predict,
    range_bank_prior,
    range_bank_update,
)
from sensorgym.trackers.bearings.models import predict

SIGMA = np.deg2rad(1.5)
Q_TILDE = 9e-6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--batch", type=int, default=10_000)
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--members", type=int, default=8, help="range-bank size")
    parser.add_argument("--out", type=Path, default=RESULTS / "bearings.json")
    args = parser.parse_args()
    B = args.batch
    rng = np.random.default_rng(0)
    x = np.column_stack(
        [rng.uniform(2e3, 8e3, B), rng.uniform(2e3, 8e3, B), rng.normal(size=(B, 2))]
    )
    p = rng.normal(size=(B, 2)) * 100.0
    z = np.arctan2(x[:, 0] - p[:, 0], x[:, 1] - p[:, 1]) + SIGMA * rng.standard_normal(B)
    J = batch_information(
        x, 0.0, 60.0 * np.arange(33), p[:, None, :] + rng.normal(size=(B, 33, 2)) * 500.0, SIGMA
    )
    prior = bearing_prior(
        z, SIGMA, p, 0.0, range_mean=5e3, range_sigma=2e3, speed_mean=2.0, speed_sigma=1.0,
        course_mean=z + np.pi, course_sigma=np.pi / np.sqrt(12), course_distribution="uniform",
    )  # fmt: skip
    bank = range_bank_prior(
        z, SIGMA, p, 0.0, range_min=1e3, range_max=1.2e4, n_members=args.members, speed_mean=2.0,
        speed_sigma=1.0, course_mean=z + np.pi, course_sigma=np.pi / np.sqrt(12),
        course_distribution="uniform",
    )  # fmt: skip
    world = PlatformWorldState(0.0, p, rng.uniform(-np.pi, np.pi, B), np.full(B, 5.0), x)
    wparams = PlatformWorldParams(dt=60.0, q_tilde=Q_TILDE, sigma_bearing=SIGMA)
    actions = rng.uniform(-0.01, 0.01, (B, 2))
    wrng = np.random.default_rng(1)

    cases = {
        "bound: add one bearing (incremental FIM)": lambda: add_bearing_information(
            J, x, 0.0, 60.0, p, SIGMA
        ),
        "bound: PCRLB step (predict + add bearing)": lambda: add_bearing_information(
            predict_information(J, 60.0, Q_TILDE), x, 60.0, 60.0, p, SIGMA
        ),
        "bound: CRLB + position/range helpers": lambda: (
            position_rms_bound(P := crlb(J)),
            range_bound(P, x[:, :2], p),
        ),
        "bound: batch FIM over 33 bearings": lambda: batch_information(
            x, 0.0, 60.0 * np.arange(33), np.broadcast_to(p[:, None, :], (B, 33, 2)), SIGMA
        ),
        "filter: EKF predict + update": lambda: ekf_update(
            predict(prior, 60.0, Q_TILDE), z, p, SIGMA
        ),
        "filter: CKF predict + update": lambda: ckf_update(
            predict(prior, 60.0, Q_TILDE), z, p, SIGMA
        ),
        f"filter: RP-EKF bank ({args.members}) predict + update": lambda: range_bank_update(
            range_bank_predict(bank, 60.0, Q_TILDE), z, p, SIGMA
        ),
        f"filter: RP-CKF bank ({args.members}) predict + update": lambda: range_bank_update(
            range_bank_predict(bank, 60.0, Q_TILDE), z, p, SIGMA, "ckf"
        ),
        "world: step (platform arc + CWNA target)": lambda: step(wparams, world, actions, wrng),
    }
    rows = []
    print(f"batch = {B} scenarios; scenario-steps per second (best of {args.repeat})")
    print(f"{'operation':<46}{'steps/s':>14}{'us/step':>10}")
    for name, fn in cases.items():
        r = best_rate(lambda _, fn=fn: fn(), B, args.repeat)
        rows.append({"operation": name, "scenario_steps_per_s": r, "us_per_step": 1e6 / r})
        print(f"{name:<46}{r:>14.3e}{1e6 / r:>10.3f}")
    write_results(args.out, rows, batch=B, repeat=args.repeat, members=args.members)


if __name__ == "__main__":
    main()
