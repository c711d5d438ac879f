"""Simulation core of the platform-manoeuvre environments (bearings-only target motion analysis).

Pure functions over frozen, batched values (leading axis ``B`` = scenario), in the gymnax
style: :func:`reset` draws ``B`` fresh scenarios, :func:`step` advances them under a
normalised action, :func:`observe` makes the agent's observation, :func:`where` swaps fresh
scenarios into a batch (vector-env autoreset). The Gymnasium env, its vector env and any
multi-agent shell call only these; none holds physics of its own.

One step (``params.world.dt`` seconds):

1. the action ``a ∈ [−1, 1]²`` becomes a heading-rate command ``a₀·ω_max`` and a speed change
   ``a₁·Δv_max``; the platform flies the exact arc, the target moves on
   (:func:`sensorgym.envs.platform_world.step`);
2. the platform measures a noisy bearing and the range-parameterised EKF bank updates on it
   (:mod:`sensorgym.trackers.bearings_filter`): this estimate is all the agent sees;
3. the reward is the gain in accuracy of the best possible estimate: the posterior Cramér–Rao
   bound (Tichavský et al. 1998) computed along the *true* trajectory
   (:mod:`sensorgym.trackers.bearings_crlb`)::

       J_{k+1} = (I + J̄ Q)⁻¹ J̄ + Hᵀ H / σ²,    J̄ = F⁻ᵀ J_k F⁻¹,     J_0 = P_prior⁻¹
       reward_k = ln m(J_k⁻¹) − ln m(J_{k+1}⁻¹)

   with ``m`` the position RMS bound ``√(P_xx + P_yy)`` or the relative range bound ``σ_r/r``.
   Rewards telescope: the return of an episode is ``ln(m_0/m_T)``, the log-factor by which
   the platform's manoeuvres shrank the bound. The bound does not depend on the noise draw,
   so the reward has no measurement noise in it, only the consequences of the actions.

Without a manoeuvre range is unobservable (SPEC §4, §7 OC-5): a platform that keeps a
straight course collects almost no reward after the first bearings.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sensorgym.trackers.bearings_crlb import (
    bearing_information,
    crlb,
    position_rms_bound,
    predict_information,
    relative_range_bound,
)
from sensorgym.trackers.bearings_filter import (
    RangeBankState,
    range_bank_predict,
    range_bank_prior,
    range_bank_update,
)
from sensorgym.trackers.bearings_models import BearingsGaussian
from sensorgym.trackers.validation import finite_array

from . import platform_world as world
from .platform_world import PlatformWorldParams, PlatformWorldState

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
Metric = Literal["position", "relative_range"]

#: observation length (see :func:`observe`)
OBS_DIM = 10
#: observations are clipped to ``[−OBS_CLIP, OBS_CLIP]`` (a diverged filter stays finite)
OBS_CLIP = 10.0


@dataclass(frozen=True)
class ManeuverParams:
    """Scenario, tracker and reward settings of the platform-manoeuvre environments."""

    world: PlatformWorldParams = field(default_factory=PlatformWorldParams)
    """Platform limits, step ``dt`` (s), bearing noise ``σ`` (rad), target noise ``q̃``."""
    initial_range: tuple[float, float] = (5_000.0, 20_000.0)
    """Initial platform–target range, drawn uniformly (m)."""
    target_speed: tuple[float, float] = (2.0, 8.0)
    """Target speed, drawn uniformly (m/s); course uniform over all directions."""
    initial_platform_speed: float = 5.0
    """Platform speed at the start (m/s); its heading is drawn uniformly."""
    bank_ranges: tuple[float, float] = (2_000.0, 40_000.0)
    """Range span (m) covered by the filter bank's members (the prior's range support)."""
    bank_members: int = 8
    """Number of range-parameterised EKF members."""
    prior_speed: tuple[float, float] = (5.0, 3.0)
    """Target-speed prior of the filter: mean and standard deviation (m/s)."""
    metric: Metric = "position"
    """Accuracy the reward measures: ``"position"`` RMS bound (m) or ``"relative_range"``
    bound ``σ_r/r``."""
    min_range: float = 500.0
    """A platform closer than this to the target ends the episode (terminated), m."""
    close_penalty: float = 5.0
    """Reward subtracted on that termination (the return is a log-factor, so 5 ≈ e⁵)."""

    def __post_init__(self) -> None:
        lo, hi = self.initial_range
        if not (np.isfinite(hi) and 0.0 < lo <= hi):
            raise ValueError(f"initial_range: need 0 < low <= high, got {self.initial_range}")
        lo_v, hi_v = self.target_speed
        if not (np.isfinite(hi_v) and 0.0 <= lo_v <= hi_v):
            raise ValueError(f"target_speed: need 0 <= low <= high, got {self.target_speed}")
        w = self.world
        if not (w.min_speed <= self.initial_platform_speed <= w.max_speed):
            raise ValueError(
                f"initial_platform_speed: {self.initial_platform_speed} outside the world's "
                f"[{w.min_speed}, {w.max_speed}] m/s"
            )
        b_lo, b_hi = self.bank_ranges
        if not (np.isfinite(b_hi) and 0.0 < b_lo < b_hi):
            raise ValueError(f"bank_ranges: need 0 < low < high, got {self.bank_ranges}")
        if self.bank_members < 1:
            raise ValueError(f"bank_members: must be >= 1, got {self.bank_members}")
        if not (self.prior_speed[0] >= 0.0 and self.prior_speed[1] > 0.0):
            raise ValueError(f"prior_speed: need mean >= 0 and sigma > 0, got {self.prior_speed}")
        if self.metric not in ("position", "relative_range"):
            raise ValueError(f"metric: 'position' or 'relative_range', got {self.metric!r}")
        if not (np.isfinite(self.min_range) and self.min_range >= 0.0):
            raise ValueError(f"min_range: must be finite and >= 0, got {self.min_range}")
        if self.speed_scale <= 0.0:
            raise ValueError("world.max_speed + target_speed[1]: must be positive (speed scale)")
        if not np.isfinite(self.close_penalty):
            raise ValueError(f"close_penalty: must be finite, got {self.close_penalty}")

    @property
    def range_scale(self) -> float:
        """Length (m) that normalises observed positions: the far end of the initial ranges."""
        return self.initial_range[1]

    @property
    def speed_scale(self) -> float:
        """Speed (m/s) that normalises observed velocities: platform plus target top speed."""
        return self.world.max_speed + self.target_speed[1]


@dataclass(frozen=True)
class ManeuverState:
    """Batched episode state: the world, the tracker and the bound (leading axis ``B``)."""

    world: PlatformWorldState
    """Platform and true target."""
    bank: RangeBankState
    """The tracker the agent sees through: range-parameterised EKF bank, batch ``(B, N)``.
    All scenarios share its clock ``bank.t`` (the dynamics are time-invariant)."""
    information: FloatArray
    """Posterior Fisher information ``J`` ``(B, 4, 4)`` about the true state, now."""
    accuracy: FloatArray
    """``m(J⁻¹)`` ``(B,)``: the bound the reward measures (m, or dimensionless)."""
    bearing: FloatArray
    """Last measured absolute bearing ``(B,)`` (rad, from North clockwise)."""

    @property
    def batch_size(self) -> int:
        """Number of scenarios ``B``."""
        return self.world.batch_size

    @property
    def estimate(self) -> BearingsGaussian:
        """The bank's moment-matched target estimate, batch ``(B,)``."""
        return self.bank.estimate()


