"""Rules for ``sensorgym/BearingsManeuver-v0`` (theory §10.5 OC-5), and a truth-informed planner.

Each rule reads only the observation (the tracker's view, see
:func:`sensorgym.envs.bearings_maneuver.simulation.observe_agents`) and implements SB3's
``predict``, so ``stable_baselines3.common.evaluation.evaluate_policy`` scores it like a
trained model. :class:`TruthLookahead` is not a rule one could field: it peeks at the
simulator (true target, true Cramér–Rao bound) and plans on the very bound the reward
measures, which shows what knowing the truth buys a receding-horizon planner. It is not a
bound on the return: a longer plan, or a policy that learnt the task, can beat it.

Every rule works for any number of platforms ``K`` (``params.platforms``): it reads the joint
view (every platform's view in turn, ``K · obs_dim``) and returns every platform's action in
turn (``2K``). The rules without a model of the shared information (:class:`StraightCourse`,
:class:`Paper002Maneuver`) run on each platform's own view. The tracker is one fused estimate,
so the information rules choose jointly, by sequential greedy: platform 1 chooses first, then
each platform chooses given the choices before it (:class:`GreedyManeuver`: its bearing's
information ``hᵀ P h`` after the earlier platforms' bearings have updated ``P``;
:class:`EstimateLookahead` and :class:`TruthLookahead`: its ``horizon``-step plan's bound with
the other platforms flying their plans, straight on until chosen). This costs
``O(K · candidates)`` (greedy) or ``O(K · candidates · horizon + K² · horizon)`` (lookahead) per
scenario, where a joint search would cost ``candidates^K``; for ``K = 1`` each is the
single-platform rule. The platforms' frames are related through the view (:func:`relative_headings`).
"""

from __future__ import annotations

from abc import abstractmethod
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sensorgym.agents.protocol import MemorylessRule, as_batch
from sensorgym.envs.bearings_maneuver.kernels import greedy_kernel, joint_plan_kernel, plan_kernel
from sensorgym.envs.bearings_maneuver.simulation import (
    OBS_DIM,
    ManeuverParams,
    ManeuverState,
)
from sensorgym.envs.shells.rows import run_rows

FloatArray = NDArray[np.float64]


def _relative_bearing(obs: FloatArray) -> FloatArray:
    """Last bearing relative to the heading (rad, starboard > 0) from obs 0, 1 (``(..., 0:2)``)."""
    return np.arctan2(obs[..., 0], obs[..., 1])


def platform_views(params: ManeuverParams, obs: FloatArray) -> FloatArray:
    """The joint view ``(N, K · obs_dim)`` as every platform's view ``(N, K, obs_dim)``."""
    return obs.reshape(obs.shape[0], params.platforms, params.obs_dim)


def relative_headings(params: ManeuverParams, views: FloatArray) -> FloatArray:
    """Each platform's heading relative to platform 1's, ``(N, K)`` (rad), read off the views
    ``(N, K, obs_dim)``: the estimated target relative to platform ``k`` is seen by ``k`` in its
    own frame (obs 3, 4) and by platform 1 as its own relative target minus ``k``'s relative
    position (obs 13 + 2(k − 1), 14 + 2(k − 1)); the frames differ by the heading difference
    (:func:`~sensorgym.envs.bearings_maneuver.simulation.body_frame` turns by the heading)."""
    N, K = views.shape[:2]
    delta = np.zeros((N, K))
    if K > 1:
        first = views[:, 0, OBS_DIM:].reshape(N, K - 1, 2)
        seen_by_1 = views[:, :1, 3:5] - first  # (N, K − 1, 2), platform 1's frame
        seen_by_k = views[:, 1:, 3:5]
        delta[:, 1:] = np.arctan2(seen_by_k[..., 1], seen_by_k[..., 0]) - np.arctan2(
            seen_by_1[..., 1], seen_by_1[..., 0]
        )
    return delta


