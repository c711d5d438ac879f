"""Saved models: the folder layout ``sensorgym train`` writes and loading it back safely.

A run folder holds ``policy.safetensors`` (the weights of the SB3 policy, the ``state_dict`` of
``model.policy``), ``config.yaml`` (env id, algorithm, seed, ``agents`` and the resolved
hyperparameters) and ``evaluation.json`` (the trained policy beside the rules).

Both files a model is loaded from are plain data: safetensors is a JSON header and raw tensor
bytes, and the config is read with ``yaml.safe_load``. Loading rebuilds the algorithm the config
describes (its policy class alias, ``policy_kwargs`` and the observation and action spaces of
the registered env, per agent for a parameter-sharing run, seen through the run's
``wrappers``) and loads the weights into its policy; nothing in the folder is ever unpickled, so a hostile folder cannot run code.

SB3's own ``model.zip`` is different: its ``data`` entry carries cloudpickled objects that run
code when loaded. ``sensorgym train`` does not write one; a folder that has only a ``model.zip``
(from an older sensorgym, or from elsewhere) is loaded with SB3's ``load`` only when the caller
opts in with ``unsafe_pickle=True`` (``--unsafe-pickle`` on the command line).
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any

import yaml
from stable_baselines3.common.base_class import BaseAlgorithm

from sensorgym.train.config import ALGORITHMS, OPTIONAL_RUN_KEYS, RUN_KEYS
from sensorgym.train.wrappers import check_wrappers

WEIGHTS_FILE = "policy.safetensors"
CONFIG_FILE = "config.yaml"
#: SB3's pickled model file: loaded only with ``unsafe_pickle=True``, never written
SB3_ZIP_FILE = "model.zip"
#: the ``format`` entry of the weights file's metadata
WEIGHTS_FORMAT = "sensorgym-policy-state-dict/1"


class RunFolderError(ValueError):
    """A path that is not a usable ``sensorgym train`` run folder (the message names the file)."""


def run_dir_of(path: Path) -> Path:
    """The run folder of ``path``: the folder itself, or the folder of a file in it (its
    ``policy.safetensors``, ``model.zip`` or ``config.yaml``)."""
    path = Path(path)
    if path.suffix in (".safetensors", ".zip", ".yaml") or path.is_file():
        return path.parent
    return path


def read_config(run_dir: Path) -> dict[str, Any]:
    """The checked ``config.yaml`` of a run folder: a mapping with a registered ``env`` id and a
    known ``algo``; anything else raises :class:`RunFolderError` naming the file."""
    import gymnasium as gym

    import sensorgym.envs  # noqa: F401  (registers the ids)

    path = Path(run_dir) / CONFIG_FILE
    if not path.is_file():
        raise RunFolderError(f"{path}: not a `sensorgym train` run folder (no {CONFIG_FILE})")
    try:
        config = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise RunFolderError(f"{path}: not valid YAML ({_one_line(exc)})") from None
    if not isinstance(config, dict):
        raise RunFolderError(f"{path}: expected a mapping with env and algo, got {config!r}")
    for key in ("env", "algo"):
        if key not in config:
            raise RunFolderError(f"{path}: no {key!r} entry")
    if config["algo"] not in ALGORITHMS:
        raise RunFolderError(f"{path}: algo {config['algo']!r} is not one of {sorted(ALGORITHMS)}")
    if not isinstance(config["env"], str) or config["env"] not in gym.registry:
        raise RunFolderError(f"{path}: env {config['env']!r} is not a registered id")
    return config


def check_run_folder(path: Path, unsafe_pickle: bool = False) -> dict[str, Any]:
    """The checked config of the run folder of ``path`` (a folder or a file in it), which must
    hold a weights file (or, with ``unsafe_pickle``, at least an SB3 ``model.zip``);
    :class:`RunFolderError` names what is wrong."""
    run_dir = run_dir_of(path)
    config = read_config(run_dir)
    weights, sb3_zip = run_dir / WEIGHTS_FILE, run_dir / SB3_ZIP_FILE
    if weights.is_file() or (unsafe_pickle and sb3_zip.is_file()):
        return config
    if sb3_zip.is_file():
        raise RunFolderError(
            f"{sb3_zip}: an SB3 pickle, which runs code from the file when loaded, and no "
            f"{WEIGHTS_FILE} beside it; to load it anyway (only a file you trust) pass "
            "--unsafe-pickle"
        )
    raise RunFolderError(f"{weights}: no such weights file")


def save_run(model: BaseAlgorithm, run_dir: Path, config: dict[str, Any]) -> None:
    """Write ``model``'s policy weights as ``policy.safetensors`` and ``config`` as
    ``config.yaml`` into ``run_dir`` (created if needed); a ``model.zip`` left there by an
    earlier run (it would not match the new weights) is removed."""
    from safetensors.torch import save_file

    run_dir = Path(run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)
    # copies: safetensors stores no aliased tensors, and a module shared by two parts of the
    # policy (a shared features extractor) is then stored, and loaded, once per name
    state = {k: v.detach().cpu().contiguous().clone() for k, v in model.policy.state_dict().items()}
    metadata = {
        "format": WEIGHTS_FORMAT,
        "env": str(config["env"]),
        "algo": str(config["algo"]),
        "agents": str(bool(config.get("agents", False))).lower(),
    }
    save_file(state, run_dir / WEIGHTS_FILE, metadata=metadata)
    (run_dir / CONFIG_FILE).write_text(yaml.safe_dump(config, sort_keys=False))
    # a model.zip of an earlier run in this folder would no longer match the weights
    (run_dir / SB3_ZIP_FILE).unlink(missing_ok=True)


def params_of(config: dict[str, Any]) -> dict[str, Any]:
    """The env params fields a run was trained with (``--param``; empty: the defaults)."""
    params = config.get("params") or {}
    if not isinstance(params, dict):
        raise RunFolderError(f"{CONFIG_FILE}, params: expected a mapping, got {params!r}")
    # YAML has no tuples: a sequence field comes back as a list
    return {k: tuple(v) if isinstance(v, list) else v for k, v in params.items()}


def check_model_params(config: dict[str, Any], params: dict[str, Any] | None) -> None:
    """:class:`RunFolderError` naming every differing field when a run trained with
    ``params_of(config)`` is asked to act in its env with ``params``."""
    from sensorgym.train.env_params import check_same_env

    try:
        check_same_env(config["env"], params_of(config), params, "the model")
    except ValueError as exc:
        raise RunFolderError(str(exc)) from None


def wrappers_of(config: dict[str, Any]) -> list[dict[str, Any]]:
    """The wrapper list (:mod:`.wrappers`) a run's policy acts through; :class:`RunFolderError`
    when ``config.yaml`` names an unknown one."""
    hp = config.get("hyperparams") or {}
    try:
        return check_wrappers(hp.get("wrappers") if isinstance(hp, dict) else None)
    except ValueError as exc:
        raise RunFolderError(f"{CONFIG_FILE}, hyperparams: {exc}") from None


def build_model(config: dict[str, Any], env: Any = None) -> BaseAlgorithm:
    """The untrained SB3 algorithm a checked ``config`` describes, on the CPU: its ``algo`` and
    hyperparameters (policy alias, ``policy_kwargs`` and the rest) over the observation and
    action spaces of the registered env at the run's ``params`` (per agent when ``agents`` is
    true) seen through the run's ``wrappers`` (:func:`wrappers_of`; ``env`` must already carry them).

    The model keeps no env unless ``env`` (an SB3 ``VecEnv`` with those spaces) is given, as
    after SB3's own ``load``. Hyperparameters that do not build the algorithm
    raise :class:`RunFolderError` naming ``config.yaml``.
    """
    from sensorgym.train.evaluation import make_sb3_env

    algo = ALGORITHMS[config["algo"]]
    hp = config.get("hyperparams") or {}
    where = f"{CONFIG_FILE}, hyperparams"
    if not isinstance(hp, dict):
        raise RunFolderError(f"{where}: expected a mapping, got {hp!r}")
    policy = hp.get("policy", "MlpPolicy")
    if not isinstance(policy, str) or policy not in algo.policy_aliases:
        known = sorted(algo.policy_aliases)
        raise RunFolderError(f"{where}: policy {policy!r} is not one of {known}")
    kwargs = {k: v for k, v in hp.items() if k not in RUN_KEYS + OPTIONAL_RUN_KEYS}
    agents = bool(config.get("agents", False))
    spaces_env = make_sb3_env(
        config["env"], 1, seed=0, agents=agents, wrappers=wrappers_of(config), **params_of(config)
    )
    try:
        if env is not None and (
            env.observation_space != spaces_env.observation_space
            or env.action_space != spaces_env.action_space
        ):
            raise RunFolderError(
                f"{CONFIG_FILE}: the model acts on {spaces_env.observation_space} -> "
                f"{spaces_env.action_space}, the env given has {env.observation_space} -> "
                f"{env.action_space}"
            )
        with warnings.catch_warnings():
            # PPO's note on a batch size that does not divide n_steps × n_envs: the env here
            # is not the training one, and the model only acts
            warnings.filterwarnings("ignore", message=".*mini-batch size", category=UserWarning)
            model = algo(
                policy,
                spaces_env if env is None else env,
                device="cpu",
                seed=config.get("seed"),
                **kwargs,
            )
    except (TypeError, ValueError, KeyError, AssertionError) as exc:
        if isinstance(exc, RunFolderError):
            raise
        raise RunFolderError(
            f"{where}: do not build a {config['algo']} model ({_one_line(exc)})"
        ) from None
    finally:
        spaces_env.close()
    if env is None:
        model.env = None  # as SB3's load without an env: the model only acts
    return model


def load_weights(model: BaseAlgorithm, path: Path, config: dict[str, Any] | None = None) -> None:
    """Load a ``policy.safetensors`` into ``model.policy`` (every entry, exact names and
    shapes); a file that is not safetensors, was saved for another env or algorithm than
    ``config``'s, or does not fit the policy raises :class:`RunFolderError` naming it."""
    from safetensors import SafetensorError, safe_open

    path = Path(path)
    try:
        with safe_open(path, framework="pt", device="cpu") as f:
            metadata = f.metadata() or {}
            state = {k: f.get_tensor(k) for k in f.keys()}
    except (SafetensorError, OSError, ValueError) as exc:
        raise RunFolderError(f"{path}: not a safetensors weights file ({_one_line(exc)})") from None
    for key in ("env", "algo"):
        if config is not None and key in metadata and metadata[key] != str(config[key]):
            raise RunFolderError(
                f"{path}: weights saved for {key} {metadata[key]!r}, but {CONFIG_FILE} says "
                f"{config[key]!r}"
            )
    try:
        model.policy.load_state_dict(state, strict=True)
    except RuntimeError as exc:
        raise RunFolderError(
            f"{path}: the weights do not fit the policy {CONFIG_FILE} describes ({_one_line(exc)})"
        ) from None
    model.policy.set_training_mode(False)


