"""Training configuration: algorithms and per-env hyperparameters from YAML.

Hyperparameters live in ``hyperparams/<algo>.yml`` keyed by env id (the rl-baselines3-zoo
layout) and are read with ``yaml.safe_load`` — values are data, never code. ``n_envs``,
``n_timesteps`` and ``policy`` are run settings, and so are the optional ``wrappers``
(:mod:`.wrappers`: what the policy sees and how it acts), ``training_wrappers`` (wrappers of
the training env only, outside ``wrappers``: reward shaping that must not reach evaluation)
and ``pretrain`` (:mod:`.experts`: imitation before RL); every other key goes to the algorithm.
"""

from __future__ import annotations

import re
from importlib.resources import files
from itertools import pairwise
from typing import Any, ClassVar

import yaml
from stable_baselines3 import PPO, SAC
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.policies import BasePolicy

from sensorgym.train.ars import ARS
from sensorgym.train.candidate_policy import CandidatePolicy
from sensorgym.train.messages import brief, format_bytes

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
OPTIONAL_RUN_KEYS = ("wrappers", "training_wrappers", "pretrain")


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


def check_overrides(
    algo: str, env_id: str, overrides: dict[str, Any], *, check_values: bool = True
) -> dict[str, Any]:
    """``algo``'s hyperparameter set for ``env_id`` with ``overrides`` applied
    (:func:`apply_overrides`), checked in both of its modes (single policy and ``agents``):
    every key a run setting or a keyword of the algorithm (:func:`check_algo_kwargs`,
    ``KeyError`` otherwise) and, with ``check_values``, the values of the right type and sizes
    a machine holds (:func:`check_run_settings`, :func:`check_sizes`, the wrappers'
    keywords; ``ValueError`` otherwise). ``check_values=False`` checks the keys only (a
    sweep's searched names, whose values are drawn later)."""
    from sensorgym.train.wrappers import check_wrappers

    hp = apply_overrides(load_hyperparams(algo, env_id), overrides)
    for agents in (False, True):
        run, algo_kwargs = split_run_settings(for_mode(hp, agents))
        check_algo_kwargs(algo, algo_kwargs)
        if check_values:
            check_run_settings(run)
            check_wrappers(run.get("wrappers"))
            check_wrappers(run.get("training_wrappers"))
            check_sizes(algo, algo_kwargs, n_envs=run["n_envs"])
    return hp


def check_run_settings(run: dict[str, Any]) -> None:
    """``ValueError`` naming the entry unless ``n_envs`` and ``n_timesteps`` are integers >= 1
    and ``policy`` a name."""
    for name in ("n_envs", "n_timesteps"):
        value = run.get(name)
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise ValueError(f"{name}: must be an integer >= 1, got {brief(value)}")
    if not isinstance(run.get("policy"), str):
        raise ValueError(f"policy: expected a policy class name, got {brief(run.get('policy'))}")


#: the widest layer a hyperparameter set may give a network: every integer inside
#: ``policy_kwargs`` (``net_arch`` widths, a policy's ``hidden``, horizons) is at most this
MAX_LAYER_WIDTH = 2**16
#: the most weights a policy built from a hyperparameter set may have (400 MB as float32)
MAX_PARAMETERS = 100_000_000
#: the most bytes the buffers an algorithm allocates when it is built may take (8 GiB)
MAX_BUFFER_BYTES = 2**33

#: annotations of the algorithms' keywords whose values :func:`check_sizes` type-checks
_CHECKED_TYPES: dict[str, tuple[type, ...]] = {
    "int": (int,),
    "int | None": (int, type(None)),
    "bool": (bool,),
    "float": (int, float),
    "float | None": (int, float, type(None)),
}


def _annotation_text(annotation: Any) -> str:
    if isinstance(annotation, str):
        return annotation
    if isinstance(annotation, type):
        return annotation.__name__
    return str(annotation)


