"""``sensorgym reproduce scanning000``: paper 000's Tables 1–2 through StereoScanning-v0's tracker.

The experiment (the env's params per cell, the batched Monte Carlo through the env's core, the
checks with paper 000's tolerances, the report) is
:mod:`sensorgym.reproduce.experiments.scanning000`.
"""

from __future__ import annotations

import argparse
import time

from sensorgym.reproduce._cli import add_common_arguments, publish
from sensorgym.reproduce.experiments.scanning000 import format_report, reproduce

HELP = (
    "Paper 000 Tables 1-2 through sensorgym/StereoScanning-v0: the env's tracker under the "
    "papers' fixed full sweep (fidelity of the env)."
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_common_arguments(parser, "scanning000", 1000, "Monte Carlo runs per table cell")


def run(args: argparse.Namespace) -> int:
    t0 = time.perf_counter()
    result = reproduce(runs=args.runs, seed=args.seed)
    result["seconds"] = time.perf_counter() - t0
    publish(args, "scanning000.json", result, format_report(result))
    return 0
