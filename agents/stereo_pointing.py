"""Heuristic pointing rules for ``sensorgym/StereoPointing-v0`` (theory §10.1 OC-1, §10.2 OC-2).

Each rule reads only the observation (own gimbal angles and the tracker's predictions, see
:func:`sensorgym.envs.stereo_pointing.simulation.observe`) plus the fixed receiver layout from the
env's params, and implements SB3's ``predict``, so
``stable_baselines3.common.evaluation.evaluate_policy`` scores it like a trained model. The
assignment rules enumerate every map of receivers to drones (``m^n`` of them) and slew each
receiver straight at the predicted position of its drone (the env's one slew controller,
:func:`~sensorgym.envs.stereo_pointing.simulation.slew_actions`, which the assignment action
:class:`~sensorgym.train.env_wrappers.stereo_pointing.AssignmentAction` uses too); the scores of all candidates are the
compiled :func:`~sensorgym.trackers.stereo.kernels.assignment_orthogonality_batch` and
:func:`~sensorgym.trackers.stereo.kernels.assignment_log_det_batch`, the lines of sight and
pointing offsets the env's compiled ones.

Every assignment rule has a ``solver`` field (:mod:`sensorgym.agents.assignment_solver`):
``"auto"`` searches all ``m^n`` assignments up to ``MAX_ASSIGNMENTS`` (4096, e.g. 4 receivers ×
8 drones or 6 × 4) — the decisions are those of the exhaustive search at every such size — and
beyond that (16 receivers × 10 drones) starts from the sequential greedy on the information
gain over the tracker's prediction (:func:`information_seed`; once from the current pointing,
once from nothing) and re-assigns one receiver at a time while the rule's own objective rises,
keeping the better of the two ends, the same objective through
:func:`~sensorgym.trackers.stereo.kernels.assignment_marginals_batch`; ``"greedy"`` takes that
polynomial path at any size, ``"exhaustive"`` the full search (refused above 4096). The
planners (``plan-estimate``, ``plan-horizon``, ``truth-plan``) score each assignment over the
whole plan, which is costly per assignment, so their ``"auto"`` is exhaustive only up to
:data:`PLAN_ASSIGNMENTS` (the registered 4 × 2's 16 assignments): at 4 × 4 and 6 × 3 the full
search takes far longer than the polynomial one (decision times:
``benchmarks/results/scaling.json``).
"""

from __future__ import annotations

from abc import abstractmethod
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sensorgym.agents.assignment_solver import (
    SeparableObjective,
    assignments,
    best_of,
    check_solver,
    exhaustive,
    sequential_greedy,
)
from sensorgym.agents.protocol import MemorylessRule, as_batch
from sensorgym.envs.stereo_pointing.simulation import (
    PointingParams,
    PointingState,
    boresights,
    lines_of_sight,
    observed_pointing,
    pointing_offsets,
    slew_actions,
    split_observation,
)
from sensorgym.trackers.stereo import kernels
from sensorgym.trackers.stereo.information import (
    MIN_RANGE,
    log_ratio_reward,
    observable,
    position_information,
    position_sigma,
)

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class RuleView:
    """What a rule knows at one step: decoded observation and the geometry it implies."""

    azimuth: FloatArray
    """(N, n) boresight azimuths, rad."""
    elevation: FloatArray
    """(N, n) boresight elevations, rad."""
    seen: FloatArray
    """(N, n, m) 1.0 where receiver k saw drone j on the last step."""
    aimed: FloatArray
    """(N, n, m) 1.0 where receiver k saw drone j on the last step or has its predicted position
    inside its field of view (on the cue at the start, before anything was seen)."""
    position: FloatArray
    """(N, m, 3) predicted drone positions, m."""
    sigma: FloatArray
    """(N, m) predicted position RMS, m."""
    velocity: FloatArray
    """(N, m, 3) estimated drone velocities, m/s."""
    los: FloatArray
    """(N, n, m, 3) unit lines of sight from the receivers to the predicted positions."""
    ranges: FloatArray
    """(N, n, m) ranges to the predicted positions, m (inf: predicted on the receiver)."""
    velocity_sigma: FloatArray | None = None
    """(N, m) velocity RMS of the tracks, m/s (``None``: not decoded)."""


