"""``sensorgym reproduce bot-benchmark``: the command line of the textbook bearings-only benchmark.

The experiment (scenario, Monte Carlo, estimators, bounds, report) is
:mod:`sensorgym.reproduce.experiments.bot_benchmark`.
"""

from __future__ import annotations

import argparse
from dataclasses import asdict

from sensorgym.reproduce._cli import add_common_arguments, write_json
from sensorgym.reproduce.experiments.bot_benchmark import format_report, run_benchmark

HELP = "Textbook bearings-only benchmark (Ristic et al. ch. 6): EKF, CKF, RP-EKF, ML vs CRLB."


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_common_arguments(parser, "bot-benchmark", 1000, "Monte Carlo runs")
    parser.add_argument("--members", type=int, default=8, help="RP bank size (default 8)")


def run(args: argparse.Namespace) -> int:
    res = run_benchmark(args.runs, args.seed, args.members)
    print(format_report(res))
    write_json(args.out, "bot_benchmark.json", asdict(res))
    return 0
