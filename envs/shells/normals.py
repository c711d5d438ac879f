"""Standard normal draws of an env's ``np.random.Generator``, compiled, in the Generator's own
stream.

numba compiles NumPy's ziggurat on the Generator's bit generator (any of NumPy's: PCG64,
PCG64DXSM, Philox, SFC64, MT19937), so :func:`standard_normal_rows` over consecutive row ranges
fills exactly what ``rng.standard_normal(out.shape)`` would return (small fills take NumPy's
own call, the same draws), and leaves the Generator where that call would
(``tests/envs/test_normals.py`` checks both). It is faster than NumPy's own call on large fills
and, filling rows ``lo..hi`` only, lets a threaded step start the kernel on the first rows while
the rest are drawn (:func:`sensorgym.envs.shells.rows.run_drawn_rows`).
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from sensorgym.envs.shells.streams import RowGenerator

#: draws below which NumPy's own call is faster (numba's call pays a fixed cost to unbox the
#: Generator, many times NumPy's own call overhead)
COMPILED_MIN_DRAWS = 8192


@njit(cache=True, nogil=True)
def _fill(rng, flat, start, stop):
    for i in range(start, stop):
        flat[i] = rng.standard_normal()


def standard_normal_rows(
    rng: np.random.Generator | RowGenerator, out: NDArray[np.float64], lo: int, hi: int
) -> None:
    """Fill rows ``out[lo:hi]`` (C-contiguous float64, rows along the first axis) with the
    Generator's next standard normal draws, in C order. Calls over consecutive ranges from 0
    to ``len(out)`` draw what one ``rng.standard_normal(out.shape)`` draws."""
    if isinstance(rng, RowGenerator):  # one stream per row (common random numbers)
        rng.standard_normal_rows(out, lo, hi)
        return
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng: expected a numpy.random.Generator, got {type(rng).__name__}")
    if not (isinstance(out, np.ndarray) and out.dtype == np.float64 and out.flags.c_contiguous):
        raise ValueError("out: expected a C-contiguous float64 array")
    if not (0 <= lo <= hi <= out.shape[0]):
        raise ValueError(f"rows: expected 0 <= lo <= hi <= {out.shape[0]}, got {lo}, {hi}")
    per_row = out.size // out.shape[0] if out.shape[0] else 0
    if (hi - lo) * per_row >= COMPILED_MIN_DRAWS:
        _fill(rng, out.reshape(-1), lo * per_row, hi * per_row)
    elif hi > lo:
        rng.standard_normal(out=out[lo:hi])
