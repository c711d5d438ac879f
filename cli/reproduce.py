"""``sensorgym reproduce NAME``: rerun a paper's experiment and print our numbers beside its.

Reproductions live in :mod:`sensorgym.reproduce`, one module per paper or benchmark; they
are discovered by name (``bot_benchmark`` is run as ``bot-benchmark``). Each exposes
``HELP``, ``add_arguments(parser)`` and ``run(args) -> int``.
"""

from __future__ import annotations

import argparse
import importlib
import pkgutil
from pathlib import Path

import sensorgym.reproduce

HELP = "Reproduce a source paper's tables and figures (seeded Monte Carlo)."


def available() -> dict[str, str]:
    """Reproduction name -> module name, found in the ``sensorgym.reproduce`` package."""
    found = {}
    for info in pkgutil.iter_modules(sensorgym.reproduce.__path__):
        if not info.name.startswith("_") and not info.ispkg:
            found[info.name.replace("_", "-")] = f"sensorgym.reproduce.{info.name}"
    return dict(sorted(found.items()))


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="reproduction", required=True, metavar="NAME")
    for name, module_name in available().items():
        module = importlib.import_module(module_name)
        p = sub.add_parser(name, help=module.HELP, description=module.HELP)
        module.add_arguments(p)
        p.set_defaults(_reproduce=module.run)


def run(args: argparse.Namespace) -> int:
    """Run the reproduction; its ``--out`` folder is created (and checked) first, so that a
    bad one fails before the Monte Carlo runs, not after."""
    from sensorgym.cli.args import output_dir

    if isinstance(getattr(args, "out", None), Path):
        output_dir(args.out)
    return int(args._reproduce(args) or 0)
