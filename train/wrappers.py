"""Observation and action wrappers a training run can name in its hyperparameters.

A run's ``wrappers`` (a run key of ``hyperparams/<algo>.yml``, recorded in the run folder's
``config.yaml``) is a list of ``{name: NAME, ...kwargs}``: SB3 ``VecEnvWrapper``s applied in
order over the SB3 env (:func:`~.evaluation.make_sb3_env`) wherever the policy acts — training,
the trainer's evaluation, ``sensorgym benchmark`` and ``sensorgym render --model``. The names are
data, looked up in :data:`WRAPPERS`; no code is loaded from a run folder.

A wrapper changes what the policy sees or how its action is expressed, never the scenarios or
the reward: the episode return stays the env's accuracy measure, so a wrapped policy is scored
against the rules on the same seeded scenarios.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from importlib import import_module
from typing import Any

import numpy as np
from gymnasium import spaces
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper, VecFrameStack

from sensorgym.train.messages import brief, one_line

#: wrapper name → ``"sensorgym.<module>:<factory>"``, factory ``(venv: VecEnv, **kwargs) -> VecEnv``
WRAPPERS: dict[str, str] = {
    "frame-stack": "sensorgym.train.wrappers:frame_stack",
    "time-feature": "sensorgym.train.wrappers:TimeFeature",
    "termination-penalty": "sensorgym.train.wrappers:TerminationPenalty",
    "final-error-penalty": "sensorgym.train.wrappers:FinalErrorPenalty",
    "pointing-assignment": "sensorgym.train.env_wrappers.stereo_pointing:assignment_wrapper",
    "pointing-plan": "sensorgym.train.env_wrappers.stereo_pointing:plan_wrapper",
    "plan-features": "sensorgym.train.env_wrappers.stereo_pointing:plan_features",
    "placement-target": "sensorgym.train.env_wrappers.stereo_placement:plan_target",
    "scan-modes": "sensorgym.train.env_wrappers.stereo_scanning:scan_modes",
    "gimbal-aim": "sensorgym.train.env_wrappers.gimbal_tracking:aim_offset",
    "gimbal-turn-memory": "sensorgym.train.env_wrappers.gimbal_tracking:turn_memory",
    "gimbal-search-order": "sensorgym.train.env_wrappers.gimbal_search:search_order",
}


class EpisodeSteps:
    """The step count of each slot's current episode in an SB3 vector env: 0 at reset and at
    the first observation of a slot's next episode (SB3 vector envs reset a finished slot in
    the same step). The wrappers that need the time of an episode
    (:class:`TimeFeature`, ``plan-features``, ``pointing-plan`` with ``cue_steps``) count
    with it."""

    def __init__(self, num_envs: int):
        self.t = np.zeros(num_envs, dtype=np.int64)
        """``(num_envs,)``: steps taken in each slot's current episode."""

    def reset(self) -> None:
        """Every slot at its episode's first step."""
        self.t[:] = 0

    def step(self, dones: np.ndarray) -> np.ndarray:
        """Count one step of every slot and restart the slots whose episode ended
        (``dones (num_envs,)``); returns the counts reached, before the restart (what a
        finished episode's terminal observation is at)."""
        self.t += 1
        reached = self.t.copy()
        self.t[np.asarray(dones, dtype=bool)] = 0
        return reached


class ObservedActionWrapper(VecEnvWrapper):
    """An action re-parameterisation that turns the policy's action into the env's own through
    the env's latest observation (which track a receiver watches → gimbal rates slewing onto that
    track's prediction, a scan mode → sectors, …). Subclasses give :meth:`env_action`; this class
    keeps :attr:`last_obs`. Observations, rewards and episodes are the env's."""

    def __init__(self, venv: VecEnv, action_space: spaces.Space):
        super().__init__(venv, action_space=action_space)
        self.last_obs: np.ndarray | None = None
        """The env's latest observation (with SAME_STEP autoreset, a finished scenario's is
        already its next episode's first): what the next action is mapped through."""

    def env_action(self, actions: np.ndarray, obs: np.ndarray) -> np.ndarray:
        """The env's own action for the policy's ``actions`` given the observation ``obs``."""
        raise NotImplementedError(f"{type(self).__name__} must define env_action")

    def reset(self) -> np.ndarray:
        self.last_obs = np.asarray(self.venv.reset())
        return self.last_obs

    def step_async(self, actions: np.ndarray) -> None:
        if self.last_obs is None:
            raise RuntimeError(f"{type(self).__name__}: call reset() first")
        action = self.env_action(np.asarray(actions), self.last_obs)
        self.venv.step_async(np.asarray(action, dtype=np.float32))

    def step_wait(self) -> Any:
        obs, rewards, dones, infos = self.venv.step_wait()
        self.last_obs = np.asarray(obs)
        return obs, rewards, dones, infos


