"""Direction vectors, angles and receiver poses (theory §2).

Frames
------
*Receiver frame of papers 000/003* (the default everywhere in sensorgym): right-handed,
``Y`` up, ``Z`` the horizontal boresight, so ``X = Y × Z`` points to the receiver's left.
Azimuth ``φ`` is measured in the horizontal plane ``XZ`` from ``Z`` towards ``X``;
elevation ``θ`` from the plane ``XZ`` towards ``Y``::

    a = (cos θ sin φ, sin θ, cos θ cos φ)ᵀ              (000 eq. 2, 003)
    φ = atan2(a_x, a_z),  θ = arcsin(a_y)               (000 eq. 3)

*Carrier frame of paper 001*: right-handed, ``Z`` up, ``OXY`` horizontal, azimuth (called
θ there) measured from ``Y`` towards ``X``, elevation (called ϕ there) from the horizontal
plane::

    u = (cos ϕ sin θ, cos ϕ cos θ, sin ϕ)ᵀ               (theory §2.2, derived)

Because both frames are right-handed, the rotation between them maps the 001 frame
``(X_right, Y_forward, Z_up)`` to the 000 frame as ``(x, y, z) = (−X, Z, Y)``: the forward
axis and the up axis agree, and positive 001 azimuth (towards its ``+X``, to the right) is
*negative* 000 azimuth (000's ``+x`` is to the left). Use :func:`yup_from_zup` /
:func:`zup_from_yup`; never share angle code between the frames without them (theory
§13.3).

Poses (theory §2.1): with ``R_k`` the local→world rotation and ``o_k`` the world position of
receiver ``k``, ``M_1 = P_k M_k + b_k`` where ``P_k = R_1ᵀ R_k`` and ``b_k = R_1ᵀ (o_k − o_1)``.

Every function accepts leading batch axes.
"""

from __future__ import annotations

import numpy as np
from numba import njit, vectorize
from numpy.typing import ArrayLike, NDArray

from sensorgym.trackers.geometry_kernels import (
    angles_from_unit_batch,
    look_at_batch,
    relative_pose_batch,
    unit_from_angles_batch,
)
from sensorgym.trackers.kernel_args import kernel_array
from sensorgym.trackers.validation import finite_array, unit_vectors

FloatArray = NDArray[np.float64]

#: Rotation taking 001-frame components (X right, Y forward, Z up) to 000-frame components
#: (x left, y up, z forward). Proper rotation (det = +1).
R_YUP_FROM_ZUP: FloatArray = np.array([[-1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]])


def wrap_angle(angle: ArrayLike) -> FloatArray:
    """Wrap angles (radians) into ``[-π, π)``. The one angle-wrapping function of sensorgym:
    :func:`wrap_angle_scalar` as a numpy ufunc (any shape, float64)."""
    return _wrap_angle_ufunc(angle)


_TWO_PI = 2.0 * np.pi


# wrap(a) = (a + π) mod 2π − π ∈ [−π, π)
@njit(cache=True, nogil=True, error_model="numpy")
def wrap_angle_scalar(a: float) -> float:
    """:func:`wrap_angle` of one float, compiled (for the numba kernels). Within one turn of
    the range the floored ``mod`` is a single exact or once-rounded add (the bits of Python's
    and numpy's ``%``, which round the same way), so the costly ``fmod`` runs only beyond."""
    v = a + np.pi
    if 0.0 <= v < _TWO_PI:
        m = v
    elif -_TWO_PI < v < 0.0:
        m = v + _TWO_PI  # fmod(v) = v, then + 2π (rounded as % rounds it)
    elif _TWO_PI <= v < 2.0 * _TWO_PI:
        m = v - _TWO_PI  # exact (Sterbenz), as fmod is
    else:
        m = v % _TWO_PI
    return m - np.pi


#: :func:`wrap_angle_scalar` elementwise (the same bits as numpy's ``(a + π) % 2π − π``)
_wrap_angle_ufunc = vectorize(["float64(float64)"], cache=True)(wrap_angle_scalar.py_func)


