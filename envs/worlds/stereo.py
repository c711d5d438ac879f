"""The passive stereo world of papers 000 and 003: what every receiver reports each period.

Per period ``i`` (start ``t = i τ``) each receiver ``k`` reports a list of fixes: unit direction
vectors in its **own** frame, their formation times ``t_k`` and normalised received powers
``w_k ∈ [0, 1]`` (theory §3.1). The list is in order of formation time (ties broken at
random), so the position in the list says nothing about the object's identity. Ground truth
(object states and which object each fix came from, −1 for a false fix) is returned apart;
trackers only ever see :class:`ReceiverFixes`.

Noise models (theory §4.1, §13.4), selectable and combinable:

* ``position_sigma`` — the papers' i.i.d. error on the position vector ``M(i, j)``: each object
  is seen by all receivers of one period displaced by one draw ``δ ~ N(0, σ_x² I₃)`` (an
  apparent-centre error). A consistent velocity-aware solve then returns ``M(i, j) = M + δ``,
  which is exactly the theory §4.1 recommended injection point, realised inside the world.
* ``angle_sigma`` — independent Gaussian errors on the azimuth φ and elevation θ of each
  direction vector (003 variant 2: 0.03°).

Detection: probability ``p_detect`` per object and receiver; Poisson false fixes (uniform in
the receiver's field of view, formed when the scan passes them, power uniform in
``[0, false_power_max]``). Received power of a true fix: ``min(1, (r_ref / r)²)``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from sensorgym.envs.worlds.drones import Trajectories
from sensorgym.envs.worlds.scanning import (
    FixedDelay,
    RasterScan,
    ReceiverLayout,
    ScanTiming,
    fix_times,
)
from sensorgym.trackers.geometry import angles_from_unit, unit_from_angles

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


@dataclass(frozen=True)
class NoiseModel:
    """Measurement noise of the direction vectors (module docstring)."""

    position_sigma: float = 0.0
    """Std of each coordinate of the apparent-position error δ shared by all receivers, m."""
    angle_sigma: float = 0.0
    """Std of the azimuth and of the elevation error of each direction vector, rad."""

    def __post_init__(self) -> None:
        if not (self.position_sigma >= 0.0 and self.angle_sigma >= 0.0):
            raise ValueError("position_sigma/angle_sigma: must be finite and non-negative")


@dataclass(frozen=True)
class DetectionModel:
    """Missed detections, false fixes and received power (module docstring)."""

    p_detect: float = 1.0
    """Probability that a receiver fixes an object inside its sector in one period."""
    false_rate: float = 0.0
    """Mean number of false fixes per receiver per period (Poisson)."""
    false_fov_deg: float = 30.0
    """Width of the square field of view around the boresight where false fixes fall, deg."""
    reference_range: float = 50.0
    """Range at which a true fix has power 1 (power ∝ 1/r² beyond), m."""
    false_power_max: float = 0.5
    """False fixes draw their power uniformly in [0, false_power_max]."""

    def __post_init__(self) -> None:
        if not 0.0 <= self.p_detect <= 1.0:
            raise ValueError("p_detect: must lie in [0, 1]")
        if not self.false_rate >= 0.0:
            raise ValueError("false_rate: must be non-negative")
        if not (0.0 < self.false_fov_deg < 180.0 and self.reference_range > 0.0):
            raise ValueError("false_fov_deg/reference_range: out of range")
        if not 0.0 <= self.false_power_max <= 1.0:
            raise ValueError("false_power_max: must lie in [0, 1]")


@dataclass(frozen=True)
class ReceiverFixes:
    """One receiver's report for one period (what a tracker sees)."""

    directions: FloatArray = field(repr=False)
    """(m_k, 3) unit direction vectors in the receiver's own frame."""
    times: FloatArray = field(repr=False)
    """(m_k,) formation times, s."""
    powers: FloatArray = field(repr=False)
    """(m_k,) normalised received powers w_k ∈ [0, 1]."""

    def __post_init__(self) -> None:
        m = self.times.shape[0]
        if self.directions.shape != (m, 3) or self.powers.shape != (m,):
            raise ValueError("directions/times/powers: lengths disagree")

    @property
    def count(self) -> int:
        """Number of fixes m_k."""
        return int(self.times.shape[0])


@dataclass(frozen=True)
class PeriodTruth:
    """Ground truth of one period, kept apart from the measurements."""

    source: tuple[IntArray, ...]
    """Per receiver, (m_k,) index of the object behind each fix, −1 for a false fix."""
    fix_positions: tuple[FloatArray, ...]
    """Per receiver, (m_k, 3) true world position at each fix time (NaN rows for false fixes)."""
    positions: FloatArray = field(repr=False)
    """(m, 3) world positions of all objects at the period start, m."""
    velocities: FloatArray = field(repr=False)
    """(m, 3) world velocities at the period start, m/s."""


