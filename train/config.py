"""Training configuration: algorithms and per-env hyperparameters from YAML.

Hyperparameters live in ``hyperparams/<algo>.yml`` keyed by env id (the rl-baselines3-zoo
layout) and are read with ``yaml.safe_load`` — values are data, never code. ``n_envs``,
``n_timesteps`` and ``policy`` are run settings, and so are the optional ``wrappers``
(:mod:`.wrappers`: what the policy sees and how it acts) and ``pretrain`` (:mod:`.experts`:
imitation before RL); every other key goes to the algorithm.
"""

from __future__ import annotations

import re
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


def parse_override(text: str) -> tuple[str, Any]:
    """``KEY=VALUE`` of ``--hyperparam`` → ``(KEY, value)``, the value read as YAML (``1e-4``,
    ``null``, ``[64, 64]``, ``{expert: "rule:plan-search", steps: 2000}``), like the YAML file's
    own entries; a dotted KEY (``pretrain.steps``) names an entry inside a mapping."""
    key, sep, value = text.partition("=")
    key = key.strip()
    if not sep or not key or any(not part for part in key.split(".")):
        raise ValueError(
            f"--hyperparam: expected KEY=VALUE (e.g. learning_rate=3e-4), got {text!r}"
        )
    try:
        return key, _exponent_floats(yaml.safe_load(value))
    except yaml.YAMLError as exc:
        raise ValueError(f"--hyperparam {key}: not a YAML value: {value!r} ({exc})") from None


#: ``3e-4``: a float to Python and YAML 1.2, a string to PyYAML's YAML 1.1 (which needs ``3.0e-4``)
_EXPONENT_FLOAT = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)[eE][-+]?\d+")


def _exponent_floats(value: Any) -> Any:
    """``value`` with every string that is a number in exponent notation made a float, in
    lists and mappings too."""
    if isinstance(value, str) and _EXPONENT_FLOAT.fullmatch(value):
        return float(value)
    if isinstance(value, list):
        return [_exponent_floats(v) for v in value]
    if isinstance(value, dict):
        return {k: _exponent_floats(v) for k, v in value.items()}
    return value


def apply_overrides(hp: dict[str, Any], overrides: dict[str, Any]) -> dict[str, Any]:
    """A copy of the hyperparameter set ``hp`` with ``overrides`` set: a plain key replaces the
    entry (``null`` for ``wrappers``/``pretrain`` leaves them out), a dotted key
    (``pretrain.steps``) the entry inside that mapping, made if the set has none
    (``policy_kwargs.net_arch``); a dotted key through anything else raises ``KeyError``."""
    out = dict(hp)
    for key, value in overrides.items():
        *path, last = key.split(".")
        node = out
        for i, part in enumerate(path):
            child = node.get(part, {})
            if not isinstance(child, dict):
                where = ".".join(path[: i + 1])
                raise KeyError(f"hyperparameter {key!r}: {where!r} is {child!r}, not a mapping")
            node[part] = node = dict(child)
        node[last] = value
    return out


#: keywords of the algorithms' constructors that the trainer sets itself
TRAINER_KEYWORDS = ("self", "policy", "env", "seed", "device", "verbose", "tensorboard_log")


def check_algo_kwargs(algo: str, algo_kwargs: dict[str, Any]) -> None:
    """``KeyError`` naming every entry of ``algo_kwargs`` that ``algo``'s constructor does not
    take (or that the trainer sets itself): a typo fails here, not deep inside SB3."""
    import inspect

    accepted = {
        name
        for name in inspect.signature(ALGORITHMS[algo].__init__).parameters
        if name not in TRAINER_KEYWORDS and not name.startswith("_")
    }
    unknown = sorted(set(algo_kwargs) - accepted)
    if unknown:
        raise KeyError(
            f"{unknown}: not a run setting ({list(RUN_KEYS + OPTIONAL_RUN_KEYS)}) nor a "
            f"keyword of {algo} ({sorted(accepted)})"
        )


def check_overrides(algo: str, env_id: str, overrides: dict[str, Any]) -> dict[str, Any]:
    """``algo``'s hyperparameter set for ``env_id`` with ``overrides`` applied
    (:func:`apply_overrides`), checked by :func:`check_algo_kwargs` in both of its modes
    (single policy and ``agents``); ``KeyError`` otherwise."""
    hp = apply_overrides(load_hyperparams(algo, env_id), overrides)
    for agents in (False, True):
        check_algo_kwargs(algo, split_run_settings(for_mode(hp, agents))[1])
    return hp
