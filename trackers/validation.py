"""Input checks shared by every tracker: clear ``ValueError`` s that name the argument.

Trackers are called from environments with arrays built elsewhere; a wrong shape or a NaN
must fail at the boundary with a message a user understands, never deep inside numpy.
"""

from __future__ import annotations

import dataclasses
import functools
import types
import typing
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray


def finite_array(
    value: ArrayLike, name: str, *, tail: tuple[int, ...] = (), check: bool = True
) -> NDArray[np.float64]:
    """Return ``value`` as a float64 array whose trailing dimensions equal ``tail``.

    Raises ``ValueError`` naming ``name`` if the shape does not end in ``tail`` or, with
    ``check`` (the default), if any element is NaN or infinite. ``check=False`` keeps only
    the shape check, like scipy's ``check_finite=False``, for callers whose arrays are known
    good (e.g. an environment's own simulation) and that need the speed.
    """
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: cannot be read as an array of floats ({exc})") from None
    if tail:
        if arr.ndim < len(tail) or arr.shape[arr.ndim - len(tail) :] != tail:
            want = "(..., " + ", ".join(str(t) for t in tail) + ")"
            raise ValueError(f"{name}: expected shape {want}, got {arr.shape}")
    if not check:
        return arr
    # one fast reduction first: the sum is finite unless an element is NaN/inf (or it overflows,
    # which the elementwise check below then clears; the overflow itself is no error)
    with np.errstate(over="ignore", invalid="ignore"):
        total = arr.sum()
    if not np.isfinite(total) and not np.isfinite(arr).all():
        raise ValueError(f"{name}: contains NaN or infinite values")
    return arr


