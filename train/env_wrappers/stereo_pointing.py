"""Action and observation re-parameterisations of ``sensorgym/StereoPointing-v0`` for training,
as SB3 wrappers.

:class:`AssignmentAction` replaces the gimbal-rate action by an *assignment*: for each receiver,
which drone's track it watches. The env's own slew controller
(:func:`~sensorgym.envs.stereo_pointing.simulation.slew_actions`, the one the assignment rules
use) turns it into gimbal rates that slew each receiver onto the tracker's predicted position of
its drone. The scenarios and rewards are the base env's, so the episode return stays the env's
accuracy measure and a policy acting through the wrapper is scored beside the rules on the same
seed. ``sensorgym.train.wrappers.WRAPPERS["pointing-assignment"]`` builds it from a
hyperparameter set's ``wrappers:`` list.

:class:`PlanAction` (``pointing-plan``) indexes the same choice by one number: ``Discrete(m^n)``
over the candidate assignments the assignment rules enumerate, in their order.
:class:`PlanFeatures` (``plan-features``) appends the planner's own evidence to the
observation: :func:`~sensorgym.agents.stereo_pointing.plan_values` of every candidate on the
tracker's estimate for a few horizons and for the time left, so that a policy can reproduce the
``plan-estimate`` rule by an argmax and learn when to deviate from it. With ``sharing``
``pointing-plan`` aims a receiver between two drones as the ``plan-acquire-share`` rule does.
With ``cue_steps`` (1) ``pointing-plan`` holds each receiver on the drone it is cued to for the
episode's first step as the ``plan-fix-first`` rule does, so that with both the zero point of a
learned correction is that rule. Everything it computes
comes from the observation and the step count of the episode (fieldable), never from the
simulator state.
"""

from __future__ import annotations

from dataclasses import fields
from typing import Any

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper

from sensorgym.agents.stereo_pointing import (
    acquisition_probability,
    all_assignments,
    drone_rewards,
    grid_prefix,
    hysteresis_bonus,
    plan_geometry,
    rewards_acquired,
    rewards_values,
    rule_view,
)
from sensorgym.agents.stereo_pointing_horizon import check_cue_steps, plan_aims
from sensorgym.agents.stereo_pointing_schedule import (
    SCHEDULE_FEATURES,
    Schedule,
    schedule_features,
)
from sensorgym.agents.stereo_pointing_search import EpipolarSearch
from sensorgym.agents.stereo_pointing_sharing import Sharing
from sensorgym.envs.stereo_pointing.simulation import (
    PointingParams,
    assignment_actions,
    slew_actions,
)
from sensorgym.train.wrappers import EpisodeSteps, ObservedActionWrapper, time_limit_of


class AssignmentAction(ObservedActionWrapper):
    """``MultiDiscrete([m] * n)`` actions over an SB3 vector env of StereoPointing: action
    ``i`` is the drone receiver ``i`` watches; the wrapper slews it onto the tracker's predicted
    position of that drone (:func:`~sensorgym.envs.stereo_pointing.simulation.assignment_actions`
    of the latest observation). Observations, rewards and episodes are the base env's."""

    def __init__(self, venv: VecEnv, params: PointingParams | None = None):
        p = _pointing_params(venv, params)
        shape = venv.observation_space.shape
        if shape != (p.obs_dim,):
            raise ValueError(
                f"venv: expected the joint observation ({p.obs_dim},), got {shape}"
                " (the assignment action drives all receivers of a scenario at once)"
            )
        super().__init__(venv, spaces.MultiDiscrete([p.n_drones] * p.n_receivers))
        self.params = p

    def env_action(self, actions: NDArray[Any], obs: NDArray[Any]) -> NDArray[Any]:
        target = actions.reshape(self.num_envs, self.params.n_receivers)
        return assignment_actions(self.params, obs, target)


def assignment_wrapper(venv: VecEnv) -> VecEnv:
    """Factory of the ``pointing-assignment`` wrapper (``WRAPPERS`` registry)."""
    return AssignmentAction(venv)


def _pointing_params(venv: VecEnv, params: PointingParams | None) -> PointingParams:
    """``params`` or the StereoPointing params of ``venv``; ``TypeError``/``ValueError`` when
    ``venv`` is not a joint StereoPointing env."""
    p = params if params is not None else venv.get_attr("params")[0]
    if not isinstance(p, PointingParams):
        raise TypeError(f"venv: expected a StereoPointing env, its params are {type(p)!r}")
    return p