def rule_view(params: PointingParams, obs: FloatArray) -> RuleView:
    """Decode ``obs``. A drone predicted on a receiver (the zero line of sight, which that
    receiver never sees) is at infinite range from it: it adds no information there and is
    never the nearest."""
    _, pairs, drones = split_observation(params, obs)
    azimuth, elevation, position = observed_pointing(params, obs)
    los, r = lines_of_sight(params, position)
    inside = np.einsum("nkjc,nkc->nkj", los, boresights(azimuth, elevation)) >= np.cos(params.fov)
    return RuleView(
        azimuth=azimuth,
        elevation=elevation,
        seen=pairs[..., 2],
        aimed=np.maximum(pairs[..., 2], inside),
        position=position,
        sigma=np.exp(drones[..., 3]) * params.sigma_ref,
        velocity=drones[..., 4:7] * params.velocity_scale,
        los=los,
        ranges=np.where(r > MIN_RANGE, np.maximum(r, MIN_RANGE), np.inf),
        velocity_sigma=np.exp(drones[..., 7]) * params.sigma_ref,
    )


def all_assignments(params: PointingParams) -> NDArray[np.int64]:
    """Every map of the ``n`` receivers to the ``m`` drones, ``(m^n, n)``."""
    return assignments(params.n_receivers, params.n_drones)


def _weights(sigma_ang: float, ranges: FloatArray) -> FloatArray:
    """Information weights ``1/(σ r)²`` of lines of sight at ``ranges``, ranges floored at
    ``MIN_RANGE`` (as :func:`~sensorgym.trackers.stereo.kernels.position_information`);
    ``σ = 0`` counts as 1e-9 rad (the exhaustive scores' floor)."""
    sr = max(sigma_ang, 1e-9) * np.maximum(ranges, MIN_RANGE)
    return 1.0 / (sr * sr)


def _one_step(
    kind: int, los: FloatArray, w: FloatArray, prior: FloatArray, consts: tuple[float, ...]
) -> SeparableObjective:
    """A one-step objective of lines of sight ``los (N, n, m, 3)`` with weights ``w (N, n, m)``
    and a prior ``(N, m)``, every receiver counted."""
    N, n, m = w.shape
    return SeparableObjective(
        kind=kind,
        u=np.ascontiguousarray(los[:, None]),
        w=np.ascontiguousarray(w[:, None]),
        ready=np.ones((N, 1, n, m), dtype=bool),
        prior=np.ascontiguousarray(prior, dtype=np.float64),
        weight=np.ones((N, 1)),
        consts=np.array(consts, dtype=np.float64),
    )


def information_seed(
    params: PointingParams,
    los: FloatArray,
    ranges: FloatArray,
    sigma: FloatArray,
    aimed: FloatArray | None = None,
) -> NDArray[np.int64]:
    """The polynomial solvers' start ``(N, n)``: each receiver aimed at a drone (``aimed
    (N, n, m)``, :attr:`RuleView.aimed`; the first such drone) stays on it — the search starts
    from the current pointing, so that re-planning every step does not jump between equally
    good assignments — and the others follow the sequential greedy
    (:func:`~sensorgym.agents.assignment_solver.sequential_greedy`) on the information gain
    ``Σ_j ln det(I/σ_j² + I_j) − ln det(I/σ_j²)`` of the receivers each drone gets over the
    tracker's prediction (position RMS ``sigma (N, m)``, floored at 1e-6 m and capped at 1e6
    m), ``I_j`` their position information at lines of sight ``los (N, n, m, 3)`` and
    ``ranges (N, n, m)`` (a line of sight within ``MIN_RANGE`` adds nothing). The gain is
    monotone and submodular: from nothing aimed, the greedy comes within half of its best
    assignment; it spreads the receivers over the drones and favours near-orthogonal
    crossings."""
    w = np.where(ranges > MIN_RANGE, _weights(params.sigma_ang, ranges), 0.0)
    prior = 1.0 / np.clip(sigma, 1e-6, 1e6) ** 2
    start = None if aimed is None else aimed_drone(aimed)
    return sequential_greedy(_one_step(kernels.GAIN, los, w, prior, ()), start=start)


