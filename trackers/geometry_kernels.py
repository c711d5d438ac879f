"""Compiled primitives of :mod:`.geometry`: one 3-vector or 3×3 pose at a time, in registers.

Each function here is written once and called both by the batched public functions of
:mod:`.geometry` (through the small batch loops at the end of this module) and by the envs'
fused step kernels (e.g. :mod:`sensorgym.envs.stereo_placement.kernels`). Vectors are tuples
``(x, y, z)``; a rotation is a tuple of its three *columns* (the local axes in world
components), so ``R = (x, y, z)`` reads as in :func:`.geometry.look_at_rotation`.

The arithmetic follows the numpy expressions it replaces operation for operation (sums left to
right, no fused multiply-add), so the batched functions return the same bits as before.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

_JIT = {"cache": True, "nogil": True, "error_model": "numpy", "boundscheck": False}


@njit(inline="always")
def dot3(u, v):
    """``u · v``."""
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]


@njit(inline="always")
def cross3(u, v):
    """``u × v``."""
    return (u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0])


@njit(inline="always")
def norm3(u):
    """``‖u‖ = √(u_x² + u_y² + u_z²)``."""
    return np.sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2])


@njit(inline="always")
def unit_from_angles3(azimuth, elevation):
    """``a = (cos θ sin φ, sin θ, cos θ cos φ)`` (000 eq. 2)."""
    ct = np.cos(elevation)
    return (ct * np.sin(azimuth), np.sin(elevation), ct * np.cos(azimuth))


#: ``|atan2_near(y, x) − atan2(y, x)|`` stays below this, rad (the polynomial's error is
#: 2.8e-10; ``tests/trackers/test_geometry.py`` checks the bound on a dense sample)
ATAN2_NEAR_ERROR = 1e-8

# atan(a)/a ≈ Σ c_k u^k, u = a², a ∈ [0, 1]: a degree-10 Chebyshev fit in u, as monomials
_ATAN_C = (
    0.9999999996155006, -0.3333332367226497, 0.19999595986486163, -0.14279049617739104,
    0.11053790693864282, -0.08796135044569692, 0.06710145849908022, -0.04427402900529784,
    0.022203700135139476, -0.007166255552429937, 0.0010845065272410376,
)  # fmt: skip


@njit(inline="always")
def atan2_near(y, x):
    """``atan2(y, x)`` for ``x > 0`` within :data:`ATAN2_NEAR_ERROR` — a polynomial, a fraction of
    libm's cost, for tests that only need the angle to lie on the right side of a boundary
    (the caller decides exactly when it lies within the error of one). ``a = min/max`` of
    ``|y|, x`` in ``[0, 1]``, ``atan a`` by the polynomial (Estrin's scheme), ``π/2 − atan a``
    when ``|y| > x``, the sign of ``y``."""
    c = _ATAN_C
    ay = abs(y)
    big = ay > x
    a = x / ay if big else ay / x
    u = a * a
    u2 = u * u
    u4 = u2 * u2
    low = (c[0] + c[1] * u) + u2 * (c[2] + c[3] * u)
    mid = (c[4] + c[5] * u) + u2 * (c[6] + c[7] * u)
    high = (c[8] + c[9] * u) + u2 * c[10]
    r = a * (low + u4 * (mid + u4 * high))
    if big:
        r = 0.5 * np.pi - r
    return -r if y < 0.0 else r


@njit(**_JIT)
def angles_from_unit3(u):
    """``(φ, θ, has)``: azimuth ``φ = atan2(u_x, u_z)`` and elevation ``θ = arcsin u_y``
    (000 eq. 3) of a unit ``u`` (``u_y`` clipped to ``[−1, 1]``, NaN stays NaN); the zero vector
    (no direction) gives ``(0, 0, False)``. The one copy: :func:`.geometry.angles_from_unit` and
    the stereo kernels (:mod:`sensorgym.trackers.stereo.kernels`) call it."""
    if u[0] == 0.0 and u[1] == 0.0 and u[2] == 0.0:
        return 0.0, 0.0, False
    y = u[1]
    if y < -1.0:
        y = -1.0
    elif y > 1.0:
        y = 1.0
    return math.atan2(u[0], u[2]), math.asin(y), True


@njit(inline="always")
def look_at3(position, target, up):
    """Columns ``(X, Y, Z)`` of the local→world rotation looking from ``position`` at ``target``
    and a status: 0, 1 (target on the position) or 2 (``up`` parallel to the boresight).

    ``Z = (t − p)/‖t − p‖``, ``Y = (u − (u·Z) Z)/‖·‖``, ``X = Y × Z``.
    """
    z = (target[0] - position[0], target[1] - position[1], target[2] - position[2])
    zn = norm3(z)
    status = 1 if zn == 0.0 else 0
    z = (z[0] / zn, z[1] / zn, z[2] / zn)
    s = up[0] * z[0] + up[1] * z[1] + up[2] * z[2]
    y = (up[0] - s * z[0], up[1] - s * z[1], up[2] - s * z[2])
    yn = norm3(y)
    if status == 0 and not (yn >= 1e-12):
        status = 2
    y = (y[0] / yn, y[1] / yn, y[2] / yn)
    return (cross3(y, z), y, z), status


@njit(inline="always")
def to_world3(R, v):
    """``R v`` for ``R`` given by its columns."""
    return (
        R[0][0] * v[0] + R[1][0] * v[1] + R[2][0] * v[2],
        R[0][1] * v[0] + R[1][1] * v[1] + R[2][1] * v[2],
        R[0][2] * v[0] + R[1][2] * v[1] + R[2][2] * v[2],
    )


@njit(inline="always")
def to_local3(R, v):
    """``Rᵀ v`` for ``R`` given by its columns: the components of ``v`` along each local axis."""
    return (dot3(R[0], v), dot3(R[1], v), dot3(R[2], v))


@njit(inline="always")
def relative_pose3(R1, o1, Rk, ok):
    """``P_k = R_1ᵀ R_k`` (columns) and ``b_k = R_1ᵀ (o_k − o_1)`` (theory §2.1)."""
    P = (to_local3(R1, Rk[0]), to_local3(R1, Rk[1]), to_local3(R1, Rk[2]))
    b = to_local3(R1, (ok[0] - o1[0], ok[1] - o1[1], ok[2] - o1[2]))
    return P, b


@njit(inline="always")
def los_angle3(u, v):
    """Angle between unit vectors ``γ = atan2(‖u × v‖, u · v)`` (accurate at 0 and π), rad."""
    return np.arctan2(norm3(cross3(u, v)), dot3(u, v))


@njit(inline="always")
def perturbed_direction3(a, z, sigma):
    """``(a + δ)/‖a + δ‖`` with ``δ = (z − (z·a) a) σ``: the normals ``z`` projected across the
    unit vector ``a`` (isotropic angular noise of ``σ`` rad, theory §4.1)."""
    s = z[0] * a[0] + z[1] * a[1] + z[2] * a[2]
    v = (
        a[0] + (z[0] - s * a[0]) * sigma,
        a[1] + (z[1] - s * a[1]) * sigma,
        a[2] + (z[2] - s * a[2]) * sigma,
    )
    n = norm3(v)
    return (v[0] / n, v[1] / n, v[2] / n)


@njit(inline="always")
def _row(x, i):
    return (x[i, 0], x[i, 1], x[i, 2])


# ---------------------------------------------------------------------------------------------
# batch loops of the public functions in :mod:`.geometry` (flat ``(N, 3)`` / ``(N, 3, 3)``)


@njit(**_JIT)
def look_at_batch(position, target, up, out):
    """:func:`look_at3` over ``N`` rows into ``out (N, 3, 3)`` (``out[i, :, c]`` = column ``c``);
    returns 1 if any target lies on its position, else 2 if any ``up`` is parallel to its
    boresight, else 0."""
    coincident = False
    parallel = False
    for i in range(position.shape[0]):
        R, status = look_at3(_row(position, i), _row(target, i), _row(up, i))
        coincident |= status == 1
        parallel |= status == 2
        for c in range(3):
            for r in range(3):
                out[i, r, c] = R[c][r]
    return 1 if coincident else (2 if parallel else 0)


@njit(**_JIT)
def relative_pose_batch(R1, o1, Rk, ok, P, b):
    """:func:`relative_pose3` over ``N`` rows into ``P (N, 3, 3)`` and ``b (N, 3)``."""
    for i in range(R1.shape[0]):
        r1 = ((R1[i, 0, 0], R1[i, 1, 0], R1[i, 2, 0]),
              (R1[i, 0, 1], R1[i, 1, 1], R1[i, 2, 1]),
              (R1[i, 0, 2], R1[i, 1, 2], R1[i, 2, 2]))  # fmt: skip
        rk = ((Rk[i, 0, 0], Rk[i, 1, 0], Rk[i, 2, 0]),
              (Rk[i, 0, 1], Rk[i, 1, 1], Rk[i, 2, 1]),
              (Rk[i, 0, 2], Rk[i, 1, 2], Rk[i, 2, 2]))  # fmt: skip
        Pk, bk = relative_pose3(r1, _row(o1, i), rk, _row(ok, i))
        for c in range(3):
            b[i, c] = bk[c]
            for r in range(3):
                P[i, r, c] = Pk[c][r]


@njit(**_JIT)
def perturb_batch(a, z, sigma, out):
    """:func:`perturbed_direction3` over ``N`` rows into ``out (N, 3)``; a zero row stays zero
    (no direction to measure)."""
    for i in range(a.shape[0]):
        u = _row(a, i)
        if u[0] == 0.0 and u[1] == 0.0 and u[2] == 0.0:
            out[i, 0] = out[i, 1] = out[i, 2] = 0.0
            continue
        v = perturbed_direction3(u, _row(z, i), sigma[i])
        out[i, 0], out[i, 1], out[i, 2] = v[0], v[1], v[2]


@njit(**_JIT)
def unit_from_angles_batch(azimuth, elevation, out):
    """:func:`unit_from_angles3` over flat ``azimuth``/``elevation (N,)`` into ``out (N, 3)``."""
    for i in range(azimuth.shape[0]):
        out[i, 0], out[i, 1], out[i, 2] = unit_from_angles3(azimuth[i], elevation[i])


@njit(**_JIT)
def angles_from_unit_batch(a, azimuth, elevation):
    """:func:`angles_from_unit3` over flat ``a (N, 3)`` into ``azimuth``/``elevation (N,)``."""
    for i in range(a.shape[0]):
        azimuth[i], elevation[i], _ = angles_from_unit3(_row(a, i))
