"""Simulation core of the scanning-receiver environments (papers 000/003's scanning tracker).

The simulation contract of every env (:mod:`sensorgym.envs.shells.contract`): pure functions
over frozen, batched values (leading axis ``B`` = scenario) — :func:`spaces`, :func:`reset`,
:func:`step`, :func:`observe` (the joint view), :func:`observe_agents` (one view per receiver)
and :func:`info`. One step is one scan period ``τ``; the compiled pass is
:func:`.kernels.step_rows` (split over threads by :func:`~sensorgym.envs.shells.rows.run_rows`),
which also writes the new state's observation, so :func:`observe` only reads it.

World frame: ``Y`` up, azimuth from ``+Z`` towards ``+X`` (theory §2.2). ``n`` receivers (3 by
default) stand on a circle (default radius 120 m at azimuths 0°, 90°, 270°: paper 000's arc with
orthogonal lines of sight; :func:`default_azimuths` for other ``n``), each with a fixed frame
looking at the scene centre ``(0, h_aim, 0)``. Per period:

1. the action sets each receiver's *sector* — centre (azimuth, elevation) about its boresight
   and a width ``w`` — and the receiver sweeps a ``L × L`` TV raster over it in ``sweep_time``,
   starting ``scan_offsets[k]`` after the period start (theory §6.1);
2. a drone inside the sector is fixed when the raster reaches it (pixel-visit rule, theory §6.3)
   with angular noise ``σ_k = max(κ w, σ_min)`` — the raster has a fixed pixel count, so a wider
   sector covers more but measures coarser (the sector trade-off) — plus, optionally, a shared
   apparent-position error ``σ_x`` (paper 000's model) and false detections;
3. the tracker (paper 000's proposed velocity-aware algorithm, theory §5.3, or its alternative
   of §5.2) conjugates every triple (pair) of fixes of receivers 1–3 (1–2), lets receivers
   4 … n refine each triple by least squares over all their fixes (proposed only), associates
   candidates to tracks over periods, initiates and confirms tracks (:mod:`.kernels`);
4. the reward: per present drone ``clip(ln(σ_ref/σ_pos), −R, R)`` for the confirmed track
   assigned to it (nearest within ``truth_gate``, at the track's own time if it took a
   candidate in the period, else at the period end), ``σ_pos`` the track's own (a triple's
   exact first-order one, theory §3.5; a joint fit's ``σ_e √([(AᵀA)⁻¹]_11 + 2)``) grown by
   ``σ_vel`` over the time since its latest member; ``−R`` without a track; averaged over the
   present drones, less ``false_track_penalty`` per unassigned confirmed track.
"""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.stats import chi2

from sensorgym.envs.shells.contract import EnvSpaces, with_agent_index
from sensorgym.envs.shells.normals import standard_normal_rows
from sensorgym.envs.shells.params_pickle import FieldsOnlyPickle
from sensorgym.envs.shells.rows import MIN_ROWS_PER_THREAD, run_drawn_rows, run_rows
from sensorgym.envs.stereo_scanning import kernels
from sensorgym.trackers.geometry_kernels import look_at_batch, relative_pose_batch
from sensorgym.trackers.metrics_kernels import gospa_batch
from sensorgym.trackers.stereo.association import norm_quantile
from sensorgym.trackers.stereo.information import MAX_REWARD_CLIP
from sensorgym.trackers.validation import check_fields, count, finite_array

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
IntArray = NDArray[np.int64]

TRACKERS = {
    "proposed": kernels.PROPOSED,
    "alternative": kernels.ALTERNATIVE,
    "algorithmic": kernels.ALGORITHMIC,
}

#: observed values per track slot (:func:`observe`)
TRACK_FEATURES = 11
#: observed values per receiver (:func:`observe`)
RECEIVER_FEATURES = 4


#: paper 000's arc: receivers at azimuths 0°, 90°, 270° (orthogonal lines of sight possible)
PAPER_AZIMUTHS = (0.0, float(np.pi / 2), float(3 * np.pi / 2))
#: span of the default sweep offsets, s: ``(0, 0.25, 0.5)`` for three receivers
OFFSET_SPAN = 0.5


def _spread_order(n: int) -> list[int]:
    """The even spread's indices ``j`` of the receivers in order: receivers 1–3 (the
    candidates' triple) at ``j = 0, round(n/3), round(2n/3)``, the others in ascending ``j``."""
    first = [0, round(n / 3), round(2 * n / 3)]
    return first + [j for j in range(n) if j not in first]


def default_azimuths(n: int) -> tuple[float, ...]:
    """The receivers' azimuths ``(n,)`` when none are given, rad: paper 000's ``(0°, 90°, 270°)``
    for n = 3; else the even spread ``2π j/n`` in :func:`_spread_order` — receivers 1–3 about a
    third of the circle apart (n = 4: 0°, 90°, 270°, then 180°)."""
    if n == 3:
        return PAPER_AZIMUTHS
    return tuple(float(2 * np.pi * j / n) for j in _spread_order(n))


def default_offsets(n: int) -> tuple[float, ...]:
    """The sweep offsets ``(n,)`` when none are given, s: evenly over ``[0, OFFSET_SPAN]``,
    ``OFFSET_SPAN · j/(n − 1)``, with receivers 1–3 at the start, the middle and the end
    (``(0, 0.25, 0.5)`` for n = 3; the others in ascending ``j``): distinct delays keep the
    velocity observable, and the triple that forms the candidates gets the widest ones."""
    first = [0, round((n - 1) / 2), n - 1]
    order = first + [j for j in range(n) if j not in first]
    return tuple(float(x) for x in np.linspace(0.0, OFFSET_SPAN, n)[order])


def _receiver_count(
    n: int | None, azimuths: tuple[float, ...] | None, offsets: tuple[float, ...] | None
) -> int:
    """``n``: :attr:`ScanningParams.n_receivers` (an integer: :func:`check_fields` has seen
    it), else the length of the first given tuple, else 3."""
    if n is not None:
        if n < 3:
            raise ValueError(f"n_receivers: need at least 3 (velocity-aware conjugation), got {n}")
        return int(n)
    for given in (azimuths, offsets):
        if given is not None:
            return len(given)
    return 3