def aimed_drone(aimed: ArrayLike) -> NDArray[np.int64]:
    """The drone each receiver is aimed at ``(N, n)`` from :attr:`RuleView.aimed` ``(N, n, m)``:
    the first drone it saw or has inside its field of view, ``-1`` for none (in transit)."""
    aimed = np.asarray(aimed) > 0.0
    return np.where(aimed.any(axis=-1), np.argmax(aimed, axis=-1), -1)


def search_starts(params: PointingParams, view: RuleView) -> list[NDArray[np.int64]]:
    """The polynomial search's two starts at the tracker's predictions: the
    :func:`information_seed` from the current pointing, and from nothing (a coordinate-wise
    ascent cannot exchange two receivers' drones: from the current pairs alone it would
    never re-pair)."""
    aimed = view.aimed > 0.0
    return [information_seed(params, view.los, view.ranges, view.sigma, a) for a in (aimed, None)]


def hysteresis_bonus(view: RuleView, cand: NDArray[np.int64], bonus: float) -> FloatArray:
    """``bonus`` times the number of receivers each candidate leaves on a drone they are aimed
    at (:attr:`RuleView.aimed`) ``(N, C)``: hysteresis, so that near-ties do not make receivers
    slew back and forth. Counting the aim and not only the last step's sightings matters at the
    start: nothing has been seen yet, and a near-tie would otherwise send receivers off the cue."""
    n = cand.shape[1]
    kept = view.aimed[:, np.arange(n)[None, :], cand]  # (N, C, n)
    return bonus * kept.sum(axis=-1)


class _AssignAndSlew(MemorylessRule):
    """Rules that pick a drone per receiver (``choose``) and slew to it."""

    params: PointingParams

    @abstractmethod
    def choose(self, view: RuleView) -> NDArray[np.int64]:
        """Drone index per receiver ``(N, n)``."""

    def assign(self, observation: NDArray[Any]) -> NDArray[np.int64]:
        """The drone each receiver is sent to, ``(n,)`` or ``(n_envs, n)``."""
        obs, single = as_batch(observation, self.params.obs_dim)
        choice = self.choose(rule_view(self.params, obs))
        return choice[0] if single else choice

    def act(self, obs: FloatArray) -> FloatArray:
        """Actions ``(N, action size)`` for observations ``(N, obs_dim)``."""
        view = rule_view(self.params, obs)
        return slew_actions(
            self.params, view.azimuth, view.elevation, view.position, self.choose(view)
        )


@dataclass(frozen=True)
class HoldStill(MemorylessRule):
    """Never slew: the receivers keep their starting directions (the baseline to beat)."""

    params: PointingParams = field(default_factory=PointingParams)
    """Env settings (observation layout, action size)."""

    def act(self, obs: FloatArray) -> FloatArray:
        """Actions ``(N, action size)`` for observations ``(N, obs_dim)``."""
        return np.zeros((obs.shape[0], 2 * self.params.n_receivers))


@dataclass(frozen=True)
class HoldCue(_AssignAndSlew):
    """Keep the starting cue assignment: receiver ``k`` follows drone ``k mod m`` (where the
    cued start points it) for the whole episode, slewing onto the tracker's prediction. The
    constant assignment is the baseline an adaptive assignment has to beat."""

    params: PointingParams = field(default_factory=PointingParams)
    """Env settings (receiver layout, slew limit, observation layout)."""

    def choose(self, view: RuleView) -> NDArray[np.int64]:
        """Drone index per receiver ``(N, n)``: ``k mod m``."""
        n, m = self.params.n_receivers, self.params.n_drones
        return np.broadcast_to(np.arange(n) % m, (view.azimuth.shape[0], n)).copy()


@dataclass(frozen=True)
class TrackNearest(_AssignAndSlew):
    """Each receiver slews to the drone whose predicted position is nearest to it (the naive
    rule OC-1 improves on: nearby receivers end up on one drone with near-parallel sight lines)."""

    params: PointingParams = field(default_factory=PointingParams)
    """Env settings (receiver layout, slew limit, observation layout)."""

    def choose(self, view: RuleView) -> NDArray[np.int64]:
        """Drone index per receiver ``(N, n)``."""
        return np.argmin(view.ranges, axis=-1)


