"""Rules for ``sensorgym/BearingsManeuver-v0`` (theory §10.5 OC-5), and the oracle ceiling above them.

Each rule reads only the observation (the tracker's view, see
:func:`sensorgym.envs.bearings_maneuver.simulation.observe_agents`) and implements SB3's
``predict``, so ``stable_baselines3.common.evaluation.evaluate_policy`` scores it like a
trained model. :class:`OracleLookahead` is not a rule one could field: it peeks at the
simulator (true target, true Cramér–Rao bound) and plans on the very bound the reward
measures, which shows how much of the gap to the best manoeuvres comes from not knowing the
target (the rules) and how much from planning.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sensorgym.agents.protocol import MemorylessRule, as_batch
from sensorgym.envs.bearings_maneuver.kernels import greedy_kernel, plan_kernel
from sensorgym.envs.bearings_maneuver.simulation import (
    OBS_DIM,
    ManeuverParams,
    ManeuverState,
)
from sensorgym.envs.shells.rows import run_rows

FloatArray = NDArray[np.float64]


def _relative_bearing(obs: FloatArray) -> FloatArray:
    """Last bearing relative to the heading (rad, starboard > 0) from obs 0, 1."""
    return np.arctan2(obs[:, 0], obs[:, 1])


def _turn_command(params: ManeuverParams, turn: FloatArray) -> FloatArray:
    """Normalised turn action that changes the heading by ``turn`` (rad) within one step."""
    w = params.world
    if w.max_turn_rate == 0.0:
        return np.zeros_like(turn)
    return np.clip(turn / (w.dt * w.max_turn_rate), -1.0, 1.0)


@dataclass(frozen=True)
class StraightCourse(MemorylessRule):
    """Hold course and speed: range stays unobservable (the baseline every rule must beat)."""

    obs_dim = OBS_DIM

    def act(self, obs: FloatArray) -> FloatArray:
        """Actions ``(N, action size)`` for observations ``(N, obs_dim)``."""
        return np.zeros((obs.shape[0], 2))


@dataclass(frozen=True)
class Paper002Maneuver:
    """Move along the first bearing for two more bearings, then turn perpendicular to the
    bearing and speed up (paper 002, theory §10.5 OC-5).

    The rule needs the step count, kept as its ``state`` (an int array per env, reset by
    ``episode_start``), as SB3 does for recurrent policies. The perpendicular is taken to the
    latest bearing, on the side that needs the smaller turn.
    """

    params: ManeuverParams = field(default_factory=ManeuverParams)
    """Env settings (step length and turn limit scale the turn command)."""
    run_in: int = 2
    """Steps spent on the first bearing before the turn (bearings 2 and 3)."""

    def predict(
        self,
        observation: NDArray[Any],
        state: NDArray[np.int64] | None = None,
        episode_start: NDArray[np.bool_] | None = None,
        deterministic: bool = True,
    ) -> tuple[NDArray[np.float32], NDArray[np.int64]]:
        obs, single = as_batch(observation, OBS_DIM)
        n = obs.shape[0]
        k = np.zeros(n, dtype=np.int64) if state is None else np.asarray(state, dtype=np.int64)
        if episode_start is not None:
            k = np.where(np.asarray(episode_start, dtype=bool), 0, k)
        theta = _relative_bearing(obs)
        # phase 1: head along the bearing; phase 2: put the target abeam, full speed
        abeam = np.where(theta >= 0.0, 0.5 * np.pi, -0.5 * np.pi)
        run_in = k < self.run_in
        turn = np.where(run_in, theta, theta - abeam)
        action = np.stack([_turn_command(self.params, turn), np.where(run_in, 0.0, 1.0)], -1)
        action = action.astype(np.float32)
        return (action[0] if single else action), k + 1


@dataclass(frozen=True)
class GreedyManeuver(MemorylessRule):
    """Take the action whose next bearing adds the most position information, by the tracker's
    own estimate (one-step D-optimal: maximise ``ln det(J + h hᵀ/σ²)``, i.e. ``hᵀ P h``).

    ``h = n̂/r`` is the bearing's gradient at the predicted relative position (``n̂`` normal to
    the line of sight), ``P`` the estimate's position covariance from the observation. Candidate
    actions form a grid; positions closer than ``safety · min_range`` are ruled out.
    """

    params: ManeuverParams = field(default_factory=ManeuverParams)
    """Env settings (kinematics, normalisation scales, ``min_range``)."""
    turns: int = 9
    """Candidate turn actions, evenly spaced in ``[−1, 1]``."""
    speeds: tuple[float, ...] = (-1.0, 0.0, 1.0)
    """Candidate speed actions."""
    safety: float = 2.0
    """Candidates predicted within ``safety · min_range`` of the target are not taken."""

    def candidates(self) -> NDArray[np.float64]:
        """Candidate actions ``(C, 2)``."""
        a_turn, a_speed = np.meshgrid(np.linspace(-1.0, 1.0, self.turns), self.speeds)
        return np.stack([a_turn.ravel(), a_speed.ravel()], -1)

    def act(self, obs: FloatArray) -> FloatArray:
        """Actions ``(N, action size)`` for observations ``(N, obs_dim)``: the env's flight of
        every candidate from the platform's frame, the estimate moved on by its velocity, the
        gain ``hᵀ P h`` at the new relative position (compiled:
        :func:`sensorgym.envs.bearings_maneuver.kernels.greedy_kernel`)."""
        p, w = self.params, self.params.world
        cand = self.candidates()
        command = np.ascontiguousarray(cand * [w.max_turn_rate, w.max_speed_change])
        # P from log standard deviations (obs 7, 8) and correlation (obs 9)
        sd = np.exp(obs[:, 7:9]) * p.range_scale
        choice = np.empty(obs.shape[0], dtype=np.int64)
        greedy_kernel(
            p.kernel_constants,
            np.ascontiguousarray(obs, dtype=np.float64),
            np.ascontiguousarray(sd),
            command,
            float(self.safety * p.min_range),
            choice,
        )
        return cand[choice]


@dataclass(frozen=True)
class OracleLookahead(MemorylessRule):
    """Hold each candidate action for ``horizon`` steps on the true, noise-free trajectory and
    take the first action of the plan with the smallest bound (receding horizon).

    ``state_fn`` returns the simulator's current :class:`ManeuverState` (batch = the
    observations' batch), e.g. ``lambda: vec_env.get_attr("simulator_state")[0]`` for an SB3
    view of the native vector env. One platform only (the Gymnasium env). The target's future is its mean
    path ``F x`` (exact for ``q̃ = 0``); plans that come within ``safety · min_range`` of it are
    ruled out.
    """

    state_fn: Callable[[], ManeuverState]
    """The simulator's current state (the oracle's privilege)."""
    params: ManeuverParams = field(default_factory=ManeuverParams)
    """Env settings (kinematics, bearing noise, reward metric, ``min_range``)."""
    turns: int = 7
    """Candidate turn actions, evenly spaced in ``[−1, 1]``."""
    speeds: tuple[float, ...] = (-1.0, 0.0, 1.0)
    """Candidate speed actions."""
    horizon: int = 5
    """Steps each candidate is held for."""
    safety: float = 1.5
    """Plans predicted within ``safety · min_range`` of the target are not taken."""

    def __post_init__(self) -> None:
        if self.params.platforms != 1:
            raise ValueError("params.platforms: the oracle plans for one platform")
        if self.horizon < 1 or self.turns < 1 or not self.speeds:
            raise ValueError("horizon, turns and speeds: need at least one each")

    def candidates(self) -> NDArray[np.float64]:
        """Candidate actions ``(C, 2)``."""
        turn, speed = np.meshgrid(np.linspace(-1.0, 1.0, self.turns), self.speeds)
        return np.stack([turn.ravel(), speed.ravel()], -1)

    def plan_bounds(self, s: ManeuverState) -> NDArray[np.float64]:
        """Bound after ``horizon`` steps of each candidate, ``(B, C)`` (``inf`` if too close):
        the env's own flight and bound recursion, compiled
        (:func:`sensorgym.envs.bearings_maneuver.kernels.plan_kernel`; what
        :func:`~sensorgym.envs.bearings_maneuver.simulation.advance_bound` and
        :func:`~sensorgym.envs.bearings_maneuver.simulation.accuracy_of` compute)."""
        p, w = self.params, self.params.world
        command = np.ascontiguousarray(self.candidates() * [w.max_turn_rate, w.max_speed_change])
        B = s.batch_size
        out = np.empty((B, command.shape[0]))
        arrays = (
            p.kernel_constants,
            *(
                np.ascontiguousarray(a, dtype=np.float64)
                for a in (s.platform_position, s.heading, s.speed, s.target, s.bound_factor)
            ),
            command,
            int(self.horizon),
            float(self.safety * p.min_range),
            out,
        )
        run_rows(B, lambda lo, hi: plan_kernel(lo, hi, *arrays))
        return out

    def act(self, obs: FloatArray) -> FloatArray:
        """Actions ``(N, action size)`` for observations ``(N, obs_dim)``."""
        s = self.state_fn()
        if s.batch_size != obs.shape[0]:
            raise ValueError(
                f"state_fn: simulator batch {s.batch_size} != {obs.shape[0]} observations"
            )
        return self.candidates()[np.argmin(self.plan_bounds(s), axis=1)]


@dataclass(frozen=True)
class EstimateLookahead(MemorylessRule):
    """The oracle's receding-horizon planner run on the tracker's estimate instead of the
    truth (certainty equivalence): hold each candidate action for ``horizon`` steps while the
    *estimated* target moves on at its estimated velocity, run the bound recursion from the
    estimate's covariance, and take the first action of the plan with the smallest bound.

    Everything comes from the observation, in the platform's frame (platform at the origin,
    heading 0 = ahead): the estimated relative position and velocity (obs 3–6), the position
    covariance (obs 7–9). The observation holds no velocity covariance; the plan starts from
    the prior's per-axis velocity spread (course uniform, speed moments of the prior:
    ``σ_v² = (v̄² + σ_s²)/2``), uncorrelated with the position. With ``horizon=1`` this is the
    one-step greedy on the bound; ``horizon=2`` is the two-step lookahead a reviewer asks for.
    Plans predicted within ``safety · min_range`` of the estimate are ruled out.
    """

    params: ManeuverParams = field(default_factory=ManeuverParams)
    """Env settings (kinematics, bearing noise, normalisation scales, ``min_range``)."""
    turns: int = 7
    """Candidate turn actions, evenly spaced in ``[−1, 1]``."""
    speeds: tuple[float, ...] = (-1.0, 0.0, 1.0)
    """Candidate speed actions."""
    horizon: int = 8
    """Steps each candidate is held for (8 scored best of 1, 2, 3, 5, 8, 12, 16 on tuning
    scenarios, seed 500)."""
    safety: float = 2.0
    """Plans predicted within ``safety · min_range`` of the estimate are not taken."""

    obs_dim = OBS_DIM

    def __post_init__(self) -> None:
        if self.params.platforms != 1:
            raise ValueError("params.platforms: the lookahead plans for one platform")
        if self.horizon < 1 or self.turns < 1 or not self.speeds:
            raise ValueError("horizon, turns and speeds: need at least one each")

    def candidates(self) -> NDArray[np.float64]:
        """Candidate actions ``(C, 2)``."""
        turn, speed = np.meshgrid(np.linspace(-1.0, 1.0, self.turns), self.speeds)
        return np.stack([turn.ravel(), speed.ravel()], -1)

    def act(self, obs: FloatArray) -> FloatArray:
        """Actions ``(N, action size)`` for observations ``(N, obs_dim)``: the oracle's compiled
        plans (:func:`sensorgym.envs.bearings_maneuver.kernels.plan_kernel`) from the estimate."""
        p, w = self.params, self.params.world
        n = obs.shape[0]
        obs = np.asarray(obs, dtype=np.float64)
        v = obs[:, 2] * w.max_speed
        pos = np.zeros((n, 1, 2))
        heading = np.zeros((n, 1))
        speed = v[:, None].copy()
        # estimated target state in the platform frame: relative velocity + own (0, v)
        target = np.empty((n, 4))
        target[:, :2] = obs[:, 3:5] * p.range_scale
        target[:, 2] = obs[:, 5] * p.speed_scale
        target[:, 3] = obs[:, 6] * p.speed_scale + v
        # the bound's square root from the estimate: position block from obs 7–9 (Cholesky of
        # [[s0², ρ s0 s1], [ρ s0 s1, s1²]]), velocity block the prior's spread
        s = np.exp(obs[:, 7:9]) * p.range_scale
        rho = np.clip(obs[:, 9], -0.999, 0.999)
        mean, sigma = p.prior_speed_moments
        sv = np.sqrt(0.5 * (mean * mean + sigma * sigma))
        L = np.zeros((n, 4, 4))
        L[:, 0, 0] = s[:, 0]
        L[:, 1, 0] = rho * s[:, 1]
        L[:, 1, 1] = np.sqrt(1.0 - rho * rho) * s[:, 1]
        L[:, 2, 2] = L[:, 3, 3] = sv
        command = np.ascontiguousarray(self.candidates() * [w.max_turn_rate, w.max_speed_change])
        out = np.empty((n, command.shape[0]))
        arrays = (
            p.kernel_constants,
            pos,
            heading,
            speed,
            target,
            L,
            command,
            int(self.horizon),
            float(self.safety * p.min_range),
            out,
        )
        run_rows(n, lambda lo, hi: plan_kernel(lo, hi, *arrays))
        return self.candidates()[np.argmin(out, axis=1)]
