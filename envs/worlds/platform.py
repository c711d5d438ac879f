"""The platform/target world of bearings-only tracking: kinematics and bearings.

A 2-D platform (position, heading, speed) is commanded each step by a heading-rate and a
speed change; a target moves with nearly constant velocity (continuous white-noise
acceleration of intensity ``q̃``); the platform measures the absolute bearing of the target
(from North clockwise) with Gaussian noise ``σ``. Range is observable only when the
platform manoeuvres (theory §7.6, §10.5 OC-5).

Frame: ``x`` East, ``y`` North (m); heading from North clockwise (rad), so the platform
velocity is ``v (sin ψ, cos ψ)``.

The world model, over any leading shape of arrays
--------------------------------------------------
:class:`PlatformWorldParams` (limits, sampling interval, noise), :func:`fly` (the platform
over one step), :func:`propagate_target` (the target over one step: the exact discretisation
``x' = F x + w``, ``w ~ N(0, Q)`` of the CWNA model, :mod:`sensorgym.trackers.bearings.models`)
and :func:`noisy_bearings`. The platform-manoeuvre environments' simulation,
:mod:`sensorgym.envs.bearings_maneuver.simulation`, builds on these four with its own state,
tracker and reward.

Open-loop trajectories
----------------------
:class:`PlatformWorldState` (one batched state, leading axis = scenario), ``step(params,
state, action, rng=None)``, ``rollout(params, state, actions, rng=None)`` →
:class:`PlatformTrajectory` and :func:`true_bearings`: what the reproductions
(:mod:`sensorgym.reproduce.experiments.paper002`,
:mod:`sensorgym.reproduce.experiments.bot_benchmark`) and ``benchmarks/bearings.py`` use to
record trajectories for estimators and bounds. Pure functions over frozen values; ``rng`` is
needed only when ``q̃ > 0``.

Action (per scenario, shape ``(B, 2)``)
--------------------------------------
| index | meaning              | unit  | clipped to                                   |
|-------|----------------------|-------|----------------------------------------------|
| 0     | heading-rate command | rad/s | ``[−max_turn_rate, max_turn_rate]``          |
| 1     | speed change         | m/s   | ``[−max_speed_change, max_speed_change]``,   |
|       |                      |       | then the speed to ``[min_speed, max_speed]`` |

The speed change takes effect at the start of the step; the heading rate is held for the
whole step, and the platform flies the exact circular arc.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sensorgym.envs.worlds.platform_kernels import fly_batch, noisy_bearing_batch, propagate_batch
from sensorgym.trackers.bearings.models import (
    STATE_DIM,
    bearing,
    cwna_covariance,
)
from sensorgym.trackers.geometry import wrap_angle
from sensorgym.trackers.kernel_args import kernel_array
from sensorgym.trackers.validation import check_fields, finite_array

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class PlatformWorldParams:
    """Kinematic limits, sampling and noise of the bearings-only world."""

    dt: float = 60.0
    """Step and bearing sampling interval ``T`` (s)."""
    max_turn_rate: float = np.deg2rad(1.0)
    """Largest heading-rate command magnitude (rad/s); default 1°/s = 60°/min."""
    min_speed: float = 0.0
    """Lowest platform speed (m/s)."""
    max_speed: float = 15.0
    """Highest platform speed (m/s)."""
    max_speed_change: float = 2.0
    """Largest speed change per step (m/s)."""
    q_tilde: float = 0.0
    """Target acceleration noise intensity ``q̃`` (m²/s³) per axis; 0 = constant velocity."""
    sigma_bearing: float = np.deg2rad(1.5)
    """Bearing noise standard deviation ``σ`` (rad)."""

    def __post_init__(self) -> None:
        check_fields(self)  # every field a real number, not a bool
        for name in ("dt", "max_turn_rate", "min_speed", "max_speed", "max_speed_change"):
            value = getattr(self, name)
            if not np.isfinite(value) or value < 0.0:
                raise ValueError(f"{name}: must be finite and >= 0, got {value}")
        if self.dt <= 0.0:
            raise ValueError(f"dt: must be positive, got {self.dt}")
        if self.min_speed > self.max_speed:
            raise ValueError(f"min_speed {self.min_speed} exceeds max_speed {self.max_speed}")
        if not np.isfinite(self.q_tilde) or self.q_tilde < 0.0:
            raise ValueError(f"q_tilde: must be finite and >= 0, got {self.q_tilde}")
        if not np.isfinite(self.sigma_bearing) or self.sigma_bearing <= 0.0:
            raise ValueError(f"sigma_bearing: must be positive, got {self.sigma_bearing}")


@dataclass(frozen=True)
class PlatformWorldState:
    """Batched world state; leading axis ``B`` = scenario."""

    t: FloatArray
    """Time ``(B,)`` (s) of each scenario (a scalar is broadcast). The dynamics are
    time-invariant, so scenarios may run on their own clocks."""
    platform_position: FloatArray
    """Platform position ``(B, 2)`` East, North (m)."""
    heading: FloatArray
    """Platform heading ``(B,)`` from North clockwise (rad, wrapped to [−π, π))."""
    speed: FloatArray
    """Platform speed ``(B,)`` (m/s)."""
    target: FloatArray
    """Target state ``(B, 4)``: East, North (m), velocity (m/s)."""

    def __post_init__(self) -> None:
        p = finite_array(self.platform_position, "platform_position", tail=(2,))
        if p.ndim != 2:
            raise ValueError(f"platform_position: expected shape (B, 2), got {p.shape}")
        B = p.shape[0]
        h = finite_array(self.heading, "heading")
        s = finite_array(self.speed, "speed")
        x = finite_array(self.target, "target", tail=(STATE_DIM,))
        if h.shape != (B,) or s.shape != (B,) or x.shape != (B, STATE_DIM):
            raise ValueError(
                f"heading/speed/target: expected (B,), (B,), (B, 4) with B={B}, "
                f"got {h.shape}, {s.shape}, {x.shape}"
            )
        if np.any(s < 0.0):
            raise ValueError("speed: must be >= 0")
        t = finite_array(self.t, "t")
        if t.ndim > 1 or (t.ndim == 1 and t.shape != (B,)):
            raise ValueError(f"t: expected a scalar or shape ({B},), got {t.shape}")
        object.__setattr__(self, "t", np.broadcast_to(t, (B,)).copy())
        object.__setattr__(self, "platform_position", p)
        object.__setattr__(self, "heading", wrap_angle(h))
        object.__setattr__(self, "speed", s)
        object.__setattr__(self, "target", x)

    @property
    def batch_size(self) -> int:
        """Number of scenarios ``B``."""
        return self.platform_position.shape[0]

    @property
    def platform_velocity(self) -> FloatArray:
        """Platform velocity ``v (sin ψ, cos ψ)`` ``(B, 2)`` (m/s)."""
        return self.speed[:, None] * np.stack([np.sin(self.heading), np.cos(self.heading)], -1)


def fly(
    position: FloatArray,
    heading: FloatArray,
    speed: FloatArray,
    command: ArrayLike,
    params: PlatformWorldParams,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Platform kinematics over one step, for any leading shape ``(...)`` (e.g. ``(B, K)``
    platforms): ``position (..., 2)``, ``heading``, ``speed`` ``(...)``, ``command (..., 2)``
    (heading rate, speed change; clipped to the limits). Returns the new three."""
    c = finite_array(command, "action", tail=(2,))
    shape = np.broadcast_shapes(c.shape[:-1], np.shape(speed), np.shape(heading))
    shape = np.broadcast_shapes(shape, np.shape(position)[:-1])
    # C order: the kernel writes through reshape(-1, …), which must be a view (a copy of a
    # broadcast input keeps its zero strides' order and would reshape to a copy)
    p = np.array(np.broadcast_to(position, (*shape, 2)), dtype=np.float64, order="C")
    h = np.array(np.broadcast_to(heading, shape), dtype=np.float64, order="C")
    v = np.array(np.broadcast_to(speed, shape), dtype=np.float64, order="C")
    # exact arc: Δp = v T sinc(ωT/2) (sin ψ_m, cos ψ_m), ψ_m = ψ₀ + ωT/2
    # (compiled: platform_kernels.fly_platform)
    fly_batch(
        p.reshape(-1, 2),
        h.reshape(-1),
        v.reshape(-1),
        kernel_array(c, (*shape, 2)).reshape(-1, 2),
        float(params.dt),
        float(params.max_turn_rate),
        float(params.max_speed_change),
        float(params.min_speed),
        float(params.max_speed),
    )
    return p, h, v


