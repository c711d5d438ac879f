"""Input checks shared by every tracker: clear ``ValueError`` s that name the argument.

Trackers are called from environments with arrays built elsewhere; a wrong shape or a NaN
must fail at the boundary with a message a user understands, never deep inside numpy.
"""

from __future__ import annotations

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


def count(value: object, name: str, minimum: int = 1) -> int:
    """``value`` as an ``int`` of at least ``minimum``; a bool, a float, a string or anything
    else not an integer raises ``TypeError`` naming ``name``, a smaller one ``ValueError``."""
    if isinstance(value, bool) or not isinstance(value, int | np.integer):
        raise TypeError(f"{name}: expected an integer, got {value!r}")
    if value < minimum:
        raise ValueError(f"{name}: must be >= {minimum}, got {value}")
    return int(value)