def load_model(path: Path, env: Any = None, *, unsafe_pickle: bool = False) -> BaseAlgorithm:
    """Load a trained model from its run folder (or a file in it) on the CPU.

    The safe path, always taken when the folder has a ``policy.safetensors``: rebuild the
    algorithm from ``config.yaml`` (:func:`build_model`) and load the weights into its policy
    (:func:`load_weights`). A folder with only SB3's ``model.zip`` is loaded with SB3's ``load``
    when ``unsafe_pickle`` is true — which unpickles the file and so runs any code in it: use it
    only on files you trust — and otherwise refused with a :class:`RunFolderError`.
    """
    config = check_run_folder(path, unsafe_pickle)
    run_dir = run_dir_of(path)
    weights = run_dir / WEIGHTS_FILE
    if weights.is_file():
        model = build_model(config, env)
        load_weights(model, weights, config)
        return model
    sb3_zip = run_dir / SB3_ZIP_FILE
    try:  # unsafe_pickle: the caller trusts this file
        return ALGORITHMS[config["algo"]].load(sb3_zip, env=env, device="cpu")
    except Exception as exc:
        raise RunFolderError(f"{sb3_zip}: not a loadable SB3 model ({_one_line(exc)})") from None


def _one_line(exc: BaseException, limit: int = 300) -> str:
    """An exception's message on one line, at most ``limit`` characters."""
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if len(text) <= limit else text[: limit - 1] + "…"