def propagate_target(
    target: FloatArray, params: PlatformWorldParams, rng: np.random.Generator | None = None
) -> FloatArray:
    """Target states ``(B, 4)`` one step on: ``x' = F x + w``, ``w ~ N(0, Q)`` (CWNA)."""
    x = finite_array(target, "target", tail=(STATE_DIM,))
    lead = x.shape[:-1]
    if params.q_tilde > 0.0:
        if rng is None:
            raise ValueError("rng: a np.random.Generator is required when q_tilde > 0")
        eps = rng.standard_normal(x.shape)
    else:
        eps = _NO_NOISE
    out = np.empty(x.shape)
    # x' = F x + G ε  (compiled: platform_kernels.propagate_target)
    propagate_batch(
        np.ascontiguousarray(x).reshape(-1, STATE_DIM),
        eps.reshape(-1, STATE_DIM),
        cwna_noise_factor(params.dt, params.q_tilde),
        float(params.dt),
        float(params.q_tilde),
        out.reshape(-1, STATE_DIM),
    )
    return out.reshape(*lead, STATE_DIM)


_NO_NOISE = np.zeros((0, STATE_DIM))


@functools.lru_cache(maxsize=16)
def cwna_noise_factor(dt: float, q_tilde: float) -> FloatArray:
    """The factor ``G = chol(Q(dt))`` ``(4, 4)`` that colours the target's process noise
    ``w = G ε`` (zeros when ``q̃ = 0``); cached, read-only."""
    if q_tilde > 0.0:
        G = np.linalg.cholesky(cwna_covariance(dt, q_tilde))
    else:
        G = np.zeros((STATE_DIM, STATE_DIM))
    G.flags.writeable = False
    return G


