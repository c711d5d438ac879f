"""An env's parameters set by name: ``--param NAME=VALUE`` on the command line, recorded in runs.

Every registered env takes its params dataclass's fields as keyword arguments (``gym.make(id,
n_drones=4)``); this module turns ``NAME=VALUE`` strings into such keywords, checks them by
building the params (so a bad value gets the field's own error message), and compares the
parameters a policy was trained with against those of the env it is asked to act in.
"""

from __future__ import annotations

import ast
import dataclasses
import math
import os
from collections.abc import Iterable
from typing import Any

from sensorgym.train.messages import brief, format_bytes, one_line


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


#: the longest value text ``--param`` reads (a tuple of hundreds of numbers fits)
MAX_VALUE_CHARS = 10_000


def _value(text: str, default: Any) -> Any:
    """A Python literal from ``text`` (``16``, ``0.5``, ``(1, 2)``, ``true``), shaped like the
    field's default: a list becomes a tuple, an integer for a float field a float.
    ``ValueError`` when the text is longer than :data:`MAX_VALUE_CHARS` or nested too deeply
    to read (``-`` repeated thousands of times)."""
    if len(text) > MAX_VALUE_CHARS:
        raise ValueError(f"the value is {len(text)} characters long, more than {MAX_VALUE_CHARS}")
    lowered = text.strip().lower()
    if lowered in ("true", "false"):
        value: Any = lowered == "true"
    else:
        try:
            value = ast.literal_eval(text.strip())
        except (ValueError, SyntaxError):
            value = text.strip()  # a bare word: a string field's value
        except (RecursionError, MemoryError):
            raise ValueError("the value is nested too deeply to read") from None
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


def parse_params(env_id: str, pairs: Iterable[str], scenarios: int = 1) -> dict[str, Any]:
    """``{field: value}`` from ``NAME=VALUE`` strings, checked by building ``env_id``'s params
    (``ValueError`` with the field's own message otherwise) and against the memory of this
    machine for ``scenarios`` scenarios at once (:func:`check_memory`)."""
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
        try:
            fields[name] = _value(text, defaults[name])
        except ValueError as exc:
            raise ValueError(f"--param {name}: {exc}") from None
    resolve(env_id, fields)
    try:
        check_memory(env_id, fields, scenarios)
    except ValueError as exc:
        raise ValueError(f"--param {exc}" if _counts(fields) else str(exc)) from None
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
        raise ValueError(f"--param: {one_line(exc)}") from None


def check_same_env(
    env_id: str, trained: dict[str, Any] | None, asked: dict[str, Any] | None, what: str
) -> None:
    """``ValueError`` saying which parameters differ when a policy trained with ``trained``
    is asked to act in an env with ``asked`` (both: overrides of the defaults)."""
    a, b = resolve(env_id, trained), resolve(env_id, asked)
    if a == b:
        return
    diff = [
        f"{f.name}: trained with {brief(getattr(a, f.name))}, asked for {brief(getattr(b, f.name))}"
        for f in dataclasses.fields(a)
        if getattr(a, f.name) != getattr(b, f.name)
    ]
    raise ValueError(f"{what} was trained on another {env_id}: " + "; ".join(diff))


#: integer fields (counts: drones, receivers, bank members) at most this are taken as they are;
#: a larger one makes :func:`check_memory` probe the env
PROBE_ABOVE = 64
#: a batch of more scenarios than this is probed as well
PROBE_SCENARIOS = 1024
#: the probe builds the env with its largest count field at 4, 8, 16, … up to this
PROBE_MAX_SIZE = 256
#: the probe stops doubling before a build it expects to trace more than this many bytes
PROBE_BUDGET = 32_000_000
#: when the probe cannot build the env at small sizes (fields that constrain one another), no
#: count field may exceed this
UNPROBED_LIMIT = 100_000


def check_memory(
    env_id: str, fields: dict[str, Any], scenarios: int = 1, available: int | None = None
) -> None:
    """``ValueError`` (one line, naming the field and the estimate) when ``scenarios``
    scenarios of ``env_id`` with the params ``fields`` would need more memory than
    ``available`` bytes (default: what this machine has available now,
    :func:`available_memory`), before anything of that size is allocated.

    Only large requests are estimated (a count field above :data:`PROBE_ABOVE` or more than
    :data:`PROBE_SCENARIOS` scenarios), by :func:`memory_estimate`; when the env cannot be
    probed at small sizes, no count field may exceed :data:`UNPROBED_LIMIT`.
    """
    counts = _counts(fields)
    if not counts and scenarios <= PROBE_SCENARIOS:
        return
    available = available_memory() if available is None else available
    if available is None:
        return  # nothing to compare with
    estimate = memory_estimate(env_id, fields, scenarios)
    if counts:
        name = max(counts, key=counts.__getitem__)
        what = f"{name}={brief(counts[name])}"
    else:
        what = f"{scenarios} scenarios"
    if estimate is None:
        if counts and counts[name] > UNPROBED_LIMIT:
            raise ValueError(
                f"{what}: the env could not be probed at smaller sizes to estimate its memory; "
                f"a count above {UNPROBED_LIMIT} is refused"
            )
        return
    if estimate > available:
        batch = "" if scenarios == 1 else f" for {scenarios} scenarios"
        raise ValueError(
            f"{what}: {env_id} would need ~{format_bytes(estimate)}{batch}, more than the "
            f"{format_bytes(available)} this machine has available (estimated from the env "
            f"built at smaller sizes)"
        )


