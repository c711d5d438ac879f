"""``sensorgym reproduce paper001``: the command line of paper 001's angle prediction.

The experiment (predictors, Monte Carlo, checks, report) is
:mod:`sensorgym.reproduce.experiments.paper001`; its figures are
:mod:`sensorgym.reproduce.experiments.paper001_figures`.
"""

from __future__ import annotations

import argparse
import time

from sensorgym.reproduce._cli import add_common_arguments, publish
from sensorgym.reproduce.experiments.paper001 import format_report, reproduce
from sensorgym.reproduce.experiments.paper001_figures import write_figures

HELP = "Paper 001: azimuth/elevation prediction through target loss (A-B-C vs LS fit vs Kalman)."


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_common_arguments(parser, "paper001", 500, "noise realisations", plots=True)
    parser.add_argument(
        "--loss-frame", type=int, default=400, help="frame of the last measurement (default 400)"
    )
    parser.add_argument("--gate", type=int, default=200, help="prediction gate, frames (200)")
    parser.add_argument(
        "--turn-rates",
        type=float,
        nargs="*",
        default=[0.01, 0.03],
        help="turn rates (deg/frame) of the manoeuvring-target table (default 0.01 0.03)",
    )


def run(args: argparse.Namespace) -> int:
    t0 = time.perf_counter()
    result = reproduce(
        runs=args.runs,
        seed=args.seed,
        loss_frame=args.loss_frame,
        gate=args.gate,
        turn_rates_deg=tuple(args.turn_rates),
    )
    result["seconds"] = time.perf_counter() - t0
    publish(args, "paper001.json", result, format_report(result), write_figures)
    return 0
