"""Time-share the receiver pairs between more drones than pairs: the ``plan-schedule`` rule
(``sensorgym/StereoPointingCrowded-v0``, issue 37).

With four receivers and three drones at most two drones hold a pair (unless one receiver holds
two drones in its field of view). The drone left without one drifts: its track only predicts
and its RMS error grows, and once that error is wider than a receiver's cone at its range the
pair sent back to it no longer finds it. :class:`PlanSchedule` is the ``plan-search`` planner
(:class:`~sensorgym.agents.stereo_pointing_horizon.PlanHorizon` with acquisition, sharing, the
cue hold and the epipolar search; its exhaustive candidate values, its aiming) with one
constraint from a schedule: each step it predicts, for every drone, the step at which its
error passes what the fields of view re-acquire (:func:`reacquire_steps`) and how many steps
the fastest pair of receivers needs to reach it (:func:`slew_steps`); when a drone's deadline comes within that transit plus ``lead`` steps, the most
urgent such drone (the largest growing uncertainty for its deadline) must get a pair, and the
planner picks the best assignment that gives it one (which pair hands over, and whom the
others watch). A drone already past its deadline is not forced: a pair sent there would
likely miss it, and the plan's acquisition weight and the epipolar search handle it.

What it measured (tuning seeds 500 and 600, ``research/stereo_pointing/results/pointing_schedule.json``): the
gain over ``plan-search`` is the exhaustive acquisition-weighted search; the schedule on top
of it costs return (the more hand-overs, the more): a pair sent back to the
drifting drone leaves a fixed one, and the slew there earns nothing, since the reward counts
only the drones fixed now. ``plan-search-exhaustive`` (the same planner, never forced:
``schedule=None``) is registered beside it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sensorgym.agents.assignment_solver import exhaustive
from sensorgym.agents.stereo_pointing import RuleView, all_assignments, slew_steps
from sensorgym.agents.stereo_pointing_horizon import PlanHorizon
from sensorgym.envs.stereo_pointing.simulation import PointingParams

#: the furthest a deadline is predicted, steps (beyond it: never)
MAX_DEADLINE = 1000

#: ``solver="auto"`` schedules the exhaustive search up to this many assignments (each is
#: scored over the whole plan, so the search's cost grows with their number)
SCHEDULE_ASSIGNMENTS = 256


@dataclass(frozen=True)
class Schedule:
    """When a drifting drone gets a pair back. The defaults are the best schedule measured on
    tuning seeds 500 and 600 (``research/stereo_pointing/pointing_schedule.py``,
    ``research/stereo_pointing/results/pointing_schedule.json``, 128 episodes each, paired to ``plan-search``).
    Every schedule measured there forces hand-overs that cost return: the same planner never
    forced (``plan-search-exhaustive``) scored higher, and earlier or more hand-overs (``lead``
    3, ``reach`` 0.5) less than later ones."""

    reach: float = 1.0
    """The error a pair still re-acquires, in units of the field of view's radius ``fov ·
    r̄_j`` at the drone's mean range from the receivers (at 1, a receiver sent to the
    prediction finds the drone with probability 0.78 under the plan's acquisition model)."""
    lead: float = 0.0
    """Steps of margin: a drone is handed a pair when its deadline is at most its transit plus
    ``lead`` steps away."""

    def __post_init__(self) -> None:
        if not (np.isfinite(self.reach) and self.reach > 0.0):
            raise ValueError(f"reach: must be finite and > 0, got {self.reach!r}")
        if not self.lead >= 0.0:  # NaN fails; inf hands over as soon as a drone is reachable
            raise ValueError(f"lead: must be >= 0, got {self.lead!r}")


def reacquire_steps(params: PointingParams, view: RuleView, reach: float) -> NDArray[np.float64]:
    """Steps ``(N, m)`` until drone ``j``'s predicted RMS error exceeds ``reach · fov · r̄_j``
    (``r̄_j`` its mean range from the receivers): the track predicts without a fix, ``σ̂²(τ) =
    σ̂² + σ̂_v² τ² + q τ³`` (``τ`` in s, the CV filter's growth of ``tr P_pp`` without the
    position-velocity correlation, ``q`` its process noise). 0 when it is already past,
    :data:`MAX_DEADLINE` when it stays inside that long."""
    p = params
    ranges = np.where(np.isfinite(view.ranges), view.ranges, np.nan)
    limit = reach * p.fov * np.nanmean(ranges, axis=1)  # (N, m)
    tau = np.arange(MAX_DEADLINE + 1, dtype=np.float64) * p.dt  # (T,)
    grown = (
        view.sigma[..., None] ** 2
        + (view.velocity_sigma[..., None] * tau) ** 2
        + p.process_noise * tau**3
    )  # (N, m, T)
    past = grown > limit[..., None] ** 2
    return np.where(past.any(axis=-1), np.argmax(past, axis=-1), MAX_DEADLINE).astype(np.float64)


def forced_drone(params: PointingParams, view: RuleView, schedule: Schedule) -> NDArray[np.int64]:
    """The drone ``(N,)`` that must get a pair now, ``-1`` for none: among the drones whose
    :func:`reacquire_steps` deadline is positive and at most the fastest pair's transit
    (the second-smallest :func:`~sensorgym.agents.stereo_pointing.slew_steps` over the
    receivers) plus ``lead``, the one with the least slack (deadline minus transit)."""
    deadline = reacquire_steps(params, view, schedule.reach)
    steps = slew_steps(params, view.azimuth, view.elevation, view.position)  # (N, n, m)
    transit = np.sort(steps, axis=1)[:, 1]  # (N, m): the fastest pair's slower receiver
    slack = deadline - transit
    urgent = (deadline > 0) & (slack <= schedule.lead)
    slack = np.where(urgent, slack, np.inf)
    return np.where(urgent.any(axis=-1), np.argmin(slack, axis=-1), -1)


