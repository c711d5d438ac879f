"""The one form every compiled kernel takes its array inputs in.

numba compiles a kernel once for each combination of argument types it meets, and an array's
type holds its layout (``'C'`` or ``'A'``) and whether it is read-only. ``np.broadcast_to``
returns read-only views, even when nothing is broadcast; a caller's strided slice is ``'A'``;
so one public function called from the envs, the rules and user code compiled its kernel up to
six times (seconds each, once per install; the test suite paid it in full). Passing every
input through :func:`kernel_array` gives each kernel one signature.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, DTypeLike


def kernel_array(
    value: ArrayLike, shape: tuple[int, ...], dtype: DTypeLike = np.float64
) -> np.ndarray:
    """``value`` broadcast to ``shape`` as a C-contiguous, writable array of ``dtype``; copied
    only where it is not one already."""
    a = np.asarray(value, dtype=dtype)
    if a.shape != shape:
        a = np.broadcast_to(a, shape)
    if not (a.flags.c_contiguous and a.flags.writeable):
        a = np.array(a, dtype=dtype, order="C")  # a writable copy
    return a
