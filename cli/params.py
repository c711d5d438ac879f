"""``--param NAME=VALUE``: set any params field of the env, for ``benchmark``, ``train`` and
``render`` alike (:mod:`sensorgym.train.env_params`)."""

from __future__ import annotations

import argparse
from typing import Any

PARAM_HELP = (
    "set a field of the env's params, e.g. --param n_drones=4 or --param "
    "initial_range='(5000, 20000)'; repeatable; checked by the params' own validation"
)


def add_param_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--param", action="append", default=[], metavar="NAME=VALUE", help=PARAM_HELP
    )


def params_from(env_id: str, pairs: list[str]) -> dict[str, Any]:
    """The checked fields of ``--param`` for ``env_id``; a clear ``SystemExit`` otherwise."""
    from sensorgym.train.env_params import parse_params

    try:
        return parse_params(env_id, pairs)
    except (KeyError, ValueError) as exc:
        raise SystemExit(str(exc.args[0]) if exc.args else str(exc)) from None