@dataclass(frozen=True)
class PlanSchedule(PlanHorizon):
    """:class:`~sensorgym.agents.stereo_pointing_horizon.PlanHorizon` on a schedule: the
    exhaustive planner (every assignment, ``acquisition`` weighted; ``solver``: see
    :meth:`choose`), restricted on each step
    where :func:`forced_drone` names a drone to the assignments that send at least two
    receivers to it. Aiming (cue hold, sharing, search) and the step count are
    :class:`PlanHorizon`'s."""

    schedule: Schedule | None = Schedule()
    """When a drifting drone gets a pair back; ``None``: never forced, the exhaustive plan
    alone (the ``plan-search-exhaustive`` rule)."""

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.schedule is not None and not isinstance(self.schedule, Schedule):
            raise ValueError(f"schedule: must be a Schedule or None, got {self.schedule!r}")

    def choose(self, view: RuleView, t: NDArray[Any]) -> NDArray[np.int64]:
        """Drone index per receiver ``(N, n)`` at episode steps ``t (N,)``: with ``solver``
        ``"auto"`` the schedule constrains the exhaustive search up to
        :data:`SCHEDULE_ASSIGNMENTS` assignments (4 × 3's 81, 4 × 4's 256), beyond that (and
        with ``"greedy"``) the rule is :class:`PlanHorizon`'s polynomial search, unscheduled."""
        p = self.params
        if not exhaustive(self.solver, p.n_receivers, p.n_drones, SCHEDULE_ASSIGNMENTS):
            return super().choose(view, t)
        cand = all_assignments(p)  # (C, n)
        values = self.values(view, self.geometry(view, t))  # (N, C)
        if self.schedule is None:
            return cand[np.argmax(values, axis=-1)]
        forced = forced_drone(p, view, self.schedule)  # (N,)
        pairs = (cand[None] == forced[:, None, None]).sum(axis=-1) >= 2  # (N, C)
        allowed = pairs | (forced < 0)[:, None]
        return cand[np.argmax(np.where(allowed, values, -np.inf), axis=-1)]


#: the per-candidate schedule evidence of :func:`schedule_features`, in order
SCHEDULE_FEATURES = ("unpaired_urgency", "urgent_paired", "lost_paired", "unpaired_growth")

#: steps of re-acquisition slack over which a drone's urgency falls by ``e``
SLACK_SCALE = 10.0

#: decades (natural-log units) of RMS below the re-acquisition limit over which a drone's
#: growth feature rises from 0 to 1
GROWTH_SPAN = 6.0


def schedule_features(
    params: PointingParams, view: RuleView, schedule: Schedule = Schedule()
) -> NDArray[np.float64]:
    """Per candidate assignment of :func:`~sensorgym.agents.stereo_pointing.all_assignments`
    the schedule's evidence ``(N, C, len(SCHEDULE_FEATURES))``, each O(1), for a policy that
    learns when to hand a pair back to a drifting drone (the ``plan-features`` wrapper with
    ``schedule``). A drone is *paired* by a candidate that sends at least two receivers to it;
    its *slack* is its :func:`reacquire_steps` deadline minus the fastest pair's transit
    (:func:`forced_drone`'s), its *urgency* ``exp(−max(slack, 0) / SLACK_SCALE)`` while its
    deadline lies ahead (0 once past: a pair would likely miss it):

    * ``unpaired_urgency``: the urgency summed over the drones the candidate leaves unpaired,
      ``[0, m]``;
    * ``urgent_paired``: 1 when the candidate pairs the drone :func:`forced_drone` names (the
      one ``plan-schedule`` forces), else 0;
    * ``lost_paired``: the drones already past their deadline that it pairs, ``[0, m]``;
    * ``unpaired_growth``: over the drones it leaves unpaired, ``clip(1 + log(σ̂_j / L_j) /
      GROWTH_SPAN, 0, 1)``, ``L_j`` the error :func:`reacquire_steps` still re-acquires: how far
      each one's RMS has grown towards being lost, ``[0, m]``.

    The track's RMS integrates the steps since the drone's last fix, so the features need no
    memory: they are a function of the observation, like the plan's."""
    p = params
    cand = all_assignments(p)  # (C, n)
    paired = (cand[:, :, None] == np.arange(p.n_drones)).sum(axis=1) >= 2  # (C, m)
    deadline = reacquire_steps(p, view, schedule.reach)  # (N, m)
    steps = slew_steps(p, view.azimuth, view.elevation, view.position)  # (N, n, m)
    slack = deadline - np.sort(steps, axis=1)[:, 1]
    live = deadline > 0
    urgency = np.where(live, np.exp(-np.maximum(slack, 0.0) / SLACK_SCALE), 0.0)  # (N, m)
    ranges = np.where(np.isfinite(view.ranges), view.ranges, np.nan)
    limit = schedule.reach * p.fov * np.nanmean(ranges, axis=1)  # (N, m), reacquire_steps'
    growth = np.clip(1.0 + np.log(np.maximum(view.sigma, 1e-12) / limit) / GROWTH_SPAN, 0.0, 1.0)
    forced = forced_drone(p, view, schedule)  # (N,)
    unpaired = (~paired).astype(np.float64)
    urgent = np.where(
        (forced >= 0)[:, None], paired.T[np.maximum(forced, 0)].astype(np.float64), 0.0
    )  # (N, C)
    return np.stack(
        [
            urgency @ unpaired.T,
            urgent,
            (~live).astype(np.float64) @ paired.T.astype(np.float64),
            growth @ unpaired.T,
        ],
        axis=-1,
    )