def step(
    params: PlatformWorldParams,
    state: PlatformWorldState,
    action: ArrayLike,
    rng: np.random.Generator | None = None,
) -> PlatformWorldState:
    """Advance every scenario by ``params.dt`` under ``action`` (see the module docstring)."""
    a = np.broadcast_to(finite_array(action, "action", tail=(2,)), (state.batch_size, 2))
    position, heading, speed = fly(state.platform_position, state.heading, state.speed, a, params)
    return PlatformWorldState(
        t=state.t + params.dt,
        platform_position=position,
        heading=heading,
        speed=speed,
        target=propagate_target(state.target, params, rng),
    )


def true_bearings(state: PlatformWorldState) -> FloatArray:
    """Noise-free absolute bearings ``(B,)`` (rad, from North clockwise)."""
    return bearing(state.target[:, :2], state.platform_position)


def noisy_bearings(
    target_position: ArrayLike,
    platform_position: ArrayLike,
    sigma: float,
    rng: np.random.Generator,
) -> FloatArray:
    """``z = wrap(β + σ ε)`` for broadcasting positions ``(..., 2)`` → ``(...)`` (rad)."""
    t = finite_array(target_position, "target_position", tail=(2,))
    p = finite_array(platform_position, "platform_position", tail=(2,))
    shape = np.broadcast_shapes(t.shape[:-1], p.shape[:-1])
    t = kernel_array(t, (*shape, 2)).reshape(-1, 2)
    p = kernel_array(p, (*shape, 2)).reshape(-1, 2)
    if np.any((t[:, 0] == p[:, 0]) & (t[:, 1] == p[:, 1])):
        raise ValueError("target_position: coincides with the platform, bearing undefined")
    eps = rng.standard_normal(shape)
    out = np.empty(shape)
    # compiled: platform_kernels.noisy_bearing
    noisy_bearing_batch(t, p, float(sigma), eps.reshape(-1), out.reshape(-1))
    return out


@dataclass(frozen=True)
class PlatformTrajectory:
    """A recorded rollout: what estimators and bounds consume."""

    t: FloatArray
    """Sample times ``(K,)`` (s)."""
    platform_position: FloatArray
    """Platform positions ``(B, K, 2)`` (m)."""
    platform_velocity: FloatArray
    """Platform velocities ``(B, K, 2)`` (m/s) at the sample times (after the speed change)."""
    target: FloatArray
    """True target states ``(B, K, 4)``."""


def rollout(
    params: PlatformWorldParams,
    state: PlatformWorldState,
    actions: ArrayLike,
    rng: np.random.Generator | None = None,
) -> PlatformTrajectory:
    """Apply ``actions`` ``(K−1, B, 2)`` (or ``(K−1, 2)``, shared); record ``K`` states.

    All scenarios must share one clock (``state.t`` constant over the batch).
    """
    acts = finite_array(actions, "actions", tail=(2,))
    if np.ptp(state.t) > 0.0:
        raise ValueError("state: rollout needs all scenarios on one clock (equal t)")
    states = [state]
    for k in range(acts.shape[0]):
        states.append(step(params, states[-1], acts[k], rng))
    return PlatformTrajectory(
        t=np.array([s.t[0] for s in states]),
        platform_position=np.stack([s.platform_position for s in states], axis=1),
        platform_velocity=np.stack([s.platform_velocity for s in states], axis=1),
        target=np.stack([s.target for s in states], axis=1),
    )
