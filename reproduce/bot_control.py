"""``sensorgym reproduce bot-control``: the command line of the textbook observer-control problem.

The experiment (policies, the fixed plan, the per-run hindsight-optimum ceiling, book PCRLB,
report) is
:mod:`sensorgym.reproduce.experiments.bot_control`.
"""

from __future__ import annotations

import argparse

from sensorgym.reproduce._cli import add_common_arguments, publish
from sensorgym.reproduce.experiments.bot_control import (
    format_report,
    result_dict,
    run_bot_control,
)

HELP = (
    "Textbook observer control (Ristic et al. ch. 6): PCRLB at 32 min of rules, the book's leg "
    "change, a fixed optimised plan and the trained policies, against each run's hindsight "
    "optimum (the ceiling)."
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    # the held-out benchmark seed: the shipped policies never trained or were tuned on it
    add_common_arguments(parser, "bot-control", 256, "episodes per policy", seed=10_000)
    parser.add_argument(
        "--restarts", type=int, default=8, help="random starts of the optimiser (default 8)"
    )


def run(args: argparse.Namespace) -> int:
    if args.runs < 2:
        raise SystemExit(f"--runs: need at least 2, got {args.runs}")
    if args.restarts < 0:
        raise SystemExit(f"--restarts: must be >= 0, got {args.restarts}")
    res = run_bot_control(args.runs, args.seed, args.restarts)
    publish(args, "bot_control.json", result_dict(res), format_report(res))
    return 0