class PlanAction(ObservedActionWrapper):
    """``Discrete(m^n)`` actions over an SB3 vector env of StereoPointing: action ``c`` is the
    ``c``-th candidate assignment of the assignment rules (:attr:`candidates`, every map of
    receivers to drones in lexicographic order), slewed onto as by :class:`AssignmentAction`.
    With ``sharing`` a receiver aims instead between its drone and another one that fits in its
    field of view (:func:`~sensorgym.agents.stereo_pointing_sharing.shared_aims`, the
    ``plan-acquire-share`` rule's aiming). With ``cue_steps`` the wrapper counts the steps of
    each env's episode (:class:`~sensorgym.train.wrappers.EpisodeSteps`) and on the first
    ``cue_steps`` a receiver aimed at a drone keeps it whatever the candidate says (the
    ``plan-fix-first`` rule's hold). With ``search`` the other receivers sent to a lost drone
    that one receiver sees aim along that receiver's line of sight
    (:func:`~sensorgym.agents.stereo_pointing_search.search_aims`, the ``plan-search`` rule's
    search). The aiming is the rules' own,
    :func:`~sensorgym.agents.stereo_pointing_horizon.plan_aims`. Observations, rewards and episodes are the base env's."""

    def __init__(
        self,
        venv: VecEnv,
        params: PointingParams | None = None,
        sharing: Sharing | None = None,
        cue_steps: int = 0,
        search: EpipolarSearch | None = None,
    ):
        p = _pointing_params(venv, params)
        if search is not None and not isinstance(search, EpipolarSearch):
            raise TypeError(f"search: expected an EpipolarSearch or None, got {type(search)!r}")
        self.search = search
        """Where the receivers of a lost drone look; ``None``: at its prediction."""
        if sharing is not None and not isinstance(sharing, Sharing):
            raise TypeError(f"sharing: expected a Sharing or None, got {type(sharing)!r}")
        self.cue_steps = check_cue_steps(cue_steps)
        """On an episode's first ``cue_steps`` steps every receiver aimed at a drone stays on
        it whatever the candidate says (:func:`~sensorgym.agents.stereo_pointing_horizon.cue_hold`,
        the ``plan-fix-first`` rule's hold: 1); 0: the candidate alone."""
        self._steps = EpisodeSteps(venv.num_envs)
        self.sharing = sharing
        """When a receiver aims between two drones; ``None``: always at its own drone."""
        if venv.observation_space.shape != (p.obs_dim,):
            raise ValueError(
                f"venv: expected the joint observation ({p.obs_dim},), got "
                f"{venv.observation_space.shape} (pointing-plan must lie under observation wrappers)"
            )
        self.candidates = all_assignments(p)
        """``(m^n, n)``: candidate ``c`` sends receiver ``k`` to drone ``candidates[c, k]``."""
        super().__init__(venv, spaces.Discrete(len(self.candidates)))
        self.params = p

    def index(self, assignment: NDArray[Any]) -> NDArray[np.int64]:
        """The candidate index ``(N,)`` of assignments ``(N, n)`` (drone per receiver)."""
        a = np.asarray(assignment, dtype=np.int64)
        return np.ravel_multi_index(tuple(a.T), (self.params.n_drones,) * self.params.n_receivers)

    def env_action(self, actions: NDArray[Any], obs: NDArray[Any]) -> NDArray[Any]:
        a = np.asarray(actions, dtype=np.int64).reshape(self.num_envs, -1)
        if a.shape[1] != 1:
            raise ValueError(f"actions: expected 1 value per env, got {a.shape[1]}")
        choice = a[:, 0]
        if np.any((choice < 0) | (choice >= len(self.candidates))):
            raise ValueError(f"actions: candidate indices must lie in [0, {len(self.candidates)})")
        target = self.candidates[choice]
        if self.sharing is None and not self.cue_steps and self.search is None:
            return assignment_actions(self.params, obs, target)
        view = rule_view(self.params, np.asarray(obs, dtype=np.float64))
        points, index = plan_aims(
            self.params, view, target, self._steps.t, self.cue_steps, self.sharing, self.search
        )
        return slew_actions(self.params, view.azimuth, view.elevation, points, index)

    def reset(self) -> NDArray[Any]:
        self._steps.reset()
        return super().reset()

    def step_wait(self) -> Any:
        obs, rewards, dones, infos = super().step_wait()
        self._steps.step(dones)
        return obs, rewards, dones, infos


