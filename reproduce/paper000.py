"""``sensorgym reproduce paper000``: the command line of paper 000's Tables 1–2.

The experiment (scenario, Monte Carlo, checks, report) is
:mod:`sensorgym.reproduce.experiments.paper000`.
"""

from __future__ import annotations

import argparse
import time

from sensorgym.reproduce._cli import add_common_arguments, publish
from sensorgym.reproduce.experiments.paper000 import format_report, reproduce

HELP = "Paper 000 Tables 1-2: alternative (n=2) vs proposed velocity-aware (n=3) stereo tracking."


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_common_arguments(parser, "paper000", 1000, "Monte Carlo runs per table cell")
    parser.add_argument("--jobs", type=int, default=2, help="worker processes (default 2)")


def run(args: argparse.Namespace) -> int:
    t0 = time.perf_counter()
    result = reproduce(runs=args.runs, seed=args.seed, jobs=args.jobs)
    result["seconds"] = time.perf_counter() - t0
    publish(args, "paper000.json", result, format_report(result))
    return 0
