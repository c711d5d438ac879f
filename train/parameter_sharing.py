"""Parameter sharing: one SB3 policy drives every agent of cooperative PettingZoo envs.

:class:`ParameterSharingVecEnv` presents ``copies`` parallel envs with ``n`` agents each as one
SB3 ``VecEnv`` of ``copies · n`` slots (slot ``i`` = agent ``i mod n`` of copy ``i div n``), so
PPO or SAC trains a single policy on every agent's experience. Agents are told apart by their
observation (our multi-agent envs put the agent's index or own frame in it). It replaces
SuperSuit's conversion, whose SB3 path is unmaintained; it needs what our envs guarantee:
every agent has the same spaces, and all agents of a copy end their episode together.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from typing import Any

import numpy as np
from pettingzoo import ParallelEnv
from stable_baselines3.common.vec_env import VecEnv
from stable_baselines3.common.vec_env.base_vec_env import VecEnvStepReturn


class ParameterSharingVecEnv(VecEnv):
    """``copies`` PettingZoo parallel envs, every agent a slot of one SB3 ``VecEnv``."""

    def __init__(self, env_fns: Sequence[Callable[[], ParallelEnv]]):
        if not env_fns:
            raise ValueError("env_fns: need at least one env constructor")
        self.envs = [fn() for fn in env_fns]
        self.agents = list(self.envs[0].possible_agents)
        obs_space = self.envs[0].observation_space(self.agents[0])
        act_space = self.envs[0].action_space(self.agents[0])
        for env in self.envs:
            if list(env.possible_agents) != self.agents:
                raise ValueError("env_fns: every copy must have the same agents")
            for agent in self.agents:
                if (
                    env.observation_space(agent) != obs_space
                    or env.action_space(agent) != act_space
                ):
                    raise ValueError(f"{agent}: parameter sharing needs identical spaces per agent")
        self.n_agents = len(self.agents)
        self._actions: np.ndarray | None = None
        super().__init__(len(self.envs) * self.n_agents, obs_space, act_space)

    def _stack(self, per_env: list[dict[str, Any]]) -> np.ndarray:
        return np.stack([obs[agent] for obs in per_env for agent in self.agents])

    def reset(self) -> np.ndarray:
        # SB3 seeds slot i with seed + i; a copy takes the seed of its first slot
        obs = [env.reset(seed=self._seeds[c * self.n_agents])[0] for c, env in enumerate(self.envs)]
        self._reset_seeds()
        self._reset_options()
        return self._stack(obs)

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions)

    def step_wait(self) -> VecEnvStepReturn:
        if self._actions is None:
            raise RuntimeError("step_wait: call step_async first")
        actions = self._actions.reshape(len(self.envs), self.n_agents, *self._actions.shape[1:])
        self._actions = None
        all_obs, rewards, dones, infos = [], [], [], []
        for env, joint in zip(self.envs, actions, strict=True):
            obs, rew, term, trunc, info = env.step(dict(zip(self.agents, joint, strict=True)))
            ended = [term[a] or trunc[a] for a in self.agents]
            if any(ended) and not all(ended):
                raise RuntimeError("parameter sharing needs all agents of an env to end together")
            slot_infos = [dict(info.get(agent, {})) for agent in self.agents]
            if all(ended):
                for agent, slot in zip(self.agents, slot_infos, strict=True):
                    slot["terminal_observation"] = obs[agent]
                    slot["TimeLimit.truncated"] = bool(trunc[agent] and not term[agent])
                obs, _ = env.reset()
            all_obs.append(obs)
            rewards += [rew[agent] for agent in self.agents]
            dones += [all(ended)] * self.n_agents
            infos += slot_infos
        return (
            self._stack(all_obs),
            np.asarray(rewards, dtype=np.float32),
            np.asarray(dones, dtype=bool),
            infos,
        )

    def close(self) -> None:
        for env in self.envs:
            env.close()

    def get_attr(self, attr_name: str, indices: Iterable[int] | int | None = None) -> list[Any]:
        return [getattr(self.envs[i // self.n_agents], attr_name, None) for i in self._idx(indices)]

    def set_attr(
        self, attr_name: str, value: Any, indices: Iterable[int] | int | None = None
    ) -> None:
        for c in {i // self.n_agents for i in self._idx(indices)}:
            setattr(self.envs[c], attr_name, value)

    def env_method(
        self,
        method_name: str,
        *method_args: Any,
        indices: Iterable[int] | int | None = None,
        **method_kwargs: Any,
    ) -> list[Any]:
        return [
            getattr(self.envs[i // self.n_agents], method_name)(*method_args, **method_kwargs)
            for i in self._idx(indices)
        ]

    def env_is_wrapped(
        self, wrapper_class: type, indices: Iterable[int] | int | None = None
    ) -> list[bool]:
        return [False for _ in self._idx(indices)]

    def _idx(self, indices: Iterable[int] | int | None) -> Sequence[int]:
        if indices is None:
            return range(self.num_envs)
        if isinstance(indices, int):
            return [indices]
        return list(indices)