def _accuracy(params: ManeuverParams, J: FloatArray, w: PlatformWorldState) -> FloatArray:
    P = crlb(J)
    if params.metric == "position":
        return position_rms_bound(P)
    return relative_range_bound(P, w.target[:, :2], w.platform_position)


def reset(
    params: ManeuverParams, rng: np.random.Generator, batch: int, t: float = 0.0
) -> ManeuverState:
    """``batch`` fresh scenarios: platform at the origin, target at a random range and bearing.

    ``t`` is the tracker clock to start on (a vector env passes its running clock, so that
    fresh scenarios can be swapped into a running batch by :func:`where`).
    """
    if batch < 1:
        raise ValueError(f"batch: must be >= 1, got {batch}")
    w = params.world
    # scenario draws, in a fixed order so that a seed fixes every scenario
    heading = rng.uniform(-np.pi, np.pi, batch)
    r0 = rng.uniform(*params.initial_range, batch)
    beta0 = rng.uniform(-np.pi, np.pi, batch)
    v_t = rng.uniform(*params.target_speed, batch)
    course = rng.uniform(-np.pi, np.pi, batch)
    target = np.stack(
        [
            r0 * np.sin(beta0),
            r0 * np.cos(beta0),
            v_t * np.sin(course),
            v_t * np.cos(course),
        ],
        axis=-1,
    )
    state = PlatformWorldState(
        t=np.zeros(batch),
        platform_position=np.zeros((batch, 2)),
        heading=heading,
        speed=np.full(batch, params.initial_platform_speed),
        target=target,
    )
    z = world.measure_bearings(state, w, rng)
    # prior from the first bearing (Ristic §6.3.1): course uniform over the half plane
    # heading towards the platform
    bank = range_bank_prior(
        z,
        w.sigma_bearing,
        state.platform_position,
        t,
        range_min=params.bank_ranges[0],
        range_max=params.bank_ranges[1],
        n_members=params.bank_members,
        speed_mean=params.prior_speed[0],
        speed_sigma=params.prior_speed[1],
        course_mean=z + np.pi,
        course_sigma=np.pi / np.sqrt(12.0),
        course_distribution="uniform",
    )
    # J_0 = P_prior⁻¹: the prior already conditions on the first bearing (its position
    # covariance carries the bearing spread σ), so the bound starts from what the tracker knows
    J = np.linalg.inv(bank.estimate().P)
    return ManeuverState(state, bank, J, _accuracy(params, J, state), z)