def plan_wrapper(
    venv: VecEnv,
    sharing: bool | dict[str, float] | None = None,
    cue_steps: int = 0,
    search: bool | dict[str, Any] | None = None,
) -> VecEnv:
    """Factory of the ``pointing-plan`` wrapper (``WRAPPERS`` registry). ``sharing``: ``true``
    for the registered :class:`~sensorgym.agents.stereo_pointing_sharing.Sharing` (the
    ``plan-acquire-share`` rule's), a mapping of its fields (``margin``, ``fraction``,
    ``max_rms``), or absent/``false``/``null`` for none; ``cue_steps``: the episode's first
    steps on which a receiver aimed at a drone keeps it (absent: 0, none; the
    ``plan-fix-first`` rule's 1); ``search``: ``true`` for the registered
    :class:`~sensorgym.agents.stereo_pointing_search.EpipolarSearch` (the ``plan-search``
    rule's), a mapping of its fields, or absent/``false``/``null`` for none
    (:class:`PlanAction`)."""
    return PlanAction(
        venv,
        sharing=_sharing(sharing),
        cue_steps=cue_steps,
        search=_search(search),
    )


def _setting(value: Any, kind: type, name: str, convert: Any) -> Any:
    """The settings object of class ``kind`` that a wrapper keyword ``name`` names: ``true``
    its defaults, a mapping of its fields (each value through ``convert(field, value)``),
    ``false``/``null`` none; ``ValueError`` otherwise."""
    if value is None or value is False:
        return None
    if value is True:
        return kind()
    if isinstance(value, dict):
        unknown = set(value) - {f.name for f in fields(kind)}
        if unknown:
            raise ValueError(f"{name}: unknown fields {sorted(unknown)}")
        return kind(**{k: convert(k, v) for k, v in value.items()})
    raise ValueError(f"{name}: expected true, false, null or a mapping, got {value!r}")


def _sharing(value: bool | dict[str, float] | None) -> Sharing | None:
    """The :class:`Sharing` a wrapper's ``sharing`` keyword names."""
    return _setting(value, Sharing, "sharing", lambda _, v: float(v))


def _search(value: bool | dict[str, Any] | None) -> EpipolarSearch | None:
    """The :class:`EpipolarSearch` a wrapper's ``search`` keyword names."""
    return _setting(value, EpipolarSearch, "search", _search_field)


def _search_field(name: str, value: Any) -> Any:
    """One :class:`EpipolarSearch` field from a wrapper's keywords (YAML gives lists)."""
    if name == "sweep":
        return tuple(int(x) for x in value)
    if name == "across":
        return tuple(float(x) for x in value)
    if name == "anchor":
        return value  # a bool, checked by EpipolarSearch
    return float(value)