def _per_receiver(name: str, value, n: int, default) -> tuple[float, ...]:
    """One float per receiver: ``value`` checked against ``n``, or ``default(n)``."""
    if value is None:
        return default(n)
    try:
        out = tuple(float(x) for x in value)
    except TypeError as exc:
        raise ValueError(f"{name}: need a tuple of {n} numbers, got {value!r}") from exc
    if len(out) < 3:
        raise ValueError(
            f"{name}: the velocity-aware tracker needs at least 3 receivers, got {len(out)}"
        )
    if len(out) != n:
        raise ValueError(
            f"{name}: {len(out)} values for n_receivers = {n} (give one per receiver, or leave "
            f"{name} unset for the default layout)"
        )
    return out


@dataclass(frozen=True)
class ScanningParams(FieldsOnlyPickle):
    """Receivers, rasters, drones, noise, tracker and reward of the scanning environments."""

    n_receivers: int | None = None
    """Number of receivers ``n`` (≥ 3: the velocity-aware conjugation needs three; receivers
    1–3 form the candidates, the others refine them). ``None``: one per given azimuth, else 3."""
    receiver_azimuths: tuple[float, ...] | None = None
    """Azimuths of the receivers on their circle, rad, one per receiver; the first is the
    conjugation's reference receiver. ``None``: :func:`default_azimuths` — paper 000's
    ``(0°, 90°, 270°)`` for n = 3, else an even spread with receivers 1–3 about a third of the
    circle apart (stored as ``None`` when given equal to those; the values in use are
    :attr:`azimuths_array`)."""
    circle_radius: float = 120.0
    """Radius of the receivers' circle around the origin, m (ground level)."""
    aim_height: float = 40.0
    """The receivers' fixed boresights look at ``(0, aim_height, 0)``, m."""
    n_drones: int = 4
    """Number of drones ``m`` (present or not at a time)."""
    close_drones: int = 1
    """Drones that start ``close_spacing`` from drone 0 on a close, near-parallel path."""
    late_drones: int = 1
    """Drones (the last ones) that enter the scene at a time drawn from ``enter_window``."""
    enter_window: tuple[float, float] = (5.0, 20.0)
    """Entry time of a late drone, s, drawn uniformly and rounded up to a period start."""
    start_spread: float = 30.0
    """Drones start uniformly within ``±start_spread`` of the origin in X and Z, m."""
    start_altitude: tuple[float, float] = (20.0, 60.0)
    """Height of a drone's start, drawn uniformly, m."""
    drone_speed: tuple[float, float] = (2.0, 8.0)
    """Horizontal speed, drawn uniformly, m/s; heading uniform."""
    climb_rate: tuple[float, float] = (-0.5, 0.5)
    """Vertical speed, drawn uniformly, m/s."""
    max_acceleration: float = 0.2
    """Each drone accelerates gently: constant horizontal acceleration of a uniform magnitude up
    to this, uniform direction, m/s²."""
    close_spacing: tuple[float, float] = (2.0, 4.0)
    """Start distance of a close drone from drone 0, drawn uniformly, m."""
    scene_half_width: float = 80.0
    """A drone beyond ``±scene_half_width`` in X or Z (or below ``scene_floor``, above
    ``scene_height``) has left the scene for good, m."""
    scene_height: float = 120.0
    """Ceiling of the scene, m."""
    scene_floor: float = 1.0
    """Floor of the scene: a drone below it has left (landed), m."""
    period: float = 1.0
    """Scan period ``τ`` = one step, s."""
    sweep_time: float = 0.5
    """Duration of one raster sweep of the sector, s (fixed: a fixed pixel count and dwell)."""
    scan_offsets: tuple[float, ...] | None = None
    """Start of each receiver's sweep after the period start, s (one per receiver, each plus
    ``sweep_time`` within ``τ``); distinct offsets give the distinct delays the velocity-aware
    system needs (theory §3.5). ``None``: :func:`default_offsets` — evenly over ``[0, 0.5]`` s,
    receivers 1–3 at 0, 0.25 and 0.5 s (stored as ``None`` when given equal to those; the values in
    use are :attr:`offsets_array`)."""
    raster_lines: int = 100
    """``L``: the raster has ``L × L`` pixels (theory §6.2: 100 × 100)."""
    pixel_iterations: int = 4
    """Fixed-point iterations of the pixel-visit rule (theory §6.3)."""
    field_of_regard: float = float(np.deg2rad(90.0))
    """Sector centres lie within ``±field_of_regard/2`` of the boresight in azimuth and
    elevation, rad."""
    sector_width: tuple[float, float] = (float(np.deg2rad(5.0)), float(np.deg2rad(90.0)))
    """Smallest and largest sector width ``w`` (square, azimuth × elevation), rad."""
    noise_per_width: float = 1e-3
    """``κ``: a fix from a sector of width ``w`` has isotropic angular noise ``κ w`` rad (a
    tenth of a pixel of a 100-line raster); 0 turns the width's noise off."""
    sigma_ang_min: float = 0.0
    """Floor of the angular noise, rad."""
    position_sigma: float = 0.0
    """``σ_x``: one apparent-position error per drone and period, ``N(0, σ_x² I)``, seen by
    every receiver (paper 000's simulation, theory §4.1), m."""
    clutter_rate: float = 0.0
    """Mean number of false detections per receiver and period (Poisson), uniform in the
    sector."""
    max_clutter: int = 2
    """Most false detections per receiver and period."""
    tracker: str = "proposed"
    """``"proposed"`` (paper 000's velocity-aware triples, theory §5.3), ``"alternative"``
    (receivers 1–2 only, delays ignored, line fits, theory §5.2) or ``"algorithmic"`` (paper
    003's detector on receivers 1–2: pairs re-solved with the track's motion, the index
    ``c_1 J_1 + c_2 J_2 + c_3 J_3``, theory §5.5)."""
    max_speed: float = 50.0
    """Candidates faster than this are implausible and dropped, m/s (theory §13.13)."""
    gate_probability: float = 0.999
    """Probability that a true continuation passes the gate ``δ`` (theory §13.6)."""
    fit_false_alarm: float = 1e-6
    """Probability (dimensionless, in (0, 1)) that a true drone's joint fit of more than three
    receivers fails its χ² test, ``J/σ_e²`` beyond the upper ``fit_false_alarm`` point of
    ``χ²_{2n'−6}`` plus the unmodelled drift (theory §5.3): the candidate is then dropped as
    a ghost. Unused with three receivers."""
    confirm_hits: int = 2
    """A tentative track is confirmed once it holds this many periods' candidates."""
    max_misses: int = 2
    """A confirmed track is dropped after more than this many periods without a candidate."""
    ghost_misses: int = 2
    """Negative information (n ≥ 4): a triple of receivers 1–3 whose prediction lies inside
    the sectors of this many receivers 4 … n, by more than its uncertainty and its motion
    during their sweeps, with no fix in its gate there, is a ghost and dropped before its
    joint fit (detection is certain inside a sector, so a real drone misses one receiver's
    gate with probability ``1 − gate_probability``, two of them with about its square per pair
    of receivers). ``0``: off."""
    track_capacity: int = 32
    """Rows of the tracker's table (tentative and confirmed tracks)."""
    track_slots: int = 8
    """Confirmed tracks shown in the observation (in table order)."""
    cond_max: float = 1e7
    """Candidates whose conjugation has ``κ_F`` above this are degenerate and dropped."""
    sigma_ref: float = 1.0
    """Position accuracy that earns zero reward, m."""
    reward_clip: float = 5.0
    """``R``: per-drone rewards are clipped to ``[−R, R]``; ``−R`` for a drone without a track."""
    false_track_penalty: float = 0.5
    """Reward subtracted per confirmed track that no present drone is assigned to."""
    truth_gate: float = 4.0
    """A confirmed track is assigned to the nearest present drone within this distance at the
    period end (one-to-one, greedy), m."""

    def __post_init__(self) -> None:
        check_fields(self)  # every field of its annotated type: no bool for a count or a number
        n = _receiver_count(self.n_receivers, self.receiver_azimuths, self.scan_offsets)
        azimuths = _per_receiver("receiver_azimuths", self.receiver_azimuths, n, default_azimuths)
        offsets = _per_receiver("scan_offsets", self.scan_offsets, n, default_offsets)
        # normalised, so that equal settings compare equal: n_receivers always the count, the
        # per-receiver tuples None where they are the defaults (dataclasses.replace(params,
        # n_receivers=8) then spreads the default layout over the new count)
        object.__setattr__(self, "n_receivers", n)
        object.__setattr__(
            self, "receiver_azimuths", None if azimuths == default_azimuths(n) else azimuths
        )
        object.__setattr__(self, "scan_offsets", None if offsets == default_offsets(n) else offsets)
        if not np.all(np.isfinite(azimuths)):
            raise ValueError("receiver_azimuths: must be finite")
        if len(set(np.round(np.mod(azimuths, 2 * np.pi), 9))) != n:
            raise ValueError("receiver_azimuths: receivers may not share a place on the circle")
        for name in ("circle_radius", "period", "sweep_time", "scene_half_width",
                     "scene_height", "max_speed", "sigma_ref", "truth_gate", "field_of_regard",
                     "cond_max", "start_spread"):  # fmt: skip
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0.0):
                raise ValueError(f"{name}: must be positive and finite, got {value}")
        for name in ("aim_height",):
            if not np.isfinite(getattr(self, name)):
                raise ValueError(f"{name}: must be finite")
        for name in ("max_acceleration", "noise_per_width", "sigma_ang_min", "position_sigma",
                     "clutter_rate", "false_track_penalty"):  # fmt: skip
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0.0):
                raise ValueError(f"{name}: must be finite and >= 0, got {value}")
        for name in ("enter_window", "start_altitude", "drone_speed", "close_spacing",
                     "sector_width"):  # fmt: skip
            lo, hi = getattr(self, name)
            if not (np.isfinite(lo) and np.isfinite(hi) and 0.0 <= lo <= hi):
                raise ValueError(f"{name}: need finite 0 <= low <= high, got {(lo, hi)}")
        lo, hi = self.climb_rate
        if not (np.isfinite(lo) and np.isfinite(hi) and lo <= hi):
            raise ValueError(f"climb_rate: need finite low <= high, got {(lo, hi)}")
        if self.sector_width[0] <= 0.0 or self.sector_width[1] > np.pi:
            raise ValueError(f"sector_width: must lie in (0, π] rad, got {self.sector_width}")
        if self.field_of_regard + self.sector_width[1] >= 2 * np.pi:
            raise ValueError("field_of_regard: with the widest sector it must stay below 2π")
        if not np.isfinite(self.scene_floor) or self.scene_floor >= self.scene_height:
            raise ValueError(
                f"scene_floor: must be finite and below scene_height, got {self.scene_floor}"
            )
        if not (
            self.scene_floor < self.start_altitude[0] and self.start_altitude[1] < self.scene_height
        ):
            raise ValueError("start_altitude: must lie inside (scene_floor, scene_height)")
        if self.start_spread >= self.scene_half_width:
            raise ValueError("start_spread: must be smaller than scene_half_width")
        off = np.asarray(offsets, dtype=np.float64)
        if not (np.all(np.isfinite(off)) and np.all(off >= 0.0)):
            raise ValueError(f"scan_offsets: must be finite and >= 0, got {offsets}")
        if np.any(off + self.sweep_time > self.period + 1e-12):
            raise ValueError("scan_offsets: every sweep must end within the period")
        for name in ("n_drones", "raster_lines", "pixel_iterations", "confirm_hits",
                     "track_capacity", "track_slots"):  # fmt: skip
            count(getattr(self, name), name, minimum=1)
        for name in ("close_drones", "late_drones", "max_clutter", "max_misses", "ghost_misses"):
            count(getattr(self, name), name, minimum=0)
        if self.close_drones + 1 > self.n_drones and self.close_drones > 0:
            raise ValueError("close_drones: must be smaller than n_drones")
        if self.late_drones > self.n_drones:
            raise ValueError("late_drones: must not exceed n_drones")
        if self.tracker not in TRACKERS:
            raise ValueError(f"tracker: one of {sorted(TRACKERS)}, got {self.tracker!r}")
        if not 0.0 < self.gate_probability < 1.0:
            raise ValueError(f"gate_probability: must lie in (0, 1), got {self.gate_probability}")
        if not 0.0 < self.fit_false_alarm < 1.0:
            raise ValueError(f"fit_false_alarm: must lie in (0, 1), got {self.fit_false_alarm}")
        if not 0.0 < self.reward_clip <= MAX_REWARD_CLIP:
            raise ValueError(
                f"reward_clip: must lie in (0, {MAX_REWARD_CLIP}], got {self.reward_clip}"
            )

    @property
    def max_fixes(self) -> int:
        """Most fixes of one receiver in one period: every drone plus ``max_clutter``."""
        return self.n_drones + self.max_clutter

    @property
    def obs_dim(self) -> int:
        """Observation length ``11 · track_slots + 4 n`` (100 by default, :func:`observe`)."""
        return TRACK_FEATURES * self.track_slots + RECEIVER_FEATURES * self.n_receivers

    @functools.cached_property
    def offsets_array(self) -> FloatArray:
        """The sweep offsets in use ``(n,)``, s: :attr:`scan_offsets`, or
        :func:`default_offsets`."""
        off = default_offsets(self.n_receivers) if self.scan_offsets is None else self.scan_offsets
        return np.asarray(off, dtype=np.float64)

    @functools.cached_property
    def azimuths_array(self) -> FloatArray:
        """The receivers' azimuths in use ``(n,)``, rad: :attr:`receiver_azimuths`, or
        :func:`default_azimuths`."""
        az = self.receiver_azimuths
        return np.asarray(default_azimuths(self.n_receivers) if az is None else az, np.float64)

    @functools.cached_property
    def centre(self) -> FloatArray:
        """The scene centre ``(0, aim_height, 0)`` the boresights look at, m."""
        return np.array([0.0, self.aim_height, 0.0])

    @functools.cached_property
    def length_scale(self) -> float:
        """Length (m) that normalises observed positions: the scene's half width."""
        return self.scene_half_width

    @functools.cached_property
    def speed_scale(self) -> float:
        """Speed (m/s) that normalises observed velocities: the fastest drone."""
        return max(self.drone_speed[1], 1.0)

    @functools.cached_property
    def gate_q(self) -> float:
        """``q``: the ``gate_probability`` point of the norm of a unit 3-D Gaussian (4.03 at
        99.9 %, theory §13.6)."""
        return norm_quantile(1.0, self.gate_probability)

    @functools.cached_property
    def fit_thresholds(self) -> FloatArray:
        """``χ²`` thresholds ``(n − 3,)`` of the joint fits (theory §5.3): entry ``n' − 4`` is
        the upper ``fit_false_alarm`` point of ``χ²`` on ``2 n' − 6`` degrees of freedom, for
        a fit of ``n' = 4 … n`` receivers (``scipy.stats.chi2.isf``; 27.6 for ``n' = 4`` at
        1e-6)."""
        dof = 2.0 * np.arange(4, self.n_receivers + 1) - 6.0
        return np.asarray(chi2.isf(self.fit_false_alarm, dof), dtype=np.float64)

    @functools.cached_property
    def kernel_settings(self) -> NDArray[np.void]:
        """What the compiled kernels read of the params, computed once: one record of dtype
        ``kernels.SETTINGS`` (an array of one, read-only), read by field name."""
        s = np.zeros(1, kernels.SETTINGS)
        r = s[0]
        r["scene_half"], r["scene_floor"] = self.scene_half_width, self.scene_floor
        r["scene_height"], r["sweep"] = self.scene_height, self.sweep_time
        r["lines"], r["period"] = float(self.raster_lines), self.period
        r["lo_w"], r["hi_w"] = self.sector_width
        r["half_regard"] = 0.5 * self.field_of_regard
        r["kappa"], r["sigma_min"] = self.noise_per_width, self.sigma_ang_min
        r["position_sigma"] = self.position_sigma
        r["max_speed"], r["max_accel"] = self.max_speed, self.max_acceleration
        r["gate_q"], r["cond_max"] = self.gate_q, self.cond_max
        r["sigma_ref"], r["reward_clip"] = self.sigma_ref, self.reward_clip
        r["false_penalty"], r["truth_gate"] = self.false_track_penalty, self.truth_gate
        r["length"], r["speed"] = self.length_scale, self.speed_scale
        r["max_fix"] = float(self.max_fixes)
        r["tracker"], r["iters"] = TRACKERS[self.tracker], self.pixel_iterations
        r["confirm_hits"], r["max_misses"] = self.confirm_hits, self.max_misses
        r["ghost_misses"] = self.ghost_misses
        r["centre"] = self.centre
        s.flags.writeable = False
        return s

    @functools.cached_property
    def kernel_geometry(self) -> tuple[FloatArray, ...]:
        """The receivers' geometry the compiled kernels read, a plain tuple in the order of
        ``kernels.Geometry`` (read-only C-contiguous copies): places, rotations, poses in
        receiver 1's frame, sweep offsets and :attr:`fit_thresholds`."""
        P, b = self.relative
        parts = (self.receivers, self.rotations, P, b, self.offsets_array, self.fit_thresholds)
        out = []
        for x in parts:
            a = np.array(x, dtype=np.float64, order="C")
            a.flags.writeable = False
            out.append(a)
        return tuple(out)

    @functools.cached_property
    def receivers(self) -> FloatArray:
        """Receiver positions ``(n, 3)``, m."""
        az = self.azimuths_array
        rho = self.circle_radius
        return np.stack([rho * np.sin(az), np.zeros_like(az), rho * np.cos(az)], -1)

    @functools.cached_property
    def rotations(self) -> FloatArray:
        """Local→world rotations ``(n, 3, 3)`` of the receivers' fixed frames (columns = local
        axes), looking at :attr:`centre`."""
        n = self.n_receivers
        out = np.empty((n, 3, 3))
        target = np.broadcast_to(self.centre, (n, 3)).copy()
        up = np.broadcast_to(np.array([0.0, 1.0, 0.0]), (n, 3)).copy()
        look_at_batch(self.receivers, target, up, out)
        return out

    @functools.cached_property
    def relative(self) -> tuple[FloatArray, FloatArray]:
        """``P_k = R_1ᵀ R_k`` ``(n−1, 3, 3)`` and ``b_k = R_1ᵀ (O_k − O_1)`` ``(n−1, 3)``
        (theory §2.1)."""
        n = self.n_receivers
        R, O = self.rotations, self.receivers
        P, b = np.empty((n - 1, 3, 3)), np.empty((n - 1, 3))
        relative_pose_batch(
            np.repeat(R[:1], n - 1, 0), np.repeat(O[:1], n - 1, 0), R[1:].copy(), O[1:].copy(), P, b
        )
        return P, b


