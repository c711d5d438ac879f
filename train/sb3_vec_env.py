"""stable-baselines3 ``VecEnv`` over one of our native (batched) Gymnasium vector envs.

SB3 trains on its own ``VecEnv`` API; ``DummyVecEnv`` steps ``n`` single envs one after another
in Python, while our vector envs step all scenarios in one batched core call (tens of times
faster, ``benchmarks/bearings_maneuver.py``). This adapter translates the vector env, run with
``autoreset_mode=SAME_STEP``, to SB3's conventions:

* ``dones = terminated | truncated``; an ending scenario's returned observation is already the
  next episode's first one, its last one is in ``infos[i]["terminal_observation"]``;
* ``infos[i]["TimeLimit.truncated"]`` is True for a time-limit ending (not a termination), so
  SB3 bootstraps the value there and only there;
* per-env info dicts hold the vector env's scalar diagnostics.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from stable_baselines3.common.vec_env import VecEnv
from stable_baselines3.common.vec_env.base_vec_env import VecEnvStepReturn


class SB3VecEnv(VecEnv):
    """SB3 view of a native vector env (which must use ``AutoresetMode.SAME_STEP``)."""

    def __init__(self, venv: VectorEnv):
        if venv.metadata.get("autoreset_mode") is not AutoresetMode.SAME_STEP:
            raise ValueError(
                "venv: SB3 needs autoreset_mode=SAME_STEP (create the vector env with "
                "autoreset_mode='SameStep')"
            )
        self.venv = venv
        self._actions: np.ndarray | None = None
        super().__init__(venv.num_envs, venv.single_observation_space, venv.single_action_space)

    def reset(self) -> np.ndarray:
        # SB3 gives each env its own seed (seed + i); one batched env takes the first
        seed = self._seeds[0]
        obs, _ = self.venv.reset(seed=seed)
        self._reset_seeds()
        self._reset_options()
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions)

    def step_wait(self) -> VecEnvStepReturn:
        if self._actions is None:
            raise RuntimeError("step_wait: call step_async first")
        obs, reward, terminated, truncated, infos = self.venv.step(self._actions)
        self._actions = None
        dones = np.logical_or(terminated, truncated)
        per_env = self._split_infos(infos)
        for i in np.flatnonzero(dones):
            per_env[i]["terminal_observation"] = infos["final_obs"][i]
            per_env[i]["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
        return obs, reward.astype(np.float32), dones, per_env

    def _split_infos(self, infos: dict[str, Any]) -> list[dict[str, Any]]:
        """Gymnasium's dict of arrays (with ``_key`` masks) → SB3's list of per-env dicts."""
        out: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        for key, value in infos.items():
            if key.startswith("_") or key in ("final_obs", "final_info"):
                continue
            mask = infos.get(f"_{key}", np.ones(self.num_envs, dtype=bool))
            for i in np.flatnonzero(mask):
                out[i][key] = value[i].item() if hasattr(value[i], "item") else value[i]
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