@dataclass(frozen=True)
class OrthogonalPairs(_AssignAndSlew):
    """Assign receivers to drones so that each drone's lines of sight are closest to orthogonal
    (theory §10.1 OC-1): minimise ``Σ_j ln score_j`` with ``score_j = σ / √(Σ_{k∈S_j} sin²γ_k)``,
    ``γ_k`` the angle between receiver ``k``'s line of sight and the reference receiver's
    (the member of ``S_j`` that gives the best score); fewer than two receivers: infinite.

    The papers' score ignores ranges (their i.i.d. conjugation-error model); it ranks the
    geometry of the crossing only.
    """

    params: PointingParams = field(default_factory=PointingParams)
    """Env settings (receiver layout, slew limit, observation layout)."""
    keep_bonus: float = 0.3
    """Objective bonus per receiver left on a drone it is aimed at (hysteresis against flapping
    and against leaving the cue for a near-tie; tuned on training seeds 5 and 7)."""
    solver: str = "auto"
    """How the best assignment is searched: ``"auto"``, ``"exhaustive"`` or ``"greedy"``
    (:mod:`sensorgym.agents.assignment_solver`; auto is exhaustive up to 4096 assignments)."""

    def __post_init__(self) -> None:
        check_solver(self.solver)

    def choose(self, view: RuleView) -> NDArray[np.int64]:
        """Drone index per receiver ``(N, n)``."""
        p = self.params
        if not exhaustive(self.solver, p.n_receivers, p.n_drones):
            N, n, m = view.ranges.shape
            objective = _one_step(
                kernels.ORTHOGONALITY, view.los, np.ones((N, n, m)), np.zeros((N, m)), ()
            )
            return best_of(objective, search_starts(p, view), self.keep_bonus * view.aimed)
        cand = all_assignments(p)  # (C, n)
        objective = np.empty((view.los.shape[0], cand.shape[0]))
        # Σ_j ½ ln max_{k∈S_j} Σ_{l∈S_j} sin²γ_kl, compiled
        kernels.assignment_orthogonality_batch(view.los, cand, objective)
        objective += hysteresis_bonus(view, cand, self.keep_bonus)
        return cand[np.argmax(objective, axis=-1)]


@dataclass(frozen=True)
class GreedyPointing(_AssignAndSlew):
    """Choose the assignment that maximises ``Σ_j ln det I_j`` of the position information the
    assigned receivers would give at the predicted positions (one-step D-optimal sensor
    selection, theory §10.1–10.2 OC-1/OC-2): ``I_j = Σ_{k∈S_j} (I − u_k u_kᵀ)/(σ_ang² r_k²)``.

    A drone given fewer than two receivers gets no fix (its ``I_j`` is singular, and the env's
    reward for it is ``−R``); it scores ``−no_fix_cost`` instead of ``−∞``, so that when there
    are too few receivers for all drones the rule still fixes as many as it can. Unlike
    :class:`OrthogonalPairs` the score counts ranges (the angle-noise model of the reward).
    """

    params: PointingParams = field(default_factory=PointingParams)
    """Env settings (receiver layout, noise, slew limit, observation layout)."""
    keep_bonus: float = 3.0
    """Objective bonus per receiver left on a drone it is aimed at (hysteresis against flapping
    and against leaving the cue for a near-tie; tuned on training seeds 5 and 7)."""
    no_fix_cost: float = 1e3
    """Score of a drone left without a pair of receivers (ln det units)."""
    solver: str = "auto"
    """How the best assignment is searched: ``"auto"``, ``"exhaustive"`` or ``"greedy"``
    (:mod:`sensorgym.agents.assignment_solver`; auto is exhaustive up to 4096 assignments)."""

    def __post_init__(self) -> None:
        check_solver(self.solver)

    def choose(self, view: RuleView) -> NDArray[np.int64]:
        """Drone index per receiver ``(N, n)``."""
        p = self.params
        if not exhaustive(self.solver, p.n_receivers, p.n_drones):
            N, _, m = view.ranges.shape
            w = _weights(p.sigma_ang, view.ranges)
            consts = (float(self.no_fix_cost),)
            objective = _one_step(kernels.LOG_DET, view.los, w, np.zeros((N, m)), consts)
            return best_of(objective, search_starts(p, view), self.keep_bonus * view.aimed)
        cand = all_assignments(self.params)
        objective = np.empty((view.los.shape[0], cand.shape[0]))
        # Σ_j ln det I_j of the receivers each candidate assigns to drone j, compiled
        kernels.assignment_log_det_batch(
            view.los,
            view.ranges,
            max(self.params.sigma_ang, 1e-9),
            cand,
            float(self.no_fix_cost),
            objective,
        )
        objective += hysteresis_bonus(view, cand, self.keep_bonus)
        return cand[np.argmax(objective, axis=-1)]


