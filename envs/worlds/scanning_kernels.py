"""Compiled raster timing of a scanning receiver (theory §6.1, §6.3): the one copy.

:meth:`sensorgym.envs.worlds.scanning.RasterScan.visit_time` loops :func:`raster_time` and
:func:`in_sector` over its batch (:func:`visit_time_batch`); the scanning environment's step
(:mod:`sensorgym.envs.stereo_scanning.kernels`) calls them per fix.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from sensorgym.trackers.geometry import wrap_angle_scalar as wrap

_JIT = {"cache": True, "nogil": True, "error_model": "numpy", "boundscheck": False}


@njit(inline="always")
def raster_cell(phi, theta, centre_az, centre_el, az_width, el_width, rows, cols):
    """Where the local angles ``(φ, θ)`` fall on the raster, in pixels and unrounded:
    ``((θ_c + h/2 − θ) / (h/rows), (wrap(φ − φ_c) + w/2) / (w/cols))`` (the sector spans
    ``[0, rows] × [0, cols]``; the pixel is the floor)."""
    row = (centre_el + 0.5 * el_width - theta) / (el_width / rows)
    col = (wrap(phi - centre_az) + 0.5 * az_width) / (az_width / cols)
    return row, col


# row = ⌊(θ_c + h/2 − θ) / (h/rows)⌋, col = ⌊(wrap(φ − φ_c) + w/2) / (w/cols)⌋ (clipped),
# t = offset + (row · cols + col + ½) · sweep / (rows · cols)
@njit(**_JIT)
def raster_time(phi, theta, centre_az, centre_el, az_width, el_width, rows, cols, offset, sweep):
    """Time after the period start at which a TV raster of ``rows × cols`` pixels over a sector
    ``az_width × el_width`` centred on ``(φ_c, θ_c)`` reaches the pixel holding the local angles
    ``(φ, θ)`` (rad): rows from the top elevation down, columns by increasing azimuth, one sweep
    of ``sweep`` seconds starting ``offset`` after the period start. Angles outside the sector
    take the nearest edge pixel's time (a finite fallback; :func:`in_sector` tells)."""
    row, col = raster_cell(phi, theta, centre_az, centre_el, az_width, el_width, rows, cols)
    row = np.floor(row)
    col = np.floor(col)
    row = min(max(row, 0.0), rows - 1.0)
    col = min(max(col, 0.0), cols - 1.0)
    return offset + (row * cols + col + 0.5) * (sweep / (rows * cols))


@njit(**_JIT)
def in_sector(phi, theta, centre_az, centre_el, az_width, el_width):
    """Whether the local angles ``(φ, θ)`` lie in the sector (edges included)."""
    return abs(wrap(phi - centre_az)) <= 0.5 * az_width and abs(theta - centre_el) <= 0.5 * el_width


@njit(**_JIT)
def visit_time_batch(phi, theta, az_width, el_width, rows, cols, offset, sweep, t, inside):
    """:func:`raster_time` and :func:`in_sector` of a boresight-centred sector over flat
    ``phi``/``theta (N,)`` into ``t`` and ``inside``."""
    for i in range(phi.shape[0]):
        t[i] = raster_time(
            phi[i], theta[i], 0.0, 0.0, az_width, el_width, rows, cols, offset, sweep
        )
        inside[i] = in_sector(phi[i], theta[i], 0.0, 0.0, az_width, el_width)