def step(
    params: ManeuverParams, state: ManeuverState, action: ArrayLike, rng: np.random.Generator
) -> tuple[ManeuverState, FloatArray, BoolArray]:
    """Advance every scenario one step under ``action`` ``(B, 2)`` in ``[−1, 1]``.

    Actions outside ``[−1, 1]`` are clipped (documented fallback, as Box spaces allow);
    NaN or infinite actions raise ``ValueError``. Returns ``(state, reward (B,),
    terminated (B,))``; truncation (the time limit) is the shell's business.
    """
    a = finite_array(action, "action", tail=(2,))
    a = np.clip(np.broadcast_to(a, (state.batch_size, 2)), -1.0, 1.0)
    w = params.world
    command = a * np.array([w.max_turn_rate, w.max_speed_change])
    new_world = world.step(state.world, command, w, rng)
    z = world.measure_bearings(new_world, w, rng)
    bank = range_bank_predict(state.bank, state.bank.t + w.dt, w.q_tilde)
    bank = range_bank_update(bank, z, new_world.platform_position, w.sigma_bearing)
    # J_{k+1} = (I + J̄ Q)⁻¹ J̄ + Hᵀ H / σ²
    J = predict_information(state.information, w.dt, w.q_tilde) + bearing_information(
        new_world.target, new_world.platform_position, w.sigma_bearing
    )
    accuracy = _accuracy(params, J, new_world)
    # reward_k = ln m_k − ln m_{k+1}
    reward = np.log(state.accuracy) - np.log(accuracy)
    terminated = new_world.range < params.min_range
    reward = reward - params.close_penalty * terminated
    return ManeuverState(new_world, bank, J, accuracy, z), reward, terminated


