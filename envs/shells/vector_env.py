"""The native vector shell every sensorgym env shares: ``num_envs`` scenarios in one call.

:class:`CoreVectorEnv` steps all scenarios of a batched simulation at once (no Python loop over
envs) and implements Gymnasium's ``VectorEnv`` with both autoreset modes. With
``agent_view=True`` it presents the per-agent observations ``(num_envs, n_agents, obs)`` and
takes per-agent actions ``(num_envs, n_agents, action)``: what parameter-sharing training
steps (:mod:`sensorgym.train.sb3_vec_env`), still one simulation call per step.
"""

from __future__ import annotations

from types import ModuleType
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space
from numpy.typing import NDArray

from sensorgym.envs.shells.contract import (
    REGISTERED,
    BoolArray,
    Core,
    FloatArray,
    check_action,
    registered_episode_steps,
    resolve_params,
)
from sensorgym.envs.shells.streams import EpisodeStreams
from sensorgym.trackers.validation import count


class CoreVectorEnv(VectorEnv[NDArray[np.float32], NDArray[np.float32], np.ndarray]):
    """``num_envs`` scenarios of a batched core stepped in one call.

    Truncation after ``max_episode_steps`` is done here. ``autoreset_mode``: ``NEXT_STEP``
    (Gymnasium's default) — the step after an episode ends returns the first observation of
    the next one, with reward 0 and both flags False; with ``num_envs=1`` and one seed it
    produces exactly the single env's episodes. ``SAME_STEP`` — an ending scenario restarts
    within the step; its last observation and info go to ``infos["final_obs"]``
    ``(num_envs, ...)`` and ``infos["final_info"]`` (valid where ``"_final_obs"`` /
    ``"_final_info"`` are True) — what SB3 needs (:mod:`sensorgym.train.sb3_vec_env`).

    ``episode_streams=True``: every slot's every episode draws its reset and its noise from a
    generator of its own, keyed by the reset seed, the slot and the episode's number
    (:mod:`.streams`): common random numbers, so that the scenarios a slot meets do not depend
    on when its (or another slot's) episodes ended. The default, one generator
    (``np_random``) for the whole batch, draws each step's noise in one call (faster at large
    batches; what training uses); with ``num_envs=1`` it reproduces the single env.
    """

    simulation: ClassVar[ModuleType]
    params_type: ClassVar[type]
    env_id: ClassVar[str]

    def __init__(
        self,
        num_envs: int = 1,
        params: Any = None,
        max_episode_steps: int | str | None = REGISTERED,
        render_mode: str | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        agent_view: bool = False,
        episode_streams: bool = False,
        **fields: Any,
    ):
        num_envs = count(num_envs, "num_envs")
        if render_mode is not None:
            raise ValueError("render_mode: the vector env does not render (use the single env)")
        if max_episode_steps == REGISTERED:
            max_episode_steps = registered_episode_steps(self.env_id)
        if max_episode_steps is not None and max_episode_steps < 1:
            raise ValueError(f"max_episode_steps: must be >= 1 or None, got {max_episode_steps}")
        self.autoreset_mode = AutoresetMode(autoreset_mode)
        if self.autoreset_mode is AutoresetMode.DISABLED:
            raise ValueError("autoreset_mode: NEXT_STEP or SAME_STEP (DISABLED is not supported)")
        self.metadata = {"render_modes": [], "autoreset_mode": self.autoreset_mode}
        self.core = Core(self.simulation, resolve_params(self.params_type, params, **fields))
        self.params = self.core.params
        self.num_envs = num_envs
        self.max_episode_steps = max_episode_steps
        self.render_mode = render_mode
        self.agent_view = agent_view
        if not isinstance(episode_streams, bool):
            raise TypeError(f"episode_streams: expected a bool, got {episode_streams!r}")
        self.episode_streams = episode_streams
        self._streams: EpisodeStreams | None = None
        self._last_action: FloatArray | None = None
        sp = self.core.spaces
        self.n_agents = sp.n_agents
        if agent_view:
            # per-agent spaces; the batch carries a scenario and an agent axis
            self.single_observation_space, self.single_action_space = (
                sp.agent_observation,
                sp.agent_action,
            )
            self.observation_space = _batch_agents(sp.agent_observation, num_envs, sp.n_agents)
            self.action_space = _batch_agents(sp.agent_action, num_envs, sp.n_agents)
        else:
            self.single_observation_space, self.single_action_space = sp.observation, sp.action
            self.observation_space = batch_space(sp.observation, num_envs)
            self.action_space = batch_space(sp.action, num_envs)
        self._state: Any = None
        self._steps = np.zeros(num_envs, dtype=np.int64)
        self._done = np.zeros(num_envs, dtype=bool)  # NEXT_STEP: ended on the last step
        self._all_set = np.ones(num_envs, dtype=bool)
        self._all_set.flags.writeable = False

    @property
    def simulator_state(self) -> Any:
        """The simulation's current state, batch ``num_envs`` (ground truth included: for
        truth-informed rules, bounds and diagnostics, never for a policy one could field)."""
        if self._state is None:
            raise RuntimeError("simulator_state: call reset() first")
        return self._state

    @property
    def last_action(self) -> FloatArray:
        """The actions of the last step as this env took them (``action_space``'s shape,
        float64, not yet clipped): for diagnostics and bounds that replay what a policy
        played."""
        if self._last_action is None:
            raise RuntimeError("last_action: no step taken yet")
        return self._last_action

    def _observe(self, state: Any) -> NDArray[np.float32]:
        if self.agent_view:
            return self.core.observe_agents(state)
        return self.core.observe(state)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[NDArray[np.float32], dict[str, Any]]:
        super().reset(seed=seed)
        if self.episode_streams:
            # the streams' root: the seed itself, or fresh entropy from np_random when unseeded
            root = seed if seed is not None else int(self.np_random.integers(2**63))
            self._streams = EpisodeStreams(self.num_envs, root)
        self._state = self.core.reset(self._rng(), self.num_envs)
        self._steps[:] = 0
        self._done[:] = False
        return self._observe(self._state), self._infos(self._state)

    def step(
        self, actions: NDArray[np.float32]
    ) -> tuple[NDArray[np.float32], FloatArray, BoolArray, BoolArray, dict[str, Any]]:
        if self._state is None:
            raise RuntimeError("step: call reset() first")
        a = check_action(actions, self.action_space.shape)
        self._last_action = a
        if self.autoreset_mode is AutoresetMode.SAME_STEP:
            return self._step_same(a)
        return self._step_next(a)

    def _restart(self, done: BoolArray, state: Any, keep: Any = ()) -> Any:
        """Fresh scenarios where ``done``, drawn only for those (all of them when every
        scenario restarts). ``state`` is one a step has just returned: the fresh rows are
        written into its arrays, except those it shares with the previous state or with
        ``keep`` (observations and infos handed out), which are copied."""
        if self._streams is not None:
            self._streams.next_episode(done)
        if done.all():
            return self.core.reset(self._rng(), self.num_envs)
        fresh = self.core.reset(self._rng(done), int(done.sum()), like=state)
        return self.core.scatter(done, fresh, state, in_place=True, keep=(self._state, keep))

    def _truncated(self) -> BoolArray:
        if self.max_episode_steps is None:
            return np.zeros(self.num_envs, dtype=bool)
        return self._steps >= self.max_episode_steps

    def _step_next(self, a: FloatArray) -> tuple:
        done = self._done
        reward = np.zeros(self.num_envs)
        terminated = np.zeros(self.num_envs, dtype=bool)
        if done.all():
            if self._streams is not None:
                self._streams.next_episode(done)
            new = self.core.reset(self._rng(), self.num_envs)
        else:
            new, reward, terminated = self.core.step(self._state, a, self._rng())
            if done.any():
                new = self._restart(done, new)
                reward = np.where(done, 0.0, reward)
                terminated = terminated & ~done
        self._steps = np.where(done, 0, self._steps + 1)
        # as the TimeLimit wrapper of the single env: both flags may be set on one step
        truncated = self._truncated() & ~done
        self._state, self._done = new, terminated | truncated
        return self._observe(new), reward, terminated, truncated, self._infos(new)

    def _step_same(self, a: FloatArray) -> tuple:
        new, reward, terminated = self.core.step(self._state, a, self._rng())
        self._steps = self._steps + 1
        truncated = self._truncated()
        done = terminated | truncated
        obs, infos = self._observe(new), self._infos(new)
        if done.any():
            final = {"final_obs": obs, "_final_obs": done, "final_info": infos, "_final_info": done}
            # the final observation and info keep the pre-reset values
            new = self._restart(done, new, keep=(obs, infos))
            self._steps = np.where(done, 0, self._steps)
            obs, infos = self._observe(new), {**self._infos(new), **final}
        self._state = new
        return obs, reward, terminated, truncated, infos

    def _rng(self, rows: BoolArray | None = None) -> Any:
        """The generator of the batch's draws (of the rows ``rows`` only, for a partial reset):
        ``np_random``, or the rows' episode streams."""
        if self._streams is None:
            return self.np_random
        return self._streams.rows(rows)

    def _infos(self, state: Any) -> dict[str, Any]:
        # Gymnasium's vector-info layout: the values and a "_key" mask of the envs that set them
        # every env sets every key: one read-only mask serves them all
        infos: dict[str, Any] = {}
        for key, value in self.core.info(state).items():
            infos[key], infos[f"_{key}"] = value, self._all_set
        return infos


def _batch_agents(space: spaces.Box, num_envs: int, n_agents: int) -> spaces.Box:
    """``(num_envs, n_agents, *shape)`` Box of a per-agent Box."""
    shape = (num_envs, n_agents, *space.shape)
    low = np.broadcast_to(space.low, shape)
    high = np.broadcast_to(space.high, shape)
    return spaces.Box(low, high, shape, space.dtype)
