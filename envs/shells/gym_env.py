"""The Gymnasium shells every sensorgym env shares: one scenario, or a batch, over a pure core.

A simulation core steps ``B`` scenarios at once (leading axis) through pure functions; an env
module wraps its core functions in a small object with the :class:`BatchedCore` interface and
gets both Gymnasium shells from here: :class:`CoreEnv` (batch of one, ``gym.make``) and
:class:`CoreVectorEnv` (native ``VectorEnv``, both autoreset modes). Episode bookkeeping,
action checks, seeding and autoreset live here once; physics lives only in the cores.
"""

from __future__ import annotations

from typing import Any, Protocol

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


class BatchedCore(Protocol):
    """What a shell needs of a simulation core (all arrays batched over scenarios ``B``)."""

    params: Any

    def reset(self, rng: np.random.Generator, batch: int, like: Any = None) -> Any:
        """``batch`` fresh scenarios; ``like`` is the running batch they will be swapped into
        (a core whose scenarios share state, e.g. a tracker clock, matches it), or ``None``."""
        ...

    def step(
        self, state: Any, action: FloatArray, rng: np.random.Generator
    ) -> tuple[Any, FloatArray, BoolArray]:
        """``(state, reward (B,), terminated (B,))`` after ``action`` ``(B, *action shape)``."""
        ...

    def observe(self, state: Any) -> NDArray[np.float32]:
        """Observations ``(B, *observation shape)``."""
        ...

    def where(self, mask: BoolArray, new: Any, old: Any) -> Any:
        """Scenario-wise select: ``new`` where ``mask`` ``(B,)``, else ``old``."""
        ...

    def info(self, state: Any) -> dict[str, FloatArray]:
        """Diagnostics ``{key: (B,) array}`` (may hold ground truth: never for the policy)."""
        ...


