"""Short, one-line renderings of values read from files and the command line, for error
messages: a hostile file's value (a 350-byte YAML alias bomb stands for a list of 10⁹
entries) is never echoed whole."""

from __future__ import annotations

import reprlib
from typing import Any

_REPR = reprlib.Repr()
_REPR.maxlevel, _REPR.maxstring, _REPR.maxlong, _REPR.maxother = 3, 40, 40, 40
_REPR.maxlist = _REPR.maxtuple = _REPR.maxdict = _REPR.maxset = _REPR.maxfrozenset = 4
_REPR.maxdeque = _REPR.maxarray = 4


def brief(value: Any, limit: int = 80) -> str:
    """A ``repr`` of ``value`` of at most ``limit`` characters: at most 4 items of a container,
    3 levels deep, 40 characters of a string or number (:mod:`reprlib`), then cut."""
    try:
        text = _REPR.repr(value)
    except ValueError:  # an integer too long to print (Python's 4300-digit limit)
        text = f"<{type(value).__name__} of {value.bit_length()} bits>"
    return cut(text, limit)


def one_line(message: object, limit: int = 300) -> str:
    """``str(message)`` (an exception's message) on one line, at most ``limit`` characters;
    only the first ``4 × limit`` characters are ever looked at."""
    text = " ".join(str(message)[: 4 * limit].split())
    return cut(text or type(message).__name__, limit)


def cut(text: str, limit: int) -> str:
    """``text`` ending in ``…`` after ``limit − 1`` characters when it is longer."""
    return text if len(text) <= limit else text[: limit - 1] + "…"


def format_bytes(n: float) -> str:
    """``n`` bytes as text such as ``"1.5 GB"`` (powers of 1000)."""
    n = float(n) if n < 1e300 else float("inf")
    for unit in ("B", "kB", "MB", "GB", "TB", "PB"):
        if abs(n) < 1000 or unit == "PB":
            return f"{n:.3g} {unit}"
        n /= 1000
    raise AssertionError("unreachable")