def where(mask: ArrayLike, new: ManeuverState, old: ManeuverState) -> ManeuverState:
    """Scenario-wise select: ``new`` where ``mask`` ``(B,)`` is True, else ``old``.

    Both must be on the same tracker clock (pass ``t=old.bank.t`` to :func:`reset`).
    """
    m = np.asarray(mask, dtype=bool)
    if m.shape != (old.batch_size,) or new.batch_size != old.batch_size:
        raise ValueError(f"mask: expected shape ({old.batch_size},) and equal batch sizes")
    if new.bank.t != old.bank.t:
        raise ValueError(f"new: tracker clock {new.bank.t} differs from {old.bank.t}")
    mb = m[:, None]
    members = BearingsGaussian(
        np.where(mb[..., None], new.bank.members.x, old.bank.members.x),
        np.where(mb[..., None, None], new.bank.members.P, old.bank.members.P),
        old.bank.t,
    )
    return ManeuverState(
        world=world.where(m, new.world, old.world),
        bank=RangeBankState(np.where(mb, new.bank.log_weights, old.bank.log_weights), members),
        information=np.where(m[:, None, None], new.information, old.information),
        accuracy=np.where(m, new.accuracy, old.accuracy),
        bearing=np.where(m, new.bearing, old.bearing),
    )


def body_frame(heading: ArrayLike, v: ArrayLike) -> FloatArray:
    """World vectors ``(..., 2)`` (East, North) in the platform frame (starboard, ahead)."""
    h = np.asarray(heading, dtype=np.float64)[..., None]
    v = np.asarray(v, dtype=np.float64)
    s, c = np.sin(h[..., 0]), np.cos(h[..., 0])
    # ahead = (sin ψ, cos ψ), starboard = (cos ψ, −sin ψ)
    return np.stack([c * v[..., 0] - s * v[..., 1], s * v[..., 0] + c * v[..., 1]], axis=-1)


def observe(params: ManeuverParams, state: ManeuverState) -> NDArray[np.float32]:
    """The agent's observation ``(B, OBS_DIM)`` float32 — tracker output, no ground truth.

    | index | meaning                                                              |
    |-------|----------------------------------------------------------------------|
    | 0, 1  | sin, cos of the last bearing relative to the heading (starboard > 0) |
    | 2     | platform speed / ``world.max_speed``                                 |
    | 3, 4  | estimated target position relative to the platform, platform frame   |
    |       | (starboard, ahead) / ``range_scale``                                 |
    | 5, 6  | estimated relative velocity (target − platform), platform frame /    |
    |       | ``speed_scale``                                                      |
    | 7, 8  | ln of the position standard deviations along the platform axes,      |
    |       | ``ln(σ / range_scale)``                                              |
    | 9     | correlation of those two position errors                             |

    Every entry is clipped to ``[−OBS_CLIP, OBS_CLIP]``.
    """
    w = state.world
    est = state.estimate
    rel_bearing = state.bearing - w.heading
    rel_pos = body_frame(w.heading, est.position - w.platform_position)
    rel_vel = body_frame(w.heading, est.velocity - w.platform_velocity)
    # position covariance in the platform frame: R P Rᵀ with R the rows of body_frame
    s, c = np.sin(w.heading), np.cos(w.heading)
    R = np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], axis=-2)
    Pb = R @ est.P[:, :2, :2] @ np.swapaxes(R, -1, -2)
    sd = np.sqrt(np.clip(np.diagonal(Pb, axis1=-2, axis2=-1), 1e-12, None))
    rho = Pb[:, 0, 1] / (sd[:, 0] * sd[:, 1])
    obs = np.concatenate(
        [
            np.stack([np.sin(rel_bearing), np.cos(rel_bearing)], -1),
            (w.speed / max(params.world.max_speed, 1e-12))[:, None],
            rel_pos / params.range_scale,
            rel_vel / params.speed_scale,
            np.log(sd / params.range_scale),
            rho[:, None],
        ],
        axis=-1,
    )
    return np.clip(obs, -OBS_CLIP, OBS_CLIP).astype(np.float32)