def check_action(action: Any, shape: tuple[int, ...]) -> FloatArray:
    """The action as float64 of ``shape``; wrong shapes, NaN and inf raise ``ValueError``.

    Values outside the Box are not an error: cores clip them (the documented fallback).
    """
    try:
        a = np.asarray(action, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"action: cannot be read as floats ({exc})") from None
    if a.shape != shape:
        raise ValueError(f"action: expected shape {shape}, got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError("action: contains NaN or infinite values")
    return a


class CoreEnv(gym.Env[NDArray[np.float32], NDArray[np.float32]]):
    """One scenario of a batched core. Subclasses set ``metadata`` and call ``super().__init__``
    with the core and spaces, and implement :meth:`draw` for ``render_mode="rgb_array"``."""

    def __init__(
        self,
        core: BatchedCore,
        observation_space: spaces.Space,
        action_space: spaces.Space,
        render_mode: str | None = None,
    ):
        modes = self.metadata.get("render_modes", [])
        if render_mode not in (None, *modes):
            raise ValueError(f"render_mode: one of {modes}, got {render_mode!r}")
        self.core = core
        self.params = core.params
        self.render_mode = render_mode
        self.observation_space, self.action_space = observation_space, action_space
        self._state: Any = None
        self._history: list[Any] = []

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[NDArray[np.float32], dict[str, Any]]:
        super().reset(seed=seed)
        self._state = self.core.reset(self.np_random, 1)
        self._history = [self._state]
        return self.core.observe(self._state)[0], self._info()

    def step(
        self, action: NDArray[np.float32]
    ) -> tuple[NDArray[np.float32], float, bool, bool, dict[str, Any]]:
        if self._state is None:
            raise RuntimeError("step: call reset() first")
        a = check_action(action, self.action_space.shape)
        self._state, reward, terminated = self.core.step(self._state, a[None], self.np_random)
        if self.render_mode is not None:
            self._history.append(self._state)
        # truncation=False: the time limit is the TimeLimit wrapper added by gym.make
        obs = self.core.observe(self._state)[0]
        return obs, float(reward[0]), bool(terminated[0]), False, self._info()

    def _info(self) -> dict[str, Any]:
        return {k: float(v[0]) for k, v in self.core.info(self._state).items()}

    def render(self) -> NDArray[np.uint8] | None:
        if self.render_mode is None:
            gym.logger.warn("render: no render_mode was given to the environment")
            return None
        if self._state is None:
            raise RuntimeError("render: call reset() first")
        return self.draw(self._history)

    def draw(self, history: list[Any]) -> NDArray[np.uint8]:
        """An RGB image of scenario 0 of the states in ``history`` (oldest first)."""
        raise NotImplementedError(f"{type(self).__name__} does not render")


class CoreVectorEnv(VectorEnv[NDArray[np.float32], NDArray[np.float32], np.ndarray]):
    """``num_envs`` scenarios of a batched core stepped in one call.

    Truncation after ``max_episode_steps`` is done here. ``autoreset_mode``: ``NEXT_STEP``
    (Gymnasium's default) — the step after an episode ends returns the first observation of
    the next one, with reward 0 and both flags False; with ``num_envs=1`` and one seed it
    produces exactly the single env's episodes. ``SAME_STEP`` — an ending scenario restarts
    within the step; its last observation and info go to ``infos["final_obs"]``
    ``(num_envs, ...)`` and ``infos["final_info"]`` (valid where ``"_final_obs"`` /
    ``"_final_info"`` are True) — what SB3 needs (:mod:`sensorgym.train.sb3_vec_env`).
    """

    def __init__(
        self,
        core: BatchedCore,
        num_envs: int,
        observation_space: spaces.Space,
        action_space: spaces.Space,
        max_episode_steps: int | None,
        render_mode: str | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
    ):
        if num_envs < 1:
            raise ValueError(f"num_envs: must be >= 1, got {num_envs}")
        if render_mode is not None:
            raise ValueError("render_mode: the vector env does not render (use the single env)")
        if max_episode_steps is not None and max_episode_steps < 1:
            raise ValueError(f"max_episode_steps: must be >= 1 or None, got {max_episode_steps}")
        self.autoreset_mode = AutoresetMode(autoreset_mode)
        if self.autoreset_mode is AutoresetMode.DISABLED:
            raise ValueError("autoreset_mode: NEXT_STEP or SAME_STEP (DISABLED is not supported)")
        self.metadata = {"render_modes": [], "autoreset_mode": self.autoreset_mode}
        self.core = core
        self.params = core.params
        self.num_envs = num_envs
        self.max_episode_steps = max_episode_steps
        self.render_mode = render_mode
        self.single_observation_space, self.single_action_space = observation_space, action_space
        self.observation_space = batch_space(observation_space, num_envs)
        self.action_space = batch_space(action_space, num_envs)
        self._state: Any = None
        self._steps = np.zeros(num_envs, dtype=np.int64)
        self._done = np.zeros(num_envs, dtype=bool)  # NEXT_STEP: ended on the last step

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[NDArray[np.float32], dict[str, Any]]:
        super().reset(seed=seed)
        self._state = self.core.reset(self.np_random, self.num_envs)
        self._steps[:] = 0
        self._done[:] = False
        return self.core.observe(self._state), self._infos(self._state)

    def step(
        self, actions: NDArray[np.float32]
    ) -> tuple[NDArray[np.float32], FloatArray, BoolArray, BoolArray, dict[str, Any]]:
        if self._state is None:
            raise RuntimeError("step: call reset() first")
        a = check_action(actions, self.action_space.shape)
        if self.autoreset_mode is AutoresetMode.SAME_STEP:
            return self._step_same(a)
        return self._step_next(a)

    def _restart(self, done: BoolArray, state: Any) -> Any:
        """Fresh scenarios where ``done`` (all of them when every scenario restarts)."""
        if done.all():
            return self.core.reset(self.np_random, self.num_envs)
        fresh = self.core.reset(self.np_random, self.num_envs, like=state)
        return self.core.where(done, fresh, state)

    def _truncated(self) -> BoolArray:
        if self.max_episode_steps is None:
            return np.zeros(self.num_envs, dtype=bool)
        return self._steps >= self.max_episode_steps

    def _step_next(self, a: FloatArray) -> tuple:
        done = self._done
        reward = np.zeros(self.num_envs)
        terminated = np.zeros(self.num_envs, dtype=bool)
        if done.all():
            new = self._restart(done, self._state)
        else:
            new, reward, terminated = self.core.step(self._state, a, self.np_random)
            if done.any():
                new = self._restart(done, new)
                reward = np.where(done, 0.0, reward)
                terminated = terminated & ~done
        self._steps = np.where(done, 0, self._steps + 1)
        # as the TimeLimit wrapper of the single env: both flags may be set on one step
        truncated = self._truncated() & ~done
        self._state, self._done = new, terminated | truncated
        return self.core.observe(new), reward, terminated, truncated, self._infos(new)

    def _step_same(self, a: FloatArray) -> tuple:
        new, reward, terminated = self.core.step(self._state, a, self.np_random)
        self._steps = self._steps + 1
        truncated = self._truncated()
        done = terminated | truncated
        obs, infos = self.core.observe(new), self._infos(new)
        if done.any():
            final = {"final_obs": obs, "_final_obs": done, "final_info": infos, "_final_info": done}
            new = self._restart(done, new)
            self._steps = np.where(done, 0, self._steps)
            obs, infos = self.core.observe(new), {**self._infos(new), **final}
        self._state = new
        return obs, reward, terminated, truncated, infos

    def _infos(self, state: Any) -> dict[str, Any]:
        # Gymnasium's vector-info layout: the values and a "_key" mask of the envs that set them
        infos: dict[str, Any] = {}
        for key, value in self.core.info(state).items():
            infos[key], infos[f"_{key}"] = value, np.ones(self.num_envs, dtype=bool)
        return infos


def receiver_spaces(obs_dim: int, n_receivers: int, clip: float) -> tuple[spaces.Box, spaces.Box]:
    """Spaces of a receiver team: one observation ``Box(-clip, clip, (obs_dim,))`` and a
    flattened ``(2n,)`` action in ``[-1, 1]`` (SB3 policies handle one-dimensional Box actions
    everywhere)."""
    obs = spaces.Box(-clip, clip, (obs_dim,), np.float32)
    act = spaces.Box(-1.0, 1.0, (2 * n_receivers,), np.float32)
    return obs, act


class ReceiverTeamCore:
    """:class:`BatchedCore` over a core module for a team of ``n`` receivers that share one
    observation and never terminate (only the time limit ends an episode). The module (set as
    ``functions`` by a subclass) provides ``reset(params, rng, batch)``, ``step(params, state,
    action, rng) -> (state, reward)``, ``observe(params, state)`` and ``where``; subclasses add
    ``info``. PettingZoo agents get the shared observation plus a one-hot of their index."""

    functions: Any

    def __init__(self, params: Any):
        self.params = params

    def reset(self, rng: np.random.Generator, batch: int, like: Any = None) -> Any:
        return self.functions.reset(self.params, rng, batch)

    def step(
        self, state: Any, action: FloatArray, rng: np.random.Generator
    ) -> tuple[Any, FloatArray, BoolArray]:
        new, reward = self.functions.step(self.params, state, action, rng)
        # nothing physical ends an episode: only the time limit (truncation)
        return new, reward, np.zeros(reward.shape[0], dtype=bool)

    def observe(self, state: Any) -> NDArray[np.float32]:
        return self.functions.observe(self.params, state)

    def observe_agents(self, state: Any) -> NDArray[np.float32]:
        """``(B, n, obs_dim + n)``: the shared observation and a one-hot of the receiver."""
        obs = self.observe(state)
        n = self.params.n_receivers
        shared = np.broadcast_to(obs[:, None, :], (obs.shape[0], n, obs.shape[1]))
        one_hot = np.broadcast_to(np.eye(n, dtype=np.float32), (obs.shape[0], n, n))
        return np.concatenate([shared, one_hot], axis=-1)

    def where(self, mask: BoolArray, new: Any, old: Any) -> Any:
        return self.functions.where(mask, new, old)