@dataclass(frozen=True)
class ManeuverRule(MemorylessRule):
    """A memoryless rule on the joint view of ``params.platforms`` platforms."""

    params: ManeuverParams = field(default_factory=ManeuverParams)
    """Env settings (kinematics, normalisation scales, ``min_range``, number of platforms)."""

    @property
    def obs_dim(self) -> int:
        """The joint view's length, ``K · params.obs_dim``."""
        return self.params.platforms * self.params.obs_dim

    def act(self, obs: FloatArray) -> FloatArray:
        """Actions ``(N, 2K)`` for joint views ``(N, K · obs_dim)``: every platform's
        :meth:`choose` in turn."""
        return self.choose(platform_views(self.params, obs)).reshape(obs.shape[0], -1)

    @abstractmethod
    def choose(self, views: FloatArray) -> FloatArray:
        """Every platform's action ``(N, K, 2)`` from every platform's view ``(N, K, obs_dim)``."""


def _spread_factor(spread: FloatArray, scale: float) -> FloatArray:
    """Cholesky factor ``(N, 2, 2)`` of the 2-D covariance ``[[s0², ρ s0 s1], [ρ s0 s1, s1²]]``
    an observation holds as ``ln(s0/scale)``, ``ln(s1/scale)``, ``ρ`` (``spread (N, 3)``; ``ρ``
    kept inside ``±0.999``: a finite factor when the estimate has collapsed onto a line)."""
    s = np.exp(spread[:, :2]) * scale
    rho = np.clip(spread[:, 2], -0.999, 0.999)
    L = np.zeros((spread.shape[0], 2, 2))
    L[:, 0, 0] = s[:, 0]
    L[:, 1, 0] = rho * s[:, 1]
    L[:, 1, 1] = np.sqrt(1.0 - rho * rho) * s[:, 1]
    return L


def _turn_command(params: ManeuverParams, turn: FloatArray) -> FloatArray:
    """Normalised turn action that changes the heading by ``turn`` (rad) within one step."""
    w = params.world
    if w.max_turn_rate == 0.0:
        return np.zeros_like(turn)
    return np.clip(turn / (w.dt * w.max_turn_rate), -1.0, 1.0)