def observe_period(
    rng: np.random.Generator,
    trajectories: Trajectories,
    layout: ReceiverLayout,
    timings: tuple[ScanTiming, ...],
    period_index: int,
    period: float,
    noise: NoiseModel = NoiseModel(),
    detection: DetectionModel = DetectionModel(),
) -> tuple[tuple[ReceiverFixes, ...], PeriodTruth]:
    """Every receiver's fixes in period ``period_index`` (start ``period_index · period``).

    ``layout`` (the receivers' current poses) and ``timings`` (one per receiver) are inputs, so
    an environment may move or re-point receivers between periods. All noise comes from ``rng``.
    """
    if len(timings) != layout.n:
        raise ValueError(f"timings: expected one per receiver ({layout.n}), got {len(timings)}")
    if not period > 0.0 or period_index < 0:
        raise ValueError("period/period_index: need period > 0 and period_index >= 0")
    m = trajectories.m
    t0 = period_index * period
    delta = rng.normal(0.0, noise.position_sigma, (m, 3)) if noise.position_sigma > 0 else None

    def locate(t: FloatArray) -> FloatArray:
        p = trajectories.position(t)
        return p if delta is None else p + delta

    fixes, sources, fix_pos = [], [], []
    for k in range(layout.n):
        R, o = layout.rotations[k], layout.positions[k]
        t, inside = fix_times(timings[k], R, o, locate, t0, period)
        seen = inside & (rng.random(m) < detection.p_detect)
        local = (locate(t) - o) @ R
        rng_k = np.linalg.norm(local, axis=-1)
        a = local / rng_k[:, None]
        if noise.angle_sigma > 0.0:
            az, el = angles_from_unit(a)
            az = az + rng.normal(0.0, noise.angle_sigma, m)
            el = el + rng.normal(0.0, noise.angle_sigma, m)
            a = unit_from_angles(az, el)
        power = np.minimum(1.0, (detection.reference_range / rng_k) ** 2)
        idx = np.flatnonzero(seen)
        n_false = rng.poisson(detection.false_rate) if detection.false_rate > 0 else 0
        half = np.deg2rad(0.5 * detection.false_fov_deg)
        az_f, el_f = rng.uniform(-half, half, n_false), rng.uniform(-half, half, n_false)
        a_false = unit_from_angles(az_f, el_f)
        # a false fix is formed when the scan passes its direction
        if isinstance(timings[k], FixedDelay):
            t_false = np.full(n_false, t0 + timings[k].delay)
        else:
            t_false = t0 + timings[k].visit_time(az_f, el_f)[0]
        w_false = rng.uniform(0.0, detection.false_power_max, n_false)
        dirs = np.concatenate([a[idx], a_false.reshape(-1, 3)])
        times = np.concatenate([t[idx], t_false])
        powers = np.concatenate([power[idx], w_false])
        src = np.concatenate([idx, np.full(n_false, -1)]).astype(np.int64)
        truth_pos = np.concatenate([trajectories.position(t)[idx], np.full((n_false, 3), np.nan)])
        # report in order of formation time; a random permutation first breaks ties
        perm = rng.permutation(times.shape[0])
        order = perm[np.argsort(times[perm], kind="stable")]
        fixes.append(ReceiverFixes(dirs[order], times[order], powers[order]))
        sources.append(src[order])
        fix_pos.append(truth_pos[order])
    truth = PeriodTruth(
        tuple(sources), tuple(fix_pos), trajectories.position(t0), trajectories.velocity_at(t0)
    )
    return tuple(fixes), truth


def simulate(
    rng: np.random.Generator,
    trajectories: Trajectories,
    layout: ReceiverLayout,
    timings: tuple[ScanTiming, ...],
    periods: int,
    period: float,
    noise: NoiseModel = NoiseModel(),
    detection: DetectionModel = DetectionModel(),
) -> tuple[list[tuple[ReceiverFixes, ...]], list[PeriodTruth]]:
    """``periods`` consecutive periods of :func:`observe_period` with fixed receiver poses."""
    out = [
        observe_period(rng, trajectories, layout, timings, i, period, noise, detection)
        for i in range(periods)
    ]
    return [o[0] for o in out], [o[1] for o in out]


__all__ = [
    "DetectionModel",
    "FixedDelay",
    "NoiseModel",
    "PeriodTruth",
    "RasterScan",
    "ReceiverFixes",
    "ReceiverLayout",
    "observe_period",
    "simulate",
]