class PlanFeatures(VecEnvWrapper):
    """Appends the planner's evidence to the joint observation of StereoPointing.

    For each horizon ``h`` of :attr:`horizons` (steps) and, with ``time_left``, for the steps
    left in the episode (``max_episode_steps − t``, at least 1), the planned return ``v_c`` of
    holding each candidate assignment ``c`` for ``h`` steps on the tracker's estimate
    (:func:`~sensorgym.agents.stereo_pointing.plan_values`, the ``plan-estimate`` rule's
    evidence; the rule is the argmax at ``h = 100``):

    | feature (per candidate, in the rules' candidate order) | range |
    |---|---|
    | ``max(−10, (v_c − max_c' v_c') / h)``: the per-step loss against the best plan | [−10, 0] |
    | 1 for the best candidate (first on ties), else 0 | {0, 1} |

    followed by, per candidate, the fraction of receivers it leaves on the drone they are
    aimed at (the hysteresis count of the assignment rules). Size
    ``obs_dim + m^n (2H + 1)``, ``H`` the number of horizons (with the time left). The base
    observation comes first (:meth:`base_observation` recovers it).

    With ``acquisition`` the planned returns are those of the ``plan-acquire`` rule's model
    (:func:`~sensorgym.agents.stereo_pointing.acquired_values`: each drone's return weighed by
    the chance that a pair of the receivers sent to it finds it on the tracker's prediction),
    same layout; ``plain_horizons`` then adds blocks of the plain plan (without acquisition)
    at these horizons, after the ``horizons`` blocks and before the time left, so that a
    policy sees where the two models disagree (``H`` counts them too).

    With ``schedule`` (a :class:`~sensorgym.agents.stereo_pointing_schedule.Schedule`) the
    schedule block follows the kept fractions: per candidate the re-acquisition evidence
    of :func:`~sensorgym.agents.stereo_pointing_schedule.schedule_features` (the urgency of the
    drones it leaves without a pair, whether it pairs the drone ``plan-schedule`` would force,
    the lost drones it pairs, how far the unpaired drones' errors have grown),
    ``m^n · len(SCHEDULE_FEATURES)`` values in ``[0, m]``.
    """

    def __init__(
        self,
        venv: VecEnv,
        horizons: tuple[int, ...] | list[int] = (15, 50, 100),
        time_left: bool = True,
        stride: int = 3,
        max_episode_steps: int | None = None,
        params: PointingParams | None = None,
        acquisition: bool = False,
        plain_horizons: tuple[int, ...] | list[int] = (),
        schedule: Schedule | None = None,
    ):
        p = _pointing_params(venv, params)
        if schedule is not None and not isinstance(schedule, Schedule):
            raise TypeError(f"schedule: expected a Schedule or None, got {type(schedule)!r}")
        if venv.observation_space.shape != (p.obs_dim,):
            raise ValueError(
                f"venv: expected the joint observation ({p.obs_dim},), got "
                f"{venv.observation_space.shape} (plan-features must lie directly over the env "
                "or an action wrapper)"
            )
        if not all(isinstance(h, int) and h >= 1 for h in horizons) or not (horizons or time_left):
            raise ValueError(f"plan-features: horizons must be integers >= 1, got {horizons!r}")
        if not all(isinstance(h, int) and h >= 1 for h in plain_horizons) or (
            plain_horizons and not acquisition
        ):
            raise ValueError(
                "plan-features: plain_horizons must be integers >= 1 and need acquisition, got "
                f"{plain_horizons!r}"
            )
        if not isinstance(stride, int) or stride < 1:
            raise ValueError(f"plan-features: stride must be an integer >= 1, got {stride!r}")
        limit = max_episode_steps or time_limit_of(venv)
        if time_left and not (isinstance(limit, int | np.integer) and limit >= 1):
            raise ValueError(f"plan-features: time_left needs a time limit, got {limit!r}")
        self.params = p
        self.horizons = tuple(int(h) for h in horizons)
        self.time_left = bool(time_left)
        self.stride = stride
        self.acquisition = bool(acquisition)
        self.plain_horizons = tuple(int(h) for h in plain_horizons)
        self.max_episode_steps = int(limit) if limit else 0
        self.candidates = all_assignments(p)
        C = len(self.candidates)
        H = len(self.horizons) + len(self.plain_horizons) + int(self.time_left)
        self.schedule = schedule
        """With a setting, the schedule block follows the kept fractions: per candidate the
        :func:`~sensorgym.agents.stereo_pointing_schedule.schedule_features`."""
        extra = C * (2 * H + 1)
        sched = C * len(SCHEDULE_FEATURES) if schedule is not None else 0
        box = venv.observation_space
        low = np.concatenate(
            [
                box.low,
                np.full(extra, -10.0, np.float32),
                np.zeros(sched, np.float32),
            ]
        ).astype(np.float32)
        high = np.concatenate(
            [
                box.high,
                np.ones(extra, np.float32),
                np.full(sched, float(p.n_drones), np.float32),
            ]
        ).astype(np.float32)
        super().__init__(venv, observation_space=spaces.Box(low, high, dtype=np.float32))
        self._steps = EpisodeSteps(venv.num_envs)

    def features(self, obs: NDArray[Any], t: NDArray[np.int64]) -> NDArray[np.float32]:
        """The appended features ``(N, m^n (2H + 1))`` of base observations ``(N, obs_dim)``
        at episode steps ``t (N,)``."""
        view = rule_view(self.params, np.asarray(obs, dtype=np.float64))
        N, C = len(t), len(self.candidates)
        p_see = acquisition_probability(self.params, view) if self.acquisition else None
        # (horizon, acquisition probabilities or None for the plain plan) per block
        horizons = [(np.full(N, float(h)), p_see) for h in self.horizons]
        horizons += [(np.full(N, float(h)), None) for h in self.plain_horizons]
        if self.time_left:
            left = np.maximum(self.max_episode_steps - t, 1).astype(np.float64)
            horizons.append((left, p_see))
        # one geometry over the longest horizon; every block scores a prefix of its grid
        longest = np.max([h for h, _ in horizons], axis=0)
        flight = (view.azimuth, view.elevation, view.position, view.velocity)
        geometry = plan_geometry(self.params, *flight, longest, self.stride)
        rewards = drone_rewards(self.params, geometry)
        parts = []
        for h, p_block in horizons:
            r, weight = grid_prefix(rewards, h, self.stride)
            if p_block is None:
                v = rewards_values(r, weight)
            else:
                v = rewards_acquired(self.params, r, weight, p_block)
            parts.append(np.maximum((v - v.max(axis=1, keepdims=True)) / h[:, None], -10.0))
            parts.append(np.eye(C)[np.argmax(v, axis=1)])
        parts.append(hysteresis_bonus(view, self.candidates, 1.0 / self.params.n_receivers))
        if self.schedule is not None:
            parts.append(schedule_features(self.params, view, self.schedule).reshape(N, -1))
        return np.concatenate(parts, axis=1).astype(np.float32)

    def base_observation(self, obs: NDArray[Any]) -> NDArray[Any]:
        """The env's own observation in ``obs`` (the features dropped)."""
        return obs[..., : self.params.obs_dim]

    def _with_features(self, obs: NDArray[Any]) -> NDArray[np.float32]:
        return np.concatenate([obs, self.features(obs, self._steps.t)], axis=1).astype(np.float32)

    def reset(self) -> NDArray[np.float32]:
        self._steps.reset()
        return self._with_features(np.asarray(self.venv.reset()))

    def step_wait(self) -> Any:
        obs, rewards, dones, infos = self.venv.step_wait()
        reached = self._steps.step(dones)
        for i in np.flatnonzero(dones):  # the final observation, at its own step count
            terminal = infos[i].get("terminal_observation")
            if terminal is not None:
                f = self.features(terminal[None], reached[i : i + 1])[0]
                infos[i]["terminal_observation"] = np.concatenate([terminal, f]).astype(np.float32)
        return self._with_features(np.asarray(obs)), rewards, dones, infos


