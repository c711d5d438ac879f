"""Training configuration: algorithms and per-env hyperparameters from YAML.

Hyperparameters live in ``hyperparams/<algo>.yml`` keyed by env id (the rl-baselines3-zoo
layout) and are read with ``yaml.safe_load`` — values are data, never code. ``n_envs``,
``n_timesteps`` and ``policy`` are run settings, and so are the optional ``wrappers``
(:mod:`.wrappers`: what the policy sees and how it acts) and ``pretrain`` (:mod:`.experts`:
imitation before RL); every other key goes to the algorithm.
"""

from __future__ import annotations

from importlib.resources import files
from typing import Any, ClassVar

import yaml
from stable_baselines3 import PPO, SAC
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.policies import BasePolicy

from sensorgym.train.ars import ARS
from sensorgym.train.candidate_policy import CandidatePolicy

#: sensorgym's own policy classes, by the name a hyperparameter set's ``policy`` gives
POLICIES: dict[str, type[BasePolicy]] = {"CandidatePolicy": CandidatePolicy}


class SensorgymPPO(PPO):
    """SB3's PPO that also knows the policies of :data:`POLICIES` by name (a run folder's
    ``config.yaml`` names its policy class; nothing else is looked up)."""

    policy_aliases: ClassVar[dict[str, type[BasePolicy]]] = {**PPO.policy_aliases, **POLICIES}


#: algorithm name -> SB3 class (PPO and SAC handle the continuous Box actions of our envs;
#: ARS, a direct policy search, the candidate policies' discrete choice)
ALGORITHMS: dict[str, type[BaseAlgorithm]] = {"ppo": SensorgymPPO, "sac": SAC, "ars": ARS}

#: keys every hyperparameter set has that configure the run, not the algorithm
RUN_KEYS = ("n_envs", "n_timesteps", "policy")

#: keys a hyperparameter set may have that configure the run, not the algorithm
OPTIONAL_RUN_KEYS = ("wrappers", "pretrain")


def load_hyperparams(algo: str, env_id: str) -> dict[str, Any]:
    """The hyperparameter set of ``algo`` for ``env_id``; ``KeyError`` lists what exists."""
    if algo not in ALGORITHMS:
        raise KeyError(f"algo: {algo!r} is not one of {sorted(ALGORITHMS)}")
    text = files("sensorgym.train").joinpath("hyperparams", f"{algo}.yml").read_text()
    table = yaml.safe_load(text) or {}
    if env_id not in table:
        raise KeyError(f"no {algo} hyperparameters for {env_id!r}; known: {sorted(table)}")
    hp = dict(table[env_id])
    missing = [k for k in RUN_KEYS if k not in hp]
    if missing:
        raise KeyError(f"{algo}.yml, {env_id}: missing {missing}")
    return hp


#: a hyperparameter set's key holding what differs for parameter-sharing (``--agents``) runs
AGENTS_KEY = "agents"


def for_mode(hp: dict[str, Any], agents: bool) -> dict[str, Any]:
    """``hp`` for a single-policy run, or for a parameter-sharing run (``agents``) with the
    entries of its ``agents:`` mapping applied (a ``null`` entry removes the key): a recipe's
    wrappers and imitation act on the env's joint action, one agent's policy on its own."""
    hp = dict(hp)
    overrides = hp.pop(AGENTS_KEY, None) or {}
    if not isinstance(overrides, dict):
        raise KeyError(f"{AGENTS_KEY}: expected a mapping of overrides, got {overrides!r}")
    if agents:
        for key, value in overrides.items():
            if value is None:
                hp.pop(key, None)
            else:
                hp[key] = value
    return hp


def split_run_settings(hp: dict[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """``(run settings, algorithm keyword arguments)`` of a hyperparameter set."""
    run = {k: hp[k] for k in RUN_KEYS}
    run.update({k: hp[k] for k in OPTIONAL_RUN_KEYS if hp.get(k) is not None})
    algo_kwargs = {k: v for k, v in hp.items() if k not in RUN_KEYS + OPTIONAL_RUN_KEYS}
    return run, algo_kwargs
