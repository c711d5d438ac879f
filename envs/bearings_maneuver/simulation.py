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
2. the platform measures a noisy bearing and the range-parameterised EKF bank updates on it
   (:mod:`sensorgym.trackers.bearings.filters`): this estimate is all the agent sees;
3. the reward is the gain in accuracy of the best possible estimate: the posterior Cramér–Rao
   bound (Tichavský et al. 1998) computed along the *true* trajectory
   (:mod:`sensorgym.trackers.bearings.crlb`)::

       J_{k+1} = (I + J̄ Q)⁻¹ J̄ + Hᵀ H / σ²,    J̄ = F⁻ᵀ J_k F⁻¹,     J_0 = P_prior⁻¹
       reward_k = ln m(J_k⁻¹) − ln m(J_{k+1}⁻¹)

   with ``m`` the position RMS bound ``√(P_xx + P_yy)`` or the relative range bound ``σ_r/r``.
   Rewards telescope: the return of an episode is ``ln(m_0/m_T)``, the log-factor by which
   the platform's manoeuvres shrank the bound. The bound does not depend on the noise draw,
   so the reward has no measurement noise in it, only the consequences of the actions.

Without a manoeuvre range is unobservable (theory §7.6, §10.5 OC-5): a platform that keeps a
straight course collects almost no reward after the first bearings.

Several platforms (``params.platforms = K``, each an agent of the PettingZoo env) all take a
bearing every step; the tracker fuses them (sequential updates) and the bound adds their
information, so cross-bearings make range observable even without manoeuvres. Arrays of
platform quantities carry an axis ``K`` after the batch axis; ``K = 1`` is the Gymnasium env.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sensorgym.envs.shells.contract import EnvSpaces, clip_observation
from sensorgym.envs.worlds.platform import (
    PlatformWorldParams,
    fly,
    noisy_bearings,
    propagate_target,
)
from sensorgym.trackers.bearings.crlb import (
    bearing_information,
    crlb,
    position_rms_bound,
    predict_information,
    relative_range_bound,
)
from sensorgym.trackers.bearings.filters import (
    RangeBankState,
    range_bank_predict,
    range_bank_prior,
    range_bank_update,
)
from sensorgym.trackers.bearings.models import BearingsGaussian
from sensorgym.trackers.validation import count, finite_array

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
Metric = Literal["position", "relative_range"]

#: observation length of a lone platform (see :func:`observe_agents`; + 2 per other platform)
OBS_DIM = 10


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
    platforms: int = 1
    """Number of platforms ``K`` taking bearings on the one target (agents in PettingZoo)."""
    formation_radius: float = 2_000.0
    """Platforms 2..K start uniformly within this distance of platform 1 (at the origin), m."""
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
        count(self.platforms, "platforms")
        if not (np.isfinite(self.formation_radius) and self.formation_radius >= 0.0):
            raise ValueError(
                f"formation_radius: must be finite and >= 0, got {self.formation_radius}"
            )
        count(self.bank_members, "bank_members")
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
    def obs_dim(self) -> int:
        """Observation length per platform: ``OBS_DIM + 2 (K − 1)``."""
        return OBS_DIM + 2 * (self.platforms - 1)

    @property
    def speed_scale(self) -> float:
        """Speed (m/s) that normalises observed velocities: platform plus target top speed."""
        return self.world.max_speed + self.target_speed[1]


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
    """The tracker the agents see through: range-parameterised EKF bank, batch ``(B, N)``.
    All scenarios share its clock ``bank.t`` (the dynamics are time-invariant)."""
    information: FloatArray
    """Posterior Fisher information ``J`` ``(B, 4, 4)`` about the true state, now."""
    accuracy: FloatArray
    """``m(J⁻¹)`` ``(B,)``: the bound the reward measures (m, or dimensionless)."""
    bearing: FloatArray
    """Last measured absolute bearings ``(B, K)`` (rad, from North clockwise)."""

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
    def estimate(self) -> BearingsGaussian:
        """The bank's moment-matched target estimate, batch ``(B,)``."""
        return self.bank.estimate()