def plan_features(venv: VecEnv, **kwargs: Any) -> VecEnv:
    """Factory of the ``plan-features`` wrapper (``WRAPPERS`` registry); keywords as
    :class:`PlanFeatures` (``horizons``, ``time_left``, ``stride``, ``max_episode_steps``,
    ``acquisition``, ``plain_horizons``; ``schedule``: ``true`` for the default
    :class:`~sensorgym.agents.stereo_pointing_schedule.Schedule` (``plan-schedule``'s), a
    mapping of its fields, or absent/``false``/``null`` for none: the schedule block)."""
    for key in ("horizons", "plain_horizons"):
        if key in kwargs:
            kwargs[key] = tuple(kwargs[key])
    if "schedule" in kwargs:
        kwargs["schedule"] = _setting(
            kwargs["schedule"], Schedule, "schedule", lambda _, v: float(v)
        )
    return PlanFeatures(venv, **kwargs)


def _find(env: VecEnv, kind: type, name: str) -> Any:
    """The ``kind`` wrapper in an SB3 wrapper stack (outer wrappers such as frame stacks or a
    time feature may lie over it); ``ValueError`` if there is none."""
    e: Any = env
    while True:
        if isinstance(e, kind):
            return e
        if not isinstance(e, VecEnvWrapper):
            raise ValueError(f"env: no {name} wrapper in the stack")
        e = e.venv


def find_assignment(env: VecEnv) -> AssignmentAction:
    """The :class:`AssignmentAction` in an SB3 wrapper stack; ``ValueError`` if there is none."""
    return _find(env, AssignmentAction, "pointing-assignment")


class AssignmentExpert:
    """A teacher for behaviour cloning in the assignment action's space: SB3's ``predict``,
    answering with ``choose(observation)`` of the base env's latest observation (read from the
    :class:`AssignmentAction` under any outer wrappers, so frame stacks or a time feature over
    it do not matter)."""

    def __init__(self, env: VecEnv, choose: Any):
        self.wrapper = find_assignment(env)
        self.choose = choose
        """``(N, obs_dim)`` base observations → ``(N, n)`` drone per receiver."""

    def predict(
        self,
        observation: NDArray[Any],
        state: Any = None,
        episode_start: NDArray[np.bool_] | None = None,
        deterministic: bool = True,
    ) -> tuple[NDArray[np.int64], None]:
        obs = self.wrapper.last_obs
        if obs is None or len(obs) != len(np.atleast_2d(observation)):
            raise ValueError("observation: the expert acts on the wrapped env's own batch")
        return self.answer(self.choose(obs)), None

    def answer(self, choice: NDArray[Any]) -> NDArray[np.int64]:
        """The action for ``choice`` ``(N, n)`` (drone per receiver): the assignment itself."""
        return np.asarray(choice, dtype=np.int64)


