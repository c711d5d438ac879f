"""stable-baselines3 ``VecEnv`` over one of our native (batched) vector envs: single-agent and
parameter-sharing training through one adapter.

SB3 trains on its own ``VecEnv`` API; ``DummyVecEnv`` steps ``n`` single envs one after another
in Python, while our vector envs step all scenarios in one batched simulation call (tens of
times faster, ``benchmarks/bearings_maneuver.py``). This adapter translates the vector env, run
with ``autoreset_mode=SAME_STEP``, to SB3's conventions. Its slots are the vector env's
scenarios, or — for a vector env with ``agent_view=True`` — every agent of every scenario
(slot ``i`` = agent ``i mod n`` of scenario ``i div n``), so that one policy learns from every
agent's experience (parameter sharing over the env's PettingZoo agents), still one simulation
call per step:

* ``dones = terminated | truncated``; an ending scenario's returned observation is already the
  next episode's first one, its last one is in ``infos[i]["terminal_observation"]``;
* ``infos[i]["TimeLimit.truncated"]`` is True for a time-limit ending (not a termination), so
  SB3 bootstraps the value there and only there;
* per-env info dicts hold the vector env's scalar diagnostics;
* with agents as slots, every agent of a scenario gets the scenario's team reward and ends with
  it; agents are told apart by their observation (our envs put the agent's index or own frame
  in it).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from stable_baselines3.common.vec_env import VecEnv
from stable_baselines3.common.vec_env.base_vec_env import VecEnvStepReturn


class SB3VecEnv(VecEnv):
    """SB3 view of a native vector env (which must use ``AutoresetMode.SAME_STEP``); one slot
    per scenario, or per agent of every scenario when the vector env has ``agent_view``."""

    def __init__(self, venv: VectorEnv):
        if venv.metadata.get("autoreset_mode") is not AutoresetMode.SAME_STEP:
            raise ValueError(
                "venv: SB3 needs autoreset_mode=SAME_STEP (create the vector env with "
                "autoreset_mode='SameStep')"
            )
        self.venv = venv
        self.scenarios = venv.num_envs
        self.agent_view = bool(getattr(venv, "agent_view", False))
        self.agents_per_scenario = venv.n_agents if self.agent_view else 1
        self._actions: np.ndarray | None = None
        super().__init__(
            self.scenarios * self.agents_per_scenario,
            venv.single_observation_space,
            venv.single_action_space,
        )

    def _slots(self, per_scenario: np.ndarray) -> np.ndarray:
        """``(B, ...)`` per-scenario values (or ``(B, n, ...)`` per-agent ones) → per slot
        (also for one agent per scenario: its ``(B, 1, ...)`` values lose the agent axis)."""
        if not self.agent_view:
            return per_scenario
        a = np.asarray(per_scenario)
        if a.ndim >= 2 and a.shape[1] == self.agents_per_scenario and a.shape[0] == self.scenarios:
            return a.reshape(self.num_envs, *a.shape[2:])
        return np.repeat(a, self.agents_per_scenario, axis=0)

    def reset(self) -> np.ndarray:
        # SB3 gives each env its own seed (seed + i); one batched env takes the first
        seed = self._seeds[0]
        obs, _ = self.venv.reset(seed=seed)
        self._reset_seeds()
        self._reset_options()
        return self._slots(obs)

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions)

    def step_wait(self) -> VecEnvStepReturn:
        if self._actions is None:
            raise RuntimeError("step_wait: call step_async first")
        actions = self._actions
        if self.agent_view:
            actions = actions.reshape(self.scenarios, self.agents_per_scenario, *actions.shape[1:])
        obs, reward, terminated, truncated, infos = self.venv.step(actions)
        self._actions = None
        dones = self._slots(np.logical_or(terminated, truncated))
        time_limit = self._slots(truncated & ~terminated)
        per_env = self._split_infos(infos)
        if dones.any():
            final = self._slots(infos["final_obs"])
            final_info = infos.get("final_info", {})
            for i in np.flatnonzero(dones):
                per_env[i]["terminal_observation"] = final[i]
                per_env[i]["TimeLimit.truncated"] = bool(time_limit[i])
                # the diagnostics of the step that ended the episode (the slot's own info is
                # already the next episode's): what per-episode accuracy metrics are read from
                per_env[i]["final_info"] = self._final_info(
                    final_info, i // self.agents_per_scenario
                )
        return self._slots(obs), self._slots(reward).astype(np.float32), dones, per_env

    def _split_infos(self, infos: dict[str, Any]) -> list[dict[str, Any]]:
        """Gymnasium's dict of arrays (with ``_key`` masks) → SB3's list of per-slot dicts.

        Our shells set every diagnostic for every scenario, so the columns are converted to
        Python floats in one call each and zipped into the dicts; a partial mask (another
        vector env) takes the general path.
        """
        keys = [k for k in infos if not k.startswith("_") and k not in ("final_obs", "final_info")]
        n = self.agents_per_scenario
        if all(np.all(infos.get(f"_{k}", True)) for k in keys):
            columns = [np.repeat(np.asarray(infos[k]), n).tolist() for k in keys]
            return [dict(zip(keys, row, strict=True)) for row in zip(*columns, strict=True)] or [
                {} for _ in range(self.num_envs)
            ]
        out: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        for key in keys:
            value = infos[key]
            mask = infos.get(f"_{key}", np.ones(self.scenarios, dtype=bool))
            for b in np.flatnonzero(mask):
                item = value[b].item() if hasattr(value[b], "item") else value[b]
                for i in range(b * n, (b + 1) * n):
                    out[i][key] = item
        return out

    @staticmethod
    def _final_info(final_info: dict[str, Any], b: int) -> dict[str, Any]:
        """Scenario ``b``'s entries of Gymnasium's ``final_info`` (dict of masked arrays)."""
        out = {}
        for key, value in final_info.items():
            mask = final_info.get(f"_{key}")
            if key.startswith("_") or (mask is not None and not mask[b]):
                continue
            item = value[b]
            out[key] = item.item() if hasattr(item, "item") else item
        return out

    def close(self) -> None:
        self.venv.close()

    def get_attr(self, attr_name: str, indices: Iterable[int] | int | None = None) -> list[Any]:
        return [getattr(self.venv, attr_name, None) for _ in self._indices(indices)]

    def set_attr(
        self, attr_name: str, value: Any, indices: Iterable[int] | int | None = None
    ) -> None:
        setattr(self.venv, attr_name, value)

    def env_method(
        self,
        method_name: str,
        *method_args: Any,
        indices: Iterable[int] | int | None = None,
        **method_kwargs: Any,
    ) -> list[Any]:
        # one batched env: the call happens once, its result is shared by every index
        result = getattr(self.venv, method_name)(*method_args, **method_kwargs)
        return [result for _ in self._indices(indices)]

    def env_is_wrapped(
        self, wrapper_class: type, indices: Iterable[int] | int | None = None
    ) -> list[bool]:
        return [False for _ in self._indices(indices)]

    def _indices(self, indices: Iterable[int] | int | None) -> Sequence[int]:
        if indices is None:
            return range(self.num_envs)
        if isinstance(indices, int):
            return [indices]
        return list(indices)