def accuracy_of(
    params: ManeuverParams, J: FloatArray, target: FloatArray, origin: FloatArray
) -> FloatArray:
    """The accuracy ``m(J⁻¹)`` the reward measures (``params.metric``) of information ``J``
    ``(..., 4, 4)`` about ``target`` ``(..., 4)``: the position RMS bound, or the relative range
    bound taken from ``origin`` ``(..., 2)`` (platform 1). The env and the oracle call this."""
    P = crlb(J)
    if params.metric == "position":
        return position_rms_bound(P)
    return relative_range_bound(P, target[..., :2], origin)


def _fuse(
    bank: RangeBankState, z: FloatArray, positions: FloatArray, sigma: float, first: int = 0
) -> RangeBankState:
    """Sequential bank updates with the bearings ``z (B, K)`` of platforms ``first..K−1``."""
    for k in range(first, z.shape[1]):
        bank = range_bank_update(bank, z[:, k], positions[:, k], sigma)
    return bank


def spaces(params: ManeuverParams) -> EnvSpaces:
    """Agents ``platform_0 … platform_{K−1}``; each acts with ``(turn, speed change)`` and sees
    ``params.obs_dim`` entries; the joint view is every platform's observation in turn."""
    K = params.platforms
    return EnvSpaces.build("platform", K, K * params.obs_dim, params.obs_dim, 2)


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
    w, K = params.world, params.platforms
    # scenario draws, in a fixed order so that a seed fixes every scenario
    heading = rng.uniform(-np.pi, np.pi, (batch, K))
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
    positions = np.zeros((batch, K, 2))
    if K > 1:  # uniform over the disc around platform 1
        rho = params.formation_radius * np.sqrt(rng.uniform(0.0, 1.0, (batch, K - 1)))
        phi = rng.uniform(-np.pi, np.pi, (batch, K - 1))
        positions[:, 1:] = np.stack([rho * np.sin(phi), rho * np.cos(phi)], -1)
    z = noisy_bearings(target[:, None, :2], positions, w.sigma_bearing, rng)
    # prior from platform 1's first bearing (Ristic §6.3.1): course uniform over the half plane
    # heading towards it; the other platforms' first bearings update it
    bank = range_bank_prior(
        z[:, 0],
        w.sigma_bearing,
        positions[:, 0],
        t,
        range_min=params.bank_ranges[0],
        range_max=params.bank_ranges[1],
        n_members=params.bank_members,
        speed_mean=params.prior_speed[0],
        speed_sigma=params.prior_speed[1],
        course_mean=z[:, 0] + np.pi,
        course_sigma=np.pi / np.sqrt(12.0),
        course_distribution="uniform",
    )
    # J_0 = P_prior⁻¹ + Σ_{k≥2} I_k(x_0): the prior already conditions on platform 1's first
    # bearing (its position covariance carries the bearing spread σ)
    J = np.linalg.inv(bank.estimate().P)
    if K > 1:
        bank = _fuse(bank, z, positions, w.sigma_bearing, first=1)
        J = J + bearing_information(target[:, None], positions[:, 1:], w.sigma_bearing).sum(1)
    return ManeuverState(
        t=np.zeros(batch),
        platform_position=positions,
        heading=heading,
        speed=np.full((batch, K), params.initial_platform_speed),
        target=target,
        bank=bank,
        information=J,
        accuracy=accuracy_of(params, J, target, positions[:, 0]),
        bearing=z,
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
    a = finite_array(action, "action", tail=(2,))
    if a.ndim == 2 and K == 1:
        a = a[:, None]
    a = np.clip(np.broadcast_to(a, (B, K, 2)), -1.0, 1.0)
    w = params.world
    command = a * np.array([w.max_turn_rate, w.max_speed_change])
    positions, heading, speed = fly(state.platform_position, state.heading, state.speed, command, w)
    target = propagate_target(state.target, w, rng)
    z = noisy_bearings(target[:, None, :2], positions, w.sigma_bearing, rng)
    bank = range_bank_predict(state.bank, state.bank.t + w.dt, w.q_tilde)
    bank = _fuse(bank, z, positions, w.sigma_bearing)
    # J_{k+1} = (I + J̄ Q)⁻¹ J̄ + Σ_platforms Hᵀ H / σ²
    J = predict_information(state.information, w.dt, w.q_tilde) + bearing_information(
        target[:, None], positions, w.sigma_bearing
    ).sum(1)
    accuracy = accuracy_of(params, J, target, positions[:, 0])
    new = ManeuverState(state.t + w.dt, positions, heading, speed, target, bank, J, accuracy, z)
    # reward_k = ln m_k − ln m_{k+1}
    reward = np.log(state.accuracy) - np.log(accuracy)
    terminated = np.any(new.range < params.min_range, axis=1)
    reward = reward - params.close_penalty * terminated
    return new, reward, terminated


def body_frame(heading: ArrayLike, v: ArrayLike) -> FloatArray:
    """World vectors ``(..., 2)`` (East, North) in the platform frame (starboard, ahead)."""
    h = np.asarray(heading, dtype=np.float64)[..., None]
    v = np.asarray(v, dtype=np.float64)
    s, c = np.sin(h[..., 0]), np.cos(h[..., 0])
    # ahead = (sin ψ, cos ψ), starboard = (cos ψ, −sin ψ)
    return np.stack([c * v[..., 0] - s * v[..., 1], s * v[..., 0] + c * v[..., 1]], axis=-1)


def observe(params: ManeuverParams, state: ManeuverState) -> NDArray[np.float32]:
    """The joint view ``(B, K · obs_dim)``: every platform's :func:`observe_agents` row in turn
    (for ``K = 1``, the lone platform's observation)."""
    obs = observe_agents(params, state)
    return obs.reshape(obs.shape[0], -1)


def info(params: ManeuverParams, state: ManeuverState) -> dict[str, FloatArray]:
    """Diagnostics (ground truth included: for evaluation, never for the policy): the nearest
    platform's range, the bound the reward measures, the estimate's position error, the
    tracker clock."""
    est = state.estimate
    return {
        "range": state.range.min(axis=1),
        "bound": state.accuracy,
        "position_error": np.hypot(*(est.position - state.target[:, :2]).T),
        "tracker_t": np.full(state.batch_size, state.bank.t),
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
    | 10, 11 | (K > 1) each other platform's position relative to it, own frame /   |
    | …      | ``range_scale``, in platform order                                   |

    Every entry is clipped to ``[−OBS_CLIP, OBS_CLIP]``.
    """
    B, K = state.heading.shape
    est = state.estimate
    psi = state.heading
    rel_bearing = state.bearing - psi
    rel_pos = body_frame(psi, est.position[:, None] - state.platform_position)
    rel_vel = body_frame(psi, est.velocity[:, None] - state.platform_velocity)
    # position covariance in each platform frame: R P Rᵀ with R the rows of body_frame
    s, c = np.sin(psi), np.cos(psi)
    R = np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], axis=-2)  # (B, K, 2, 2)
    Pb = R @ est.P[:, None, :2, :2] @ np.swapaxes(R, -1, -2)
    sd = np.sqrt(np.clip(np.diagonal(Pb, axis1=-2, axis2=-1), 1e-12, None))
    rho = Pb[..., 0, 1] / (sd[..., 0] * sd[..., 1])
    parts = [
        np.stack([np.sin(rel_bearing), np.cos(rel_bearing)], -1),
        (state.speed / max(params.world.max_speed, 1e-12))[..., None],
        rel_pos / params.range_scale,
        rel_vel / params.speed_scale,
        np.log(sd / params.range_scale),
        rho[..., None],
    ]
    if K > 1:
        others = np.array([[j for j in range(K) if j != k] for k in range(K)])  # (K, K−1)
        d = state.platform_position[:, others] - state.platform_position[:, :, None]
        parts.append(body_frame(psi[..., None], d).reshape(B, K, 2 * (K - 1)) / params.range_scale)
    return clip_observation(np.concatenate(parts, axis=-1))