#: the most observations ``frame-stack`` may stack
MAX_STACK = 1024


def frame_stack(venv: VecEnv, n_stack: int = 4) -> VecEnv:
    """The last ``n_stack`` observations side by side (SB3's ``VecFrameStack``); the oldest
    frames of a new episode are zeros. ``n_stack``: an integer in ``[1, MAX_STACK]``."""
    if isinstance(n_stack, bool) or not isinstance(n_stack, int) or not 1 <= n_stack <= MAX_STACK:
        raise ValueError(
            f"frame-stack: n_stack must be an integer in [1, {MAX_STACK}], got {brief(n_stack)}"
        )
    return VecFrameStack(venv, n_stack)


class TimeFeature(VecEnvWrapper):
    """Appends the remaining fraction of the episode, ``1 − t/T`` (1 at reset, 1/T on the last
    step), to a flat ``Box`` observation: a policy of a finite-horizon task needs the time
    left, which the env's observation does not hold (Pardo et al., "Time limits in
    reinforcement learning", 2018).

    ``T`` is ``max_episode_steps`` (default: the vector env's own time limit). Steps are counted
    per slot and restart when the slot's episode ends.
    """

    def __init__(self, venv: VecEnv, max_episode_steps: int | None = None):
        horizon = max_episode_steps or time_limit_of(venv)
        if not isinstance(horizon, int | np.integer) or horizon < 1:
            raise ValueError(
                "time-feature: needs an env with a time limit or max_episode_steps >= 1, "
                f"got {horizon!r}"
            )
        box = venv.observation_space
        if not isinstance(box, spaces.Box) or len(box.shape) != 1:
            raise ValueError(f"time-feature: needs a flat Box observation, got {box}")
        self.horizon = int(horizon)
        low = np.append(box.low, np.float32(0.0)).astype(box.dtype)
        high = np.append(box.high, np.float32(1.0)).astype(box.dtype)
        super().__init__(venv, observation_space=spaces.Box(low, high, dtype=box.dtype))
        self._steps = EpisodeSteps(venv.num_envs)

    def _with_time(self, obs: np.ndarray) -> np.ndarray:
        remaining = 1.0 - np.minimum(self._steps.t, self.horizon) / self.horizon
        return np.concatenate([obs, remaining[:, None].astype(obs.dtype)], axis=1)

    def reset(self) -> np.ndarray:
        self._steps.reset()
        return self._with_time(self.venv.reset())

    def step_wait(self) -> Any:
        obs, rewards, dones, infos = self.venv.step_wait()
        reached = self._steps.step(dones)
        for i in np.flatnonzero(dones):  # the final observation still counts the last step
            terminal = infos[i].get("terminal_observation")
            if terminal is not None:
                remaining = 1.0 - min(reached[i], self.horizon) / self.horizon
                infos[i]["terminal_observation"] = np.append(terminal, remaining).astype(
                    terminal.dtype
                )
        return self._with_time(obs), rewards, dones, infos


class TerminationPenalty(VecEnvWrapper):
    """Subtracts ``penalty`` from the reward of every step that *terminates* an episode (a
    failure such as a broken stand-off; a time-limit truncation, ``TimeLimit.truncated`` in
    the step's info, is not penalised). A training-only reward shaping: list it under
    ``training_wrappers`` so that evaluation, the benchmark and the curve score the env's own
    return. It makes a rare failure expensive enough that the policy keeps its margin (the env's
    own penalty is of the size of one episode's return, so a policy that fails in 2 % of the
    episodes may still gain by flying closer)."""

    def __init__(self, venv: VecEnv, penalty: float = 0.0):
        if isinstance(penalty, bool) or not isinstance(penalty, int | float):
            raise ValueError(f"termination-penalty: penalty must be a number, got {brief(penalty)}")
        if not (np.isfinite(penalty) and penalty >= 0.0):
            raise ValueError(f"termination-penalty: penalty must be finite and >= 0, got {penalty}")
        super().__init__(venv)
        self.penalty = float(penalty)

    def reset(self) -> np.ndarray:
        return self.venv.reset()

    def step_wait(self) -> Any:
        obs, rewards, dones, infos = self.venv.step_wait()
        failed = np.array(
            [
                bool(d) and not info.get("TimeLimit.truncated", False)
                for d, info in zip(dones, infos, strict=True)
            ]
        )
        return obs, rewards - self.penalty * failed.astype(rewards.dtype), dones, infos


