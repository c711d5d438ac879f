"""Objects of the passive stereo world: small drones on linear or accelerating paths.

The papers simulate "several UAVs moving along close trajectories" (000) and "m = 2–5 objects a
few metres apart moving toward the receivers linearly with random trajectory parameters"
(003). A trajectory is the constant-acceleration law ``p(t) = p₀ + v₀ t + ½ a t²`` (world
frame, ``a = 0`` for the papers' linear paths); :func:`random_group` draws a group of such
objects around a centre with an explicit ``np.random.Generator``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sensorgym.trackers.validation import finite_array

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Trajectories:
    """``m`` objects moving as ``p(t) = p₀ + v₀ t + ½ a t²`` in the world frame."""

    start: FloatArray = field(repr=False)
    """(m, 3) positions at t = 0, m."""
    velocity: FloatArray = field(repr=False)
    """(m, 3) velocities at t = 0, m/s."""
    acceleration: FloatArray = field(repr=False)
    """(m, 3) constant accelerations, m/s² (zeros for linear paths)."""

    def __post_init__(self) -> None:
        p = finite_array(self.start, "start", tail=(3,))
        v = finite_array(self.velocity, "velocity", tail=(3,))
        a = finite_array(self.acceleration, "acceleration", tail=(3,))
        if p.ndim != 2 or v.shape != p.shape or a.shape != p.shape:
            raise ValueError(
                f"start/velocity/acceleration: expected equal (m, 3) shapes, got "
                f"{p.shape}, {v.shape}, {a.shape}"
            )
        for name, arr in (("start", p), ("velocity", v), ("acceleration", a)):
            object.__setattr__(self, name, arr)

    @classmethod
    def linear(cls, start: ArrayLike, velocity: ArrayLike) -> Trajectories:
        """Constant-velocity paths (the papers' linear trajectories)."""
        p = finite_array(start, "start", tail=(3,))
        return cls(p, finite_array(velocity, "velocity", tail=(3,)), np.zeros_like(p))

    @property
    def m(self) -> int:
        """Number of objects."""
        return int(self.start.shape[0])

    def position(self, t: ArrayLike) -> FloatArray:
        """World positions (m, 3) at per-object times ``t`` (m,) or one common time, s."""
        tt = np.broadcast_to(finite_array(t, "t"), (self.m,))[:, None]
        return self.start + self.velocity * tt + 0.5 * self.acceleration * tt**2

    def velocity_at(self, t: ArrayLike) -> FloatArray:
        """World velocities (m, 3) at per-object times ``t`` (m,) or one common time, m/s."""
        tt = np.broadcast_to(finite_array(t, "t"), (self.m,))[:, None]
        return self.velocity + self.acceleration * tt


@dataclass(frozen=True)
class GroupSpec:
    """How :func:`random_group` draws ``m`` objects flying together (theory §5.6, gaps §13.15, §13.35)."""

    centre: tuple[float, float, float]
    """World point around which the objects start, m."""
    spread: float = 3.0
    """Objects start uniformly in a cube of this half-width around the centre, m."""
    min_separation: float = 2.0
    """Minimum distance between any two starting positions ("a few metres apart"), m."""
    speed: tuple[float, float] = (10.0, 40.0)
    """Speed range, m/s (uniform)."""
    heading: tuple[float, float, float] | None = None
    """Mean direction of travel (world); None draws a uniformly random 3-D direction per group."""
    heading_spread_deg: float = 0.0
    """Each object's direction deviates from the group's direction by up to this cone angle, deg."""
    shared_velocity: bool = False
    """True: all objects share one velocity ("close trajectories"); False: each draws its own."""
    speed_jitter: float = 0.0
    """If > 0 (and not shared_velocity): one group speed is drawn and each object's speed is it
    times ``1 + U(−speed_jitter, speed_jitter)`` (close but distinct trajectories)."""

    def __post_init__(self) -> None:
        if len(self.centre) != 3 or not np.all(np.isfinite(self.centre)):
            raise ValueError("centre: expected three finite coordinates")
        if self.spread < 0.0 or self.min_separation < 0.0:
            raise ValueError("spread/min_separation: must be non-negative")
        if not 0.0 <= self.speed[0] <= self.speed[1]:
            raise ValueError("speed: expected 0 <= low <= high")
        if not 0.0 <= self.speed_jitter < 1.0:
            raise ValueError("speed_jitter: must lie in [0, 1)")
        if self.heading is not None and not np.linalg.norm(self.heading) > 0.0:
            raise ValueError("heading: must be a non-zero vector or None")


def _random_unit(rng: np.random.Generator, size: int) -> FloatArray:
    v = rng.standard_normal((size, 3))
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _cone(rng: np.random.Generator, axis: FloatArray, half_angle: float) -> FloatArray:
    """Unit vectors uniform on the spherical cap of ``half_angle`` (rad) around each ``axis``."""
    n = axis.shape[0]
    cos_t = 1.0 - rng.random(n) * (1.0 - np.cos(half_angle))
    psi = rng.random(n) * 2.0 * np.pi
    helper = np.where(np.abs(axis[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    e1 = np.cross(axis, helper)
    e1 /= np.linalg.norm(e1, axis=-1, keepdims=True)
    e2 = np.cross(axis, e1)
    sin_t = np.sqrt(1.0 - cos_t**2)[:, None]
    return cos_t[:, None] * axis + sin_t * (np.cos(psi)[:, None] * e1 + np.sin(psi)[:, None] * e2)


def random_group(rng: np.random.Generator, m: int, spec: GroupSpec) -> Trajectories:
    """Draw ``m`` linear trajectories per ``spec`` (rejection sampling for the separation)."""
    if m < 1:
        raise ValueError("m: need at least one object")
    centre = np.asarray(spec.centre, dtype=np.float64)
    for _ in range(1000):
        start = centre + rng.uniform(-spec.spread, spec.spread, (m, 3))
        d = np.linalg.norm(start[:, None] - start[None], axis=-1)
        if m == 1 or d[np.triu_indices(m, 1)].min() >= spec.min_separation:
            break
    else:
        raise ValueError("spec: cannot place the objects min_separation apart within spread")
    if spec.heading is None:
        axis = _random_unit(rng, 1)
    else:
        axis = np.asarray(spec.heading, dtype=np.float64)[None] / np.linalg.norm(spec.heading)
    n_draw = 1 if spec.shared_velocity else m
    direction = _cone(rng, np.repeat(axis, n_draw, axis=0), np.deg2rad(spec.heading_spread_deg))
    if spec.speed_jitter > 0.0 and not spec.shared_velocity:
        base = rng.uniform(spec.speed[0], spec.speed[1])
        speed = base * (1.0 + rng.uniform(-spec.speed_jitter, spec.speed_jitter, n_draw))[:, None]
    else:
        speed = rng.uniform(spec.speed[0], spec.speed[1], n_draw)[:, None]
    velocity = np.broadcast_to(speed * direction, (m, 3)).copy()
    return Trajectories.linear(start, velocity)
