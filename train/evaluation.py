"""Seeded evaluation of any SB3-style policy on a registered env, batched.

Rules and trained models are scored the same way: SB3's ``evaluate_policy`` over the env's
native vector env (through :class:`.sb3_vec_env.SB3VecEnv`), deterministic actions, a fixed
seed, so that two policies evaluated with one seed meet the same scenarios.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode
from stable_baselines3.common.evaluation import evaluate_policy
from stable_baselines3.common.vec_env import VecEnv, VecMonitor

import sensorgym.envs  # noqa: F401  (registers the ids)
from sensorgym.train.sb3_vec_env import SB3VecEnv


@dataclass(frozen=True)
class EpisodeStats:
    """Returns of ``episodes`` evaluation episodes."""

    mean: float
    """Mean episode return."""
    std: float
    """Standard deviation of the episode returns."""
    ci95: float
    """Half-width of the normal 95 % confidence interval of the mean."""
    episodes: int
    """Number of episodes."""
    mean_length: float
    """Mean episode length (steps)."""

    def as_dict(self) -> dict[str, float]:
        return asdict(self)


def make_sb3_env(
    env_id: str, n_envs: int, seed: int, agents: bool = False, **env_kwargs: Any
) -> VecEnv:
    """The env's native vector env of ``n_envs`` scenarios as an SB3 ``VecEnv`` (SAME_STEP
    autoreset, ``VecMonitor``); ``agents=True`` makes every agent of every scenario a slot
    (parameter sharing over the env's PettingZoo agents). ``env_kwargs``: params fields."""
    venv = gym.make_vec(
        env_id,
        num_envs=n_envs,
        vectorization_mode="vector_entry_point",
        autoreset_mode=AutoresetMode.SAME_STEP,
        agent_view=agents,
        **env_kwargs,
    )
    env = VecMonitor(SB3VecEnv(venv))
    env.seed(seed)
    return env


def env_params(env: VecEnv) -> Any:
    """The parameters dataclass of the vector env under an SB3 wrapper stack."""
    return env.get_attr("params")[0]


def simulator_state(env: VecEnv) -> Callable[[], Any]:
    """A function returning the current simulator state under ``env`` (the vector env's
    public ``simulator_state``), for oracle rules, which plan on the truth; the vector env is
    the one :func:`make_sb3_env` builds, whose batch matches the observations."""
    return lambda: env.get_attr("simulator_state")[0]


def agents_per_scenario(env: VecEnv) -> int:
    """Slots per scenario of an SB3 env from :func:`make_sb3_env` (1 unless ``agents=True``)."""
    return int(getattr(env.unwrapped, "agents_per_scenario", 1))


def evaluate(policy: Any, env: VecEnv, episodes: int, seed: int) -> EpisodeStats:
    """Score ``policy`` (anything with SB3's ``predict``) over ``episodes`` episodes of ``env``.

    ``env`` is reseeded with ``seed`` first, so policies evaluated with one seed meet the same
    scenarios (exactly so while no episode ends early by termination). On an env whose slots
    are agents (``make_sb3_env(..., agents=True)``) an episode is a scenario's, counted once:
    ``episodes`` must then be a multiple of the number of scenarios.
    """
    if episodes < 1:
        raise ValueError(f"episodes: must be >= 1, got {episodes}")
    n = agents_per_scenario(env)
    if n > 1 and episodes % (env.num_envs // n):
        raise ValueError(
            f"episodes: {episodes} is not a multiple of the {env.num_envs // n} scenarios"
        )
    env.seed(seed)
    returns, lengths = evaluate_policy(
        policy, env, n_eval_episodes=episodes * n, deterministic=True, return_episode_rewards=True
    )
    # every agent of a scenario ends with it, one after another: one return per scenario
    r = np.asarray(returns, dtype=np.float64).reshape(-1, n)
    if not np.allclose(r, r[:, :1], rtol=1e-5, atol=1e-5):
        raise RuntimeError("evaluate: the agents of a scenario disagree on its team return")
    r, lengths = r[:, 0], np.asarray(lengths).reshape(-1, n)[:, 0]
    std = float(r.std(ddof=1)) if r.size > 1 else 0.0
    return EpisodeStats(
        mean=float(r.mean()),
        std=std,
        ci95=float(1.96 * std / np.sqrt(r.size)),
        episodes=int(r.size),
        mean_length=float(np.mean(lengths)),
    )
