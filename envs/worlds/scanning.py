"""Receivers of the passive stereo world: world poses and the timing of their fixes.

Papers 000 and 003 pair each optical receiver with a *scanning* radiometric receiver. The
radiometer's line of sight (LOS) sweeps its sector in TV-raster order once per period τ, so an
object is fixed when the LOS passes it: the fix time depends on where the object lies in the
raster (theory §2.4, §6.1). An optical receiver fixes every object at once.

Raster (theory §6.2, gap §13.29). The paper's "0–30° in azimuth and elevation, step 0.03°, 100 × 100
image, 2 ms per step, τ = 20 s" is inconsistent (30°/0.03° = 1000). We keep what fixes the
timing — a 100 × 100 image swept in τ = 20 s (2 ms per pixel) — and read the step as 0.3° over
a 30° sector (``RasterScan.paper003()``). The sector is centred on the boresight: azimuth
φ ∈ [−15°, 15°] swept left to right along a row (increasing φ), rows from the top elevation
down (TV order).

Pixel-visit rule for a moving object (gap 29): the fix time ``t`` solves
``t = T_raster(φ(t), θ(t))``, where ``T_raster`` is the time the LOS reaches the pixel holding
the angles; it is found by fixed-point iteration from the period midpoint (a contraction
because the LOS moves far faster than the object's image). The measured direction is the
object's true direction at ``t`` (no pixel quantisation) plus the noise of the noise model.

Everything here is a frozen value or a pure function; poses are inputs of the per-period
measurement function, so environments can move or re-point receivers every period.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sensorgym.envs.worlds.scanning_kernels import visit_time_batch
from sensorgym.trackers.geometry import angles_from_unit, look_at_rotation, relative_pose
from sensorgym.trackers.validation import finite_array

FloatArray = NDArray[np.float64]

#: Fixed-point iterations of the pixel-visit rule; the scan outruns the image by orders of
#: magnitude, so three iterations converge except exactly on a pixel boundary.
VISIT_ITERATIONS = 4


@dataclass(frozen=True)
class ReceiverLayout:
    """World poses of ``n`` receivers (theory §2.1); receiver 0 is the papers' receiver 1.

    Leading batch axes are allowed (many layouts at once, e.g. candidate placements).
    """

    rotations: FloatArray = field(repr=False)
    """(..., n, 3, 3) local→world rotations ``R_k`` (columns: receiver axes X, Y, Z in world)."""
    positions: FloatArray = field(repr=False)
    """(..., n, 3) world positions ``o_k`` of the receiver frame origins, m."""

    def __post_init__(self) -> None:
        R = finite_array(self.rotations, "rotations", tail=(3, 3))
        o = finite_array(self.positions, "positions", tail=(3,))
        if R.ndim < 3 or R.shape[:-2] != o.shape[:-1]:
            raise ValueError(
                "rotations/positions: expected (..., n, 3, 3) and (..., n, 3), "
                f"got {R.shape} and {o.shape}"
            )
        if R.shape[-3] < 1:
            raise ValueError("rotations: need at least one receiver")
        err = np.abs(np.swapaxes(R, -1, -2) @ R - np.eye(3)).max()
        if err > 1e-9 or np.any(np.linalg.det(R) < 0.0):
            raise ValueError("rotations: must be proper rotation matrices (RᵀR = I, det R = +1)")
        object.__setattr__(self, "rotations", R)
        object.__setattr__(self, "positions", o)

    @property
    def n(self) -> int:
        """Number of receivers."""
        return int(self.positions.shape[-2])

    @property
    def relative(self) -> tuple[FloatArray, FloatArray]:
        """``(P, b)``: (n−1, 3, 3) and (n−1, 3) with ``M_1 = P_k M_k + b_k`` (theory §2.1)."""
        R, o = self.rotations, self.positions
        return relative_pose(R[..., :1, :, :], o[..., :1, :], R[..., 1:, :, :], o[..., 1:, :])

    def to_local(self, points_world: ArrayLike) -> FloatArray:
        """World points ``(..., n, 3)`` → components in each receiver's own frame: ``R_kᵀ(p − o_k)``."""
        p = finite_array(points_world, "points_world", tail=(3,))
        return np.einsum("...kji,...kj->...ki", self.rotations, p - self.positions)

    def to_frame1(self, points_world: ArrayLike) -> FloatArray:
        """World points ``(..., 3)`` → frame of receiver 1, where the trackers report: ``R_1ᵀ(p − o_1)``."""
        p = finite_array(points_world, "points_world", tail=(3,))
        return (p - self.positions[..., 0, :]) @ self.rotations[..., 0, :, :]

    def subset(self, indices: ArrayLike) -> ReceiverLayout:
        """The layout of the receivers ``indices`` (in that order; the first is the reference)."""
        idx = np.asarray(indices, dtype=int)
        return ReceiverLayout(self.rotations[..., idx, :, :], self.positions[..., idx, :])

    @classmethod
    def looking_at(cls, positions: ArrayLike, aim: ArrayLike) -> ReceiverLayout:
        """Receivers at ``positions`` (n, 3) with boresights at ``aim`` ((3,) or (n, 3)), Y up."""
        o = finite_array(positions, "positions", tail=(3,))
        t = np.broadcast_to(finite_array(aim, "aim", tail=(3,)), o.shape)
        return cls(look_at_rotation(o, t), o)

    @classmethod
    def on_circle(
        cls,
        radius: float,
        angles_deg: ArrayLike,
        heights: ArrayLike = 0.0,
        aim: ArrayLike = (0.0, 0.0, 0.0),
        centre: ArrayLike = (0.0, 0.0, 0.0),
    ) -> ReceiverLayout:
        """Receivers on a horizontal circle (world ``Y`` up) at given azimuths, aimed at ``aim``.

        ``radius`` in m; ``angles_deg`` positions on the circle measured from world ``+Z``
        towards ``+X``; ``heights`` (m) added to the centre's ``Y``.
        """
        if not radius > 0.0:
            raise ValueError("radius: must be positive")
        ang = np.deg2rad(finite_array(angles_deg, "angles_deg")).reshape(-1)
        h = np.broadcast_to(finite_array(heights, "heights"), ang.shape)
        c = finite_array(centre, "centre", tail=(3,))
        pos = c + np.stack([radius * np.sin(ang), h, radius * np.cos(ang)], axis=-1)
        return cls.looking_at(pos, aim)


