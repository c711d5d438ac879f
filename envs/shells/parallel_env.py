"""The PettingZoo shell every sensorgym env shares: its agents over one batched simulation.

The core steps one scenario (batch of one) with a joint action ``(1, n_agents, *action)``; the
shell splits observations by agent, hands every agent the one team reward, and ends all agents
together (the scenarios are cooperative: receivers or platforms serving one tracker).

``step`` takes a dict ``{agent: action}`` with an action for every live agent and no other key
(PettingZoo's convention; there is no default action); each action passes the Gymnasium door's
own check (:func:`~sensorgym.envs.shells.contract.check_action`), so a wrong shape, a NaN or an
inf gets the same one-line ``ValueError``, prefixed with the agent's name.

Every env module offers PettingZoo's three constructors: ``parallel_env(**kwargs)`` (the native
parallel env), ``env(**kwargs)`` (the AEC env, agents acting in turn, through PettingZoo's
``parallel_to_aec`` with its order checks) and ``raw_env(**kwargs)`` (the same AEC env without
the order checks), made by :func:`aec_constructors`.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Mapping
from types import ModuleType
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from numpy.typing import NDArray
from pettingzoo import AECEnv, ParallelEnv
from pettingzoo.utils.conversions import parallel_to_aec, parallel_to_aec_wrapper

from sensorgym.envs.shells.contract import (
    REGISTERED,
    Core,
    check_action,
    registered_episode_steps,
    resolve_params,
)
from sensorgym.envs.shells.rendering import RENDER_MODES, Frames, check_render_mode
from sensorgym.trackers.validation import count


class CoreParallelEnv(ParallelEnv):
    """Cooperative agents over a batched simulation (PettingZoo Parallel API). Subclasses set
    ``simulation``, ``params_type``, ``env_id``, ``metadata`` (``name``, ``render_fps``),
    ``renderer`` (the module that draws the frames, :mod:`.rendering`) and, optionally,
    ``default_fields`` (params fields that differ from the params defaults for this door).
    ``state()`` concatenates every agent's observation; ``render()`` draws the scenario as the
    Gymnasium env does."""

    metadata: ClassVar[dict[str, Any]] = {"name": "sensorgym", "render_modes": RENDER_MODES}
    simulation: ClassVar[ModuleType]
    params_type: ClassVar[type]
    env_id: ClassVar[str]
    renderer: ClassVar[str | None] = None
    default_fields: ClassVar[dict[str, Any]] = {}

    def __init__(
        self,
        params: Any = None,
        max_episode_steps: int | str = REGISTERED,
        render_mode: str | None = None,
        **fields: Any,
    ):
        if max_episode_steps == REGISTERED:
            max_episode_steps = registered_episode_steps(self.env_id)
        max_episode_steps = count(max_episode_steps, "max_episode_steps")
        check_render_mode(
            render_mode, self.metadata.get("render_modes", []) if self.renderer else []
        )
        if params is None:
            fields = {**self.default_fields, **fields}
        self.core = Core(self.simulation, resolve_params(self.params_type, params, **fields))
        self.params = self.core.params
        self.max_episode_steps = max_episode_steps
        self.render_mode = render_mode
        sp = self.core.spaces
        self.possible_agents = list(sp.agents)
        self.agents: list[str] = []
        self._observation_space, self._action_space = sp.agent_observation, sp.agent_action
        self._rng, _ = seeding.np_random(None)
        self._state: Any = None
        self._steps = 0
        self._frames = Frames(self.renderer, render_mode, self.metadata.get("render_fps", 4))

    @property
    def simulator_state(self) -> Any:
        """The simulation's current state, a batch of one (ground truth included: for
        truth-informed rules, bounds, rendering and diagnostics, never for a policy one could field)."""
        if self._state is None:
            raise RuntimeError("simulator_state: call reset() first")
        return self._state

    @functools.cache  # noqa: B019 - the same space object on every call, as PettingZoo asks
    def observation_space(self, agent: str) -> spaces.Space:
        return self._observation_space

    @functools.cache  # noqa: B019
    def action_space(self, agent: str) -> spaces.Space:
        return self._action_space

    def reset(
        self, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, NDArray[np.float32]], dict[str, dict[str, Any]]]:
        if seed is not None:
            self._rng, _ = seeding.np_random(seed)
        self.agents = list(self.possible_agents)
        self._state = self.core.reset(self._rng, 1)
        self._frames.start(self._state)
        self._steps = 0
        return self._observations(), self._infos()

    def step(self, actions: Mapping[str, Any]) -> tuple[dict, dict, dict, dict, dict]:
        """Step every live agent together under ``actions``, a dict ``{agent: action}``.

        Every live agent (:attr:`agents`) must act and no other key may appear: a missing or an
        unknown agent raises ``ValueError`` naming it and the live agents; anything but a
        mapping raises ``TypeError``. Each action is checked as the Gymnasium door checks its
        action (:func:`~sensorgym.envs.shells.contract.check_action`: shape, NaN, inf), the
        ``ValueError`` prefixed with the agent (``"actions['receiver_0']: action: …"``);
        values outside the Box are clipped by the core. Stepping before :meth:`reset` or
        after the episode ended raises ``RuntimeError``.
        """
        if self._state is None or not self.agents:
            raise RuntimeError("step: call reset() first (the episode is over)")
        if not isinstance(actions, Mapping):
            raise TypeError(
                f"actions: expected a dict {{agent: action}} for the agents {self.agents}, "
                f"got {type(actions).__name__}"
            )
        live = set(self.agents)
        missing = [agent for agent in self.agents if agent not in actions]
        unknown = [key for key in actions if key not in live]
        if missing or unknown:
            problems = [f"no action for {missing}"] if missing else []
            problems += [f"unknown agents {unknown}"] if unknown else []
            raise ValueError(f"actions: {'; '.join(problems)} (live agents: {self.agents})")
        shape = self._action_space.shape
        rows = []
        for agent in self.possible_agents:  # every agent is live: all end together
            try:
                rows.append(check_action(actions[agent], shape))
            except ValueError as exc:
                raise ValueError(f"actions[{agent!r}]: {exc}") from None
        joint = np.stack(rows)
        self._state, reward, terminated = self.core.step(self._state, joint[None], self._rng)
        self._frames.add(self._state, float(reward[0]))
        self._steps += 1
        ended, timed_out = bool(terminated[0]), self._steps >= self.max_episode_steps
        rewards = {agent: float(reward[0]) for agent in self.agents}
        terminations = {agent: ended for agent in self.agents}
        truncations = {agent: timed_out and not ended for agent in self.agents}
        obs, infos = self._observations(), self._infos()
        if ended or timed_out:
            self.agents = []
        return obs, rewards, terminations, truncations, infos

    def render(self) -> NDArray[np.uint8] | None:
        """The frame of the scenario (``"rgb_array"``) or ``None`` after showing it
        (``"human"``); ``None`` with a warning when no ``render_mode`` was given."""
        return self._frames.render(self.params)

    def close(self) -> None:
        self._frames.close()

    def state(self) -> NDArray[np.float32]:
        """Every agent's observation, concatenated in agent order (a centralised critic's view)."""
        if self._state is None:
            raise RuntimeError("state: call reset() first")
        return self.core.observe_agents(self._state)[0].reshape(-1)

    def _observations(self) -> dict[str, NDArray[np.float32]]:
        obs = self.core.observe_agents(self._state)[0]
        return {agent: obs[k] for k, agent in enumerate(self.possible_agents)}

    def _infos(self) -> dict[str, dict[str, Any]]:
        shared = {k: float(v[0]) for k, v in self.core.info(self._state).items()}
        return {agent: dict(shared) for agent in self.possible_agents}


def aec_constructors(
    parallel_env: Callable[..., CoreParallelEnv],
) -> tuple[Callable[..., AECEnv], Callable[..., AECEnv]]:
    """PettingZoo's ``env`` and ``raw_env`` for an env module whose native constructor is
    ``parallel_env``: the AEC view of the parallel env (PettingZoo's
    ``parallel_to_aec``, which steps the parallel env once every agent has acted), with and
    without PettingZoo's order-enforcing wrapper. Both take ``parallel_env``'s keywords."""

    def env(**kwargs: Any) -> AECEnv:
        return parallel_to_aec(parallel_env(**kwargs))

    def raw_env(**kwargs: Any) -> AECEnv:
        return parallel_to_aec_wrapper(parallel_env(**kwargs))

    name = parallel_env.__module__
    env.__module__ = raw_env.__module__ = name
    env.__doc__ = f"PettingZoo's AEC env of :func:`{name}.parallel_env` (agents act in turn)."
    raw_env.__doc__ = f"The AEC env of :func:`{name}.parallel_env` without order checks."
    return env, raw_env