class FinalErrorPenalty(VecEnvWrapper):
    """Subtracts ``weight · (e / scale)²`` from the reward of every step that ends an episode
    (terminated or truncated), ``e`` the value of ``key`` in the episode's final info — by default
    ``position_error``, the bearings envs' tracker's position error at the end (m). A
    training-only, tail-aware shaping: the mean of the penalty is ``weight / scale²`` times the
    mean squared final error, so it charges the policy for the RMS error a user quotes, not only
    for the bound the env's reward measures; a few badly tracked episodes cost more than many
    slightly worse ones. The error reads ground truth, which is why it may only shape training
    (list it under ``training_wrappers``): the policy still observes the tracker only, and
    evaluation, the benchmark and the curve score the env's own return.

    ``time_limit_only``: charge only episodes that reach the time limit. Needed for a measure
    that a termination itself makes small — the bound ``position_bound`` collapses when the
    platform runs into the target, so charging it at a broken stand-off pays the policy for
    breaking it; the termination is then left to ``termination-penalty``."""

    def __init__(
        self,
        venv: VecEnv,
        weight: float = 0.0,
        scale: float = 1000.0,
        key: str = "position_error",
        time_limit_only: bool = False,
    ):
        for name, value, low in (("weight", weight, 0.0), ("scale", scale, None)):
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise ValueError(
                    f"final-error-penalty: {name} must be a number, got {brief(value)}"
                )
            if not np.isfinite(value) or (value < 0.0 if low is not None else value <= 0.0):
                bound = ">= 0" if low is not None else "> 0"
                raise ValueError(
                    f"final-error-penalty: {name} must be finite and {bound}, got {value}"
                )
        if not isinstance(key, str) or not key:
            raise ValueError(f"final-error-penalty: key must be an info key, got {brief(key)}")
        if not isinstance(time_limit_only, bool):
            raise ValueError(
                f"final-error-penalty: time_limit_only must be true or false, got "
                f"{brief(time_limit_only)}"
            )
        super().__init__(venv)
        self.weight, self.scale, self.key = float(weight), float(scale), key
        self.time_limit_only = time_limit_only

    def reset(self) -> np.ndarray:
        return self.venv.reset()

    def step_wait(self) -> Any:
        obs, rewards, dones, infos = self.venv.step_wait()
        rewards = np.array(rewards, copy=True)
        for i in np.flatnonzero(dones):
            if self.time_limit_only and not infos[i].get("TimeLimit.truncated", False):
                continue
            final = infos[i].get("final_info", infos[i])
            if self.key not in final:
                raise KeyError(
                    f"final-error-penalty: the env's final info has no {self.key!r} "
                    f"(keys: {sorted(final)})"
                )
            e = float(final[self.key])
            if not np.isfinite(e):
                raise ValueError(f"final-error-penalty: {self.key} is {e} at an episode end")
            rewards[i] -= self.weight * (e / self.scale) ** 2
        return obs, rewards, dones, infos


def time_limit_of(venv: VecEnv) -> int | None:
    """The time limit of the env under ``venv``: the native vector env's ``max_episode_steps``,
    or the registration's for single Gymnasium envs (SB3's ``DummyVecEnv``)."""
    try:
        return venv.get_attr("max_episode_steps")[0]
    except AttributeError:
        spec = venv.get_attr("spec")[0]
        return None if spec is None else spec.max_episode_steps


def base_observation(env: VecEnv, obs: np.ndarray) -> np.ndarray:
    """What the env under ``env``'s wrappers observed, recovered from ``obs``: the time feature
    dropped, the newest of stacked frames kept; an env-specific wrapper that changes the
    observation says how with a ``base_observation(obs)`` method."""
    chain = []
    while isinstance(env, VecEnvWrapper):
        chain.append(env)
        env = env.venv
    for wrapper in chain:  # outermost first
        if isinstance(wrapper, TimeFeature):
            obs = obs[..., :-1]
        elif isinstance(wrapper, VecFrameStack):
            obs = obs[..., -wrapper.venv.observation_space.shape[-1] :]
        elif hasattr(wrapper, "base_observation"):
            obs = wrapper.base_observation(obs)
    return obs