def _rule_expert(env: VecEnv, name: str) -> AssignmentExpert:
    from sensorgym.agents.registry import rules_for

    wrapper = find_assignment(env)
    rule = rules_for("sensorgym/StereoPointing-v0", wrapper.params, lambda: None)[name]
    return AssignmentExpert(env, rule.assign)  # type: ignore[attr-defined]


class PlanExpert(AssignmentExpert):
    """A teacher in :class:`PlanAction`'s space: SB3's ``predict``, answering with the index of
    the candidate a rule's ``assign`` picks on the base env's latest observation."""

    def __init__(self, env: VecEnv, choose: Any):
        self.wrapper: PlanAction = _find(env, PlanAction, "pointing-plan")  # type: ignore[assignment]
        self.choose = choose
        """``(N, obs_dim)`` base observations → ``(N, n)`` drone per receiver."""

    def answer(self, choice: NDArray[Any]) -> NDArray[np.int64]:
        """The index of ``choice`` ``(N, n)`` in the candidate list."""
        return self.wrapper.index(choice)


def plan_choice_expert(env: VecEnv) -> PlanExpert:
    """The ``plan-estimate`` rule as a teacher in :class:`PlanAction`'s candidate indices
    (``EXPERTS["plan-choice-estimate"]``)."""
    from sensorgym.agents.registry import rules_for

    wrapper: PlanAction = _find(env, PlanAction, "pointing-plan")
    rule = rules_for("sensorgym/StereoPointing-v0", wrapper.params, lambda: None)["plan-estimate"]
    return PlanExpert(env, rule.assign)  # type: ignore[attr-defined]


class PlanHorizonExpert:
    """The ``plan-horizon`` rule (:class:`~sensorgym.agents.stereo_pointing_horizon.PlanHorizon`)
    as a teacher in :class:`PlanAction`'s candidate indices: SB3's ``predict`` on the base
    env's latest observation, its ``state`` the rule's step counts (restarted by
    ``episode_start``), as the rule keeps them (``EXPERTS["plan-horizon-choice"]``)."""

    def __init__(self, env: VecEnv):
        from sensorgym.agents.registry import rules_for

        self.wrapper: PlanAction = _find(env, PlanAction, "pointing-plan")
        self.rule = rules_for("sensorgym/StereoPointing-v0", self.wrapper.params, lambda: None)[
            "plan-horizon"
        ]

    def predict(
        self,
        observation: NDArray[Any],
        state: NDArray[np.int64] | None = None,
        episode_start: NDArray[np.bool_] | None = None,
        deterministic: bool = True,
    ) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        obs = self.wrapper.last_obs
        if obs is None or len(obs) != len(np.atleast_2d(observation)):
            raise ValueError("observation: the expert acts on the wrapped env's own batch")
        t = self.rule.steps(len(obs), state, episode_start)  # type: ignore[attr-defined]
        choice = self.rule.assign(obs, t)  # type: ignore[attr-defined]
        return self.wrapper.index(choice), t + 1


def hold_cue_expert(env: VecEnv) -> AssignmentExpert:
    """The ``hold-cue`` rule as an assignment teacher (``EXPERTS["pointing-hold-cue"]``)."""
    return _rule_expert(env, "hold-cue")


def orthogonal_pairs_expert(env: VecEnv) -> AssignmentExpert:
    """The ``orthogonal-pairs`` rule as an assignment teacher."""
    return _rule_expert(env, "orthogonal-pairs")


def plan_estimate_expert(env: VecEnv) -> AssignmentExpert:
    """The ``plan-estimate`` rule (the planner on the tracker's estimate) as a teacher."""
    return _rule_expert(env, "plan-estimate")


def greedy_expert(env: VecEnv) -> AssignmentExpert:
    """The ``greedy-information`` rule as an assignment teacher."""
    return _rule_expert(env, "greedy-information")


def truth_plan_expert(env: VecEnv) -> AssignmentExpert:
    """The truth-informed ``truth-plan`` rule as an assignment teacher: it plans on the
    simulator's truth (:func:`sensorgym.train.evaluation.simulator_state`); the student only
    sees the observation."""
    from sensorgym.agents.stereo_pointing import TruthPlan
    from sensorgym.train.evaluation import simulator_state

    wrapper = find_assignment(env)
    planner = TruthPlan(simulator_state(env), wrapper.params)
    return AssignmentExpert(env, planner.assign)