@dataclass(frozen=True)
class RasterScan:
    """A TV-raster scan of a sector centred on the boresight, one sweep per period (theory §6.1)."""

    az_span_deg: float = 30.0
    """Azimuth extent of the sector, degrees (centred on the boresight)."""
    el_span_deg: float = 30.0
    """Elevation extent of the sector, degrees (centred on the boresight)."""
    rows: int = 100
    """Raster lines (elevation steps)."""
    cols: int = 100
    """Pixels per line (azimuth steps)."""
    period: float = 20.0
    """Sweep duration τ, s (the pixel dwell is τ / (rows · cols))."""
    offset: float = 0.0
    """Sweep start relative to the period start, s (receivers need not be synchronised)."""

    def __post_init__(self) -> None:
        if not (0.0 < self.az_span_deg < 180.0 and 0.0 < self.el_span_deg < 180.0):
            raise ValueError("az_span_deg/el_span_deg: must lie in (0, 180) degrees")
        if self.rows < 1 or self.cols < 1:
            raise ValueError("rows/cols: need at least one pixel")
        if not self.period > 0.0:
            raise ValueError("period: must be positive")

    @property
    def dwell(self) -> float:
        """Time the LOS spends on one pixel, s."""
        return self.period / (self.rows * self.cols)

    @property
    def step_deg(self) -> tuple[float, float]:
        """Angular pixel size (azimuth, elevation), degrees."""
        return self.az_span_deg / self.cols, self.el_span_deg / self.rows

    @classmethod
    def paper003(cls) -> RasterScan:
        """100 × 100 pixels of 0.3° over 30° × 30°, 2 ms per pixel, τ = 20 s (gap 29 resolved)."""
        return cls(30.0, 30.0, 100, 100, 20.0)

    def visit_time(self, azimuth: ArrayLike, elevation: ArrayLike) -> tuple[FloatArray, NDArray]:
        """Time after the period start at which the LOS reaches the given angles (radians).

        Returns ``(t, inside)``; ``inside`` is False for angles outside the sector (edges
        belong to it; then ``t`` is the clipped pixel's time, a finite fallback the caller masks
        out).
        """
        phi, theta = np.broadcast_arrays(
            finite_array(azimuth, "azimuth"), finite_array(elevation, "elevation")
        )
        t, inside = np.empty(phi.shape), np.empty(phi.shape, dtype=bool)
        # compiled: scanning_kernels.raster_time / in_sector (the env's step calls the same)
        visit_time_batch(
            np.ascontiguousarray(phi, dtype=np.float64).reshape(-1),
            np.ascontiguousarray(theta, dtype=np.float64).reshape(-1),
            np.deg2rad(self.az_span_deg),
            np.deg2rad(self.el_span_deg),
            float(self.rows),
            float(self.cols),
            self.offset,
            self.period,
            t.reshape(-1),
            inside.reshape(-1),
        )
        return t, inside


@dataclass(frozen=True)
class FixedDelay:
    """A receiver that fixes every object at one instant of the period (optical, or paper 000's
    scanning receivers whose output lags receiver 1 by a constant delay Δt_k, theory §6.1)."""

    delay: float = 0.0
    """Fix time after the period start, s."""

    def __post_init__(self) -> None:
        if not np.isfinite(self.delay) or self.delay < 0.0:
            raise ValueError("delay: must be finite and non-negative")


ScanTiming = RasterScan | FixedDelay


def fix_times(
    timing: ScanTiming,
    rotation: FloatArray,
    position: FloatArray,
    locate,
    period_start: float,
    period: float,
) -> tuple[FloatArray, NDArray]:
    """Fix times ``(m,)`` of every object for one receiver, and whether each lies in its sector.

    ``locate(t)`` returns world positions (m, 3) at the times ``t`` (m,). For a raster the
    pixel-visit rule is solved by fixed-point iteration (module docstring); a fixed delay
    fixes all objects at ``period_start + delay``.
    """
    m = locate(np.full(1, period_start)).shape[0]
    if isinstance(timing, FixedDelay):
        return np.full(m, period_start + timing.delay), np.ones(m, dtype=bool)
    t = np.full(m, period_start + 0.5 * period)
    inside = np.ones(m, dtype=bool)
    for _ in range(VISIT_ITERATIONS):
        local = (locate(t) - position) @ rotation
        az, el = angles_from_unit(local / np.linalg.norm(local, axis=-1, keepdims=True))
        dt, inside = timing.visit_time(az, el)
        t = period_start + dt
    # objects behind the receiver are never in the sector
    local = (locate(t) - position) @ rotation
    return t, inside & (local[:, 2] > 0.0)