@dataclass(frozen=True)
class ScanningState:
    """``B`` scenarios at time ``t`` (the start of the next scan period)."""

    t: FloatArray
    """(B,) time since the episode start, s."""
    drone_position: FloatArray = field(repr=False)
    """(B, m, 3) true drone positions at ``t`` (ground truth), m."""
    drone_velocity: FloatArray = field(repr=False)
    """(B, m, 3) true velocities, m/s."""
    drone_acceleration: FloatArray = field(repr=False)
    """(B, m, 3) constant accelerations, m/s²."""
    enter: FloatArray = field(repr=False)
    """(B, m) entry times, s (a drone is in the scene from then until it leaves)."""
    exited: BoolArray = field(repr=False)
    """(B, m) True once a drone has left the scene."""
    sectors: FloatArray = field(repr=False)
    """(B, n, 3) the last period's sectors: centre azimuth, elevation and width, rad."""
    fixes: FloatArray = field(repr=False)
    """(B, n, F, 4) the last period's fixes: measured direction (world frame) and fix time (s);
    rows ``< fix_count`` are used (views: :attr:`fix_world`, :attr:`fix_time`)."""
    fix_count: IntArray = field(repr=False)
    """(B, n) number of fixes per receiver in the last period."""
    fix_drone: IntArray = field(repr=False)
    """(B, n, F) which drone each fix is of (−1: false detection; ground truth); the unused
    rows hold −1 after a reset, 0 after a step."""
    tracks: FloatArray = field(repr=False)
    """(B, T, 19) the tracker's table, per row: position (m) at its time and velocity (m/s),
    world frame (0–5); time of the latest member, s (6); ``σ_pos`` (m) and ``σ_vel`` (m/s), the
    square roots of the traces of its covariance (7, 8; a triple's exact, theory §3.5); cumulative index ``I = Σ ΔJ``, m (9); the alternative's line-fit
    sums ``(S0, Σt, Σt², ΣM, ΣtM)``, t from the latest member (10–18). Views: ``track_*``."""
    track_int: IntArray = field(repr=False)
    """(B, T, 4) per row: periods with a member, consecutive misses, status (0 empty,
    1 tentative, 2 confirmed) and the identity given at confirmation (a row not confirmed may
    keep an earlier track's). A freed row keeps its last values until it is reused."""
    next_id: IntArray = field(repr=False)
    """(B,) the next identity."""
    assigned: IntArray = field(repr=False)
    """(B, m) track row assigned to each drone at the last period end (−1: none)."""
    drone_sigma: FloatArray = field(repr=False)
    """(B, m) ``σ_pos`` of the assigned track at the period end, m (inf: none)."""
    parts: FloatArray = field(repr=False)
    """(B, 6) drones present, drones tracked, false tracks, mean per-drone reward, mean
    ``σ_pos`` of the tracked drones (m), confirmed tracks."""
    observation: NDArray[np.float32] = field(repr=False)
    """Derived: (B, obs_dim) the observation of this state (:func:`observe`), written by the
    compiled kernels with the rest of the state; :func:`observe` only reads it. A state changed
    by hand (``dataclasses.replace``) must be rebuilt with :func:`with_observation`."""

    @property
    def batch_size(self) -> int:
        """Number of scenarios ``B``."""
        return int(self.t.shape[0])

    @property
    def fix_world(self) -> FloatArray:
        """(B, n, F, 3) measured directions, world frame."""
        return self.fixes[..., :3]

    @property
    def fix_time(self) -> FloatArray:
        """(B, n, F) fix times, s."""
        return self.fixes[..., 3]

    @property
    def track_x(self) -> FloatArray:
        """(B, T, 6) track position (m) at ``track_t`` and velocity (m/s), world frame."""
        return self.tracks[..., 0:6]

    @property
    def track_t(self) -> FloatArray:
        """(B, T) time of each track's latest member, s."""
        return self.tracks[..., 6]

    @property
    def track_sigma(self) -> FloatArray:
        """(B, T, 2) ``σ_pos`` (m) and ``σ_vel`` (m/s)."""
        return self.tracks[..., 7:9]

    @property
    def track_score(self) -> FloatArray:
        """(B, T) cumulative index, m."""
        return self.tracks[..., 9]

    @property
    def track_sums(self) -> FloatArray:
        """(B, T, 9) the alternative's line-fit sums."""
        return self.tracks[..., 10:19]

    @property
    def track_hits(self) -> IntArray:
        """(B, T) periods with a member."""
        return self.track_int[..., 0]

    @property
    def track_misses(self) -> IntArray:
        """(B, T) consecutive periods without one."""
        return self.track_int[..., 1]

    @property
    def track_status(self) -> IntArray:
        """(B, T) 0 empty, 1 tentative, 2 confirmed."""
        return self.track_int[..., 2]

    @property
    def track_id(self) -> IntArray:
        """(B, T) identity given at confirmation (−1: never confirmed in this row; meaningful
        for confirmed rows only)."""
        return self.track_int[..., 3]


