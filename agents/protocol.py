"""The one interface every heuristic shares with trained stable-baselines3 models."""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray


@runtime_checkable
class PolicyPredictor(Protocol):
    """SB3's ``predict``: ``evaluate_policy`` scores anything with it like a trained model.

    ``observation`` is one observation or a batch ``(n_envs, ...)``; ``state`` is the policy's
    own memory (``None`` for memoryless rules), handed back on the next call; ``episode_start``
    ``(n_envs,)`` marks the envs whose episode has just begun.
    """

    def predict(
        self,
        observation: NDArray[Any],
        state: Any = None,
        episode_start: NDArray[np.bool_] | None = None,
        deterministic: bool = True,
    ) -> tuple[NDArray[Any], Any]: ...


def as_batch(observation: NDArray[Any], obs_dim: int) -> tuple[NDArray[np.float64], bool]:
    """``(n_envs, obs_dim)`` float64 view of one or many observations, and whether it was one."""
    obs = np.asarray(observation, dtype=np.float64)
    single = obs.ndim == 1
    obs = obs[None] if single else obs
    if obs.ndim != 2 or obs.shape[1] != obs_dim:
        raise ValueError(
            f"observation: expected shape ({obs_dim},) or (n, {obs_dim}), got {obs.shape}"
        )
    if not np.all(np.isfinite(obs)):
        raise ValueError("observation: contains NaN or infinite values")
    return obs, single


class MemorylessRule(ABC):
    """SB3's ``predict`` for rules without memory, written once: a subclass gives ``obs_dim``
    and ``act(obs (N, obs_dim)) -> actions (N, ...)``; ``predict`` accepts one observation or a
    batch and returns float32 actions and no state."""

    @property
    def obs_dim(self) -> int:
        return self.params.obs_dim  # type: ignore[attr-defined]

    @abstractmethod
    def act(self, obs: NDArray[np.float64]) -> NDArray[Any]:
        """Actions ``(N, action size)`` for observations ``(N, obs_dim)``."""

    def predict(
        self,
        observation: NDArray[Any],
        state: Any = None,
        episode_start: NDArray[np.bool_] | None = None,
        deterministic: bool = True,
    ) -> tuple[NDArray[np.float32], None]:
        obs, single = as_batch(observation, self.obs_dim)
        action = np.asarray(self.act(obs), dtype=np.float32)
        return (action[0] if single else action), None
