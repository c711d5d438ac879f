"""Params that pickle as their fields alone, without the derived values cached on them.

Every env's params is a frozen dataclass that caches derived arrays on itself
(``functools.cached_property`` and the like): the constants and geometry its compiled kernels
read, marked read-only. Pickle would carry those arrays along and bring them back *writable*;
numba types a writable array differently from a read-only one, so the first step of an
unpickled env (a ``SubprocVecEnv`` worker, a checkpoint) compiled every kernel anew, about a
minute for ``StereoScanning-v0``, bypassing the disk cache that ``sensorgym compile`` filled.
Pickled as fields only, the copy recomputes each derived value on first use, read-only again.
"""

from __future__ import annotations

from dataclasses import fields
from typing import Any


class FieldsOnlyPickle:
    """Mixin for a frozen dataclass: pickle its fields, not the values cached on the instance
    (every other entry of its ``__dict__``), which the copy recomputes on first use."""

    def __getstate__(self) -> dict[str, Any]:
        return {f.name: self.__dict__[f.name] for f in fields(self)}  # type: ignore[arg-type]