def check_sizes(
    algo: str,
    algo_kwargs: dict[str, Any],
    obs_dim: int = 1,
    act_dim: int = 1,
    n_envs: int = 1,
) -> None:
    """``ValueError`` naming the entry when ``algo_kwargs`` (keywords of ``algo``, see
    :func:`check_algo_kwargs`) has a value of the wrong type for its keyword, or would make
    the algorithm allocate more than a sane machine holds when it is built — checked before
    anything is allocated.

    * a keyword annotated ``int`` (``n_steps``, ``buffer_size``, …), ``bool`` or ``float``
      must hold that type (a bool is no integer; YAML 1.1 reads ``1e12`` as a string); a
      keyword taking a class or an object (``rollout_buffer_class``, ``action_noise``) cannot
      come from YAML and must be absent or ``null``;
    * ``policy_kwargs`` is a mapping, each ``net_arch`` width an integer >= 1 and no integer
      inside it above :data:`MAX_LAYER_WIDTH`; the weights of the networks ``net_arch``
      describes (the actor and critics, estimated for an ``obs_dim`` input and ``act_dim``
      output) at most :data:`MAX_PARAMETERS`;
    * the rollout buffer (PPO: ``n_steps × n_envs`` transitions), the replay buffer (SAC:
      ``buffer_size`` transitions) and ARS's directions at most :data:`MAX_BUFFER_BYTES`.

    ``obs_dim``, ``act_dim`` and ``n_envs`` default to 1 (a lower bound) when the env is not
    built yet.
    """
    import inspect

    parameters = inspect.signature(ALGORITHMS[algo].__init__).parameters
    for name, value in algo_kwargs.items():
        if name not in parameters:
            continue  # check_algo_kwargs names unknown keywords
        text = _annotation_text(parameters[name].annotation)
        kinds = _CHECKED_TYPES.get(text)
        if kinds is not None:
            wrong_bool = isinstance(value, bool) and bool not in kinds
            if wrong_bool or not isinstance(value, kinds):
                raise ValueError(f"{name}: expected {text}, got {brief(value)}")
        elif ("type[" in text or "ActionNoise" in text) and value is not None:
            raise ValueError(f"{name}: takes a class or object, which a YAML value cannot be")
    policy_kwargs = algo_kwargs.get("policy_kwargs") or {}
    if not isinstance(policy_kwargs, dict):
        raise ValueError(f"policy_kwargs: expected a mapping, got {brief(policy_kwargs)}")
    _check_widths(policy_kwargs, "policy_kwargs")
    networks = _networks(algo, policy_kwargs.get("net_arch"))
    weights = 0
    for widths, copies, reads_action in networks:
        sizes = [obs_dim + (act_dim if reads_action else 0), *widths, act_dim]
        weights += copies * sum(a * b + b for a, b in pairwise(sizes))
    if weights > MAX_PARAMETERS:
        raise ValueError(
            f"policy_kwargs.net_arch: {brief(policy_kwargs.get('net_arch'))} makes networks "
            f"of ~{weights:.3g} weights, more than {MAX_PARAMETERS:.3g}"
        )
    episodes = algo_kwargs.get("episodes", 64)
    episodes = episodes if isinstance(episodes, int) else 64
    buffers = {  # the entry sizing each algorithm's buffer, its default and bytes per unit
        "ppo": ("n_steps", 2048, n_envs * (obs_dim + act_dim + 6) * 4),
        "sac": ("buffer_size", 1_000_000, (2 * obs_dim + act_dim + 4) * 4),
        "ars": ("n_directions", 8, (obs_dim + 2 * episodes) * 8),
    }
    name, default, per_entry = buffers[algo]
    entries = algo_kwargs.get(name, default)
    if isinstance(entries, int) and entries * per_entry > MAX_BUFFER_BYTES:
        raise ValueError(
            f"{name}: {brief(entries)} would allocate ~{format_bytes(entries * per_entry)}, "
            f"more than {format_bytes(MAX_BUFFER_BYTES)}"
        )


def _check_widths(value: Any, where: str) -> None:
    """``ValueError`` naming the entry of ``policy_kwargs`` that holds an integer above
    :data:`MAX_LAYER_WIDTH`, or a ``net_arch`` width that is not an integer >= 1."""
    if isinstance(value, dict):
        for key, item in value.items():
            _check_widths(item, f"{where}.{key}")
    elif isinstance(value, list | tuple):
        for i, item in enumerate(value):
            _check_widths(item, f"{where}[{i}]")
    if ".net_arch" in where and not isinstance(value, dict | list | tuple):
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise ValueError(f"{where}: a layer width must be an integer >= 1, got {brief(value)}")
    if isinstance(value, int) and not isinstance(value, bool) and abs(value) > MAX_LAYER_WIDTH:
        raise ValueError(f"{where}: {brief(value)} is larger than {MAX_LAYER_WIDTH}")


def _networks(algo: str, net_arch: Any) -> list[tuple[list[int], int, bool]]:
    """``(hidden widths, copies, reads the action)`` of the networks ``net_arch`` describes:
    the actor once, PPO's value net once, SAC's two critics and their target copies four
    times (a critic also reads the action)."""
    critic, copies = ("qf", 4) if algo == "sac" else ("vf", 1)
    if isinstance(net_arch, dict):
        actor, value = net_arch.get("pi") or [], net_arch.get(critic) or []
    elif isinstance(net_arch, list | tuple):
        actor = value = list(net_arch)
    else:
        return []
    return [(list(actor), 1, False), (list(value), copies, algo == "sac")]
