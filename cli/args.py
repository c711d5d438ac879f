"""Argument types and output checks every ``sensorgym`` command shares.

A bad value ends in one line and a non-zero exit, never a traceback: the ``type=`` functions
below raise :class:`argparse.ArgumentTypeError`, which the parser reports as
``sensorgym CMD: error: argument --seed: must be an integer in [0, 2147483647], got -1``
(:class:`OneLineParser`), before any work. Output locations are checked (and folders created)
by :func:`output_dir` and :func:`output_file` when a command starts, not after minutes of
scoring or training.
"""

from __future__ import annotations

import argparse
import math
import os
from pathlib import Path
from typing import NoReturn

from sensorgym.train.messages import cut

#: the largest seed a command takes: every seed a run derives (seed + k) stays a valid seed of
#: NumPy's legacy ``np.random.seed`` (< 2**32), which SB3 calls
MAX_SEED = 2**31 - 1

#: frames per second of a rendered GIF: a frame's delay is stored in hundredths of a second
#: (at most 655.35 s), so 0.01 fps (100 s a frame) to 100 fps (10 ms a frame)
FPS_RANGE = (0.01, 100.0)


class OneLineParser(argparse.ArgumentParser):
    """An ``ArgumentParser`` whose errors are one line (``PROG: error: MESSAGE (see PROG
    --help)``) and exit with status 2, without the usage block argparse prints first."""

    def error(self, message: str) -> NoReturn:
        text = " ".join(message.split())
        self.exit(2, f"{self.prog}: error: {text} (see {self.prog} --help)\n")


class DefaultsHelpFormatter(argparse.HelpFormatter):
    """Help that states each option's default, ``(default: X)``, unless the option has none
    (``None``, ``False``, an empty list) or its help already says it (``default`` in the
    text, e.g. "default: every registered env")."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        default = action.default
        if (
            "default" in text.lower()
            or default in (None, False, argparse.SUPPRESS)
            or (isinstance(default, list | tuple) and not default)
            or not action.option_strings
        ):
            return text
        return f"{text} (default: %(default)s)"


def _integer(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {_short(text)!r}") from None


def seed(text: str) -> int:
    """A seed: an integer in ``[0, MAX_SEED]``."""
    value = _integer(text)
    if not 0 <= value <= MAX_SEED:
        raise argparse.ArgumentTypeError(
            f"must be an integer in [0, {MAX_SEED}], got {_short(text)}"
        )
    return value


def positive_int(text: str) -> int:
    """An integer >= 1 (episodes, scenarios, runs, timesteps, threads)."""
    value = _integer(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be an integer >= 1, got {_short(text)}")
    return value


def non_negative_int(text: str) -> int:
    """An integer >= 0 (a count that may be zero: "none")."""
    value = _integer(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be an integer >= 0, got {_short(text)}")
    return value


def positive_float(text: str) -> float:
    """A finite number > 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {_short(text)!r}") from None
    if not (math.isfinite(value) and value > 0.0):
        raise argparse.ArgumentTypeError(f"must be a finite number > 0, got {_short(text)}")
    return value


def fps(text: str) -> float:
    """Frames per second of a GIF: a finite number in :data:`FPS_RANGE`."""
    lo, hi = FPS_RANGE
    value = positive_float(text)
    if not lo <= value <= hi:
        raise argparse.ArgumentTypeError(f"must lie in [{lo:g}, {hi:g}], got {_short(text)}")
    return value


def output_dir(path: Path, flag: str = "--out") -> Path:
    """``path`` as a folder the command can write into: created now (with its parents) when
    missing; ``SystemExit`` with one line naming ``flag`` when it is a file, lies under one, or
    is not writable."""
    path = Path(path)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        raise SystemExit(f"{flag}: {path} exists and is not a folder") from None
    except OSError as exc:
        raise SystemExit(f"{flag}: cannot create the folder {path} ({_os_reason(exc)})") from None
    if not os.access(path, os.W_OK | os.X_OK):
        raise SystemExit(f"{flag}: the folder {path} is not writable")
    return path


def output_file(path: Path, flag: str = "--out") -> Path:
    """``path`` as a file the command can write: its folder created now (:func:`output_dir`);
    ``SystemExit`` with one line naming ``flag`` when ``path`` is a folder or a file that
    cannot be overwritten."""
    path = Path(path)
    output_dir(path.parent, flag)
    if path.is_dir():
        raise SystemExit(f"{flag}: {path} is a folder, not a file")
    if path.exists() and not os.access(path, os.W_OK):
        raise SystemExit(f"{flag}: {path} exists and is not writable")
    return path


def _os_reason(exc: OSError) -> str:
    return exc.strerror or type(exc).__name__


def _short(text: str) -> str:
    """``text`` cut to 40 characters (a value echoed in a message)."""
    return cut(text, 40)
