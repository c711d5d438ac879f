"""Simulation core of the receiver-placement environments (velocity-aware conjugation tracker).

The simulation contract of every env (:mod:`sensorgym.envs.shells.contract`): pure functions
over frozen, batched values (leading axis ``B`` = scenario) — :func:`spaces`, :func:`reset`
(:func:`start` builds scenarios from given receivers and drone), :func:`step`,
:func:`observe` (the joint view), :func:`observe_agents` (one view per receiver) and
:func:`info`.

World frame: ``Y`` up, azimuth from ``+Z`` towards ``+X`` (theory §2.2). ``n`` (default 3)
receivers are ground vehicles (``y = 0``) inside a permitted disc of radius ``arena_radius``
around the origin; they start clustered (theory §10.3 OC-3's unsatisfactory case). One drone flies a
straight level line. One step is one scan period ``τ``:

1. the action sets each receiver's planar velocity (``a · max_speed``, components clipped to
   ``[−1, 1]``, speed capped at ``max_speed``); the receivers drive for ``τ`` (positions held
   in the disc) and the drone flies on;
2. during the period receiver ``k`` fixes the drone at its own delay ``d_k`` with angular
   noise ``σ_ang``, and the velocity-aware conjugation tracker solves the period
   (:mod:`.scan`); a degenerate solve (pseudo-inverse fallback) is not trusted: the
   tracker then coasts its previous estimate by ``τ``;
3. the reward is ``clip(ln(σ_ref / σ_pos), −R, R)`` with ``σ_pos = √tr I(M)⁻¹`` the
   angle-noise Cramér–Rao bound of the period's true geometry,
   ``I(M) = Σ_k (I − u_k u_kᵀ)/(σ_ang² r_k²)`` (``u_k``, ``r_k`` the lines of sight and ranges
   at the fix times, :mod:`sensorgym.trackers.stereo.information`); ``−R`` when
   the information is singular or the conjugation degenerate: the tracker's solve took the
   pseudo-inverse fallback (``used_pinv``), or the noise-free solve of the true geometry would
   (coplanar lines of sight, equal delays — the bound of the position alone cannot see that
   the velocity-aware system is singular there, and noise only hides it).

Why the bound and not the tracker's covariance: the bound holds no noise draw, so the reward
depends on the placement alone (a low-variance signal for learning), and it is the accuracy an
efficient estimator attains under angular noise; the tracker's ``σ_e² (AᵀA)⁻¹`` is the papers'
i.i.d. model evaluated at noisy estimated ranges (optimistic away from orthogonal lines of
sight, :mod:`sensorgym.trackers.stereo.accuracy`). The agent observes that covariance; the
reward scores the geometry.
"""

from __future__ import annotations

import functools
import itertools
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sensorgym.envs.shells.contract import EnvSpaces, with_agent_index
from sensorgym.envs.shells.params_pickle import FieldsOnlyPickle
from sensorgym.envs.shells.rows import MIN_ROWS_PER_THREAD, run_rows
from sensorgym.envs.stereo_placement import kernels
from sensorgym.envs.stereo_placement.scan import ScanFix, ScanGeometry, draw_normals, solve_period
from sensorgym.trackers.stereo.conjugation import DEFAULT_COND_MAX
from sensorgym.trackers.stereo.information import MAX_REWARD_CLIP
from sensorgym.trackers.validation import check_fields, finite_array

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


#: the 3-receiver delays, s (and the span of the default delays of more receivers)
DEFAULT_DELAYS = (0.0, 0.25, 0.6)

#: params fields whose episodes reach compiled paths the defaults do not: the rules' coordinate
#: search past ``AUTO_EXHAUSTIVE`` joint moves (16 receivers), and equal delays, whose every
#: solve is degenerate (the step's slow rows: the generic solve, the tracker coasting).
#: ``sensorgym compile`` steps the env and decides with every rule at each of them, so that
#: neither costs a run its compile time midway (:func:`sensorgym.cli.compile.warm`).
COMPILE_VARIANTS: tuple[dict[str, Any], ...] = ({"n_receivers": 16}, {"delays": (0.3, 0.3, 0.3)})


