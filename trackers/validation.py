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
    # which the elementwise check below then clears)
    if not np.isfinite(arr.sum()) and not np.isfinite(arr).all():
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
    x, y, z = comp
    norm2 = x * x + y * y + z * z
    # ‖a‖² is finite for every vector iff its sum is (a NaN/inf component makes it NaN/inf);
    # the finiteness check then names the bad values, one reduction instead of two
    if not np.isfinite(norm2.sum()):
        finite_array(arr, name)
    if np.any(norm2 == 0.0):
        raise ValueError(f"{name}: contains a zero-length direction vector")
    # |‖a‖² − 1| ≈ 2 |‖a‖ − 1|
    if np.any(np.abs(norm2 - 1.0) > 2.0 * atol):
        worst = float(np.max(np.abs(np.sqrt(norm2) - 1.0)))
        raise ValueError(
            f"{name}: direction vectors must have unit length (max |‖a‖-1| = {worst:.3g})"
        )
    return arr, comp


def unit_vectors(value: ArrayLike, name: str, *, atol: float = 1e-6) -> NDArray[np.float64]:
    """Return ``value`` (shape ``(..., 3)``) checked to hold unit vectors (see above)."""
    return unit_vector_components(value, name, atol=atol)[0]


def rotation_components(
    value: ArrayLike, name: str, *, atol: float = 1e-6, check: bool = True
) -> NDArray[np.float64]:
    """Checked rotation matrices ``(..., 3, 3)`` as component-major ``(3, 3, ...)`` components.

    Raises ``ValueError`` naming ``name`` unless ``MᵀM = I`` within ``atol`` (``check=False``:
    shape only).
    """
    arr = finite_array(value, name, tail=(3, 3), check=False)
    M = np.moveaxis(arr, (-2, -1), (0, 1))
    if not check:
        return M
    # one transposing copy makes every row of the check (and the caller's P a) contiguous
    M = np.ascontiguousarray(M)
    worst = 0.0
    for i in range(3):
        for j in range(i, 3):
            # (MᵀM)_ij = Σ_k M_ki M_kj
            g = M[0, i] * M[0, j] + M[1, i] * M[1, j] + M[2, i] * M[2, j]
            err = float(np.max(np.abs(g - (i == j)), initial=0.0))
            if not np.isfinite(err):  # a NaN/inf entry (np.max propagates it): name it
                finite_array(arr, name)
            worst = max(worst, err)
    if worst > atol:
        raise ValueError(f"{name}: must hold rotation matrices (max |MᵀM − I| = {worst:.3g})")
    return M