def unit_vector_components(
    value: ArrayLike, name: str, *, atol: float = 1e-6, check: bool = True
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Checked unit vectors ``(..., 3)`` and their components as a contiguous ``(3, ...)`` array.

    Zero-length vectors are rejected; vectors whose norm differs from 1 by more than ``atol``
    are rejected rather than silently renormalised, because a non-unit direction vector means
    the caller mixed up positions and directions (``check=False``: shape only). The
    component-major copy lets batched kernels work on contiguous rows (numpy reduces a trailing
    axis of length 3 slowly).
    """
    arr = finite_array(value, name, tail=(3,), check=False)
    comp = np.ascontiguousarray(np.moveaxis(arr, -1, 0))
    if not check:
        return arr, comp
    check_unit_norms(
        comp,
        arr,
        name,
        "direction vectors must have unit length",
        atol=atol,
        zero_what="contains a zero-length direction vector",
    )
    return arr, comp


def unit_vectors(value: ArrayLike, name: str, *, atol: float = 1e-6) -> NDArray[np.float64]:
    """Return ``value`` (shape ``(..., 3)``) checked to hold unit vectors (see above)."""
    return unit_vector_components(value, name, atol=atol)[0]


def check_unit_norms(
    comp: NDArray[np.float64],
    source: ArrayLike,
    name: str,
    what: str,
    *,
    atol: float = 1e-6,
    zero_what: str | None = None,
) -> None:
    """Raise ``ValueError`` naming ``name`` unless every vector of ``comp (3, ...)`` has unit length.

    ``source`` is the argument the vectors came from: NaN or infinite values in it are reported
    as such (‖v‖² is finite everywhere iff its sum is, so one reduction serves both checks).
    ``what`` completes the message for wrong lengths, ``zero_what`` for zero-length vectors.
    """
    x, y, z = comp
    with np.errstate(over="ignore", invalid="ignore"):
        norm2 = x * x + y * y + z * z
        total = norm2.sum()
    if not np.isfinite(total):
        finite_array(source, name)
    # |‖v‖² − 1| ≈ 2 |‖v‖ − 1|
    if np.any(np.abs(norm2 - 1.0) > 2.0 * atol):
        if zero_what is not None and np.any(norm2 == 0.0):
            raise ValueError(f"{name}: {zero_what}")
        worst = float(np.max(np.abs(np.sqrt(norm2) - 1.0)))
        raise ValueError(f"{name}: {what} (max |‖v‖ − 1| = {worst:.3g})")


def is_integer(value: object) -> bool:
    """True for a Python or numpy integer that is not a bool (``True`` is an ``int`` to Python,
    never a count to a user; numpy's ``bool_`` is no integer either), False for anything else,
    an integral float such as ``2.0`` included."""
    return isinstance(value, int | np.integer) and not isinstance(value, bool)


def is_real(value: object) -> bool:
    """True for a Python or numpy integer or float that is not a bool (Python's or numpy's)."""
    return isinstance(value, int | float | np.integer | np.floating) and not isinstance(value, bool)


def count(value: object, name: str, minimum: int = 1) -> int:
    """``value`` as an ``int`` of at least ``minimum``.

    A bool, a float (even ``2.0``), a string or anything else not an integer
    (:func:`is_integer`) raises ``TypeError``, a smaller one ``ValueError``; both say
    ``"name: must be an integer >= minimum, got value"``.
    """
    if not is_integer(value):
        raise TypeError(f"{name}: must be an integer >= {minimum}, got {value!r}")
    if value < minimum:  # type: ignore[operator]
        raise ValueError(f"{name}: must be an integer >= {minimum}, got {value}")
    return int(value)  # type: ignore[arg-type]


def check_fields(params: Any) -> None:
    """Raise naming the field unless every field of the dataclass ``params`` holds a value of
    its annotated type; every env's and tracker's params call it first in ``__post_init__``.

    The annotations are the contract, read type-exactly:

    * ``int``: a Python or numpy integer, not a bool and not a float, even ``2.0``
      (:func:`is_integer`);
    * ``float``: any real number, not a bool (:func:`is_real`);
    * ``bool``: ``True`` or ``False`` (Python's or numpy's), not ``0`` or ``1``;
    * ``str``: a string; any other class: an instance of it;
    * ``tuple[float, float]``: a tuple, list or 1-d array of exactly that many values of the
      element types; ``tuple[float, ...]``: of any number;
    * ``X | None``: also ``None``; ``Literal[a, b]``: one of the values (else ``ValueError``).

    Other annotations (``Any``) are not checked. A wrong type raises ``TypeError``, one line,
    ``"name: must be an integer, got True"``. Ranges and relations between fields remain each
    params' own checks.
    """
    for name, hint in _field_hints(type(params)):
        value = getattr(params, name)
        if _matches(value, hint):
            continue
        if typing.get_origin(hint) is Literal:
            raise ValueError(f"{name}: must be {_describe(hint)}, got {value!r}")
        raise TypeError(f"{name}: must be {_describe(hint)}, got {value!r}")


@functools.cache
def _field_hints(cls: type) -> tuple[tuple[str, Any], ...]:
    """``(name, resolved annotation)`` of every dataclass field of ``cls``, resolved once."""
    hints = typing.get_type_hints(cls)
    return tuple((f.name, hints[f.name]) for f in dataclasses.fields(cls))


def _is_union(hint: Any) -> bool:
    return typing.get_origin(hint) in (typing.Union, types.UnionType)


def _matches(value: object, hint: Any) -> bool:
    """Whether ``value`` is of type ``hint`` as :func:`check_fields` reads it."""
    if hint is Any:
        return True
    if _is_union(hint):
        return any(_matches(value, h) for h in typing.get_args(hint))
    origin = typing.get_origin(hint)
    if origin is Literal:
        return any(isinstance(value, type(v)) and value == v for v in typing.get_args(hint))
    if origin is tuple:
        if isinstance(value, np.ndarray):
            if value.ndim != 1:
                return False
        elif not isinstance(value, tuple | list):
            return False
        args = typing.get_args(hint)
        if len(args) == 2 and args[1] is Ellipsis:
            return all(_matches(v, args[0]) for v in value)
        return len(value) == len(args) and all(map(_matches, value, args))
    if hint is type(None) or hint is None:
        return value is None
    if hint is int:
        return is_integer(value)
    if hint is float:
        return is_real(value)
    if hint is bool:
        return isinstance(value, bool | np.bool_)
    if isinstance(hint, type):
        return isinstance(value, hint)
    return True


_PLURALS = {int: "integers", float: "real numbers", bool: "bools", str: "strings"}


def _describe(hint: Any) -> str:
    """``hint`` in words, for :func:`check_fields`' messages (``"a pair of real numbers"``)."""
    if _is_union(hint):
        return " or ".join(_describe(h) for h in typing.get_args(hint))
    origin = typing.get_origin(hint)
    if origin is Literal:
        return "one of " + ", ".join(repr(v) for v in typing.get_args(hint))
    if origin is tuple:
        args = typing.get_args(hint)
        if len(args) == 2 and args[1] is Ellipsis:
            return f"a tuple of {_PLURALS.get(args[0], 'values')}"
        if len(set(args)) == 1:
            what = _PLURALS.get(args[0], "values")
            return f"a pair of {what}" if len(args) == 2 else f"a tuple of {len(args)} {what}"
        return f"a tuple ({', '.join(_describe(a) for a in args)})"
    if hint is type(None) or hint is None:
        return "None"
    names = {int: "an integer", float: "a real number", bool: "True or False", str: "a string"}
    if hint in names:
        return names[hint]
    return f"a {getattr(hint, '__name__', hint)}"
