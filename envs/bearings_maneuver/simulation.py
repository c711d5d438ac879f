"""Simulation core of the platform-manoeuvre environments (bearings-only target motion analysis).

The simulation contract of every env (:mod:`sensorgym.envs.shells.contract`): pure functions
over frozen, batched values (leading axis ``B`` = scenario) — :func:`spaces`, :func:`reset`,
:func:`step`, :func:`observe` (joint view), :func:`observe_agents` (one view per platform) and
:func:`info`. The Gymnasium env, its vector env and the PettingZoo env are shells over these;
none holds physics of its own.

One step (``params.world.dt`` seconds):

1. the action ``a ∈ [−1, 1]²`` becomes a heading-rate command ``a₀·ω_max`` and a speed change
   ``a₁·Δv_max``; the platform flies the exact arc, the target moves on
   (:func:`sensorgym.envs.worlds.platform.fly`, :func:`~sensorgym.envs.worlds.platform.propagate_target`);
2. the platform measures a noisy bearing and the range-parameterised bank (second-order EKF members) updates on it
   (:mod:`sensorgym.trackers.bearings.filters`): this estimate is all the agent sees;
3. the reward is the gain in accuracy of the best possible estimate: the posterior Cramér–Rao
   bound (Tichavský et al. 1998) computed along the *true* trajectory
   (:mod:`sensorgym.trackers.bearings.crlb`), carried in square-root covariance form
   ``P_k = L_k L_kᵀ = J_k⁻¹`` (theory §7.8, §11.2)::

       P̄ = F P_k Fᵀ + Q,   P_{k+1} = (P̄⁻¹ + Σ_platforms Hᵀ H / σ²)⁻¹,   P_0 = P_prior
       reward_k = ln m(P_k) − ln m(P_{k+1})

   with ``m`` the position RMS bound ``√(P_xx + P_yy)`` or the relative range bound ``σ_r/r``
   (:func:`accuracy_of`; :func:`advance_bound` is the recursion in numpy form: the step kernel
   and the lookahead planners run the same compiled primitives).
   Rewards telescope: the return of an episode is ``ln(m_0/m_T)``, the log-factor by which
   the platform's manoeuvres shrank the bound. The bound does not depend on the noise draw,
   so the reward has no measurement noise in it, only the consequences of the actions.

The tracker's prior (theory §7.9, §11.2) is the generator's distribution given the first
bearing: range uniform over ``bank_ranges`` (default the generator's ``initial_range``),
course uniform over the full circle, speed with the mean and standard deviation of the
uniform ``target_speed`` draw (unless ``prior_speed`` says otherwise), moment-matched.

The reset and the step run as compiled kernels over the batch's rows (:mod:`.kernels`:
:func:`~.kernels.reset_kernel`, :func:`~.kernels.step_kernel`, the stages of
:mod:`.reference` compiled, the step split over threads by :func:`sensorgym.envs.shells.rows.run_rows`), built from the
tracker primitives the public functions of :mod:`sensorgym.trackers.bearings` also call
(:mod:`sensorgym.trackers.bearings.kernels`) and the world's
(:mod:`sensorgym.envs.worlds.platform_kernels`); the random draws are made here with the
Generator, in the order of the numpy form, and passed in. The kernels also write the state's
derived fields (observation, nearest range, position error) from one bank estimate, so
:func:`observe` and :func:`info` only read them.

Without a manoeuvre range is unobservable (theory §7.6, §10.5 OC-5): a platform that keeps a
straight course collects almost no reward after the first bearings.

Several platforms (``params.platforms = K``, each an agent of the PettingZoo env) all take a
bearing every step; the tracker fuses them (sequential updates) and the bound adds their
information, so cross-bearings make range observable even without manoeuvres. Arrays of
platform quantities carry an axis ``K`` after the batch axis; ``K = 1`` is the Gymnasium env.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sensorgym.envs.bearings_maneuver import kernels
from sensorgym.envs.shells.contract import OBS_CLIP, EnvSpaces
from sensorgym.envs.shells.params_pickle import FieldsOnlyPickle
from sensorgym.envs.shells.rows import MIN_ROWS_PER_THREAD, run_rows
from sensorgym.envs.worlds.platform import (
    PlatformWorldParams,
    cwna_noise_factor,
)
from sensorgym.trackers.bearings.crlb import (
    predict_bound_factor,
    update_bound_factor,
)
from sensorgym.trackers.bearings.filters import (
    RangeBankState,
    angle_spread_moments,
    range_bank_cells,
)
from sensorgym.trackers.bearings.kernels import STATE_DIM, accuracy_batch
from sensorgym.trackers.bearings.models import BearingsGaussian
from sensorgym.trackers.validation import check_fields, count

#: accuracies are kept inside ``[ACCURACY_FLOOR, 1/ACCURACY_FLOOR]`` so that every reward
#: ``ln m_k − ln m_{k+1}`` is finite (a documented fallback: physical scales never reach it)
ACCURACY_FLOOR = 1e-300

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
Metric = Literal["position", "relative_range"]

#: observation length of a lone platform (see :func:`observe_agents`; + 2 per other platform)
OBS_DIM = 13


@dataclass(frozen=True)
class ManeuverParams(FieldsOnlyPickle):
    """Scenario, tracker and reward settings of the platform-manoeuvre environments."""

    world: PlatformWorldParams = field(default_factory=PlatformWorldParams)
    """Platform limits, step ``dt`` (s), bearing noise ``σ`` (rad), target noise ``q̃``."""
    initial_range: tuple[float, float] = (5_000.0, 20_000.0)
    """Initial platform–target range, drawn uniformly (m)."""
    target_speed: tuple[float, float] = (2.0, 8.0)
    """Target speed, drawn uniformly (m/s); course uniform over all directions."""
    initial_platform_speed: float = 5.0
    """Platform speed at the start (m/s); its heading is drawn uniformly."""
    initial_heading: tuple[float, float] = (-np.pi, np.pi)
    """Platform headings at the start, drawn uniformly (rad, from North clockwise); a pair
    ``(h, h)`` fixes it (a scripted scenario such as the textbook's)."""
    initial_bearing: tuple[float, float] = (-np.pi, np.pi)
    """Bearing of the target from platform 1 at the start, drawn uniformly (rad)."""
    target_course: tuple[float, float] = (-np.pi, np.pi)
    """Target course, drawn uniformly (rad, from North clockwise)."""
    platforms: int = 1
    """Number of platforms ``K`` taking bearings on the one target (agents in PettingZoo)."""
    formation_radius: float = 2_000.0
    """Platforms 2..K start uniformly within this distance of platform 1 (at the origin), m."""
    bank_ranges: tuple[float, float] | None = None
    """Range span (m) covered by the filter bank's members: the prior's range support, over
    which its range density is uniform. ``None``: ``initial_range``, the generator's."""
    bank_members: int = 8
    """Number of range-parameterised (second-order EKF) members."""
    prior_speed: tuple[float, float] | None = None
    """Target-speed prior of the filter: mean and standard deviation (m/s). ``None``: those of
    the generator's uniform ``target_speed`` draw, ``((lo + hi)/2, (hi − lo)/√12)``."""
    metric: Metric = "position"
    """Accuracy the reward measures: ``"position"`` RMS bound (m) or ``"relative_range"``
    bound ``σ_r/r``."""
    min_range: float = 500.0
    """A platform closer than this to the target ends the episode (terminated), m."""
    close_penalty: float = 5.0
    """Reward subtracted on that termination (the return is a log-factor, so 5 ≈ e⁵)."""

    def __post_init__(self) -> None:
        check_fields(self)  # every field of its annotated type: no bool for a count or a number
        lo, hi = _pair(self, "initial_range")
        if not 0.0 < lo <= hi:
            raise ValueError(f"initial_range: need 0 < low <= high, got {self.initial_range}")
        lo_v, hi_v = _pair(self, "target_speed")
        if not 0.0 <= lo_v <= hi_v:
            raise ValueError(f"target_speed: need 0 <= low <= high, got {self.target_speed}")
        w = self.world
        v0 = _number(self, "initial_platform_speed")
        if not (w.min_speed <= v0 <= w.max_speed):
            raise ValueError(
                f"initial_platform_speed: {self.initial_platform_speed} outside the world's "
                f"[{w.min_speed}, {w.max_speed}] m/s"
            )
        if self.bank_ranges is not None:
            b_lo, b_hi = _pair(self, "bank_ranges")
            if not 0.0 < b_lo < b_hi:
                raise ValueError(f"bank_ranges: need 0 < low < high, got {self.bank_ranges}")
        for name in ("initial_heading", "initial_bearing", "target_course"):
            a_lo, a_hi = _pair(self, name)
            if not a_lo <= a_hi:
                raise ValueError(f"{name}: need low <= high, got {getattr(self, name)}")
        count(self.platforms, "platforms")
        if not _number(self, "formation_radius") >= 0.0:
            raise ValueError(
                f"formation_radius: must be finite and >= 0, got {self.formation_radius}"
            )
        count(self.bank_members, "bank_members")
        if self.prior_speed is not None:
            s_mean, s_sigma = _pair(self, "prior_speed")
            if not (s_mean >= 0.0 and s_sigma >= 0.0):
                raise ValueError(
                    f"prior_speed: need mean >= 0 and sigma >= 0, got {self.prior_speed}"
                )
        if self.metric not in ("position", "relative_range"):
            raise ValueError(f"metric: 'position' or 'relative_range', got {self.metric!r}")
        if not _number(self, "min_range") >= 0.0:
            raise ValueError(f"min_range: must be finite and >= 0, got {self.min_range}")
        if self.speed_scale <= 0.0:
            raise ValueError("world.max_speed + target_speed[1]: must be positive (speed scale)")
        _number(self, "close_penalty")

    @property
    def prior_ranges(self) -> tuple[float, float]:
        """Range support (m) of the tracker's prior: ``bank_ranges``, else ``initial_range``
        (a single initial range ``(r, r)`` becomes ``r ± 0.1 %``: a bank needs a span)."""
        if self.bank_ranges is not None:
            return self.bank_ranges
        lo, hi = self.initial_range
        return (lo, hi) if lo < hi else (0.999 * lo, 1.001 * hi)

    @property
    def prior_speed_moments(self) -> tuple[float, float]:
        """Mean and standard deviation (m/s) of the tracker's speed prior: ``prior_speed``,
        else those of the uniform ``target_speed`` draw."""
        if self.prior_speed is not None:
            return self.prior_speed
        lo, hi = self.target_speed
        return 0.5 * (lo + hi), (hi - lo) / np.sqrt(12.0)

    @property
    def range_scale(self) -> float:
        """Length (m) that normalises observed positions: the far end of the initial ranges."""
        return self.initial_range[1]

    @property
    def obs_dim(self) -> int:
        """Observation length per platform: ``OBS_DIM + 2 (K − 1)``."""
        return OBS_DIM + 2 * (self.platforms - 1)

    @property
    def speed_scale(self) -> float:
        """Speed (m/s) that normalises observed velocities: platform plus target top speed."""
        return self.world.max_speed + self.target_speed[1]

    @functools.cached_property
    def kernel_constants(self) -> NDArray[np.void]:
        """The scalar settings the compiled kernels read, as one read-only record (a
        structured array of one element, dtype :data:`.kernels.SETTINGS`) that they read by
        field name; computed once per params."""
        w = self.world
        speed_mean, speed_sigma = self.prior_speed_moments
        fields = {
            "dt": w.dt,
            "q_tilde": w.q_tilde,
            "sigma": w.sigma_bearing,
            "max_turn": w.max_turn_rate,
            "max_dv": w.max_speed_change,
            "min_speed": w.min_speed,
            "max_speed": w.max_speed,
            "floor": ACCURACY_FLOOR,
            "min_range": self.min_range,
            "penalty": self.close_penalty,
            "range_scale": self.range_scale,
            "speed_scale": self.speed_scale,
            "clip": OBS_CLIP,
            "speed_mean": speed_mean,
            "speed_sigma": speed_sigma,
            "relative_range": self.metric == "relative_range",
        }
        record = np.array(
            [tuple(fields[name] for name in kernels.SETTINGS.names)], kernels.SETTINGS
        )
        record.flags.writeable = False
        return record

    @functools.cached_property
    def prior_cells(self) -> tuple[FloatArray, ...]:
        """What the tracker's prior shares over all scenarios, computed once per params: the
        bank's range cells ``r``, ``σ_r``, log weights ``(N,)`` (uniform range density over
        :attr:`prior_ranges`) and the spread factors of the first bearing (Gaussian, σ) and of
        the course (uniform over the full circle, ``σ = π/√3``)."""
        range_min, range_max = self.prior_ranges
        cells = range_bank_cells(
            np.asarray(range_min), np.asarray(range_max), self.bank_members, None, None, "uniform"
        )
        spreads = (
            angle_spread_moments(self.world.sigma_bearing),
            angle_spread_moments(np.pi / np.sqrt(3.0), "uniform"),
        )
        out = tuple(np.ascontiguousarray(a, dtype=np.float64) for a in (*cells, *spreads))
        for a in out:
            a.flags.writeable = False
        return out


def _number(params: ManeuverParams, name: str) -> float:
    """A finite real field, or ``TypeError`` / ``ValueError`` naming it."""
    value = getattr(params, name)
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise TypeError(f"{name}: must be a real number, got {value!r}")
    if not np.isfinite(value):
        raise ValueError(f"{name}: must be finite, got {value}")
    return float(value)


def _pair(params: ManeuverParams, name: str) -> tuple[float, float]:
    """A field of two finite reals ``(low, high)``, or ``TypeError`` / ``ValueError`` naming it."""
    value = getattr(params, name)
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        arr = np.empty(0)
    if arr.shape != (2,) or isinstance(value, str):
        raise TypeError(f"{name}: must be a pair of numbers (low, high), got {value!r}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name}: must be finite, got {value}")
    return float(arr[0]), float(arr[1])


@dataclass(frozen=True)
class ManeuverState:
    """Batched episode state: platforms, target, tracker and bound (leading axis ``B``)."""

    t: FloatArray
    """Time since the scenario began ``(B,)`` (s)."""
    platform_position: FloatArray
    """Platform positions ``(B, K, 2)``, East and North (m)."""
    heading: FloatArray
    """Platform headings ``(B, K)`` from North clockwise (rad)."""
    speed: FloatArray
    """Platform speeds ``(B, K)`` (m/s)."""
    target: FloatArray
    """True target state ``(B, 4)``: East, North (m), velocity (m/s)."""
    bank: RangeBankState
    """The tracker the agents see through: range-parameterised bank of second-order EKFs, batch ``(B, N)``.
    All scenarios share its clock ``bank.t`` (the dynamics are time-invariant)."""
    bound_factor: FloatArray
    """Square root ``L`` ``(B, 4, 4)`` of the posterior Cramér–Rao bound ``P = L Lᵀ = J⁻¹``
    on the true state, now (:attr:`bound` is ``P``)."""
    accuracy: FloatArray
    """``m(P)`` ``(B,)``: the bound the reward measures (m, or dimensionless)."""
    bearing: FloatArray
    """Last measured absolute bearings ``(B, K)`` (rad, from North clockwise)."""
    observation: NDArray[np.float32]
    """Derived: every platform's observation ``(B, K, obs_dim)`` of this state (the table of
    :func:`observe_agents`). Written by the reset and step kernels with the rest of the state,
    from the same bank estimate as :attr:`position_error`; :func:`observe` only reads it."""
    nearest_range: FloatArray
    """Derived: the nearest platform's range to the target ``(B,)`` (m), for :func:`info`."""
    position_error: FloatArray
    """Derived: the bank estimate's position error ``‖x̂ − x_t‖`` ``(B,)`` (m), for
    :func:`info`."""

    @classmethod
    def trusted(cls, **fields: Any) -> ManeuverState:
        """A state from arrays the kernels have just written, without the dataclass
        constructor (hot paths only: every field must be given, consistent)."""
        obj = object.__new__(cls)
        obj.__dict__.update(fields)
        return obj

    @property
    def batch_size(self) -> int:
        """Number of scenarios ``B``."""
        return self.platform_position.shape[0]

    @property
    def platform_velocity(self) -> FloatArray:
        """Platform velocities ``v (sin ψ, cos ψ)`` ``(B, K, 2)`` (m/s)."""
        return self.speed[..., None] * np.stack([np.sin(self.heading), np.cos(self.heading)], -1)

    @property
    def range(self) -> FloatArray:
        """Platform–target ranges ``(B, K)`` (m)."""
        d = self.target[:, None, :2] - self.platform_position
        return np.hypot(d[..., 0], d[..., 1])

    @property
    def bound(self) -> FloatArray:
        """The posterior Cramér–Rao bound ``P = L Lᵀ`` ``(B, 4, 4)`` on the true state."""
        L = self.bound_factor
        return L @ np.swapaxes(L, -1, -2)

    @property
    def estimate(self) -> BearingsGaussian:
        """The bank's moment-matched target estimate, batch ``(B,)``."""
        return self.bank.estimate()


def accuracy_of(
    params: ManeuverParams, L: FloatArray, target: FloatArray, origin: FloatArray
) -> FloatArray:
    """The accuracy ``m(P)`` the reward measures (``params.metric``) of the bound ``P = L Lᵀ``
    (square root ``L`` ``(..., 4, 4)``) on ``target`` ``(..., 4)``: the position RMS bound, or the
    relative range bound taken from ``origin`` ``(..., 2)`` (platform 1), by the compiled
    primitive the step kernel and the lookahead planners call. Read off ``L`` as sums of
    squares, it is never negative; it is kept inside ``[ACCURACY_FLOOR, 1/ACCURACY_FLOOR]`` so
    that log-ratio rewards are always finite."""
    L = np.asarray(L, dtype=np.float64)
    target = np.asarray(target, dtype=np.float64)
    origin = np.asarray(origin, dtype=np.float64)
    batch = np.broadcast_shapes(L.shape[:-2], target.shape[:-1], origin.shape[:-1])
    out = np.empty(batch)
    # compiled: trackers.bearings.kernels.accuracy (the step kernel calls the same)
    accuracy_batch(
        params.metric == "relative_range",
        np.ascontiguousarray(np.broadcast_to(L, (*batch, 4, 4))).reshape(-1, 4, 4),
        np.ascontiguousarray(np.broadcast_to(target, (*batch, 4))).reshape(-1, 4),
        np.ascontiguousarray(np.broadcast_to(origin, (*batch, 2))).reshape(-1, 2),
        ACCURACY_FLOOR,
        out.reshape(-1),
    )
    return out


def fuse_bound(
    L: FloatArray, target: FloatArray, positions: FloatArray, sigma: float
) -> FloatArray:
    """The bound's square root after one bearing at the true ``target`` ``(..., 4)`` from each
    platform position ``(..., K, 2)`` in turn (their information adds)."""
    for k in range(positions.shape[-2]):
        L = update_bound_factor(L, target, positions[..., k, :], sigma)
    return L


def advance_bound(
    params: ManeuverParams, L: FloatArray, target: FloatArray, positions: FloatArray
) -> FloatArray:
    """One step of the posterior-CRLB recursion on the square root ``L`` ``(..., 4, 4)``:
    predict over ``world.dt`` (``P̄ = F P Fᵀ + Q``), then fuse the bearings of the platforms at
    ``positions`` ``(..., K, 2)`` on the true ``target`` ``(..., 4)`` at the new time: the numpy
    form of the recursion the step kernel and the lookahead planners run (same compiled
    primitives, :func:`.kernels.step_kernel`, :func:`.kernels.plan_kernel`)."""
    w = params.world
    L = predict_bound_factor(L, w.dt, w.q_tilde)
    return fuse_bound(L, target, positions, w.sigma_bearing)


def spaces(params: ManeuverParams) -> EnvSpaces:
    """Agents ``platform_0 … platform_{K−1}``; each acts with ``(turn, speed change)`` and sees
    ``params.obs_dim`` entries; the joint view is every platform's observation in turn."""
    K = params.platforms
    return EnvSpaces.build("platform", K, K * params.obs_dim, params.obs_dim, 2)


def draw_scenario(
    params: ManeuverParams, rng: np.random.Generator, batch: int
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Headings ``(B, K)``, target ``(B, 4)`` and platform positions ``(B, K, 2)`` of fresh
    scenarios (theory §11.2, starting state), drawn in this order: the headings; the target's
    range ``r₀``, bearing ``β₀`` from platform 1 (at the origin), speed ``v`` and course ``c``;
    then platforms 2…K uniformly over the disc of ``formation_radius`` around platform 1."""
    K = params.platforms
    heading = rng.uniform(*params.initial_heading, (batch, K))
    r0 = rng.uniform(*params.initial_range, batch)
    beta0 = rng.uniform(*params.initial_bearing, batch)
    v = rng.uniform(*params.target_speed, batch)
    course = rng.uniform(*params.target_course, batch)
    # x = (r₀ sin β₀, r₀ cos β₀, v sin c, v cos c): angles from North clockwise (§2.5)
    target = np.stack(
        [r0 * np.sin(beta0), r0 * np.cos(beta0), v * np.sin(course), v * np.cos(course)], -1
    )
    positions = np.zeros((batch, K, 2))
    if K > 1:
        # uniform over the disc: ρ = R √u, φ uniform
        rho = params.formation_radius * np.sqrt(rng.uniform(0.0, 1.0, (batch, K - 1)))
        phi = rng.uniform(-np.pi, np.pi, (batch, K - 1))
        positions[:, 1:] = np.stack([rho * np.sin(phi), rho * np.cos(phi)], -1)
    return heading, target, positions


def reset(
    params: ManeuverParams,
    rng: np.random.Generator,
    batch: int,
    like: ManeuverState | None = None,
) -> ManeuverState:
    """``batch`` fresh scenarios: platform at the origin, target at a random range and bearing.

    All scenarios of a batch share the tracker clock ``bank.t`` (the dynamics are
    time-invariant): fresh scenarios for a running batch ``like`` start on its clock, so that
    they can be swapped into it.
    """
    if batch < 1:
        raise ValueError(f"batch: must be >= 1, got {batch}")
    t = 0.0 if like is None else like.bank.t
    K = params.platforms
    # scenario draws, in a fixed order so that a seed fixes every scenario
    heading, target, positions = draw_scenario(params, rng, batch)
    # the first bearings' noise (drawn as noisy_bearings would: z = wrap(β + σ ε))
    eps = rng.standard_normal((batch, K))
    # prior from platform 1's first bearing (Ristic §6.3.1), matched to the draws above: range
    # uniform over the prior's span, course uniform over the full circle (half-width π, so the
    # mean velocity is zero), speed moments of the target-speed draw (params.prior_cells,
    # kernel_constants); the bound starts at its square root; the other platforms' first
    # bearings update both
    N = params.bank_members
    lw, X = np.empty((batch, N)), np.empty((batch, N, STATE_DIM))
    P = np.empty((batch, N, STATE_DIM, STATE_DIM))
    z, L = np.empty((batch, K)), np.empty((batch, STATE_DIM, STATE_DIM))
    speed = np.full((batch, K), params.initial_platform_speed)
    accuracy, nearest, error = np.empty(batch), np.empty(batch), np.empty(batch)
    obs = np.empty((batch, K, params.obs_dim), dtype=np.float32)
    arrays = (positions, heading, speed, target, lw, X, P, L, accuracy, z, obs, nearest, error)
    kernels.reset_kernel(params.kernel_constants, params.prior_cells, arrays, eps)
    bank = RangeBankState.trusted(lw, BearingsGaussian.trusted(X, P, t))
    return ManeuverState.trusted(
        t=np.zeros(batch),
        platform_position=positions,
        heading=heading,
        speed=speed,
        target=target,
        bank=bank,
        bound_factor=L,
        accuracy=accuracy,
        bearing=z,
        observation=obs,
        nearest_range=nearest,
        position_error=error,
    )


def step(
    params: ManeuverParams, state: ManeuverState, action: ArrayLike, rng: np.random.Generator
) -> tuple[ManeuverState, FloatArray, BoolArray]:
    """Advance every scenario one step under the joint action ``(B, K, 2)`` in ``[−1, 1]``.

    Actions outside ``[−1, 1]`` are clipped (documented fallback, as Box spaces allow);
    NaN or infinite actions raise ``ValueError``. Returns ``(state, reward (B,),
    terminated (B,))`` — one team reward per scenario; truncation (the time limit) is the
    shell's business. An episode terminates when any platform comes within ``min_range``.
    """
    B, K = state.heading.shape
    a = _joint_action(action, B, K)
    w = params.world
    # the draws of the numpy form, in its order: target noise (q̃ > 0), then the bearing noise
    target_noise = rng.standard_normal((B, 4)) if w.q_tilde > 0.0 else _NO_TARGET_NOISE
    bearing_noise = rng.standard_normal((B, K))
    t_bank = state.bank.t + w.dt
    old, bank = state, state.bank
    N = bank.log_weights.shape[1]
    pos, heading, speed = np.empty((B, K, 2)), np.empty((B, K)), np.empty((B, K))
    target, lw = np.empty((B, STATE_DIM)), np.empty((B, N))
    X, P = np.empty((B, N, STATE_DIM)), np.empty((B, N, STATE_DIM, STATE_DIM))
    L, accuracy = np.empty((B, STATE_DIM, STATE_DIM)), np.empty(B)
    z, reward, terminated = np.empty((B, K)), np.empty(B), np.empty(B, dtype=bool)
    obs = np.empty((B, K, params.obs_dim), dtype=np.float32)
    nearest, error = np.empty(B), np.empty(B)
    draws = (target_noise, cwna_noise_factor(w.dt, w.q_tilde), bearing_noise)
    new = (pos, heading, speed, target, lw, X, P, L, accuracy, z, obs, nearest, error)
    bad: list[int] = []
    # fly, move the target, bearings, bank predict + update, P̄ = F P Fᵀ + Q,
    # P_{k+1} = (P̄⁻¹ + Σ_platforms Hᵀ H / σ²)⁻¹ in square-root form, reward_k = ln m_k − ln m_{k+1}
    arrays = (params.kernel_constants, state_arrays(old), a, draws, new, (reward, terminated))
    if B < 2 * MIN_ROWS_PER_THREAD:  # run_rows would not split it: skip its bookkeeping
        bad.append(kernels.step_kernel(0, B, *arrays))
    else:
        run_rows(B, lambda lo, hi: bad.append(kernels.step_kernel(lo, hi, *arrays)))
    if any(bad):
        raise ValueError("action: contains NaN or infinite values")
    new = ManeuverState.trusted(
        t=state.t + w.dt,
        platform_position=pos,
        heading=heading,
        speed=speed,
        target=target,
        # kernel outputs: the constructors' checks are skipped (see the trusted doc)
        bank=RangeBankState.trusted(lw, BearingsGaussian.trusted(X, P, t_bank)),
        bound_factor=L,
        accuracy=accuracy,
        bearing=z,
        observation=obs,
        nearest_range=nearest,
        position_error=error,
    )
    return new, reward, terminated


_NO_TARGET_NOISE = np.zeros((0, STATE_DIM))


def state_arrays(state: ManeuverState) -> tuple[NDArray[Any], ...]:
    """The state's arrays in the order the kernels take them (:data:`.kernels.StateArrays`):
    platforms, target, bank, bound, accuracy, bearings and the derived fields."""
    bank = state.bank
    return (
        state.platform_position,
        state.heading,
        state.speed,
        state.target,
        bank.log_weights,
        bank.members.x,
        bank.members.P,
        state.bound_factor,
        state.accuracy,
        state.bearing,
        state.observation,
        state.nearest_range,
        state.position_error,
    )


def _joint_action(action: ArrayLike, B: int, K: int) -> FloatArray:
    """The action as a contiguous float64 ``(B, K, 2)`` (``(B, 2)`` for one platform, or
    anything that broadcasts); bad shapes raise ``ValueError`` naming ``action``. Finiteness is
    checked by the step kernel."""
    try:
        a = np.asarray(action, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"action: cannot be read as floats ({exc})") from None
    if a.shape == (B, K, 2):
        return a if a.flags.c_contiguous else np.ascontiguousarray(a)
    if a.ndim == 2 and K == 1:
        a = a[:, None]
    try:
        return np.ascontiguousarray(np.broadcast_to(a, (B, K, 2)))
    except ValueError:
        raise ValueError(f"action: expected shape ({B}, {K}, 2), got {np.shape(action)}") from None


def body_frame(heading: ArrayLike, v: ArrayLike) -> FloatArray:
    """World vectors ``(..., 2)`` (East, North) in the platform frame (starboard, ahead)."""
    h = np.asarray(heading, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    # ahead = (sin ψ, cos ψ), starboard = (cos ψ, −sin ψ)  (compiled: kernels.body_frame)
    return np.stack(kernels.body_frame(np.sin(h), np.cos(h), v[..., 0], v[..., 1]), axis=-1)


def observe(params: ManeuverParams, state: ManeuverState) -> NDArray[np.float32]:
    """The joint view ``(B, K · obs_dim)``: every platform's :func:`observe_agents` row in turn
    (for ``K = 1``, the lone platform's observation)."""
    obs = state.observation
    return obs.reshape(obs.shape[0], -1).copy()


def info(params: ManeuverParams, state: ManeuverState) -> dict[str, FloatArray]:
    """Diagnostics (ground truth included: for evaluation, never for the policy): the nearest
    platform's range, the bound the reward measures, the estimate's position error, the
    position RMS bound ``√(P_xx + P_yy)`` (m, whatever ``params.metric`` the reward measures:
    the bound a user quotes in metres, :mod:`sensorgym.train.tail`), the tracker clock (read
    off the state's derived fields)."""
    L = state.bound_factor[:, :2]
    return {
        "range": state.nearest_range,
        "bound": state.accuracy,
        "position_error": state.position_error,
        "position_bound": np.sqrt(np.einsum("bij,bij->b", L, L)),
        "tracker_t": np.full(state.accuracy.shape[0], state.bank.t),
    }


def observe_agents(params: ManeuverParams, state: ManeuverState) -> NDArray[np.float32]:
    """Each platform's observation ``(B, K, params.obs_dim)`` float32 — tracker output in that
    platform's own frame, no ground truth.

    | index  | meaning                                                              |
    |--------|----------------------------------------------------------------------|
    | 0, 1   | sin, cos of its last bearing relative to its heading (starboard > 0) |
    | 2      | its speed / ``world.max_speed``                                      |
    | 3, 4   | estimated target position relative to it, own frame (starboard,      |
    |        | ahead) / ``range_scale``                                             |
    | 5, 6   | estimated relative velocity (target − own), own frame /              |
    |        | ``speed_scale``                                                      |
    | 7, 8   | ln of the position standard deviations along its axes,               |
    |        | ``ln(σ / range_scale)``                                              |
    | 9      | correlation of those two position errors                             |
    | 10, 11 | ln of the velocity standard deviations along its axes,               |
    |        | ``ln(σ_v / speed_scale)``                                            |
    | 12     | correlation of those two velocity errors                             |
    | 13, 14 | (K > 1) each other platform's position relative to it, own frame /   |
    | …      | ``range_scale``, in platform order                                   |

    Every entry is clipped to ``[−OBS_CLIP, OBS_CLIP]``. Computed by the kernels with the
    state (:func:`.kernels.observe_platform`), from the bank's moment-matched estimate.
    """
    return state.observation.copy()
