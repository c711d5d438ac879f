"""``--param NAME=VALUE``: set any params field of the env, for ``benchmark``, ``train`` and
``render`` alike (:mod:`sensorgym.train.env_params`); ``--hyperparam KEY=VALUE``: set any entry
of the training recipe, for ``train`` and ``sweep`` (:mod:`sensorgym.train.config`)."""

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


def params_from(env_id: str, pairs: list[str], scenarios: int = 1) -> dict[str, Any]:
    """The checked fields of ``--param`` for ``env_id``, ``scenarios`` of which must fit in
    this machine's memory (:func:`~sensorgym.train.env_params.parse_params`); a clear
    ``SystemExit`` otherwise."""
    from sensorgym.train.env_params import parse_params

    try:
        return parse_params(env_id, pairs, scenarios)
    except (KeyError, ValueError) as exc:
        raise SystemExit(str(exc.args[0]) if exc.args else str(exc)) from None


HYPERPARAM_HELP = (
    "set an entry of the YAML hyperparameters, the value read as YAML, e.g. --hyperparam "
    "learning_rate=3e-4, --hyperparam pretrain.steps=2000 (inside a mapping) or --hyperparam "
    "pretrain=null (no imitation phase); repeatable; recorded in the run's config.yaml"
)


def add_hyperparam_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--hyperparam", action="append", default=[], metavar="KEY=VALUE", help=HYPERPARAM_HELP
    )


def hyperparams_from(algo: str, env_id: str, pairs: list[str]) -> dict[str, Any]:
    """The overrides of ``--hyperparam``, checked against ``algo``'s set for ``env_id`` (a
    dotted key must go through mappings, a top-level key must be a run setting or a keyword
    of the algorithm); a clear ``SystemExit`` otherwise."""
    from sensorgym.train.config import check_overrides, parse_override

    try:
        overrides = dict(parse_override(pair) for pair in pairs)
        check_overrides(algo, env_id, overrides)
    except (KeyError, ValueError) as exc:
        raise SystemExit(f"--hyperparam: {exc.args[0] if exc.args else exc}") from None
    return overrides
