"""Saved models: the folder layout ``sensorgym train`` writes and loading it back safely.

A run folder holds ``policy.safetensors`` (the weights of the SB3 policy, the ``state_dict`` of
``model.policy``), ``config.yaml`` (env id, algorithm, seed, ``agents`` and the resolved
hyperparameters) and ``evaluation.json`` (the trained policy beside the rules).

Both files a model is loaded from are plain data: safetensors is a JSON header and raw tensor
bytes, and the config is read with a bounded ``yaml.SafeLoader`` (:func:`read_config`: at most
:data:`MAX_CONFIG_BYTES` of UTF-8 text standing for at most :data:`MAX_CONFIG_NODES` values once
its aliases are unfolded, so a few hundred bytes of nested aliases cannot stand for a billion). Loading rebuilds the algorithm the config
describes (its policy class alias, ``policy_kwargs`` and the observation and action spaces of
the registered env, per agent for a parameter-sharing run, seen through the run's
``wrappers``) and loads the weights into its policy; nothing in the folder is ever unpickled, so a hostile folder cannot run code.
Nor can it exhaust memory or end in a traceback: sizes are checked before anything is allocated
(the hyperparameters' keywords, types, networks and buffers, :func:`~.config.check_sizes`; the
env's params, :func:`~.env_params.check_memory`), the weights must match the policy's names,
shapes and dtypes and be finite, and every refusal is a :class:`RunFolderError` of one bounded
line that never echoes a value from the folder whole.

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

from sensorgym.train.config import (
    ALGORITHMS,
    OPTIONAL_RUN_KEYS,
    RUN_KEYS,
    check_algo_kwargs,
    check_sizes,
)
from sensorgym.train.messages import brief, one_line
from sensorgym.train.wrappers import check_wrappers

WEIGHTS_FILE = "policy.safetensors"
CONFIG_FILE = "config.yaml"
#: SB3's pickled model file: loaded only with ``unsafe_pickle=True``, never written
SB3_ZIP_FILE = "model.zip"
#: the ``format`` entry of the weights file's metadata
WEIGHTS_FORMAT = "sensorgym-policy-state-dict/1"


#: the largest ``config.yaml`` read (``sensorgym train`` writes under 2 kB)
MAX_CONFIG_BYTES = 1_000_000
#: the most values (YAML nodes) a ``config.yaml`` may stand for with its aliases unfolded
MAX_CONFIG_NODES = 10_000
#: the longest single value (scalar) of a ``config.yaml``, in characters
MAX_SCALAR_CHARS = 10_000
#: the longest message of a :class:`RunFolderError`
MAX_MESSAGE_CHARS = 1_000


class RunFolderError(ValueError):
    """A path that is not a usable ``sensorgym train`` run folder (the message names the file).

    The message is one line of at most :data:`MAX_MESSAGE_CHARS` characters, whatever it is
    given (:func:`~.messages.one_line`)."""

    def __init__(self, message: object) -> None:
        super().__init__(one_line(message, MAX_MESSAGE_CHARS))


class _RefusedYAML(yaml.YAMLError):
    """A YAML document :class:`_BoundedLoader` refuses to build (the message says why)."""


class _BoundedLoader(yaml.SafeLoader):
    """PyYAML's ``SafeLoader`` that refuses, while composing and before any Python value is
    built, a document standing for more than :data:`MAX_CONFIG_NODES` nodes once its aliases
    are unfolded (an alias counts as the whole of the node it names: a "billion laughs" of
    nested aliases is refused after a few hundred nodes), a recursive alias, or a scalar
    longer than :data:`MAX_SCALAR_CHARS`."""

    def __init__(self, stream: str) -> None:
        super().__init__(stream)
        self._unfolded = 0
        self._sizes: dict[int, int] = {}  # id(node) -> nodes it stands for, unfolded

    def _count(self, n: int) -> None:
        self._unfolded += n
        if self._unfolded > MAX_CONFIG_NODES:
            raise _RefusedYAML(
                f"stands for more than {MAX_CONFIG_NODES} values once its aliases are "
                "unfolded; a run's config has a few dozen"
            )

    def compose_node(self, parent: Any, index: Any) -> Any:
        if self.check_event(yaml.AliasEvent):
            target = self.anchors.get(self.peek_event().anchor)
            if target is not None:  # an undefined alias: the composer's own error
                size = self._sizes.get(id(target))
                if size is None:  # named while it is still being composed
                    raise _RefusedYAML("holds a recursive alias (a value that contains itself)")
                self._count(size)
            return super().compose_node(parent, index)
        start = self._unfolded
        node = super().compose_node(parent, index)
        if isinstance(node, yaml.ScalarNode) and len(node.value) > MAX_SCALAR_CHARS:
            raise _RefusedYAML(f"holds a value longer than {MAX_SCALAR_CHARS} characters")
        self._count(1)
        self._sizes[id(node)] = self._unfolded - start
        return node


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
    config = _load_yaml(path)
    if not isinstance(config, dict):
        raise RunFolderError(f"{path}: expected a mapping with env and algo, got {brief(config)}")
    for key in ("env", "algo"):
        if key not in config:
            raise RunFolderError(f"{path}: no {key!r} entry")
    if not isinstance(config["algo"], str) or config["algo"] not in ALGORITHMS:
        raise RunFolderError(
            f"{path}: algo {brief(config['algo'])} is not one of {sorted(ALGORITHMS)}"
        )
    if not isinstance(config["env"], str) or config["env"] not in gym.registry:
        raise RunFolderError(f"{path}: env {brief(config['env'])} is not a registered id")
    seed = config.get("seed")
    if seed is not None and (
        isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2**32
    ):
        raise RunFolderError(f"{path}: seed {brief(seed)} is not an integer in [0, 2**32)")
    if not isinstance(config.get("agents", False), bool):
        raise RunFolderError(f"{path}: agents {brief(config['agents'])} is not true or false")
    return config


def _load_yaml(path: Path) -> Any:
    """The YAML document of ``path``, read within bounds (:data:`MAX_CONFIG_BYTES`, UTF-8,
    :class:`_BoundedLoader`); :class:`RunFolderError` naming the file otherwise."""
    try:
        with path.open("rb") as f:
            data = f.read(MAX_CONFIG_BYTES + 1)
    except OSError as exc:
        raise RunFolderError(f"{path}: cannot be read ({exc.strerror or exc})") from None
    if len(data) > MAX_CONFIG_BYTES:
        raise RunFolderError(
            f"{path}: larger than {MAX_CONFIG_BYTES} bytes (a run's config is a few kB)"
        )
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise RunFolderError(
            f"{path}: not UTF-8 text (byte {data[exc.start]:#04x} at offset {exc.start})"
        ) from None
    try:
        return yaml.load(text, Loader=_BoundedLoader)  # a SafeLoader: data only
    except _RefusedYAML as exc:
        raise RunFolderError(f"{path}: refused: the YAML {exc}") from None
    except RecursionError:
        raise RunFolderError(f"{path}: not valid YAML (nested too deeply)") from None
    except (yaml.YAMLError, ValueError, OverflowError) as exc:
        # ValueError: an integer of more digits than Python converts
        raise RunFolderError(f"{path}: not valid YAML ({one_line(exc)})") from None


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
    if not isinstance(params, dict) or not all(isinstance(k, str) for k in params):
        raise RunFolderError(
            f"{CONFIG_FILE}, params: expected a mapping of field names, got {brief(params)}"
        )
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
        raise RunFolderError(f"{CONFIG_FILE}, hyperparams: {one_line(exc)}") from None


def build_model(config: dict[str, Any], env: Any = None) -> BaseAlgorithm:
    """The untrained SB3 algorithm a checked ``config`` describes, on the CPU: its ``algo`` and
    hyperparameters (policy alias, ``policy_kwargs`` and the rest) over the observation and
    action spaces of the registered env at the run's ``params`` (per agent when ``agents`` is
    true) seen through the run's ``wrappers`` (:func:`wrappers_of`; ``env`` must already carry them).

    The model keeps no env unless ``env`` (an SB3 ``VecEnv`` with those spaces) is given, as
    after SB3's own ``load``. Hyperparameters that do not build the algorithm
    raise :class:`RunFolderError` naming ``config.yaml``.
    """
    from gymnasium.spaces import flatdim

    from sensorgym.train.env_params import check_memory, resolve
    from sensorgym.train.evaluation import make_sb3_env

    algo = ALGORITHMS[config["algo"]]
    hp = config.get("hyperparams") or {}
    where = f"{CONFIG_FILE}, hyperparams"
    if not isinstance(hp, dict) or not all(isinstance(k, str) for k in hp):
        raise RunFolderError(f"{where}: expected a mapping of names, got {brief(hp)}")
    policy = hp.get("policy", "MlpPolicy")
    if not isinstance(policy, str) or policy not in algo.policy_aliases:
        known = sorted(algo.policy_aliases)
        raise RunFolderError(f"{where}: policy {brief(policy)} is not one of {known}")
    kwargs = {k: v for k, v in hp.items() if k not in RUN_KEYS + OPTIONAL_RUN_KEYS}
    try:  # only the algorithm's own public keywords (no `_init_setup_model`, no `env`)
        check_algo_kwargs(config["algo"], kwargs)
    except KeyError as exc:
        raise RunFolderError(f"{where}: {exc.args[0]}") from None
    agents = bool(config.get("agents", False))
    params = params_of(config)
    n_envs = 1 if env is None else env.num_envs
    try:  # the params are valid and fit in memory before the env is built with them
        resolve(config["env"], params)
        check_memory(config["env"], params, n_envs)
    except ValueError as exc:
        raise RunFolderError(f"{CONFIG_FILE}, params: {exc}") from None
    wrappers = wrappers_of(config)
    try:
        spaces_env = make_sb3_env(
            config["env"], 1, seed=0, agents=agents, wrappers=wrappers, **params
        )
    except ValueError as exc:  # a wrapper's values
        raise RunFolderError(f"{where}: {exc}") from None
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
        obs_dim = flatdim(spaces_env.observation_space)
        act_dim = flatdim(spaces_env.action_space)
        try:  # types and sizes before anything of that size is allocated
            check_sizes(config["algo"], kwargs, obs_dim, act_dim, n_envs)
        except ValueError as exc:
            raise RunFolderError(f"{where}: {exc}") from None
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
    except RunFolderError:
        raise
    except Exception as exc:  # the values are data from a file: whatever they break, name it
        raise RunFolderError(
            f"{where}: do not build a {config['algo']} model ({one_line(exc)})"
        ) from None
    finally:
        spaces_env.close()
    if env is None:
        model.env = None  # as SB3's load without an env: the model only acts
    return model


#: the dtype code of the safetensors header for each torch dtype a policy may hold
_SAFETENSORS_DTYPES: dict[str, str] = {
    "float64": "F64",
    "float32": "F32",
    "float16": "F16",
    "bfloat16": "BF16",
    "int64": "I64",
    "int32": "I32",
    "int16": "I16",
    "int8": "I8",
    "uint8": "U8",
    "bool": "BOOL",
}


def load_weights(model: BaseAlgorithm, path: Path, config: dict[str, Any] | None = None) -> None:
    """Load a ``policy.safetensors`` into ``model.policy``; :class:`RunFolderError` naming the
    file when it is not safetensors or was saved for another env or algorithm than
    ``config``'s, and before any tensor is read when its names, shapes or dtypes are not
    exactly the policy's (a tensor of another dtype, e.g. int64 for float32, is refused, not
    cast: a cast would change the weights silently); a tensor holding NaN or infinite values
    is refused too (a policy that acts on them fails mid-episode)."""
    import torch
    from safetensors import SafetensorError, safe_open

    path = Path(path)
    expected = model.policy.state_dict()
    try:
        with safe_open(path, framework="pt", device="cpu") as f:
            metadata = f.metadata() or {}
            for key in ("env", "algo"):
                if config is not None and key in metadata and metadata[key] != str(config[key]):
                    raise RunFolderError(
                        f"{path}: weights saved for {key} {brief(metadata[key])}, but "
                        f"{CONFIG_FILE} says {brief(config[key])}"
                    )
            names = list(f.keys())
            misfits = [f"no tensor {brief(k)}" for k in expected if k not in names]
            misfits += [f"unexpected tensor {brief(k)}" for k in names if k not in expected]
            for name in names:
                if name not in expected:
                    continue
                entry = f.get_slice(name)
                shape, want = tuple(entry.get_shape()), tuple(expected[name].shape)
                if shape != want:
                    misfits.append(f"{name}: shape {shape} in the file, {want} in the policy")
                dtype = entry.get_dtype()
                want = str(expected[name].dtype).removeprefix("torch.")
                if dtype != _SAFETENSORS_DTYPES.get(want):
                    names = {code: kind for kind, code in _SAFETENSORS_DTYPES.items()}
                    raise RunFolderError(
                        f"{path}: {name} holds {names.get(dtype, brief(dtype))} values where "
                        f"the policy's are {want}: refused, not cast"
                    )
            if misfits:
                raise RunFolderError(
                    f"{path}: the weights do not fit the policy {CONFIG_FILE} describes "
                    f"({'; '.join(misfits[:3])}{'; …' if len(misfits) > 3 else ''})"
                )
            state = {k: f.get_tensor(k) for k in names}
    except RunFolderError:
        raise
    except (SafetensorError, OSError, ValueError) as exc:
        raise RunFolderError(f"{path}: not a safetensors weights file ({one_line(exc)})") from None
    for name, tensor in state.items():
        if tensor.is_floating_point() and not bool(torch.isfinite(tensor).all()):
            bad = int((~torch.isfinite(tensor)).sum())
            raise RunFolderError(
                f"{path}: {name} holds {bad} NaN or infinite values; a policy's weights must "
                "be finite"
            )
    try:
        model.policy.load_state_dict(state, strict=True)
    except RuntimeError as exc:
        raise RunFolderError(
            f"{path}: the weights do not fit the policy {CONFIG_FILE} describes ({one_line(exc)})"
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
        raise RunFolderError(f"{sb3_zip}: not a loadable SB3 model ({one_line(exc)})") from None