def spaces(params: ScanningParams) -> EnvSpaces:
    """Agents ``receiver_0 … receiver_{n−1}``, each choosing its sector ``(φ_c, θ_c, w)``; the
    joint view is :func:`observe`, each agent's that plus a one-hot of its index."""
    n = params.n_receivers
    return EnvSpaces.build("receiver", n, params.obs_dim, params.obs_dim + n, 3)


#: the state fields a step writes, in the order of the step kernel's outputs
_WRITTEN = ("t", "drone_position", "drone_velocity", "exited", "tracks", "track_int", "next_id",
            "sectors", "fixes", "fix_count", "fix_drone", "assigned", "drone_sigma", "parts",
            "observation")  # fmt: skip


def _outputs(params: ScanningParams, B: int) -> tuple[np.ndarray, ...]:
    """Uninitialised arrays of every field a step writes, in :data:`_WRITTEN` order (the
    kernel fills each one)."""
    n, F, m, T = params.n_receivers, params.max_fixes, params.n_drones, params.track_capacity
    return (
        np.empty(B),
        np.empty((B, m, 3)),
        np.empty((B, m, 3)),
        np.empty((B, m), bool),
        np.empty((B, T, 19)),
        np.empty((B, T, 4), np.int64),
        np.empty(B, np.int64),
        np.empty((B, n, 3)),
        np.empty((B, n, F, 4)),
        np.empty((B, n), np.int64),
        np.empty((B, n, F), np.int64),
        np.empty((B, m), np.int64),
        np.empty((B, m)),
        np.empty((B, 6)),
        np.empty((B, params.obs_dim), np.float32),
    )