def estimate_frame(
    params: ManeuverParams, views: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """The planning world the observation holds, in platform 1's frame (platform 1 at the
    origin, heading 0 = ahead), from every platform's view ``(N, K, obs_dim)``: platform
    positions ``(N, K, 2)``, headings and speeds ``(N, K)``, the estimated target state
    ``(N, 4)`` and the square root ``(N, 4, 4)`` of the estimate's covariance, block-diagonal
    (the observation holds no position–velocity cross-covariance): the position block from
    obs 7–9, the velocity block from obs 10–12 (what :class:`EstimateLookahead` and
    :class:`~sensorgym.agents.bearings_mpc.RecedingPlan` plan on)."""
    p, w = params, params.world
    n, K = views.shape[:2]
    views = np.asarray(views, dtype=np.float64)
    first = views[:, 0]
    pos = np.zeros((n, K, 2))
    if K > 1:
        pos[:, 1:] = first[:, OBS_DIM:].reshape(n, K - 1, 2) * p.range_scale
    heading = relative_headings(p, views)
    speed = views[:, :, 2] * w.max_speed
    # estimated target state in platform 1's frame: relative velocity + own (0, v)
    target = np.empty((n, 4))
    target[:, :2] = first[:, 3:5] * p.range_scale
    target[:, 2] = first[:, 5] * p.speed_scale
    target[:, 3] = first[:, 6] * p.speed_scale + speed[:, 0]
    L = np.zeros((n, 4, 4))
    L[:, :2, :2] = _spread_factor(first[:, 7:10], p.range_scale)
    L[:, 2:, 2:] = _spread_factor(first[:, 10:13], p.speed_scale)
    return pos, heading, speed, target, L


@dataclass(frozen=True)
class StraightCourse(ManeuverRule):
    """Hold course and speed: range stays unobservable (the baseline every rule must beat)."""

    def choose(self, views: FloatArray) -> FloatArray:
        """Every platform's action ``(N, K, 2)``: no turn, no speed change."""
        return np.zeros((*views.shape[:2], 2))


@dataclass(frozen=True)
class Paper002Maneuver:
    """Move along the first bearing for two more bearings, then turn perpendicular to the
    bearing and speed up (paper 002, theory §10.5 OC-5).

    The rule needs the step count, kept as its ``state`` (an int array per env, reset by
    ``episode_start``), as SB3 does for recurrent policies. The perpendicular is taken to the
    latest bearing, on the side that needs the smaller turn. Each of ``K`` platforms does so
    on its own bearing.
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
        p = self.params
        obs, single = as_batch(observation, p.platforms * p.obs_dim)
        n = obs.shape[0]
        k = np.zeros(n, dtype=np.int64) if state is None else np.asarray(state, dtype=np.int64)
        if episode_start is not None:
            k = np.where(np.asarray(episode_start, dtype=bool), 0, k)
        theta = _relative_bearing(platform_views(p, obs))  # (n, K)
        # phase 1: head along the bearing; phase 2: put the target abeam, full speed
        abeam = np.where(theta >= 0.0, 0.5 * np.pi, -0.5 * np.pi)
        run_in = (k < self.run_in)[:, None]
        turn = np.where(run_in, theta, theta - abeam)
        speed = np.broadcast_to(np.where(run_in, 0.0, 1.0), turn.shape)
        action = np.stack([_turn_command(p, turn), speed], -1).reshape(n, -1)
        action = action.astype(np.float32)
        return (action[0] if single else action), k + 1


@dataclass(frozen=True)
class GreedyManeuver(ManeuverRule):
    """Take the action whose next bearing adds the most position information, by the tracker's
    own estimate (one-step D-optimal: maximise ``ln det(J + h hᵀ/σ²)``, i.e. ``hᵀ P h``).

    ``h = n̂/r`` is the bearing's gradient at the predicted relative position (``n̂`` normal to
    the line of sight), ``P`` the estimate's position covariance from the observation. Candidate
    actions form a grid; positions closer than ``safety · min_range`` are ruled out. With
    ``K`` platforms the choice is sequential greedy on the joint ``ln det`` (submodular: within
    ``1 − 1/e`` of the best joint choice): platform ``k`` maximises ``hᵀ P h`` with ``P`` already
    updated by the bearings chosen for platforms ``1 … k − 1``.
    """

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

    def choose(self, views: FloatArray) -> FloatArray:
        """Every platform's action ``(N, K, 2)``: the env's flight of every candidate from the
        platform's frame, the estimate moved on by its velocity, the gain ``hᵀ P h`` at the new
        relative position, platform by platform (compiled:
        :func:`sensorgym.envs.bearings_maneuver.kernels.greedy_kernel`)."""
        p, w = self.params, self.params.world
        cand = self.candidates()
        command = np.ascontiguousarray(cand * [w.max_turn_rate, w.max_speed_change])
        # P from platform 1's log standard deviations (obs 7, 8) and correlation (obs 9)
        sd = np.exp(views[:, 0, 7:9]) * p.range_scale
        choice = np.empty(views.shape[:2], dtype=np.int64)
        greedy_kernel(
            p.kernel_constants,
            np.ascontiguousarray(views, dtype=np.float64),
            np.ascontiguousarray(sd),
            relative_headings(p, views),
            command,
            float(self.safety * p.min_range),
            choice,
        )
        return cand[choice]


def _joint_plans(
    rule: TruthLookahead | EstimateLookahead,
    pos: FloatArray,
    heading: FloatArray,
    speed: FloatArray,
    target: FloatArray,
    L: FloatArray,
) -> FloatArray:
    """Every platform's first action ``(B, K, 2)`` of the sequential receding-horizon plans of
    ``rule`` (its candidates, horizon, safety) from platforms ``pos (B, K, 2)``, ``heading``,
    ``speed`` ``(B, K)``, target ``(B, 4)`` and the bound's square root ``L (B, 4, 4)``, all in
    one frame (compiled: :func:`sensorgym.envs.bearings_maneuver.kernels.joint_plan_kernel`)."""
    p, w = rule.params, rule.params.world
    cand = rule.candidates()
    command = np.ascontiguousarray(cand * [w.max_turn_rate, w.max_speed_change])
    B, K = heading.shape
    choice = np.empty((B, K), dtype=np.int64)
    arrays = (
        p.kernel_constants,
        *(np.ascontiguousarray(a, dtype=np.float64) for a in (pos, heading, speed, target, L)),
        command,
        int(rule.horizon),
        float(rule.safety * p.min_range),
        choice,
    )
    run_rows(B, lambda lo, hi: joint_plan_kernel(lo, hi, *arrays))
    return cand[choice]


def _check_plan_settings(horizon: int, turns: int, speeds: tuple[float, ...]) -> None:
    if horizon < 1 or turns < 1 or not speeds:
        raise ValueError("horizon, turns and speeds: need at least one each")


@dataclass(frozen=True)
class TruthLookahead(MemorylessRule):
    """Hold each candidate action for ``horizon`` steps on the true, noise-free trajectory and
    take the first action of the plan with the smallest bound (receding horizon).

    ``state_fn`` returns the simulator's current :class:`ManeuverState` (batch = the
    observations' batch), e.g. ``lambda: vec_env.get_attr("simulator_state")[0]`` for an SB3
    view of the native vector env. The target's future is its mean path ``F x`` (exact for
    ``q̃ = 0``); plans that come within ``safety · min_range`` of it are ruled out. With ``K``
    platforms the plans are chosen platform by platform (module docstring).
    """

    state_fn: Callable[[], ManeuverState]
    """The simulator's current state (the truth this planner is given)."""
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
        _check_plan_settings(self.horizon, self.turns, self.speeds)

    @property
    def obs_dim(self) -> int:
        """The joint view's length, ``K · params.obs_dim``."""
        return self.params.platforms * self.params.obs_dim

    def candidates(self) -> NDArray[np.float64]:
        """Candidate actions ``(C, 2)``."""
        turn, speed = np.meshgrid(np.linspace(-1.0, 1.0, self.turns), self.speeds)
        return np.stack([turn.ravel(), speed.ravel()], -1)

    def plan_bounds(self, s: ManeuverState) -> NDArray[np.float64]:
        """Bound after ``horizon`` steps of each candidate for platform 1 alone, ``(B, C)``
        (``inf`` if too close): the env's own flight and bound recursion, compiled
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
        """Actions ``(N, 2K)`` for joint views ``(N, K · obs_dim)``: the plans on the truth."""
        s = self.state_fn()
        if s.batch_size != obs.shape[0]:
            raise ValueError(
                f"state_fn: simulator batch {s.batch_size} != {obs.shape[0]} observations"
            )
        if s.heading.shape[1] != self.params.platforms:
            raise ValueError(
                f"state_fn: {s.heading.shape[1]} platforms, params say {self.params.platforms}"
            )
        plans = _joint_plans(
            self, s.platform_position, s.heading, s.speed, s.target, s.bound_factor
        )
        return plans.reshape(obs.shape[0], -1)


@dataclass(frozen=True)
class EstimateLookahead(ManeuverRule):
    """:class:`TruthLookahead`'s receding-horizon planner run on the tracker's estimate instead
    of the truth (certainty equivalence): hold each candidate action for ``horizon`` steps while the
    *estimated* target moves on at its estimated velocity, run the bound recursion from the
    estimate's covariance, and take the first action of the plan with the smallest bound.

    Everything comes from the observation, in platform 1's frame (platform 1 at the origin,
    heading 0 = ahead): the estimated relative position and velocity (obs 3–6), the position
    covariance (obs 7–9) and the velocity covariance (obs 10–12); the observation holds no
    position–velocity cross-covariance, so the plan's bound starts block-diagonal. The other
    platforms' positions (obs 13…), headings (:func:`relative_headings`) and speeds (their
    obs 2) place them in that frame. With ``horizon=1`` this is the one-step greedy on the
    bound; ``horizon=2`` is the two-step lookahead a reviewer asks for. Plans predicted within
    ``safety · min_range`` of the estimate are ruled out.
    """

    turns: int = 7
    """Candidate turn actions, evenly spaced in ``[−1, 1]``."""
    speeds: tuple[float, ...] = (-1.0, 0.0, 1.0)
    """Candidate speed actions."""
    horizon: int = 8
    """Steps each candidate is held for (8 scored best of 1, 2, 3, 5, 8, 12, 16 on tuning
    scenarios, seed 500)."""
    safety: float = 2.0
    """Plans predicted within ``safety · min_range`` of the estimate are not taken."""

    def __post_init__(self) -> None:
        _check_plan_settings(self.horizon, self.turns, self.speeds)

    def candidates(self) -> NDArray[np.float64]:
        """Candidate actions ``(C, 2)``."""
        turn, speed = np.meshgrid(np.linspace(-1.0, 1.0, self.turns), self.speeds)
        return np.stack([turn.ravel(), speed.ravel()], -1)

    def choose(self, views: FloatArray) -> FloatArray:
        """Every platform's action ``(N, K, 2)``: :class:`TruthLookahead`'s compiled plans from
        the estimate, in platform 1's frame (:func:`estimate_frame`)."""
        return _joint_plans(self, *estimate_frame(self.params, views))
