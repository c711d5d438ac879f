"""``sensorgym`` command line: one parser, one module per subcommand.

Each subcommand module exposes ``HELP`` (one line), ``add_arguments(parser)`` and
``run(args) -> int``, and may name other names of the command in ``ALIASES``. Every module is imported to build the parser, so subcommand modules
keep their module-level imports light and import heavy libraries inside ``run``.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from importlib.metadata import version

from sensorgym.cli.args import DefaultsHelpFormatter, OneLineParser

#: subcommand name -> module implementing it
COMMANDS: dict[str, str] = {
    "triangulate-demo": "sensorgym.cli.triangulate_demo",
    "reproduce": "sensorgym.cli.reproduce",
    "benchmark": "sensorgym.cli.benchmark",
    "train": "sensorgym.cli.train",
    "render": "sensorgym.cli.render",
    "sweep": "sensorgym.cli.sweep",
    "compile": "sensorgym.cli.compile",
}

#: the main job: what ``scripts/run.sh`` runs when given no arguments (bare ``sensorgym``, like
#: any other CLI, prints its help and names it)
DEFAULT_JOB: list[str] = ["benchmark"]


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(
        prog="sensorgym",
        description="Sensor-management environments and passive-location trackers.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {version('sensorgym')}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, module_name in COMMANDS.items():
        module = importlib.import_module(module_name)
        aliases = getattr(module, "ALIASES", [])
        p = sub.add_parser(
            name,
            aliases=aliases,
            help=module.HELP,
            description=module.HELP,
            formatter_class=DefaultsHelpFormatter,
        )
        module.add_arguments(p)
        p.set_defaults(_run=module.run)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run ``sensorgym ARGS``; with no arguments at all, print the help and the main job
    (:data:`DEFAULT_JOB`, which ``scripts/run.sh`` runs) and return 0.

    A mistake in the arguments, the environment or a model folder ends in one line and a
    non-zero exit, never a traceback: the parser's errors (status 2), ``SENSORGYM_THREADS``
    checked before the command runs, and a run folder refused anywhere in a command
    (:class:`~sensorgym.train.models.RunFolderError`, status 1).
    """
    if argv is None:
        argv = sys.argv[1:]
    parser = build_parser()
    if not argv:
        parser.print_help()
        print(
            f"\nThe main job: sensorgym {' '.join(DEFAULT_JOB)} (what `bash scripts/run.sh` runs)."
        )
        return 0
    args = parser.parse_args(argv)
    _check_environment()
    try:
        return int(args._run(args) or 0)
    except Exception as exc:
        # a RunFolderError exists only once its (heavy) module is loaded: never import it here
        models = sys.modules.get("sensorgym.train.models")
        if models is None or not isinstance(exc, models.RunFolderError):
            raise
        raise SystemExit(f"sensorgym {args.command}: {models.one_line(exc)}") from None


def _check_environment() -> None:
    """``SystemExit`` with one line when ``SENSORGYM_THREADS`` is set to something other than
    a thread count (empty counts as unset, :func:`sensorgym.envs.shells.rows.threads`)."""
    if not os.environ.get("SENSORGYM_THREADS", "").strip():
        return  # unset: nothing to import
    from sensorgym.envs.shells.rows import threads

    try:
        threads()
    except ValueError as exc:
        raise SystemExit(str(exc)) from None


if __name__ == "__main__":
    raise SystemExit(main())