def default_delays(n: int) -> tuple[float, ...]:
    """The fix delays ``(n,)`` of ``n`` receivers when none are given, s: ``(0, 0.25, 0.6)`` for
    n = 3 (the registered env), else ``d_k = 0.6 k/(n − 1)``, ``k = 0 … n−1`` — the same span,
    evenly spread (distinct, so the velocity stays observable)."""
    if n == 3:
        return DEFAULT_DELAYS
    return tuple(float(x) for x in np.linspace(0.0, DEFAULT_DELAYS[-1], n))


@dataclass(frozen=True)
class PlacementParams(FieldsOnlyPickle):
    """Receivers, drone, scan timing, noise and reward of the receiver-placement environments."""

    n_receivers: int | None = None
    """Number of receiver vehicles ``n`` (≥ 3: the velocity-aware conjugation needs three).
    ``None``: one per given delay, else 3."""
    delays: tuple[float, ...] | None = None
    """Fix time of each receiver after the period start, s, one per receiver. Keep them
    distinct (theory §10.3 OC-3): equal delays make the velocity unobservable (a degenerate
    conjugation, reward ``−R``). ``None``: :func:`default_delays` — ``(0, 0.25, 0.6)`` for
    n = 3, for larger n the same span ``[0, 0.6]`` s evenly spread (stored as ``None`` when
    given equal to those; the values in use are :attr:`delays_array`)."""
    period: float = 1.0
    """Scan period ``τ`` = one step, s."""
    max_speed: float = 5.0
    """Speed limit of a receiver vehicle, m/s."""
    arena_radius: float = 200.0
    """Radius of the permitted disc around the origin that receivers stay in, m."""
    cluster_radius: float = 15.0
    """Receivers start uniformly within this distance of the origin, m (OC-3: clustered)."""
    start_distance: tuple[float, float] = (60.0, 150.0)
    """Horizontal distance of the drone's start from the origin, drawn uniformly, m."""
    start_altitude: tuple[float, float] = (20.0, 80.0)
    """Height of the drone above the ground, drawn uniformly, m (level flight)."""
    drone_speed: tuple[float, float] = (5.0, 15.0)
    """Horizontal drone speed, drawn uniformly, m/s; heading uniform over all directions."""
    sigma_ang: float = 1e-3
    """Isotropic angular noise of each fixed direction, rad; 0 gives noise-free fixes."""
    cue_sigma: tuple[float, float] = (5.0, 2.0)
    """Errors (per axis, Gaussian) of the external cue in position (m) and velocity (m/s): the
    tracker's estimate before its first fix, where the receivers' frames first look."""
    max_boresight_elevation: float = float(np.deg2rad(80.0))
    """Receiver frames look at the predicted drone with elevation held within this, rad."""
    sigma_ref: float = 1.0
    """Position accuracy that earns zero reward, m."""
    reward_clip: float = 5.0
    """``R``: the reward ``ln(σ_ref/σ_pos)`` is clipped to ``[−R, R]``; ``−R`` when degenerate."""

    def __post_init__(self) -> None:
        check_fields(self)  # every field of its annotated type: no bool for a count or a number
        n = self.n_receivers
        if n is not None and n < 3:
            raise ValueError(f"n_receivers: need at least 3 (velocity-aware conjugation), got {n}")
        if self.delays is None:
            n = 3 if n is None else int(n)
            d = np.array(default_delays(n))
        else:
            d = np.asarray(self.delays, dtype=np.float64)
            if d.ndim != 1 or d.size < 3:
                raise ValueError(
                    f"delays: need at least 3 (velocity-aware n ≥ 3), got {self.delays}"
                )
            if n is not None and d.size != n:
                raise ValueError(
                    f"delays: {d.size} values for n_receivers = {n} (give one per receiver, "
                    "or leave delays unset for the default spread)"
                )
            n = d.size
        if not (np.all(np.isfinite(d)) and np.all(d >= 0.0) and np.all(d <= self.period)):
            raise ValueError(f"delays: must lie in [0, period], got {tuple(d.tolist())}")
        # normalised, so that equal settings compare equal: n_receivers always the count,
        # delays None where they are the default spread (dataclasses.replace(params,
        # n_receivers=6) then spreads the default delays over the new count)
        explicit = tuple(float(x) for x in d)
        object.__setattr__(self, "n_receivers", n)
        object.__setattr__(self, "delays", None if explicit == default_delays(n) else explicit)
        for name in ("period", "max_speed", "arena_radius", "cluster_radius"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0.0):
                raise ValueError(f"{name}: must be positive and finite, got {value}")
        if self.cluster_radius > self.arena_radius:
            raise ValueError("cluster_radius: must not exceed arena_radius")
        for name in ("start_distance", "start_altitude", "drone_speed"):
            lo, hi = getattr(self, name)
            if not (np.isfinite(lo) and np.isfinite(hi) and 0.0 <= lo <= hi):
                raise ValueError(f"{name}: need finite 0 <= low <= high, got {(lo, hi)}")
        if self.start_altitude[0] <= 0.0:
            raise ValueError(f"start_altitude: must be above the ground, got {self.start_altitude}")
        if not (np.all(np.isfinite(self.cue_sigma)) and min(self.cue_sigma) >= 0.0):
            raise ValueError(f"cue_sigma: need finite values >= 0, got {self.cue_sigma}")
        if not (np.isfinite(self.sigma_ang) and self.sigma_ang >= 0.0):
            raise ValueError(f"sigma_ang: must be finite and >= 0, got {self.sigma_ang}")
        if not 0.0 < self.max_boresight_elevation < np.pi / 2:
            raise ValueError("max_boresight_elevation: must lie in (0, π/2) rad")
        if not (np.isfinite(self.sigma_ref) and self.sigma_ref > 0.0):
            raise ValueError(f"sigma_ref: must be positive, got {self.sigma_ref}")
        if not 0.0 < self.reward_clip <= MAX_REWARD_CLIP:
            raise ValueError(
                f"reward_clip: must lie in (0, {MAX_REWARD_CLIP}], got {self.reward_clip}"
            )

    @property
    def length_scale(self) -> float:
        """Length (m) that normalises observed positions: half the permitted radius."""
        return 0.5 * self.arena_radius

    @property
    def speed_scale(self) -> float:
        """Speed (m/s) that normalises the observed velocity: the fastest drone or vehicle."""
        return max(self.drone_speed[1], self.max_speed)

    @functools.cached_property
    def pairs(self) -> tuple[tuple[int, int], ...]:
        """Receiver pairs ``(k, l)``, ``k < l``, in the order of the observed angles."""
        return tuple(itertools.combinations(range(self.n_receivers), 2))

    @functools.cached_property
    def pairs_array(self) -> NDArray[np.int64]:
        """:attr:`pairs` as an ``(n(n−1)/2, 2)`` integer array (the kernels' form)."""
        return np.array(self.pairs, dtype=np.int64).reshape(-1, 2)

    @functools.cached_property
    def delays_array(self) -> FloatArray:
        """The fix delays in use ``(n,)``, s: :attr:`delays`, or :func:`default_delays`."""
        d = default_delays(self.n_receivers) if self.delays is None else self.delays
        return np.array(d, dtype=np.float64)

    @functools.cached_property
    def kernel_settings(self) -> NDArray[np.void]:
        """The scalar settings the compiled step reads, as one read-only record (a structured
        array of one element, dtype :data:`.kernels.SETTINGS`) that it reads by field name;
        computed once per params."""
        fields = {
            "period": self.period,
            "sigma_ang": self.sigma_ang,
            "max_elevation": self.max_boresight_elevation,
            "max_speed": self.max_speed,
            "arena_radius": self.arena_radius,
            "sigma_ref": self.sigma_ref,
            "reward_clip": self.reward_clip,
            "cond_max": DEFAULT_COND_MAX,
            "length_scale": self.length_scale,
            "speed_scale": self.speed_scale,
        }
        settings = np.zeros(1, dtype=kernels.SETTINGS)
        for name, value in fields.items():
            settings[name] = value
        settings.flags.writeable = False
        return settings

    @functools.cached_property
    def obs_dim(self) -> int:
        """Observation length ``5n + 9 + n(n−1)/2`` (27 for n = 3, see :func:`observe`)."""
        return 5 * self.n_receivers + 9 + len(self.pairs)


