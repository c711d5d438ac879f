"""Target trajectories and the angles a carrier-mounted gimbal sees (paper 001, theory §8.7).

World model only: the predictors in :mod:`sensorgym.trackers.angles.prediction` and
:mod:`sensorgym.trackers.angles.baselines` see nothing but the measured angles produced here.

Frame (theory §2.2, §8.2): the carrier body frame ``OXYZ`` of paper 001, ``OXY`` horizontal,
``OZ`` up, carrier at ``O``. Azimuth θ is measured in ``OXY`` from ``OY`` towards ``OX``,
elevation ϕ from the horizontal plane (:func:`sensorgym.trackers.geometry.zup_angles_from_unit`).

Trajectory (theory §8.7)::

    X(n) = X₀ + δ_X n ,  Y(n) = Y₀ + δ_Y n ,  Z(n) = Z₀ + δ_Z n
    δ_Z = V sin β₀ ,  δ_X = V cos β₀ cos α₀ ,  δ_Y = V cos β₀ sin α₀

with ``n`` the frame number, ``V`` the speed per frame, ``β₀`` the climb angle and ``α₀`` the
heading of the horizontal projection measured from ``OX``. Measurement noise (theory §8.7,
§13.19): independent ``N(0, σ²)`` on θ and on ϕ, drawn from an explicit generator.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sensorgym.trackers.geometry import wrap_angle, zup_angles_from_unit
from sensorgym.trackers.validation import finite_array

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class StraightTrajectory:
    """Uniform rectilinear motion of the target relative to the carrier (theory §8.7).

    Defaults are the paper's example.
    """

    x0: float = -5700.0
    """X coordinate at frame 0 (m)."""
    y0: float = 1000.0
    """Y coordinate at frame 0 (m)."""
    z0: float = 500.0
    """Z coordinate (height above the carrier) at frame 0 (m)."""
    speed: float = 5.7
    """Speed V (m per frame)."""
    climb: float = np.deg2rad(30.0)
    """Climb angle β₀ of the trajectory above the horizontal plane (rad)."""
    heading: float = 0.0
    """Angle α₀ between ``OX`` and the horizontal projection of the trajectory (rad)."""

    def __post_init__(self) -> None:
        for name in ("x0", "y0", "z0", "speed", "climb", "heading"):
            if not np.isfinite(getattr(self, name)):
                raise ValueError(f"{name}: must be finite")
        if self.speed < 0.0:
            raise ValueError("speed: must be non-negative")

    @property
    def velocity(self) -> FloatArray:
        """Per-frame displacement ``(δ_X, δ_Y, δ_Z)`` (m per frame)."""
        v, b, a = self.speed, self.climb, self.heading
        # δ_X = V cos β₀ cos α₀, δ_Y = V cos β₀ sin α₀, δ_Z = V sin β₀
        return np.array([v * np.cos(b) * np.cos(a), v * np.cos(b) * np.sin(a), v * np.sin(b)])

    def positions(self, frames: ArrayLike) -> FloatArray:
        """Target positions ``(..., 3)`` (m) at the given frame numbers (any shape)."""
        n = finite_array(frames, "frames")
        return np.array([self.x0, self.y0, self.z0]) + n[..., None] * self.velocity

    def angles(self, frames: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """True azimuth θ and elevation ϕ (rad) at the given frames (theory §2.2, 001 frame).

        Raises ``ValueError`` if the target passes through the carrier (zero range).
        """
        return zup_angles_from_unit(self.positions(frames))


@dataclass(frozen=True)
class TurningTrajectory(StraightTrajectory):
    """Horizontal coordinated turn at constant speed and climb angle: a manoeuvring target that
    breaks the straight-line assumption of paper 001 (the remark under step 7 of theory §8.6).

    The heading of the horizontal projection is ``α(n) = α₀ + ω n``; with
    ``v_h = V cos β₀``::

        X(n) = X₀ + (v_h/ω)(sin α(n) − sin α₀),  Y(n) = Y₀ − (v_h/ω)(cos α(n) − cos α₀)
        Z(n) = Z₀ + V sin β₀ n

    ``ω = 0`` is the straight trajectory.
    """

    turn_rate: float = 0.0
    """ω: heading change per frame (rad/frame, positive counter-clockwise seen from above)."""

    def __post_init__(self) -> None:
        super().__post_init__()
        if not np.isfinite(self.turn_rate):
            raise ValueError("turn_rate: must be finite")

    def positions(self, frames: ArrayLike) -> FloatArray:
        n = finite_array(frames, "frames")
        w = self.turn_rate
        vh = self.speed * np.cos(self.climb)
        a0, a = self.heading, self.heading + w * n
        if abs(w) < 1e-12:
            dx, dy = vh * np.cos(a0) * n, vh * np.sin(a0) * n
        else:
            # ∫ v_h (cos α, sin α) dn with α = α₀ + ω n
            dx = vh / w * (np.sin(a) - np.sin(a0))
            dy = -vh / w * (np.cos(a) - np.cos(a0))
        dz = self.speed * np.sin(self.climb) * n
        return np.stack([self.x0 + dx, self.y0 + dy, self.z0 + dz], axis=-1)


def measure_angles(
    rng: np.random.Generator,
    azimuth: ArrayLike,
    elevation: ArrayLike,
    sigma: float,
) -> tuple[FloatArray, FloatArray]:
    """Noisy gimbal readings ``θ + ζ_θ``, ``ϕ + ζ_ϕ`` with ``ζ ~ N(0, σ²)`` iid (rad).

    The azimuth is wrapped into ``[-π, π)``; ``sigma`` is the angle-sensor noise (rad).
    """
    az = finite_array(azimuth, "azimuth")
    el = finite_array(elevation, "elevation")
    if not np.isfinite(sigma) or sigma < 0.0:
        raise ValueError("sigma: must be finite and non-negative")
    az, el = np.broadcast_arrays(az, el)
    noise = rng.normal(0.0, 1.0, size=(2, *az.shape)) * sigma
    return wrap_angle(az + noise[0]), el + noise[1]