def start(
    params: ScanningParams,
    drone_position: FloatArray,
    drone_velocity: FloatArray,
    drone_acceleration: FloatArray,
    enter: FloatArray,
) -> ScanningState:
    """Scenarios from given drones ``(B, m, 3)`` (positions at their entry times ``enter
    (B, m)``, s) with an empty track table at ``t = 0``: no fixes yet, zero sectors."""
    m = params.n_drones
    p = finite_array(drone_position, "drone_position", tail=(m, 3))
    v = finite_array(drone_velocity, "drone_velocity", tail=(m, 3))
    a = finite_array(drone_acceleration, "drone_acceleration", tail=(m, 3))
    e = finite_array(enter, "enter", tail=(m,))
    B = p.shape[0]
    if p.ndim != 3 or v.shape != p.shape or a.shape != p.shape or e.shape != (B, m):
        raise ValueError("drone_position/drone_velocity/drone_acceleration/enter: shapes differ")
    out = dict(zip(_WRITTEN, _outputs(params, B), strict=True))
    out["t"][:] = 0.0
    out["drone_position"][:] = p
    out["drone_velocity"][:] = v
    out["exited"][:] = False
    out["tracks"][:] = 0.0
    out["track_int"][:] = 0
    out["track_int"][..., 3] = -1
    out["next_id"][:] = 0
    out["sectors"][:] = 0.0
    out["fixes"][:] = 0.0
    out["fix_count"][:] = 0
    out["fix_drone"][:] = -1
    out["assigned"][:] = -1
    out["drone_sigma"][:] = np.inf
    out["parts"][:] = 0.0
    state = ScanningState(
        drone_acceleration=np.ascontiguousarray(a), enter=np.ascontiguousarray(e), **out
    )
    return with_observation(params, state)


