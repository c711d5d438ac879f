"""What every reproduction command shares: the common command-line options and the output files.

Private module (leading underscore): not a ``sensorgym reproduce`` entry of its own. The
experiments and their report text live in :mod:`sensorgym.reproduce.experiments`.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

from sensorgym.cli import args as types


def add_common_arguments(
    parser: argparse.ArgumentParser,
    name: str,
    runs: int,
    runs_help: str,
    *,
    plots: bool = False,
    seed: int = 0,
) -> None:
    """``--runs`` (an integer >= 1), ``--seed`` (default ``seed``; :func:`sensorgym.cli.args.seed`),
    ``--out`` (default ``results/NAME``; ``sensorgym reproduce`` creates it before the run) and,
    with plots, ``--no-plots``."""
    parser.add_argument(
        "--runs", type=types.positive_int, default=runs, help=f"{runs_help} (default {runs})"
    )
    parser.add_argument("--seed", type=types.seed, default=seed, help=f"root seed (default {seed})")
    parser.add_argument(
        "--out",
        type=Path,
        default=Path("results") / name,
        help=f"output directory (results/{name})",
    )
    if plots:
        parser.add_argument("--no-plots", action="store_true", help="skip the matplotlib figures")


def write_json(out: Path, filename: str, data: Any) -> Path:
    """Write ``data`` as ``out/filename`` (creating ``out``), print and return the path."""
    out.mkdir(parents=True, exist_ok=True)
    path = out / filename
    path.write_text(json.dumps(data, indent=1) + "\n")
    print(f"wrote {path}")
    return path


def publish(
    args: argparse.Namespace,
    filename: str,
    result: dict,
    report: str,
    write_figures: Callable[[dict, Path], list[Path]] | None = None,
) -> None:
    """Print the report and the run time, write the JSON and (unless ``--no-plots``) the figures."""
    print(report)
    write_json(args.out, filename, result)
    if write_figures is not None and not getattr(args, "no_plots", False):
        for path in write_figures(result, args.out):
            print(f"wrote {path}")
    if "seconds" in result:
        print(f"{result['seconds']:.1f} s")