#: episode length of the registered env (``max_episode_steps``): :class:`TruthPlan` plans to its
#: end
EPISODE_STEPS = 150


#: the planners' ``"auto"`` searches every assignment up to this many (module docstring)
PLAN_ASSIGNMENTS = 32


class TruthPlan(MemorylessRule):
    """Plan on the truth (reads ``simulator_state``; a truth-informed planner, neither a
    fieldable rule nor a bound on the return — ``plan-search`` beats it): at every step, for
    every assignment of receivers to drones held from now to the episode's end, sum the env's
    reward over the remaining steps of the true straight-line flights — each receiver
    counted once its gimbal, slewing at full rate, has reached its drone — and take the best
    (``solver``: all assignments, or the polynomial search from :func:`information_seed` at
    the true positions with the tracker's covariance).

    The plan assumes that a receiver sent to a drone sees it (the tracker keeps up); the act is
    the assignment rules' slew onto the tracker's prediction. Planning over constant assignments
    only, it re-plans every step, so it may switch when the geometry turns."""

    def __init__(
        self,
        state_fn: Callable[[], Any],
        params: PointingParams,
        episode_steps: int = EPISODE_STEPS,
        stride: int = 3,
        solver: str = "auto",
    ):
        check_solver(solver)
        self.state_fn = state_fn
        self.params = params
        self.episode_steps = int(episode_steps)
        """Episode length in steps (the registration's ``max_episode_steps``)."""
        self.stride = int(stride)
        """Planning grid: every ``stride``-th future step is scored (weighted by ``stride``)."""
        self.solver = solver
        """``"auto"``, ``"exhaustive"`` or ``"greedy"`` (:mod:`..assignment_solver`)."""

    def assign(self, observation: NDArray[Any]) -> NDArray[np.int64]:
        """The drone each receiver is sent to, ``(n,)`` or ``(n_envs, n)``."""
        obs, single = as_batch(observation, self.params.obs_dim)
        choice = self.choose(self.state_fn(), obs.shape[0], rule_view(self.params, obs))
        return choice[0] if single else choice

    def act(self, obs: FloatArray) -> FloatArray:
        """Actions ``(N, action size)`` for observations ``(N, obs_dim)``."""
        view = rule_view(self.params, obs)
        target = self.choose(self.state_fn(), obs.shape[0], view)
        return slew_actions(self.params, view.azimuth, view.elevation, view.position, target)

    def choose(
        self, state: PointingState, N: int, view: RuleView | None = None
    ) -> NDArray[np.int64]:
        """The best held assignment ``(N, n)`` of every scenario of ``state`` (the polynomial
        search starts from the pointing of ``view``, if given)."""
        if state.batch_size != N:
            raise ValueError(f"observation: {N} envs, but the simulator holds {state.batch_size}")
        p = self.params
        if exhaustive(self.solver, p.n_receivers, p.n_drones, PLAN_ASSIGNMENTS):
            return all_assignments(p)[np.argmax(self.values(state), axis=-1)]
        los, r = lines_of_sight(p, state.drone_position)
        sigma = state.track.position_sigma
        starts = [information_seed(p, los, r, sigma, None if view is None else view.aimed > 0.0)]
        if view is not None:  # and from nothing (see search_starts)
            starts.append(information_seed(p, los, r, sigma))
        return best_of(plan_objective(p, self.geometry(state)), starts)

    def geometry(self, state: PointingState) -> PlanGeometry:
        """The plan's :class:`PlanGeometry` from ``state`` (the truth) to the episode's end."""
        left = self.episode_steps - np.rint(state.t / self.params.dt)
        return plan_geometry(
            self.params,
            state.azimuth,
            state.elevation,
            state.drone_position,
            state.drone_velocity,
            left,
            self.stride,
        )

    def values(self, state: PointingState) -> FloatArray:
        """Planned return ``(B, C)`` of every candidate of :func:`all_assignments` from ``state``."""
        return geometry_values(self.params, self.geometry(state))