def with_observation(params: ScanningParams, state: ScanningState) -> ScanningState:
    """``state`` with its derived :attr:`~ScanningState.observation` computed from its other
    fields (for a state built or changed by hand; :func:`step` writes it itself)."""
    obs = np.empty((state.batch_size, params.obs_dim), np.float32)
    kernels.observe_kernel(
        params.kernel_settings,
        np.ascontiguousarray(state.t, dtype=np.float64),
        np.ascontiguousarray(state.tracks, dtype=np.float64),
        np.ascontiguousarray(state.track_int, dtype=np.int64),
        np.ascontiguousarray(state.sectors, dtype=np.float64),
        np.ascontiguousarray(state.fix_count, dtype=np.int64),
        obs,
    )
    return dataclasses.replace(state, observation=obs)


def draw_scenario(
    params: ScanningParams, rng: np.random.Generator, batch: int
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """The drones of ``batch`` fresh scenarios (theory §11.5): positions ``(B, m, 3)`` at their
    entry times, velocities and constant accelerations ``(B, m, 3)`` and entry times
    ``(B, m)``, s. Drawn in a fixed order, so that a seed fixes every scenario: start places
    (X, Z), heights, horizontal speeds, headings, climb rates, acceleration magnitudes and
    directions, close-drone spacings, their offset directions and speed jitters, then the late
    drones' entry times (every draw is taken for all ``m`` drones, used or not)."""
    m = params.n_drones
    xz = rng.uniform(-params.start_spread, params.start_spread, (batch, m, 2))
    height = rng.uniform(*params.start_altitude, (batch, m))
    speed = rng.uniform(*params.drone_speed, (batch, m))
    heading = rng.uniform(-np.pi, np.pi, (batch, m))
    climb = rng.uniform(*params.climb_rate, (batch, m))
    acc = rng.uniform(0.0, params.max_acceleration, (batch, m))
    acc_dir = rng.uniform(-np.pi, np.pi, (batch, m))
    spacing = rng.uniform(*params.close_spacing, (batch, m))
    offset_dir = rng.normal(size=(batch, m, 3))
    jitter = rng.uniform(-0.1, 0.1, (batch, m))
    late = rng.uniform(*params.enter_window, (batch, m))
    p = np.stack([xz[..., 0], height, xz[..., 1]], -1)
    v = np.stack([speed * np.sin(heading), climb, speed * np.cos(heading)], -1)
    a = np.stack([acc * np.sin(acc_dir), np.zeros_like(acc), acc * np.cos(acc_dir)], -1)
    c = params.close_drones
    if c > 0:
        # close drones: a few metres from drone 0 on a near-parallel path (papers' "close
        # trajectories"), speed within ±10 % of drone 0's
        u = offset_dir[:, 1 : c + 1]
        u = u / np.maximum(np.linalg.norm(u, axis=-1, keepdims=True), 1e-12)
        p[:, 1 : c + 1] = p[:, :1] + spacing[:, 1 : c + 1, None] * u
        v[:, 1 : c + 1] = v[:, :1] * (1.0 + jitter[:, 1 : c + 1, None])
        a[:, 1 : c + 1] = a[:, :1]
    enter = np.zeros((batch, m))
    if params.late_drones > 0:
        k = m - params.late_drones
        enter[:, k:] = np.ceil(late[:, k:] / params.period - 1e-9) * params.period
    p[..., 1] = np.clip(p[..., 1], params.scene_floor, params.scene_height)
    return p, v, a, enter


def reset(
    params: ScanningParams,
    rng: np.random.Generator,
    batch: int,
    like: ScanningState | None = None,
) -> ScanningState:
    """``batch`` fresh scenarios: drones over the scene centre, one close group, late entries
    (:func:`draw_scenario`). Scenarios share nothing: ``like`` is unused."""
    if batch < 1:
        raise ValueError(f"batch: must be >= 1, got {batch}")
    return start(params, *draw_scenario(params, rng, batch))


def step(
    params: ScanningParams, state: ScanningState, action: FloatArray, rng: np.random.Generator
) -> tuple[ScanningState, FloatArray, BoolArray]:
    """Advance every scenario one scan period under the joint ``action`` ``(B, n, 3)`` (or
    ``(B, 3n)``): per receiver the sector centre (azimuth, elevation) and width, each in
    ``[−1, 1]``.

    Out-of-range actions are clipped; NaN or infinite actions raise ``ValueError`` (the
    compiled step checks them: the noise is drawn first). Returns ``(state, reward (B,),
    terminated (B,))``: terminated once every drone has entered and left the scene; the time
    limit is the shells' business. The new state carries its observation.
    """
    B, n, m = state.t.shape[0], params.n_receivers, params.n_drones
    a = np.asarray(action, dtype=np.float64)
    if a.shape != (B, n, 3):
        if a.size != B * 3 * n:
            raise ValueError(f"action: expected {B * 3 * n} values (B, 3n), got shape {a.shape}")
        a = a.reshape(B, n, 3)
    if not a.flags.c_contiguous:
        a = np.ascontiguousarray(a)
    # noise draws, in a fixed order: directions, apparent positions, false detections. With
    # the directions only (the default), a threaded step draws them row range by row range as
    # its chunks start (run_drawn_rows: the same stream)
    normals = np.empty((B, n, m, 3))
    pipelined = not (params.position_sigma > 0.0 or params.clutter_rate > 0.0)
    pipelined = pipelined and B >= 2 * MIN_ROWS_PER_THREAD
    if not pipelined:
        standard_normal_rows(rng, normals, 0, B)
    if params.position_sigma > 0.0:
        pos_noise = params.position_sigma * rng.standard_normal((B, m, 3))
    else:
        pos_noise = _zeros(params, "pos_noise", (B, m, 3))
    if params.clutter_rate > 0.0 and params.max_clutter > 0:
        clutter_count = rng.poisson(params.clutter_rate, (B, n)).astype(np.int64)
        clutter_uv = rng.uniform(0.0, 1.0, (B, n, params.max_clutter, 2))
    else:
        clutter_count = _zeros(params, "clutter_count", (B, n), np.int64)
        clutter_uv = _zeros(params, "clutter_uv", (B, n, max(params.max_clutter, 1), 2))
    # read-only like the zeros: numba types a read-only array apart from a writable one, and
    # the step kernel would be compiled once more (half a minute) for every mix of the two
    for drawn in (pos_noise, clutter_count, clutter_uv):
        drawn.flags.writeable = False
    out = _outputs(params, B)
    reward, terminated = np.empty(B), np.empty(B, bool)
    # the state's arrays go in as they are: step and start make them float64 and C-contiguous
    old = (
        state.t, state.drone_position, state.drone_velocity, state.drone_acceleration,
        state.enter, state.exited, state.tracks, state.track_int, state.next_id,
    )  # fmt: skip
    args = (params.kernel_settings, params.kernel_geometry, a, old,
            (normals, pos_noise, clutter_count, clutter_uv), out, (reward, terminated))  # fmt: skip
    if B < 2 * MIN_ROWS_PER_THREAD:  # what run_rows does for a batch this small, sooner
        finite = kernels.step_rows(0, B, *args)
    else:
        chunks: list[bool] = []
        kernel_on = lambda lo, hi: chunks.append(kernels.step_rows(lo, hi, *args))  # noqa: E731
        if pipelined:
            draw = lambda lo, hi: standard_normal_rows(rng, normals, lo, hi)  # noqa: E731
            run_drawn_rows(B, draw, kernel_on, key=__name__)
        else:
            run_rows(B, kernel_on)
        finite = all(chunks)
    if not finite:
        raise ValueError("action: contains NaN or infinite values")
    # kernel outputs: the constructor is skipped (every field is set, consistent)
    new = object.__new__(ScanningState)
    new.__dict__.update(zip(_WRITTEN, out, strict=True))
    new.__dict__["drone_acceleration"] = state.drone_acceleration
    new.__dict__["enter"] = state.enter
    return new, reward, terminated


def _zeros(params: ScanningParams, name: str, shape: tuple[int, ...], dtype: type = np.float64):
    """A read-only zero array of ``shape`` kept on ``params`` (the draws a step without that
    noise passes to the kernel: allocated once, not per step)."""
    cache = params.__dict__.setdefault("_zeros", {})
    key = (name, shape)
    z = cache.get(key)
    if z is None:
        z = np.zeros(shape, dtype)
        z.flags.writeable = False
        cache[key] = z
    return z


def observe(params: ScanningParams, state: ScanningState) -> NDArray[np.float32]:
    """The agent's observation ``(B, obs_dim)`` float32 — the tracker's table and the sectors,
    no ground truth.

    ``track_slots`` rows of 11 (the confirmed tracks in table order; empty rows all zero), then
    4 per receiver (``L = length_scale``, ``S = speed_scale``, ``c`` the scene centre, ``p̂``,
    ``v̂`` a track's position predicted to ``t`` and velocity, ``Δ`` the time since its latest
    member):

    | block       | entry                        | meaning                                        |
    |-------------|------------------------------|------------------------------------------------|
    | track row   | 0                            | 1.0 (valid row mask)                           |
    |             | 1–3                          | ``(p̂ − c)/L``                                  |
    |             | 4–6                          | ``v̂ / S``                                      |
    |             | 7                            | ``ln(σ_pos(t)/σ_ref)``, ``σ_pos² + (σ_vel Δ)²`` |
    |             | 8                            | ``ln(σ_vel τ/σ_ref)``                          |
    |             | 9                            | ``Δ/τ`` (staleness)                            |
    |             | 10                           | periods with a member / 10 (age)               |
    | receiver k  | 0, 1                         | sector centre azimuth, elevation ``/(regard/2)`` |
    |             | 2                            | width, ``w_min … w_max`` mapped to ``−1 … 1``   |
    |             | 3                            | fixes last period / ``max_fixes``              |

    Every entry is clipped to ``[−OBS_CLIP, OBS_CLIP]``.
    """
    return state.observation


def observe_agents(params: ScanningParams, state: ScanningState) -> NDArray[np.float32]:
    """Per-receiver views ``(B, n, obs_dim + n)``: :func:`observe` and a one-hot of the
    receiver's index."""
    return with_agent_index(observe(params, state), params.n_receivers)


def info(params: ScanningParams, state: ScanningState) -> dict[str, FloatArray]:
    """Diagnostics (ground truth included: for evaluation, never for the policy); ``gospa``:
    the GOSPA (m; ``c = truth_gate``, ``p = 2``, ``α = 2``, :func:`~sensorgym.trackers.metrics.gospa`)
    at the period end ``t`` between the confirmed tracks, predicted to ``t``, and the true
    positions of the drones in the scene through the period (entered by its start, not left
    at its end): the tail measure of :mod:`sensorgym.train.tail`."""
    parts = state.parts
    return {
        "drones_present": parts[:, 0],
        "drones_tracked": parts[:, 1],
        "false_tracks": parts[:, 2],
        "drone_reward": parts[:, 3],
        "mean_sigma_pos": parts[:, 4],
        "confirmed_tracks": parts[:, 5],
        "gospa": period_gospa(params, state),
    }


def period_gospa(params: ScanningParams, state: ScanningState) -> FloatArray:
    """``(B,)`` GOSPA (m) of each scenario at its period end (:func:`info`)."""
    t = state.t
    confirmed = state.track_status == kernels.CONFIRMED
    present = (state.enter <= (t - params.period)[:, None] + 1e-9) & ~state.exited
    x = state.track_x
    with np.errstate(invalid="ignore", over="ignore"):  # empty rows: whatever they hold
        lead = t[:, None] - state.track_t  # each track predicted to the period end
    out = np.empty(t.shape[0])
    # every scenario in one compiled pass (reference: trackers.metrics.gospa, one at a time)
    gospa_batch(x[..., :3], x[..., 3:6], lead, confirmed, state.drone_position, present,
                params.truth_gate, out)  # fmt: skip
    return out


def split_observation(params: ScanningParams, obs: FloatArray) -> dict[str, FloatArray]:
    """Inverse of :func:`observe`'s layout for observations ``(N, obs_dim)``, in world units:
    ``valid (N, S)``, ``position (N, S, 3)``, ``velocity (N, S, 3)``, ``sigma (N, S)`` (m),
    ``sectors (N, n, 3)`` (rad)."""
    o = np.asarray(obs, dtype=np.float64)
    N, S, n = o.shape[0], params.track_slots, params.n_receivers
    rows = o[:, : TRACK_FEATURES * S].reshape(N, S, TRACK_FEATURES)
    rec = o[:, TRACK_FEATURES * S :].reshape(N, n, RECEIVER_FEATURES)
    lo_w, hi_w = params.sector_width
    half = 0.5 * params.field_of_regard
    sectors = np.stack(
        [rec[..., 0] * half, rec[..., 1] * half, lo_w + 0.5 * (rec[..., 2] + 1.0) * (hi_w - lo_w)],
        -1,
    )
    return {
        "valid": rows[..., 0] > 0.5,
        "position": rows[..., 1:4] * params.length_scale + params.centre,
        "velocity": rows[..., 4:7] * params.speed_scale,
        "sigma": params.sigma_ref * np.exp(rows[..., 7]),
        "sectors": sectors,
    }


def sector_action(params: ScanningParams, sectors: FloatArray) -> FloatArray:
    """Normalised actions ``(..., n, 3)`` of sectors ``(..., n, 3)`` (centre azimuth,
    elevation, width, rad) — the inverse of the action's scaling, clipped to ``[−1, 1]``."""
    s = np.asarray(sectors, dtype=np.float64)
    half = 0.5 * params.field_of_regard
    lo_w, hi_w = params.sector_width
    out = np.stack(
        [
            s[..., 0] / half,
            s[..., 1] / half,
            2.0 * (s[..., 2] - lo_w) / max(hi_w - lo_w, 1e-12) - 1,
        ],
        -1,
    )
    return np.clip(out, -1.0, 1.0)


def local_angles(params: ScanningParams, points: FloatArray) -> FloatArray:
    """Azimuth and elevation ``(..., n, 2)`` of world ``points (..., 3)`` in each receiver's
    fixed frame, rad (theory §2.2), and the range as a third entry: ``(..., n, 3)``."""
    p = np.asarray(points, dtype=np.float64)[..., None, :] - params.receivers
    d = np.einsum("kjc,...kj->...kc", params.rotations, p)
    az = np.arctan2(d[..., 0], d[..., 2])
    el = np.arctan2(d[..., 1], np.hypot(d[..., 0], d[..., 2]))
    return np.stack([az, el, np.linalg.norm(d, axis=-1)], -1)
