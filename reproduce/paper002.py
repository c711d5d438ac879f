"""``sensorgym reproduce paper002``: the command line of paper 002's fictitious-bearing method.

The experiment (scenario, closed-loop runs, statistics, report) is
:mod:`sensorgym.reproduce.experiments.paper002`.
"""

from __future__ import annotations

import argparse

from sensorgym.reproduce._cli import add_common_arguments, write_json
from sensorgym.reproduce.experiments.paper002 import format_report, reproduce

HELP = "Paper 002: fictitious-bearing method, noise-free (RT-8) and block-smoothed noisy (RT-9)."


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_common_arguments(parser, "paper002", 100, "noise sets, as the paper")
    parser.add_argument("--degree", type=int, default=1, help="smoothing polynomial degree")


def run(args: argparse.Namespace) -> int:
    result = reproduce(runs=args.runs, seed=args.seed, degree=args.degree)
    print(format_report(result))
    write_json(args.out, "paper002.json", result)
    return 0
