"""An env's parameters set by name: ``--param NAME=VALUE`` on the command line, recorded in runs.

Every registered env takes its params dataclass's fields as keyword arguments (``gym.make(id,
n_drones=4)``); this module turns ``NAME=VALUE`` strings into such keywords, checks them by
building the params (so a bad value gets the field's own error message), and compares the
parameters a policy was trained with against those of the env it is asked to act in.
"""

from __future__ import annotations

import ast
import dataclasses
from collections.abc import Iterable
from typing import Any


def params_type(env_id: str) -> type:
    """The params dataclass of a registered env id."""
    import gymnasium as gym

    import sensorgym.envs  # noqa: F401  (registers the ids)

    if env_id not in gym.registry:
        raise KeyError(f"{env_id!r} is not a registered env id")
    entry = gym.spec(env_id).entry_point
    if isinstance(entry, str):
        module, _, attr = entry.partition(":")
        entry = getattr(__import__(module, fromlist=[attr]), attr)
    return entry.params_type


def _value(text: str, default: Any) -> Any:
    """A Python literal from ``text`` (``16``, ``0.5``, ``(1, 2)``, ``true``), shaped like the
    field's default: a list becomes a tuple, an integer for a float field a float."""
    lowered = text.strip().lower()
    if lowered in ("true", "false"):
        value: Any = lowered == "true"
    else:
        try:
            value = ast.literal_eval(text.strip())
        except (ValueError, SyntaxError):
            value = text.strip()  # a bare word: a string field's value
    if isinstance(value, list):
        value = tuple(value)
    if isinstance(default, float) and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    if isinstance(default, tuple) and isinstance(value, tuple) and default:
        if all(isinstance(d, float) for d in default):
            value = tuple(
                float(v) if isinstance(v, int) and not isinstance(v, bool) else v for v in value
            )
    return value


def parse_params(env_id: str, pairs: Iterable[str]) -> dict[str, Any]:
    """``{field: value}`` from ``NAME=VALUE`` strings, checked by building ``env_id``'s params;
    ``ValueError`` with the field's own message otherwise."""
    kind = params_type(env_id)
    defaults = {f.name: _default(f) for f in dataclasses.fields(kind)}
    fields: dict[str, Any] = {}
    for pair in pairs:
        name, sep, text = pair.partition("=")
        name = name.strip()
        if not sep or not name:
            raise ValueError(f"--param: expected NAME=VALUE, got {pair!r}")
        if name not in defaults:
            raise ValueError(
                f"--param: {name!r} is not a parameter of {env_id} ({kind.__name__}: "
                f"{', '.join(sorted(defaults))})"
            )
        fields[name] = _value(text, defaults[name])
    resolve(env_id, fields)
    return fields


def _default(field: dataclasses.Field) -> Any:
    if field.default is not dataclasses.MISSING:
        return field.default
    if field.default_factory is not dataclasses.MISSING:
        return field.default_factory()
    return None


def resolve(env_id: str, fields: dict[str, Any] | None) -> Any:
    """The params of ``env_id`` with ``fields`` set; ``ValueError`` naming the field when the
    params refuse them."""
    kind = params_type(env_id)
    try:
        return kind(**(fields or {}))
    except (TypeError, ValueError) as exc:
        raise ValueError(f"--param: {exc}") from None


def check_same_env(
    env_id: str, trained: dict[str, Any] | None, asked: dict[str, Any] | None, what: str
) -> None:
    """``ValueError`` saying which parameters differ when a policy trained with ``trained``
    is asked to act in an env with ``asked`` (both: overrides of the defaults)."""
    a, b = resolve(env_id, trained), resolve(env_id, asked)
    if a == b:
        return
    diff = [
        f"{f.name}: trained with {getattr(a, f.name)!r}, asked for {getattr(b, f.name)!r}"
        for f in dataclasses.fields(a)
        if getattr(a, f.name) != getattr(b, f.name)
    ]
    raise ValueError(f"{what} was trained on another {env_id}: " + "; ".join(diff))
