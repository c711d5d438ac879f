"""``sensorgym reproduce paper003``: the command line of paper 003's accuracy and P(m) tables.

The experiment (scenarios, algebraic accuracy, algorithmic P(m) cells, checks, report) is
:mod:`sensorgym.reproduce.experiments.paper003`.
"""

from __future__ import annotations

import argparse
import time

from sensorgym.reproduce._cli import add_common_arguments, publish
from sensorgym.reproduce.experiments.paper003 import format_report, reproduce

HELP = "Paper 003: algebraic accuracy (variants 1, 2) and algorithmic detection probability P(m)."


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_common_arguments(parser, "paper003", 1000, "Monte Carlo runs per experiment")
    parser.add_argument(
        "--algorithmic-runs", type=int, default=None, help="runs per P(m) cell (default: --runs)"
    )
    parser.add_argument("--jobs", type=int, default=2, help="worker processes (default 2)")


def run(args: argparse.Namespace) -> int:
    t0 = time.perf_counter()
    res = reproduce(
        runs=args.runs, seed=args.seed, algorithmic_runs=args.algorithmic_runs, jobs=args.jobs
    )
    res["seconds"] = time.perf_counter() - t0
    publish(args, "paper003.json", res, format_report(res))
    return 0
