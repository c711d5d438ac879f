"""``sensorgym reproduce paper004``: the command line of paper 004's fused-tracking accuracy.

The experiment (formulas, closed-loop Monte Carlo, checks, report) is
:mod:`sensorgym.reproduce.experiments.paper004`; its figures are
:mod:`sensorgym.reproduce.experiments.paper004_figures`.
"""

from __future__ import annotations

import argparse
import time

from sensorgym.reproduce._cli import add_common_arguments, publish
from sensorgym.reproduce.experiments.paper004 import format_report, reproduce
from sensorgym.reproduce.experiments.paper004_figures import write_figures

HELP = "Paper 004: detection probability, variance recurrence, Fig. 2 and fused tracking."


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_common_arguments(parser, "paper004", 500, "closed-loop runs", plots=True)
    parser.add_argument("--frames", type=int, default=300, help="frames per run (default 300)")
    parser.add_argument(
        "--ranges", type=float, nargs="+", default=[0.5, 1.0, 2.0, 3.0], help="L values, km"
    )


def run(args: argparse.Namespace) -> int:
    t0 = time.perf_counter()
    result = reproduce(
        runs=args.runs, seed=args.seed, frames=args.frames, ranges_km=tuple(args.ranges)
    )
    result["seconds"] = time.perf_counter() - t0
    publish(args, "paper004.json", result, format_report(result), write_figures)
    return 0
