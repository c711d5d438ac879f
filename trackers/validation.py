"""Input checks shared by every tracker: clear ``ValueError`` s that name the argument.

Trackers are called from environments with arrays built elsewhere; a wrong shape or a NaN
must fail at the boundary with a message a user understands, never deep inside numpy.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray


def finite_array(value: ArrayLike, name: str, *, tail: tuple[int, ...] = ()) -> NDArray[np.float64]:
    """Return ``value`` as a float64 array whose trailing dimensions equal ``tail``.

    Raises ``ValueError`` naming ``name`` if the shape does not end in ``tail`` or if any
    element is NaN or infinite.
    """
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: cannot be read as an array of floats ({exc})") from None
    if tail:
        if arr.ndim < len(tail) or arr.shape[arr.ndim - len(tail) :] != tail:
            want = "(..., " + ", ".join(str(t) for t in tail) + ")"
            raise ValueError(f"{name}: expected shape {want}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name}: contains NaN or infinite values")
    return arr


def unit_vectors(value: ArrayLike, name: str, *, atol: float = 1e-6) -> NDArray[np.float64]:
    """Return ``value`` (shape ``(..., 3)``) checked to hold unit vectors.

    Zero-length vectors are rejected; vectors whose norm differs from 1 by more than
    ``atol`` are rejected rather than silently renormalised, because a non-unit direction
    vector means the caller mixed up positions and directions.
    """
    arr = finite_array(value, name, tail=(3,))
    norm = np.linalg.norm(arr, axis=-1)
    if np.any(norm == 0.0):
        raise ValueError(f"{name}: contains a zero-length direction vector")
    if np.any(np.abs(norm - 1.0) > atol):
        worst = float(np.max(np.abs(norm - 1.0)))
        raise ValueError(
            f"{name}: direction vectors must have unit length (max |‖a‖-1| = {worst:.3g})"
        )
    return arr
