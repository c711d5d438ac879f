"""The planner on the tracker's estimate that plans to the episode's end, with hysteresis: the
``plan-horizon`` rule of ``sensorgym/StereoPointing-v0``.

:class:`~sensorgym.agents.stereo_pointing.PlanEstimate` holds the assignment whose planned
return over the next 100 steps is best, re-planned every step. Two things it ignores cost it
return: near the episode's end it still weighs steps that will never come (a re-pairing that
pays off only after the time limit looks good), and between near-equal assignments it slews
receivers away from a drone they already watch (a receiver in transit adds nothing). This rule
counts the steps of its episode and plans over ``min(horizon, steps left)``, and adds
``keep_bonus`` per receiver left on a drone it is aimed at.

The observation carries no clock: the rule keeps its own step count as its ``state`` (an int
array per env, restarted by ``episode_start``), as SB3 does for recurrent policies, and reads
the episode length from the registration (``max_episode_steps``, :data:`EPISODE_STEPS`). Its
decisions are the argmax of the :class:`~sensorgym.train.env_wrappers.stereo_pointing.PlanFeatures`
evidence at that horizon plus the hysteresis count (the wrapper counts the steps the same way).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sensorgym.agents.assignment_solver import best_of, check_solver, exhaustive
from sensorgym.agents.protocol import as_batch
from sensorgym.agents.stereo_pointing import (
    EPISODE_STEPS,
    PLAN_ASSIGNMENTS,
    PlanGeometry,
    RuleView,
    acquired_values,
    acquisition_probability,
    aimed_drone,
    all_assignments,
    geometry_values,
    hysteresis_bonus,
    plan_geometry,
    plan_objective,
    rule_view,
    search_starts,
)
from sensorgym.agents.stereo_pointing_search import EpipolarSearch, search_aims
from sensorgym.agents.stereo_pointing_sharing import Sharing, shared_aims
from sensorgym.envs.stereo_pointing.simulation import PointingParams, slew_actions


@dataclass(frozen=True)
class PlanHorizon:
    """Hold the assignment whose planned return over the next ``min(horizon, steps left)``
    steps (:func:`~sensorgym.agents.stereo_pointing.plan_values` on the tracker's estimate),
    plus ``keep_bonus`` per receiver it leaves on a drone it is aimed at, is best; re-planned
    every step. ``horizon`` and ``keep_bonus`` were chosen on tuning seeds 500 and 600 (see
    ``research/stereo_pointing/README.md``)."""

    params: PointingParams = field(default_factory=PointingParams)
    """Env settings (receiver layout, noise, slew limit, reward, observation layout)."""
    horizon: int = 100
    """Longest planning horizon, steps (plan-estimate's)."""
    keep_bonus: float = 0.3
    """Planned-return bonus per receiver left on a drone it is aimed at (hysteresis)."""
    episode_steps: int = EPISODE_STEPS
    """Episode length, steps (the registration's ``max_episode_steps``)."""
    stride: int = 3
    """Planning grid: every ``stride``-th future step is scored."""
    solver: str = "auto"
    """How the best assignment is searched: ``"auto"``, ``"exhaustive"`` or ``"greedy"``
    (:mod:`sensorgym.agents.assignment_solver`; auto is exhaustive up to
    :data:`~sensorgym.agents.stereo_pointing.PLAN_ASSIGNMENTS` assignments)."""
    acquisition: bool = False
    """Weigh each drone's planned return by the chance that a pair of the receivers sent to it
    finds it on the tracker's prediction
    (:func:`~sensorgym.agents.stereo_pointing.acquired_values`; the ``plan-acquire`` rule).
    Only the exhaustive search weighs it: beyond
    :data:`~sensorgym.agents.stereo_pointing.PLAN_ASSIGNMENTS` assignments the polynomial search
    plans as without it."""
    sharing: Sharing | None = None
    """Aim a receiver between its drone and another one that fits in its field of view
    (:mod:`sensorgym.agents.stereo_pointing_sharing`; the ``plan-acquire-share`` rule);
    ``None``: straight at its drone's prediction."""
    search: EpipolarSearch | None = None
    """Send the receivers of a lost drone that one receiver sees along that receiver's line of
    sight (:mod:`sensorgym.agents.stereo_pointing_search`; the ``plan-search`` rule); ``None``:
    at the prediction."""
    cue_steps: int = 0
    """On the episode's first ``cue_steps`` steps every receiver aimed at a drone stays on it
    (the cue's hand-over; a receiver aimed at none follows the plan), so that each track gets
    its first fix before the plan re-pairs (the ``plan-fix-first`` rule, 1). The plan's
    acquisition chance is that of the track it sees: on the cue (``σ̂`` ≈ 9 m) a re-pairing
    sends receivers to predictions that are metres off and leaves both drones without a fix,
    while one step on the cue brings the tracks to centimetres."""

    def __post_init__(self) -> None:
        check_solver(self.solver)
        for name in ("horizon", "episode_steps", "stride"):
            value = getattr(self, name)
            if not isinstance(value, int | np.integer) or value < 1:
                raise ValueError(f"{name}: must be an integer >= 1, got {value!r}")
        check_cue_steps(self.cue_steps)
        if not (np.isfinite(self.keep_bonus) and self.keep_bonus >= 0.0):
            raise ValueError(f"keep_bonus: must be finite and >= 0, got {self.keep_bonus!r}")

    @property
    def obs_dim(self) -> int:
        return self.params.obs_dim

    def planning_horizon(self, t: NDArray[Any]) -> NDArray[np.float64]:
        """Steps planned over ``(N,)`` at episode steps ``t (N,)``: ``min(horizon, steps
        left)``, at least 1 (the last step still plans over itself)."""
        left = self.episode_steps - np.asarray(t, dtype=np.int64)
        return np.clip(left, 1, self.horizon).astype(np.float64)

    def geometry(self, view: RuleView, t: NDArray[Any]) -> PlanGeometry:
        """The plan's :class:`~sensorgym.agents.stereo_pointing.PlanGeometry` at episode steps
        ``t (N,)``."""
        return plan_geometry(
            self.params,
            view.azimuth,
            view.elevation,
            view.position,
            view.velocity,
            self.planning_horizon(t),
            self.stride,
        )

    def values(self, view: RuleView, geometry: PlanGeometry) -> NDArray[np.float64]:
        """The exhaustive search's value ``(N, C)`` of every candidate of
        :func:`~sensorgym.agents.stereo_pointing.all_assignments`: its planned return (with
        ``acquisition``, weighted by the chance of a fix) plus the hysteresis bonus."""
        p = self.params
        if self.acquisition:
            values = acquired_values(p, geometry, acquisition_probability(p, view))
        else:
            values = geometry_values(p, geometry)
        return values + hysteresis_bonus(view, all_assignments(p), self.keep_bonus)

    def choose(self, view: RuleView, t: NDArray[Any]) -> NDArray[np.int64]:
        """Drone index per receiver ``(N, n)`` at episode steps ``t (N,)``."""
        p = self.params
        geometry = self.geometry(view, t)
        if not exhaustive(self.solver, p.n_receivers, p.n_drones, PLAN_ASSIGNMENTS):
            return best_of(
                plan_objective(p, geometry), search_starts(p, view), self.keep_bonus * view.aimed
            )
        return all_assignments(p)[np.argmax(self.values(view, geometry), axis=-1)]

    def assign(self, observation: NDArray[Any], t: NDArray[Any] | int = 0) -> NDArray[np.int64]:
        """The drone each receiver is sent to, ``(n,)`` or ``(n_envs, n)``, at episode step(s)
        ``t`` (default: the episode's first)."""
        obs, single = as_batch(observation, self.obs_dim)
        steps = np.broadcast_to(np.asarray(t, dtype=np.int64), (obs.shape[0],))
        choice = self.choose(rule_view(self.params, obs), steps)
        return choice[0] if single else choice

    def steps(
        self, n: int, state: NDArray[Any] | None, episode_start: NDArray[Any] | None
    ) -> NDArray[np.int64]:
        """The episode step ``(n,)`` of each env: ``state`` (0 without one), 0 where
        ``episode_start``."""
        t = np.zeros(n, dtype=np.int64) if state is None else np.asarray(state, dtype=np.int64)
        if t.shape != (n,):
            raise ValueError(f"state: expected the step counts of {n} envs, got shape {t.shape}")
        if episode_start is not None:
            t = np.where(np.asarray(episode_start, dtype=bool).reshape(n), 0, t)
        return t

    def predict(
        self,
        observation: NDArray[Any],
        state: NDArray[np.int64] | None = None,
        episode_start: NDArray[np.bool_] | None = None,
        deterministic: bool = True,
    ) -> tuple[NDArray[np.float32], NDArray[np.int64]]:
        obs, single = as_batch(observation, self.obs_dim)
        t = self.steps(obs.shape[0], state, episode_start)
        view = rule_view(self.params, obs)
        target = self.choose(view, t)
        points, index = plan_aims(
            self.params, view, target, t, self.cue_steps, self.sharing, self.search
        )
        action = slew_actions(self.params, view.azimuth, view.elevation, points, index)
        action = np.asarray(action, dtype=np.float32)
        return (action[0] if single else action), t + 1


def plan_aims(
    params: PointingParams,
    view: RuleView,
    target: NDArray[np.int64],
    t: NDArray[np.int64],
    cue_steps: int = 0,
    sharing: Sharing | None = None,
    search: EpipolarSearch | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Aim points ``(N, P, 3)`` and each receiver's point index ``(N, n)`` for
    :func:`~sensorgym.envs.stereo_pointing.simulation.slew_actions`, from the drone each
    receiver is sent to ``target (N, n)`` at episode steps ``t (N,)``: the :func:`cue_hold` on
    the first ``cue_steps`` steps; with ``sharing`` a receiver aims between its drone and
    another one (:func:`~sensorgym.agents.stereo_pointing_sharing.shared_aims`); with
    ``search`` the receivers of a lost drone search along its one sighting
    (:func:`~sensorgym.agents.stereo_pointing_search.search_aims`, appended as points ``P − n``
    onward). The one aiming of the ``plan-*`` rules and the ``pointing-plan`` wrapper."""
    target = cue_hold(view.aimed, target, t, cue_steps)
    points, index = view.position, target
    if sharing is not None:
        points, index = shared_aims(params, view, target, sharing)
    if search is not None:
        found, searching = search_aims(params, view, target, t, search)
        n_points = points.shape[1]
        points = np.concatenate([points, found], axis=1)
        index = np.where(searching, n_points + np.arange(params.n_receivers)[None], index)
    return points, index


def check_cue_steps(cue_steps: Any) -> int:
    """``cue_steps`` as an int; ``ValueError`` unless it is an integer >= 0 (not a bool)."""
    if isinstance(cue_steps, bool) or not isinstance(cue_steps, int | np.integer) or cue_steps < 0:
        raise ValueError(f"cue_steps: must be an integer >= 0, got {cue_steps!r}")
    return int(cue_steps)


def cue_hold(
    aimed: NDArray[Any], target: NDArray[Any], t: NDArray[Any], cue_steps: int
) -> NDArray[np.int64]:
    """The drone per receiver ``(N, n)``: ``target``'s, except that on an episode's first
    ``cue_steps`` steps (``t (N,) < cue_steps``) a receiver aimed at a drone
    (:func:`~sensorgym.agents.stereo_pointing.aimed_drone` of :attr:`RuleView.aimed`
    ``(N, n, m)``) stays on it (:attr:`PlanHorizon.cue_steps`; the ``pointing-plan`` wrapper's
    ``cue_steps`` holds the same)."""
    target = np.asarray(target, dtype=np.int64)
    if not cue_steps:
        return target
    held = aimed_drone(aimed)
    early = np.asarray(t, dtype=np.int64).reshape(-1) < cue_steps
    return np.where(early[:, None] & (held >= 0), held, target)