@dataclass(frozen=True)
class PlacementState:
    """``B`` scenarios at time ``t`` (the end of the last scan period)."""

    t: FloatArray
    """(B,) time since the episode start, s."""
    receivers: FloatArray
    """(B, n, 3) receiver positions (``y = 0``), world frame, m."""
    drone_position: FloatArray = field(repr=False)
    """(B, 3) true drone position, m (ground truth: never observed)."""
    drone_velocity: FloatArray = field(repr=False)
    """(B, 3) true drone velocity, m/s (ground truth)."""
    fix: ScanFix = field(repr=False)
    """The conjugation tracker's raw output for the last period."""
    estimate: FloatArray = field(repr=False)
    """(B, 6) the tracker's position (m) and velocity (m/s) at ``t``: the fix, or the previous
    estimate coasted by ``τ`` where the fix was degenerate."""
    geometry: ScanGeometry = field(repr=False)
    """True geometry of the last period (reward, rendering)."""
    bound: FloatArray = field(repr=False)
    """(B,) CRLB position RMS ``σ_pos`` of the last period, m (inf: singular)."""
    observation: NDArray[np.float32] = field(repr=False)
    """(B, obs_dim) derived: :func:`observe` of this state, written with it by the step kernel
    (a function of ``receivers``, ``estimate`` and ``fix`` only)."""
    position_error: FloatArray = field(repr=False)
    """(B,) derived diagnostic: ``‖p̂ − p‖``, the estimate's distance from the drone, m."""
    min_los_angle: FloatArray = field(repr=False)
    """(B,) derived diagnostic: the smallest angle between the receivers' lines of sight to the
    drone, rad."""

    @classmethod
    def trusted(cls, **fields: Any) -> PlacementState:
        """One from arrays the kernels have just written, without the dataclass constructor
        (hot paths only: every field must be given, consistent)."""
        obj = object.__new__(cls)
        obj.__dict__.update(fields)
        return obj

    @property
    def batch_size(self) -> int:
        """Number of scenarios ``B``."""
        return int(self.t.shape[0])


