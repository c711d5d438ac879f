"""The rich console every command prints its tables and written files through.

On a terminal the tables take its width; in a log (stdout not a tty, where rich would
assume 80 columns) they take 160, so that a wide table stays whole. A file path is printed
as it is, on one line: never wrapped, however long, and never read as rich markup (a path may
hold ``[`` and ``]``), so that it can be copied from the output.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Any

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


class Steps:
    """Progress through ``total`` named steps of a long command: a rich progress bar on a
    terminal (what runs now, how many are done), a line per finished step with its seconds in
    a log, so that a first run never looks hung.

    ``with Steps(console, "StereoPointing-v0", 12) as steps:`` then ``steps.start(name)``
    before each step; a step ends when the next starts or the block ends."""

    def __init__(self, console: Console, title: str, total: int):
        self.console, self.title, self.total = console, title, total
        self.done, self._name, self._t0 = 0, None, 0.0
        self._progress: Any = None
        self._task: Any = None

    def __enter__(self) -> Steps:
        if self.console.is_terminal:
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                Progress,
                TextColumn,
                TimeElapsedColumn,
            )

            self._progress = Progress(
                TextColumn("{task.description}"),
                BarColumn(),
                MofNCompleteColumn(),
                TimeElapsedColumn(),
                console=self.console,
                transient=True,
            )
            self._task = self._progress.add_task(self.title, total=self.total)
            self._progress.start()
        return self

    def start(self, name: str) -> None:
        """Step ``name`` begins (and the one before it has ended)."""
        self._finish()
        self._name, self._t0 = name, time.perf_counter()
        if self._progress is not None:
            self._progress.update(self._task, description=f"{self.title}: {name}")

    def _finish(self) -> None:
        if self._name is None:
            return
        self.done += 1
        if self._progress is not None:
            self._progress.update(self._task, completed=self.done)
        else:
            seconds = time.perf_counter() - self._t0
            self.console.print(
                f"{self.title}: {self._name} ({self.done}/{self.total}, {seconds:.1f} s)",
                markup=False,
                highlight=False,
            )
        self._name = None

    def __exit__(self, *exc: object) -> None:
        if exc[0] is None:
            self._finish()
        if self._progress is not None:
            self._progress.stop()