def memory_estimate(env_id: str, fields: dict[str, Any], scenarios: int = 1) -> float | None:
    """Estimated bytes of ``scenarios`` scenarios of ``env_id`` with the params ``fields``,
    without building it at that size; ``None`` when the env cannot be built at the probe sizes.

    The env is built, reset and stepped once with one scenario at small sizes, the memory it
    allocates traced each time (:mod:`tracemalloc`): its count fields above
    :data:`PROBE_ABOVE` scaled together so that the largest is 4, 8, 16, … (the others in
    proportion, at least 2), doubling while a build stays within :data:`PROBE_BUDGET` and
    :data:`PROBE_MAX_SIZE`. When the requested size is within reach it is measured itself;
    otherwise the growth between the last probes gives a power law in the size (the exponent
    of the last two increments, between 1 and 4; 4 with only two probes), extrapolated to the
    requested size. The result is multiplied by ``scenarios``: an estimate that errs high,
    meant to refuse what a machine cannot hold, not to budget.
    """
    counts = _counts(fields)
    largest = max(counts.values(), default=0)

    def at(size: int | None) -> int:
        scale = 1.0 if size is None else size / largest
        probe = {**fields, **{k: max(round(v * scale), 2) for k, v in counts.items()}}
        return _traced_bytes(env_id, probe)

    try:
        at(4 if counts else None)  # the first build also loads what the env imports
        if not counts:
            return float(at(None)) * scenarios
        measured: list[tuple[int, int]] = []
        size = 4
        while True:
            if size >= largest:
                return float(at(None)) * scenarios  # within reach: measured, not estimated
            measured.append((size, at(size)))
            last = measured[-1][1]
            grows = last * last / max(measured[-2][1], 1) if len(measured) > 1 else 4 * last
            if 2 * size > PROBE_MAX_SIZE or grows > PROBE_BUDGET:
                break
            size *= 2
    except Exception:  # the env refuses the probe sizes: no estimate
        return None
    if len(measured) < 2:
        return None
    (_, b1), (s2, b2) = measured[-2:]
    power = 4.0
    if len(measured) > 2:
        b0 = measured[-3][1]
        d1, d2 = b1 - b0, b2 - b1
        power = min(max(math.log2(d2 / d1), 1.0), 4.0) if d1 > 0 and d2 > 0 else 1.0
    d = max(b2 - b1, 0)
    t = largest / s2
    grown = d * (t**power - 1.0) / (1.0 - 2.0**-power)
    return (b2 + grown) * scenarios


def _counts(fields: dict[str, Any]) -> dict[str, int]:
    """The integer fields of ``fields`` above :data:`PROBE_ABOVE`."""
    return {
        k: v
        for k, v in fields.items()
        if isinstance(v, int) and not isinstance(v, bool) and v > PROBE_ABOVE
    }


def _traced_bytes(env_id: str, fields: dict[str, Any]) -> int:
    """Peak bytes traced while one scenario of ``env_id`` with ``fields`` is built, reset and
    stepped once (with a zero action)."""
    import tracemalloc

    import gymnasium as gym
    import numpy as np

    import sensorgym.envs  # noqa: F401  (registers the ids)

    started = not tracemalloc.is_tracing()
    if started:
        tracemalloc.start()
    before = tracemalloc.get_traced_memory()[0]
    tracemalloc.reset_peak()
    try:
        env = gym.make(env_id, disable_env_checker=True, **fields)
        try:
            env.reset(seed=0)
            env.step(np.zeros(env.action_space.shape, env.action_space.dtype))
        finally:
            env.close()
        return tracemalloc.get_traced_memory()[1] - before
    finally:
        if started:
            tracemalloc.stop()


def available_memory() -> int | None:
    """Bytes of memory this machine has available now (``MemAvailable`` of ``/proc/meminfo``,
    else the physical memory); ``None`` when neither can be read."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None