def spaces(params: PlacementParams) -> EnvSpaces:
    """Agents ``receiver_0 … receiver_{n−1}``, each driving its vehicle ``(v_x, v_z)``; the joint
    view is :func:`observe`, each agent's that plus a one-hot of its index."""
    n = params.n_receivers
    return EnvSpaces.build("receiver", n, params.obs_dim, params.obs_dim + n, 2)


def _advance(
    params: PlacementParams,
    t: FloatArray,
    receivers: FloatArray,
    action: FloatArray | None,
    drone: FloatArray,
    drone_velocity: FloatArray,
    previous: FloatArray,
    rng: np.random.Generator,
) -> tuple[PlacementState, FloatArray]:
    """One scan period of every scenario, and the state after it with its observation and
    diagnostics: one compiled pass (:func:`.kernels.period_rows`, rows split over threads).

    With ``action`` ``(B, n, 2)`` the receivers drive for ``τ`` and the drone flies on (a step);
    without, the period ends where they are (the first fix). The period's fix, estimate (the
    fix, or ``previous`` coasted by ``τ`` where degenerate), bound ``σ_pos = σ_ang √tr G⁻¹`` of
    the true geometry (``G = Σ_k Π_k / r_k²``) and reward ``clip(ln(σ_ref/σ_pos), −R, R)``
    (``−R`` where degenerate) are those of :func:`.scan.scan_period`; the scenarios the closed
    form or the normal equations leave (``κ_F > cond_max``) go through its generic path. Returns
    ``(state, reward)``.
    """
    B, n = receivers.shape[0], params.n_receivers
    normals = draw_normals(rng, B, n, params.sigma_ang)
    moving = action is not None
    act = action if moving else _NO_ACTION
    t_out, end, drone_end = np.empty(B), np.empty((B, n, 3)), np.empty((B, 3))
    origins, los, ranges = np.empty((B, n, 3)), np.empty((B, n, 3)), np.empty((B, n))
    position, velocity = np.empty((B, 3)), np.empty((B, 3))
    range_sigma, velocity_sigma, condition = np.empty((B, n)), np.empty(B), np.empty(B)
    degenerate, degenerate_true = np.empty(B, np.bool_), np.empty(B, np.bool_)
    estimate, bound, reward = np.empty((B, 6)), np.empty(B), np.empty(B)
    obs = np.empty((B, params.obs_dim), np.float32)
    error, min_angle, slow = np.empty(B), np.empty(B), np.empty(B, np.bool_)
    layout = (params.delays_array, params.pairs_array)
    old = (t, receivers, drone, drone_velocity, previous)
    new = (
        t_out, end, drone_end, origins, los, ranges, position, velocity, range_sigma,
        velocity_sigma, condition, degenerate, degenerate_true, estimate, bound,
    )  # fmt: skip
    args = (moving, params.kernel_settings, layout, old, act, normals, new,
            (reward, obs, error, min_angle, slow))  # fmt: skip
    if B < 2 * MIN_ROWS_PER_THREAD:  # one chunk (run_rows would not split it)
        code = kernels.period_rows(0, B, *args)
    else:
        flags = [0]
        run_rows(B, lambda lo, hi: flags.append(kernels.period_rows(lo, hi, *args)))
        code = functools.reduce(int.__or__, flags)
    if code & kernels.BAD_ACTION:
        raise ValueError("action: contains NaN or infinite values")
    if code & kernels.SLOW:
        rows = np.flatnonzero(slow)
        fix, geometry, est, bnd, rew = solve_period(
            params.delays_array, params.period, params.sigma_ang,
            params.max_boresight_elevation, receivers[rows], end[rows], drone_end[rows],
            drone_velocity[rows], previous[rows], normals[rows], params.sigma_ref,
            params.reward_clip,
        )  # fmt: skip
        origins[rows], los[rows], ranges[rows] = geometry.origins, geometry.los, geometry.ranges
        degenerate_true[rows], degenerate[rows] = geometry.degenerate, fix.degenerate
        position[rows], velocity[rows], condition[rows] = fix.position, fix.velocity, fix.condition
        range_sigma[rows], velocity_sigma[rows] = fix.range_sigma, fix.velocity_sigma
        estimate[rows], bound[rows], reward[rows] = est, bnd, rew
        kernels.observe_kernel(
            rows, params.kernel_settings, params.pairs_array, end, estimate, range_sigma,
            velocity_sigma, condition, degenerate, obs,
        )  # fmt: skip
        kernels.info_kernel(rows, end, estimate, drone_end, params.pairs_array, error, min_angle)
    fix = ScanFix.trusted(
        position=position, velocity=velocity, range_sigma=range_sigma,
        velocity_sigma=velocity_sigma, condition=condition, degenerate=degenerate,
    )  # fmt: skip
    geometry = ScanGeometry.trusted(
        origins=origins, los=los, ranges=ranges, degenerate=degenerate_true
    )
    state = PlacementState.trusted(
        t=t_out, receivers=end, drone_position=drone_end, drone_velocity=drone_velocity, fix=fix,
        estimate=estimate, geometry=geometry, bound=bound, observation=obs,
        position_error=error, min_los_angle=min_angle,
    )  # fmt: skip
    return state, reward