@dataclass(frozen=True)
class PlanGeometry:
    """What a plan scores: the drones' flights on the planning grid seen from the receivers."""

    u: FloatArray
    """(B, S, n, m, 3) unit lines of sight from receiver ``k`` to drone ``j`` on step ``s``."""
    r: FloatArray
    """(B, S, n, m) their ranges, floored at ``MIN_RANGE``, m."""
    ready: NDArray[np.bool_]
    """(B, S, n, m) whether receiver ``k``'s boresight, slewing at full rate, has reached
    drone ``j`` by step ``s`` (within half a field of view)."""
    weight: FloatArray
    """(B, S) weight of each grid step: ``stride`` within the horizon, 0 beyond."""


def plan_geometry(
    params: PointingParams,
    azimuth: FloatArray,
    elevation: FloatArray,
    position: FloatArray,
    velocity: FloatArray,
    left: FloatArray,
    stride: int,
) -> PlanGeometry:
    """The :class:`PlanGeometry` of the next ``left (B,)`` steps, for drones flying straight
    from ``position`` with ``velocity`` ``(B, m, 3)`` and boresights at
    ``azimuth``/``elevation (B, n)``, on every ``stride``-th step."""
    p = params
    n, m, B = p.n_receivers, p.n_drones, azimuth.shape[0]
    # future steps s = 1, 1 + stride, …, weighted by stride where s ≤ left
    s = np.arange(1, max(int(np.max(left)), 1) + 1, stride, dtype=np.float64)  # (S,)
    weight = np.where(s[None, :] <= left[:, None], float(stride), 0.0)  # (B, S)
    dt = (s * p.dt)[None, :, None, None]
    q = position[:, None] + velocity[:, None] * dt  # (B, S, m, 3)
    u, r = lines_of_sight(p, q.reshape(B * len(s), m, 3))
    reach = slew_steps(p, azimuth, elevation, q[:, 0])  # (B, n, m)
    return PlanGeometry(
        u=u.reshape(B, len(s), n, m, 3),
        r=np.maximum(r, MIN_RANGE).reshape(B, len(s), n, m),
        ready=s[None, :, None, None] >= reach[:, None],  # (B, S, n, m)
        weight=weight,
    )


def slew_steps(
    params: PointingParams, azimuth: FloatArray, elevation: FloatArray, points: FloatArray
) -> FloatArray:
    """Steps ``(B, n, m)``, at least 1, until receiver ``k``'s boresight (at
    ``azimuth``/``elevation (B, n)``), slewing at full rate, is within half a field of view of
    ``points (B, m, 3)`` (the plan's :attr:`PlanGeometry.ready`)."""
    step = max(params.slew_rate * params.dt, 1e-12)
    off = np.abs(pointing_offsets(params, azimuth, elevation, points))  # (B, n, m, 2)
    return np.maximum(np.ceil((off.max(axis=-1) - 0.5 * params.fov) / step), 1.0)


def plan_values(params: PointingParams, *flight: Any) -> FloatArray:
    """Planned return ``(B, C)`` of holding each assignment of :func:`all_assignments` for the
    next ``left (B,)`` steps, ``flight = (azimuth, elevation, position, velocity, left,
    stride)`` as for :func:`plan_geometry`: the env's reward of the receivers assigned to each
    drone, each counted from the step its gimbal, slewing at full rate, is within half a field
    of view of its drone, on every ``stride``-th step (:func:`geometry_values`)."""
    return geometry_values(params, plan_geometry(params, *flight))


