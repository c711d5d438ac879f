"""The rich console every command prints its tables and written files through.

On a terminal the tables take its width; in a log (stdout not a tty, where rich would
assume 80 columns) they take 160, so that a wide table stays whole. A file path is printed
as it is, on one line: never wrapped, however long, and never read as rich markup (a path may
hold ``[`` and ``]``), so that it can be copied from the output.
"""

from __future__ import annotations

import sys
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rich.console import Console

#: the table width when stdout is not a terminal
LOG_WIDTH = 160


def make_console() -> Console:
    """A console for stdout: the terminal's width, or :data:`LOG_WIDTH` in a log."""
    from rich.console import Console

    return Console(width=None if sys.stdout.isatty() else LOG_WIDTH)


def print_path(console: Console, text: str, path: Path | str) -> None:
    """Print ``text`` followed by ``path`` on one unwrapped line, with no markup read in either."""
    console.print(f"{text}{path}", soft_wrap=True, markup=False, highlight=False)


def print_written(console: Console, paths: Iterable[Path | str]) -> None:
    """Print ``wrote:`` and one path per line, each whole (:func:`print_path`)."""
    console.print("wrote:")
    for path in paths:
        print_path(console, "  ", path)