#: the action argument of a period without one (never read)
_NO_ACTION = np.zeros((1, 1, 2))


def draw_scenario(
    params: PlacementParams, rng: np.random.Generator, batch: int
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Receivers ``(B, n, 3)``, drone position and velocity ``(B, 3)`` of ``batch`` fresh
    scenarios, drawn in this order so that a seed fixes every scenario: receivers uniform in
    the disc of ``cluster_radius`` (radius ``ρ_c √U``, bearing), then the drone's distance,
    bearing, height, speed and heading (a straight level line); azimuths from +Z towards +X
    (theory §2.2)."""
    n = params.n_receivers
    radius = params.cluster_radius * np.sqrt(rng.uniform(0.0, 1.0, (batch, n)))
    angle = rng.uniform(-np.pi, np.pi, (batch, n))
    dist = rng.uniform(*params.start_distance, batch)
    bearing = rng.uniform(-np.pi, np.pi, batch)
    height = rng.uniform(*params.start_altitude, batch)
    speed = rng.uniform(*params.drone_speed, batch)
    heading = rng.uniform(-np.pi, np.pi, batch)
    zero = np.zeros_like(radius)
    o = np.stack([radius * np.sin(angle), zero, radius * np.cos(angle)], -1)
    p = np.stack([dist * np.sin(bearing), height, dist * np.cos(bearing)], -1)
    v = np.stack([speed * np.sin(heading), np.zeros(batch), speed * np.cos(heading)], -1)
    return o, p, v


def draw_cue(
    params: PlacementParams, p: FloatArray, v: FloatArray, rng: np.random.Generator
) -> FloatArray:
    """The tracker's first estimate ``(B, 6)``: the external cue (the drone's position ``p`` and
    velocity ``v`` plus Gaussian errors ``cue_sigma``, drawn position then velocity) at
    ``t = 0``, carried back to the start of the first period (``t = −τ``)."""
    sp, sv = params.cue_sigma
    cue_p = p + sp * rng.standard_normal(p.shape)
    cue_v = v + sv * rng.standard_normal(v.shape)
    return np.concatenate([cue_p - params.period * cue_v, cue_v], -1)


def start(
    params: PlacementParams,
    receivers: ArrayLike,
    drone_position: ArrayLike,
    drone_velocity: ArrayLike,
    rng: np.random.Generator,
) -> PlacementState:
    """Scenarios from given receivers ``(B, n, 3)`` (``y`` set to 0, held in the disc) and drone
    ``(B, 3)``. The tracker starts from the cue (truth plus ``cue_sigma`` errors) and its first
    fix is one scan period of the receivers standing still, ending at ``t = 0``."""
    n = params.n_receivers
    o = finite_array(receivers, "receivers", tail=(n, 3))
    p = finite_array(drone_position, "drone_position", tail=(3,))
    v = finite_array(drone_velocity, "drone_velocity", tail=(3,))
    B = p.shape[0]
    if o.ndim != 3 or p.ndim != 2 or o.shape[0] != B or v.shape != p.shape:
        raise ValueError(f"receivers/drone_position/drone_velocity: batch {B} shapes differ")
    o = in_arena(params, o * np.array([1.0, 0.0, 1.0]))
    before = draw_cue(params, p, v, rng)
    o, p, v = (np.ascontiguousarray(x) for x in (o, p, v))
    state, _ = _advance(params, np.zeros(B), o, None, p, v, before, rng)
    return state


def reset(
    params: PlacementParams,
    rng: np.random.Generator,
    batch: int,
    like: PlacementState | None = None,
) -> PlacementState:
    """``batch`` fresh scenarios: receivers clustered near the origin, a drone on a random line.
    Scenarios share nothing: ``like`` is unused."""
    if batch < 1:
        raise ValueError(f"batch: must be >= 1, got {batch}")
    o, p, v = draw_scenario(params, rng, batch)
    return start(params, o, p, v, rng)


def in_arena(params: PlacementParams, positions: FloatArray, margin: float = 0.0) -> FloatArray:
    """Ground positions ``(..., 3)`` pulled radially back onto the permitted disc (less
    ``margin`` m) where outside it (:func:`.kernels.in_disc_batch`)."""
    p = np.ascontiguousarray(positions, dtype=np.float64)
    out = np.empty_like(p)
    kernels.in_disc_batch(p.reshape(-1, 3), params.arena_radius - margin, out.reshape(-1, 3))
    return out


def step(
    params: PlacementParams, state: PlacementState, action: ArrayLike, rng: np.random.Generator
) -> tuple[PlacementState, FloatArray, BoolArray]:
    """Advance every scenario one scan period under the joint ``action`` ``(B, n, 2)`` (or
    ``(B, 2n)``).

    Out-of-range actions are clipped; NaN or infinite actions raise ``ValueError`` (checked in
    the step kernel: the period's noise has then been drawn from ``rng``). Returns
    ``(state, reward (B,), terminated (B,))``: nothing ends an episode here (always False); the
    time limit is the shells' business. The new state carries its observation and diagnostics
    (:func:`observe`, :func:`info` only read them).
    """
    B, n = state.batch_size, params.n_receivers
    try:
        a = np.asarray(action, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"action: cannot be read as floats ({exc})") from None
    if a.size != B * 2 * n:
        raise ValueError(f"action: expected {B * 2 * n} values (B, 2n), got shape {a.shape}")
    if a.shape != (B, n, 2) or not a.flags.c_contiguous:
        a = np.ascontiguousarray(a.reshape(B, n, 2))
    new, reward = _advance(
        params, state.t, state.receivers, a, state.drone_position, state.drone_velocity,
        state.estimate, rng,
    )  # fmt: skip
    return new, reward, np.zeros(B, dtype=bool)


def los_angles(params: PlacementParams, receivers: FloatArray, point: FloatArray) -> FloatArray:
    """Angles ``γ_kl`` ``(B, n(n−1)/2)`` between the lines of sight from receivers ``(B, n, 3)``
    to ``point (B, 3)``, pairs in :attr:`PlacementParams.pairs` order, rad."""
    o = np.ascontiguousarray(receivers, dtype=np.float64)
    out = np.empty((o.shape[0], len(params.pairs)))
    kernels.los_angles_kernel(
        o, np.ascontiguousarray(point, dtype=np.float64), params.pairs_array, out
    )
    return out


def observe(params: PlacementParams, state: PlacementState) -> NDArray[np.float32]:
    """The agent's observation ``(B, obs_dim)`` float32 — own positions and the tracker, no truth.

    Blocks in this order (``L = length_scale``, ``S = speed_scale``, ``p̂``, ``v̂`` the tracker's
    estimate, ``ĝ`` its ground point):

    | block      | shape          | meaning                                                  |
    |------------|----------------|----------------------------------------------------------|
    | receivers  | ``(n, 2)``     | own ``(x, z) / L``, world                                |
    | relative   | ``(n, 2)``     | ``(x_k − x̂, z_k − ẑ) / L``: receiver from ``ĝ``           |
    | drone      | ``(3,)``       | ``p̂ / L``                                                |
    | velocity   | ``(3,)``       | ``v̂ / S``                                                |
    | ranges     | ``(n,)``       | ``ln(σ[r̂_k] / σ_ref)`` from ``σ_e² (AᵀA)⁻¹``               |
    | vel. error | ``(1,)``       | ``ln(σ_V / (σ_ref/τ))``, ``σ_V = √tr Q_VV``              |
    | condition  | ``(1,)``       | ``log10 κ_F``                                            |
    | angles     | ``(n(n−1)/2,)``| ``γ_kl / (π/2)`` between lines of sight to ``p̂``           |
    | degenerate | ``(1,)``       | 1.0 if the last fix was degenerate (the tracker coasted)  |

    Every entry is clipped to ``[−OBS_CLIP, OBS_CLIP]``. The step kernel computes it with the
    state (:attr:`PlacementState.observation`); this returns that array.
    """
    return state.observation


def observe_agents(params: PlacementParams, state: PlacementState) -> NDArray[np.float32]:
    """Per-receiver views ``(B, n, obs_dim + n)``: :func:`observe` and a one-hot of the
    receiver's index."""
    return with_agent_index(observe(params, state), params.n_receivers)


def info(params: PlacementParams, state: PlacementState) -> dict[str, FloatArray]:
    """Diagnostics (ground truth included: for evaluation, never for the policy), computed
    with the state by the step kernel; for the tail measures (:mod:`sensorgym.train.tail`),
    as in StereoPointing, the share of drones without a fix (the degenerate periods: the tracker
    coasted) and the sum and count of the CRLB ``σ_pos`` (m) over the fixed ones with a finite
    bound."""
    fixed = ~state.fix.degenerate
    counted = fixed & np.isfinite(state.bound)
    return {
        "position_error": state.position_error,
        "bound": state.bound,
        "condition": state.fix.condition,
        "degenerate": state.fix.degenerate.astype(np.float64),
        "min_los_angle": state.min_los_angle,
        "unfixed_share": state.fix.degenerate.astype(np.float64),
        "fixed_sigma_sum": np.where(counted, state.bound, 0.0),
        "fixed_sigma_count": counted.astype(np.float64),
    }


def split_observation(params: PlacementParams, obs: ArrayLike) -> dict[str, FloatArray]:
    """Inverse of :func:`observe`'s layout for observations ``(N, obs_dim)``, in world units:
    ``receivers (N, n, 3)``, ``position (N, 3)``, ``velocity (N, 3)``, ``angles (N, pairs)``."""
    n, L = params.n_receivers, params.length_scale
    o = np.asarray(obs, dtype=np.float64)
    N = o.shape[0]
    xz = o[:, : 2 * n].reshape(N, n, 2) * L
    receivers = np.stack([xz[..., 0], np.zeros((N, n)), xz[..., 1]], -1)
    i = 4 * n
    position = o[:, i : i + 3] * L
    velocity = o[:, i + 3 : i + 6] * params.speed_scale
    j = i + 6 + n + 2
    return {
        "receivers": receivers,
        "position": position,
        "velocity": velocity,
        "angles": o[:, j : j + len(params.pairs)] * (np.pi / 2),
    }