def unit_from_angles(azimuth: ArrayLike, elevation: ArrayLike) -> FloatArray:
    """Unit vector ``a = (cos θ sin φ, sin θ, cos θ cos φ)`` in the 000/003 frame (000 eq. 2).

    ``azimuth`` φ and ``elevation`` θ in radians, broadcast together; returns shape ``(..., 3)``.
    """
    phi = finite_array(azimuth, "azimuth")
    theta = finite_array(elevation, "elevation")
    shape = np.broadcast_shapes(phi.shape, theta.shape)
    out = np.empty((*shape, 3))
    # a = (cos θ sin φ, sin θ, cos θ cos φ)  (geometry_kernels.unit_from_angles3)
    unit_from_angles_batch(
        kernel_array(phi, shape).reshape(-1),
        kernel_array(theta, shape).reshape(-1),
        out.reshape(-1, 3),
    )
    return out


def angles_from_unit(a: ArrayLike, *, check: bool = True) -> tuple[FloatArray, FloatArray]:
    """Azimuth ``φ = atan2(a_x, a_z)`` and elevation ``θ = arcsin(a_y)`` (000 eq. 3), radians.

    At the zenith/nadir (``a_x = a_z = 0``) the azimuth is undefined; ``atan2(0, 0) = 0`` is
    returned, a finite documented fallback. ``check=False`` skips the unit-length check (for
    callers whose vectors are unit by construction; the shape is still checked).
    """
    a = unit_vectors(a, "a") if check else finite_array(a, "a", tail=(3,), check=False)
    flat = np.ascontiguousarray(a, dtype=np.float64).reshape(-1, 3)
    azimuth, elevation = np.empty(flat.shape[0]), np.empty(flat.shape[0])
    # φ = atan2(a_x, a_z), θ = arcsin a_y  (compiled: geometry_kernels.angles_from_unit3)
    angles_from_unit_batch(flat, azimuth, elevation)
    return azimuth.reshape(a.shape[:-1]), elevation.reshape(a.shape[:-1])


def unit_from_pixel(
    x: ArrayLike, y: ArrayLike, f: ArrayLike, inverted: ArrayLike = True
) -> FloatArray:
    """Unit direction vector from optical pixel coordinates (theory §2.3).

    ``x, y`` are measured from the principal point, in the same unit as the focal length
    ``f`` (e.g. pixels). ``inverted=True`` gives paper 003's physical focal-plane form
    ``(−x, −y, f)/ρ`` (the lens forms an inverted image); ``inverted=False`` gives the
    virtual-image form ``(x, y, f)/ρ`` (000 eq. 1 as printed). ``inverted`` may be an array
    (a per-receiver flag) broadcast against ``x``.
    """
    x = finite_array(x, "x")
    y = finite_array(y, "y")
    f = finite_array(f, "f")
    if np.any(f <= 0.0):
        raise ValueError("f: focal length must be positive")
    sign = np.where(np.asarray(inverted, dtype=bool), -1.0, 1.0)
    v = np.stack(np.broadcast_arrays(sign * x, sign * y, f), axis=-1)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def pixel_from_unit(
    a: ArrayLike, f: ArrayLike, inverted: ArrayLike = True
) -> tuple[FloatArray, FloatArray]:
    """Inverse of :func:`unit_from_pixel`: pixel coordinates ``(x, y)`` of direction ``a``.

    Raises ``ValueError`` for directions at or behind the image plane (``a_z <= 0``).
    """
    a = unit_vectors(a, "a")
    f = finite_array(f, "f")
    if np.any(a[..., 2] <= 0.0):
        raise ValueError("a: direction is not in front of the camera (a_z <= 0)")
    sign = np.where(np.asarray(inverted, dtype=bool), -1.0, 1.0)
    scale = sign * f / a[..., 2]
    return scale * a[..., 0], scale * a[..., 1]


def unit_from_zup_angles(azimuth: ArrayLike, elevation: ArrayLike) -> FloatArray:
    """Unit vector in paper 001's Z-up carrier frame: ``(cos ϕ sin θ, cos ϕ cos θ, sin ϕ)``.

    ``azimuth`` is 001's θ (from ``OY`` towards ``OX``), ``elevation`` is 001's ϕ.
    """
    az = finite_array(azimuth, "azimuth")
    el = finite_array(elevation, "elevation")
    ce = np.cos(el)
    return np.stack(np.broadcast_arrays(ce * np.sin(az), ce * np.cos(az), np.sin(el)), axis=-1)