def geometry_values(params: PointingParams, geometry: PlanGeometry) -> FloatArray:
    """Planned return ``(B, C)`` of holding each assignment of :func:`all_assignments` over
    ``geometry``: the env's reward of the receivers assigned to each drone, each counted from
    the step it is ready, averaged over the drones and summed with the steps' weights."""
    return rewards_values(drone_rewards(params, geometry), geometry.weight)


def rewards_values(rewards: FloatArray, weight: FloatArray) -> FloatArray:
    """:func:`geometry_values` of the per-drone rewards ``(B, C, S, m)`` of
    :func:`drone_rewards` on a grid weighted by ``weight (B, S)``."""
    return np.einsum("bcs,bs->bc", rewards.mean(axis=-1), weight)


def grid_prefix(
    rewards: FloatArray, left: FloatArray, stride: int
) -> tuple[FloatArray, FloatArray]:
    """``(rewards, weight)`` of a plan over the next ``left (B,)`` steps cut from the per-drone
    rewards ``(B, C, S, m)`` of a plan over at least as many steps on the same ``stride``
    grid (:func:`drone_rewards`): its first grid steps and their weights, exactly the arrays
    :func:`plan_geometry` at ``left`` would score, so that one geometry serves several
    horizons."""
    s = np.arange(1, max(int(np.max(left)), 1) + 1, stride, dtype=np.float64)
    if len(s) > rewards.shape[2]:
        raise ValueError(f"left: {np.max(left)} steps lie beyond the {rewards.shape[2]}-step grid")
    weight = np.where(s[None, :] <= left[:, None], float(stride), 0.0)
    return np.ascontiguousarray(rewards[:, :, : len(s)]), weight


def drone_rewards(params: PointingParams, geometry: PlanGeometry) -> FloatArray:
    """The env's per-drone reward ``(B, C, S, m)`` on each grid step of the plan of each
    candidate of :func:`all_assignments`, each receiver counted from the step it is ready."""
    p, g = params, geometry
    cand = all_assignments(p)  # (C, n)
    # candidate c sends receiver k to drone c_k
    sent = cand[:, None, :] == np.arange(p.n_drones)[None, :, None]  # (C, m, n)
    # (B, S, m, n) views of the geometry, receivers last
    u, r, ready = g.u.transpose(0, 1, 3, 2, 4), g.r.transpose(0, 1, 3, 2), g.ready.swapaxes(2, 3)
    mask = sent[None, :, None] & ready[:, None]  # (B, C, S, m, n)
    sigma_ang = p.sigma_ang if p.sigma_ang > 0.0 else 1e-9
    info = position_information(u[:, None], r[:, None], sigma_ang, mask)
    sigma = position_sigma(info, observable(info, mask))
    return log_ratio_reward(sigma, p.sigma_ref, p.reward_clip)


def acquisition_probability(params: PointingParams, view: RuleView) -> FloatArray:
    """Probability ``(N, n, m)`` that receiver ``k``, slewed onto the tracker's prediction of
    drone ``j``, finds the drone inside its field of view: 1 where it saw the drone on the last
    step, else ``1 − exp(−(fov r_kj)² / (2 s_j²))``, the chance that an isotropic Gaussian
    position error of RMS ``σ̂_j`` (``s_j = σ̂_j / √3`` per axis) lies within the cone's radius
    ``fov · r_kj`` across the line of sight (``r_kj`` the range to the prediction).

    The plan of :func:`geometry_values` assumes a receiver sent to a drone sees it. That holds
    once the drone is tracked (``σ̂`` of centimetres); on the cue (``σ̂`` ≈ 9 m) a receiver
    50 m from a drone misses it about a third of the time, and a drone that no pair of
    receivers sees is never fixed: its track only predicts, and its error grows."""
    s = np.maximum(view.sigma, 1e-9)[:, None, :] / np.sqrt(3.0)  # (N, 1, m)
    reach = params.fov * np.minimum(view.ranges, 1e12)  # (N, n, m)
    p = -np.expm1(-0.5 * (reach / s) ** 2)
    return np.where(view.seen > 0.0, 1.0, p)