def base_env(env: VecEnv) -> VecEnv:
    """The innermost env of an SB3 wrapper chain."""
    while isinstance(env, VecEnvWrapper):
        env = env.venv
    return env


def find_wrapper(env: VecEnv, kind: type[VecEnvWrapper]) -> Any:
    """The first wrapper of class ``kind`` in ``env``'s SB3 wrapper chain (``env`` itself
    included); ``ValueError`` naming the class when there is none."""
    inner = env
    while not isinstance(inner, kind):
        if not hasattr(inner, "venv"):
            raise ValueError(f"env: no {kind.__name__} in its wrapper stack")
        inner = inner.venv
    return inner


#: the class whose keywords a factory that takes ``**kwargs`` passes them on to
KEYWORDS_OF: dict[str, str] = {
    "plan-features": "sensorgym.train.env_wrappers.stereo_pointing:PlanFeatures",
    "placement-target": "sensorgym.train.env_wrappers.stereo_placement:PlanTargetAction",
}


def wrapper_keywords(name: str) -> list[str] | None:
    """The keywords the wrapper registered as ``name`` takes (its factory's parameters after
    the env, or those of the class :data:`KEYWORDS_OF` names), none starting with ``_``;
    ``None`` when they cannot be told (a factory taking ``**kwargs`` with no class named)."""
    import inspect

    target: Any = wrapper_factory(name)
    if name in KEYWORDS_OF:
        module, _, attr = KEYWORDS_OF[name].partition(":")
        target = getattr(import_module(module), attr)
    parameters = list(inspect.signature(target).parameters.values())
    if parameters and parameters[0].name == "self":
        parameters = parameters[1:]
    if any(p.kind is inspect.Parameter.VAR_KEYWORD for p in parameters):
        return None
    return [
        p.name
        for p in parameters[1:]  # the first is the env wrapped
        if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY) and not p.name.startswith("_")
    ]


def wrapper_factory(name: str) -> Callable[..., VecEnv]:
    """The factory registered as ``name`` in :data:`WRAPPERS`; ``KeyError`` lists the names."""
    if name not in WRAPPERS:
        raise KeyError(f"wrapper {name!r} is not one of {sorted(WRAPPERS)}")
    module, _, attr = WRAPPERS[name].partition(":")
    return getattr(import_module(module), attr)


def check_wrappers(specs: Any) -> list[dict[str, Any]]:
    """``specs`` as a list of ``{name, ...kwargs}`` mappings with registered names and only
    keywords their wrapper takes (:func:`wrapper_keywords`), or ``ValueError`` saying what is
    wrong (a config's ``wrappers`` entry is data from a file; no value is echoed whole)."""
    if specs is None:
        return []
    if not isinstance(specs, Sequence) or isinstance(specs, str):
        raise ValueError(f"wrappers: expected a list of {{name: ...}} mappings, got {brief(specs)}")
    checked = []
    for spec in specs:
        if not isinstance(spec, Mapping) or not isinstance(spec.get("name"), str):
            raise ValueError(f"wrappers: every entry needs a 'name', got {brief(spec)}")
        name = spec["name"]
        if name not in WRAPPERS:
            raise ValueError(f"wrappers: {brief(name)} is not one of {sorted(WRAPPERS)}")
        accepted = wrapper_keywords(name)
        unknown = [k for k in spec if k != "name" and (accepted is None or k not in accepted)]
        if accepted is not None and unknown:
            raise ValueError(
                f"wrappers: {name!r} does not take {brief(unknown)} (its keywords: "
                f"{', '.join(accepted) or 'none'})"
            )
        checked.append(dict(spec))
    return checked


def apply_wrappers(venv: VecEnv, specs: Any) -> VecEnv:
    """``venv`` wrapped by each of ``specs`` in order (see :func:`check_wrappers`)."""
    for spec in check_wrappers(specs):
        kwargs = {k: v for k, v in spec.items() if k != "name"}
        try:
            venv = wrapper_factory(spec["name"])(venv, **kwargs)
        except (TypeError, ValueError, KeyError, AttributeError) as exc:
            # a value of the wrong kind: a wrapper's own checks or its first use of it
            raise ValueError(
                f"wrappers: {spec['name']!r} with {brief(kwargs)}: {one_line(exc)}"
            ) from None
    return venv