def zup_angles_from_unit(u: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """001-frame azimuth ``θ = atan2(X, Y)`` and elevation ``ϕ = atan2(Z, √(X²+Y²))``."""
    u = finite_array(u, "u", tail=(3,))
    if np.any(np.linalg.norm(u, axis=-1) == 0.0):
        raise ValueError("u: contains a zero-length vector")
    return np.arctan2(u[..., 0], u[..., 1]), np.arctan2(u[..., 2], np.hypot(u[..., 0], u[..., 1]))


def yup_from_zup(v: ArrayLike) -> FloatArray:
    """Components in the 000/003 Y-up frame of vectors given in the 001 Z-up frame."""
    return finite_array(v, "v", tail=(3,)) @ R_YUP_FROM_ZUP.T


def zup_from_yup(v: ArrayLike) -> FloatArray:
    """Components in the 001 Z-up frame of vectors given in the 000/003 Y-up frame."""
    return finite_array(v, "v", tail=(3,)) @ R_YUP_FROM_ZUP


def look_at_rotation(
    position: ArrayLike, target: ArrayLike, up: ArrayLike = (0.0, 1.0, 0.0)
) -> FloatArray:
    """Local→world rotation ``R`` of a receiver at ``position`` whose boresight ``Z`` points at ``target``.

    The receiver's ``Y`` axis is the component of ``up`` orthogonal to the boresight and
    ``X = Y × Z`` completes the right-handed 000/003 frame. Columns of ``R`` are the local
    axes in world components. Raises ``ValueError`` if the boresight is parallel to ``up``.
    """
    p = finite_array(position, "position", tail=(3,))
    t = finite_array(target, "target", tail=(3,))
    u = finite_array(up, "up", tail=(3,))
    shape = np.broadcast_shapes(p.shape, t.shape, u.shape)
    flat = [kernel_array(x, shape).reshape(-1, 3) for x in (p, t, u)]
    out = np.empty((flat[0].shape[0], 3, 3))
    # Z = (t − p)/‖t − p‖,  Y = (up − (up·Z) Z)/‖·‖,  X = Y × Z  (geometry_kernels.look_at3)
    code = look_at_batch(*flat, out)
    if code == 1:
        raise ValueError("target: coincides with position, boresight undefined")
    if code == 2:
        raise ValueError("up: parallel to the boresight, receiver roll undefined")
    return out.reshape(*shape[:-1], 3, 3)


def relative_pose(
    R1: ArrayLike, o1: ArrayLike, Rk: ArrayLike, ok: ArrayLike
) -> tuple[FloatArray, FloatArray]:
    """``P_k = R_1ᵀ R_k`` and ``b_k = R_1ᵀ (o_k − o_1)`` so that ``M_1 = P_k M_k + b_k`` (theory §2.1).

    ``R1, Rk``: local→world rotations ``(..., 3, 3)``; ``o1, ok``: world positions ``(..., 3)``.
    Computed by the compiled :func:`~.geometry_kernels.relative_pose3` (dot products summed left to
    right: ``P`` agrees with numpy's ``R1ᵀ @ Rk`` to round-off, at most 2.3e-16 absolute; ``b``
    bit for bit).
    """
    R1 = finite_array(R1, "R1", tail=(3, 3))
    Rk = finite_array(Rk, "Rk", tail=(3, 3))
    o1 = finite_array(o1, "o1", tail=(3,))
    ok = finite_array(ok, "ok", tail=(3,))
    shape = np.broadcast_shapes(R1.shape[:-2], Rk.shape[:-2], o1.shape[:-1], ok.shape[:-1])
    flat = [
        kernel_array(x, (*shape, *tail)).reshape(-1, *tail)
        for x, tail in ((R1, (3, 3)), (o1, (3,)), (Rk, (3, 3)), (ok, (3,)))
    ]
    P, b = np.empty((flat[0].shape[0], 3, 3)), np.empty((flat[0].shape[0], 3))
    # P_k = R_1ᵀ R_k,  b_k = R_1ᵀ (o_k − o_1)  (geometry_kernels.relative_pose3)
    relative_pose_batch(*flat, P, b)
    return P.reshape(*shape, 3, 3), b.reshape(*shape, 3)