def acquired_values(
    params: PointingParams, geometry: PlanGeometry, p_see: FloatArray
) -> FloatArray:
    """:func:`geometry_values` with acquisition: each drone's planned return counts with the
    probability ``q_cj`` that at least two of the receivers candidate ``c`` sends to drone
    ``j`` find it (receivers independent, each with ``p_see (B, n, m)``,
    :func:`acquisition_probability`), and the floor ``−R`` on every planned step otherwise
    (a drone no pair finds is never fixed)."""
    return rewards_acquired(params, drone_rewards(params, geometry), geometry.weight, p_see)


def rewards_acquired(
    params: PointingParams, rewards: FloatArray, weight: FloatArray, p_see: FloatArray
) -> FloatArray:
    """:func:`acquired_values` of the per-drone rewards ``(B, C, S, m)`` of
    :func:`drone_rewards` on a grid weighted by ``weight (B, S)``."""
    p = params
    cand = all_assignments(p)  # (C, n)
    n, m = cand.shape[1], p.n_drones
    sent = cand[:, None, :] == np.arange(m)[None, :, None]  # (C, m, n)
    planned = np.einsum("bcsj,bs->bcj", rewards, weight)  # (B, C, m)
    floor = -p.reward_clip * weight.sum(axis=1)[:, None, None]  # (B, 1, 1)
    # P(at least two of the sent receivers see drone j): counts 0, 1, ≥ 2 over the receivers
    pk = p_see.transpose(0, 2, 1)[:, None] * sent[None]  # (B, C, m, n), 0 if not sent
    none, one, two = np.ones(pk.shape[:-1]), np.zeros(pk.shape[:-1]), np.zeros(pk.shape[:-1])
    for k in range(n):
        q = pk[..., k]
        none, one, two = none * (1 - q), one * (1 - q) + none * q, two + one * q
    return ((two * planned + (1.0 - two) * floor) / m).sum(axis=-1)


def plan_objective(params: PointingParams, geometry: PlanGeometry) -> SeparableObjective:
    """:func:`geometry_values` as a separable objective (per drone: its reward summed over the
    steps with their weights, over ``m``) for the polynomial solver."""
    p, g = params, geometry
    sigma_ang = p.sigma_ang if p.sigma_ang > 0.0 else 1e-9
    sr = sigma_ang * g.r
    return SeparableObjective(
        kind=kernels.REWARD,
        u=g.u,
        w=1.0 / (sr * sr),
        ready=g.ready,
        prior=np.zeros((g.weight.shape[0], p.n_drones)),
        weight=np.ascontiguousarray(g.weight / p.n_drones),
        consts=np.array([p.sigma_ref, p.reward_clip], dtype=np.float64),
    )


@dataclass(frozen=True)
class PlanEstimate(_AssignAndSlew):
    """:class:`TruthPlan`'s planner on the tracker's estimate (a fieldable rule): hold the
    assignment whose planned return over the next ``horizon`` steps (:func:`plan_values`, the
    drones flying straight from their predicted positions with their estimated velocities) is
    best, re-planned every step. The observation carries no clock, so the horizon recedes."""

    params: PointingParams = field(default_factory=PointingParams)
    """Env settings (receiver layout, noise, slew limit, reward, observation layout)."""
    horizon: int = 100
    """Planning horizon, steps (tuned on seeds 5 and 7 among 15, 50, 100, 150)."""
    stride: int = 3
    """Planning grid: every ``stride``-th future step is scored."""
    solver: str = "auto"
    """How the best assignment is searched: ``"auto"``, ``"exhaustive"`` or ``"greedy"``
    (:mod:`sensorgym.agents.assignment_solver`; auto is exhaustive up to
    :data:`PLAN_ASSIGNMENTS` assignments)."""

    def __post_init__(self) -> None:
        check_solver(self.solver)

    def choose(self, view: RuleView) -> NDArray[np.int64]:
        """Drone index per receiver ``(N, n)``."""
        p, N = self.params, view.azimuth.shape[0]
        geometry = plan_geometry(
            p,
            view.azimuth,
            view.elevation,
            view.position,
            view.velocity,
            np.full(N, float(self.horizon)),
            self.stride,
        )
        if not exhaustive(self.solver, p.n_receivers, p.n_drones, PLAN_ASSIGNMENTS):
            return best_of(plan_objective(p, geometry), search_starts(p, view))
        return all_assignments(p)[np.argmax(geometry_values(p, geometry), axis=-1)]
