"""Saved models load without running code (issue 10, defect 1).

A run folder's policy is ``policy.safetensors`` (tensors and a JSON header) plus ``config.yaml``
(``yaml.safe_load``); loading rebuilds the SB3 algorithm from the config and loads the weights
into its policy. SB3's ``model.zip``, whose ``data`` entry is unpickled by SB3's ``load``, is
read only behind ``--unsafe-pickle``. The hostile files below carry a payload that, executed,
creates a marker; it must never appear unless the flag is given.
"""

from __future__ import annotations

import base64
import json
import os
import time
import zipfile
from collections.abc import Callable
from itertools import pairwise
from pathlib import Path

import numpy as np
import pytest
import torch
import yaml

from sensorgym.cli.main import main
from sensorgym.envs.bearings_maneuver.simulation import OBS_DIM
from sensorgym.train.evaluation import make_sb3_env
from sensorgym.train.models import (
    CONFIG_FILE,
    SB3_ZIP_FILE,
    WEIGHTS_FILE,
    RunFolderError,
    build_model,
    load_model,
    save_run,
)
from sensorgym.train.trainer import VALIDATION_SEED, train

BEARINGS = "sensorgym/BearingsManeuver-v0"
PLACEMENT = "sensorgym/StereoPlacement-v0"


class Payload:
    """Unpickling this creates the folder ``marker``: the proof that loading ran code."""

    def __init__(self, marker: Path):
        self.marker = str(marker)

    def __reduce__(self):
        return (os.makedirs, (self.marker,))


def _hostile_zip(path: Path, marker: Path) -> None:
    """An SB3-style model.zip whose ``data`` JSON has an extra cloudpickled entry."""
    import cloudpickle

    blob = base64.b64encode(cloudpickle.dumps(Payload(marker))).decode()
    data = {"extra": {":type:": "<class 'object'>", ":serialized:": blob}}
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("data", json.dumps(data))
        archive.writestr("_stable_baselines3_version", "2.3.0")


def _hostile_run(tmp_path: Path, weights: bool) -> tuple[Path, Path]:
    """A run folder with a valid config.yaml, a hostile model.zip and (``weights``) a hostile
    torch pickle named as the weights file; returns ``(run folder, marker)``."""
    run, marker = tmp_path / "run", tmp_path / "marker"
    run.mkdir()
    config = {"env": BEARINGS, "algo": "ppo", "seed": 0, "agents": False}
    (run / CONFIG_FILE).write_text(yaml.safe_dump(config))
    _hostile_zip(run / SB3_ZIP_FILE, marker)
    if weights:
        torch.save({"policy": Payload(marker)}, run / WEIGHTS_FILE)
    return run, marker


def _exit_message(argv: list[str]) -> str:
    """The one-line SystemExit message of ``sensorgym ARGV`` (which must fail)."""
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code not in (0, None)
    message = str(exc.value.code)
    assert "\n" not in message
    return message


def _commands(run: Path, tmp_path: Path) -> dict[str, list[str]]:
    bench = ["--episodes", "2", "--n-envs", "2", "--out", str(tmp_path / "bench")]
    render = ["--out", str(tmp_path / "e.gif")]
    return {
        "benchmark": ["benchmark", "--env", BEARINGS, *bench, "--model", str(run)],
        "render": ["render", "--env", BEARINGS, "--model", str(run), *render],
    }


@pytest.mark.parametrize("command", ["benchmark", "render"])
def test_a_pickled_model_zip_is_not_loaded_without_the_flag(tmp_path, command):
    run, marker = _hostile_run(tmp_path, weights=False)
    message = _exit_message(_commands(run, tmp_path)[command])
    assert str(run / SB3_ZIP_FILE) in message and "--unsafe-pickle" in message
    assert not marker.exists()


@pytest.mark.parametrize("unsafe", [False, True])
@pytest.mark.parametrize("command", ["benchmark", "render"])
def test_a_hostile_weights_file_is_refused_not_run(tmp_path, command, unsafe):
    run, marker = _hostile_run(tmp_path, weights=True)
    # the weights file, when present, is what is loaded: even --unsafe-pickle does not reach
    # the model.zip beside it
    argv = _commands(run, tmp_path)[command] + (["--unsafe-pickle"] if unsafe else [])
    message = _exit_message(argv)
    assert str(run / WEIGHTS_FILE) in message and "not a safetensors weights file" in message
    assert not marker.exists()


def test_the_payloads_are_live(tmp_path):
    """The control: the same files do run their payload through pickle-based loading."""
    run, marker = _hostile_run(tmp_path, weights=True)
    # (through a file object: torch.load reads a path ending in .safetensors as safetensors)
    with open(run / WEIGHTS_FILE, "rb") as f:
        torch.load(f, weights_only=False)
    assert marker.exists()
    os.rmdir(marker)
    with open(run / WEIGHTS_FILE, "rb") as f, pytest.raises(Exception, match="Weights only"):
        torch.load(f, weights_only=True)  # refused, as safetensors refuses it
    assert not marker.exists()
    (run / WEIGHTS_FILE).unlink()
    message = _exit_message([*_commands(run, tmp_path)["benchmark"], "--unsafe-pickle"])
    assert marker.exists()  # the opt-in unpickled the zip: SB3's load then fails on it
    assert str(run / SB3_ZIP_FILE) in message


def test_the_unsafe_flag_says_it_runs_code(capsys):
    for command in ("benchmark", "render"):
        with pytest.raises(SystemExit):
            main([command, "--help"])
        text = " ".join(capsys.readouterr().out.split())
        assert "--unsafe-pickle" in text and "EXECUTES ANY CODE" in text and "trust" in text


@pytest.mark.parametrize("algo", ["ppo", "sac"])
def test_trained_weights_reload_to_the_same_actions(tmp_path, algo):
    result = train(
        BEARINGS, algo, seed=3, timesteps=300, n_envs=2, out=tmp_path, eval_episodes=2,
        progress=False,
    )  # fmt: skip
    files = sorted(p.name for p in result.run_dir.iterdir())
    # no pickle written
    assert files == [
        CONFIG_FILE, "cost.json", "curve.json", "curve.png", "evaluation.json", WEIGHTS_FILE
    ]  # fmt: skip
    loaded = load_model(result.run_dir)
    assert type(loaded) is type(result.model) and loaded.get_env() is None
    size = loaded.observation_space.shape[0]  # the env's 10 and what the run's wrappers add
    obs = np.random.default_rng(0).uniform(-3, 3, (64, size)).astype(np.float32)
    expected = result.model.predict(obs, deterministic=True)[0]
    np.testing.assert_array_equal(loaded.predict(obs, deterministic=True)[0], expected)
    trained = result.model.policy.state_dict()
    for name, tensor in loaded.policy.state_dict().items():  # SAC: actor, critic, target
        torch.testing.assert_close(tensor, trained[name], rtol=0, atol=0)
    # the saved run scores in `benchmark` exactly as in training's own evaluation
    bench = ["--env", BEARINGS, "--episodes", "2", "--n-envs", "2", "--seed", str(VALIDATION_SEED)]
    out = tmp_path / "bench"
    assert main(["benchmark", *bench, "--model", str(result.run_dir), "--out", str(out)]) == 0
    doc = json.loads((out / "sensorgym__BearingsManeuver-v0.json").read_text())
    scored = doc["results"][f"model:{result.run_dir.name}"]
    # the benchmark adds each episode's bound (the hindsight optimum over what every policy
    # played); the rest is training's own evaluation, to the bit
    assert len(scored.pop("bounds")) == 2
    assert scored == result.evaluation["trained"]


def test_parameter_sharing_weights_reload_and_render(tmp_path, capsys):
    result = train(
        PLACEMENT, "ppo", timesteps=128, n_envs=2, out=tmp_path, eval_episodes=2,
        progress=False, agents=True,
    )  # fmt: skip
    loaded = load_model(result.run_dir / WEIGHTS_FILE)
    view = make_sb3_env(PLACEMENT, 2, seed=0, agents=True)
    obs = view.reset()  # every agent of 2 scenarios, each its own observation
    np.testing.assert_array_equal(
        loaded.predict(obs, deterministic=True)[0], result.model.predict(obs, deterministic=True)[0]
    )
    assert load_model(result.run_dir, view).get_env() is not None
    view.close()
    out = tmp_path / "episode.png"
    render = ["render", "--env", PLACEMENT, "--model", str(result.run_dir), "--out", str(out)]
    assert main(render) == 0
    assert out.is_file() and "return" in capsys.readouterr().out


def test_weights_that_do_not_fit_the_config_are_named(tmp_path):
    env = make_sb3_env(BEARINGS, 1, seed=0)
    from stable_baselines3 import PPO

    model = PPO("MlpPolicy", env, policy_kwargs={"net_arch": [8]}, device="cpu")
    env.close()
    config = {"env": BEARINGS, "algo": "ppo", "hyperparams": {"policy": "MlpPolicy"}}
    save_run(model, tmp_path, config)
    with pytest.raises(RunFolderError, match="do not fit"):  # default net_arch: [64, 64]
        load_model(tmp_path)
    config["hyperparams"]["policy_kwargs"] = {"net_arch": [8]}
    save_run(model, tmp_path, config)
    assert load_model(tmp_path).policy.state_dict().keys() == model.policy.state_dict().keys()
    config["algo"] = "sac"
    (tmp_path / CONFIG_FILE).write_text(yaml.safe_dump(config))
    with pytest.raises(RunFolderError, match="saved for algo 'ppo'"):
        load_model(tmp_path)


@pytest.mark.parametrize(
    "hyperparams, words",
    [
        ({"policy": "os.system"}, ["policy 'os.system'"]),
        ({"policy": "MlpPolicy", "no_such_argument": 1}, ["no_such_argument", "keyword of ppo"]),
        ({"policy": "MlpPolicy", "n_steps": "sixty"}, ["n_steps: expected int", "'sixty'"]),
        ("nonsense", ["expected a mapping"]),
    ],
)
def test_hyperparams_that_do_not_build_a_model_are_named(hyperparams, words):
    with pytest.raises(RunFolderError) as exc:
        build_model({"env": BEARINGS, "algo": "ppo", "hyperparams": hyperparams})
    for word in [CONFIG_FILE, *words]:
        assert word in str(exc.value)


def test_retraining_into_a_folder_removes_its_old_model_zip(tmp_path):
    run = tmp_path / "sensorgym__BearingsManeuver-v0" / "sac_seed0"
    run.mkdir(parents=True)
    (run / SB3_ZIP_FILE).write_bytes(b"an earlier run's pickle")
    train(BEARINGS, "sac", timesteps=100, n_envs=2, out=tmp_path, eval_episodes=2, progress=False)
    assert not (run / SB3_ZIP_FILE).exists() and (run / WEIGHTS_FILE).is_file()


def test_an_older_run_folder_with_only_model_zip_loads_with_the_flag(tmp_path):
    from stable_baselines3 import PPO

    env = make_sb3_env(BEARINGS, 1, seed=0)
    model = PPO("MlpPolicy", env, policy_kwargs={"net_arch": [8]}, device="cpu")
    env.close()
    run = tmp_path / "run"
    run.mkdir()
    model.save(run / SB3_ZIP_FILE)  # what sensorgym train wrote before policy.safetensors
    (run / CONFIG_FILE).write_text(yaml.safe_dump({"env": BEARINGS, "algo": "ppo"}))
    with pytest.raises(RunFolderError, match="--unsafe-pickle"):
        load_model(run)
    obs = np.random.default_rng(1).uniform(-3, 3, (16, OBS_DIM)).astype(np.float32)
    loaded = load_model(run, unsafe_pickle=True)
    np.testing.assert_array_equal(
        loaded.predict(obs, deterministic=True)[0], model.predict(obs, deterministic=True)[0]
    )
    bench = ["--env", BEARINGS, "--episodes", "2", "--n-envs", "2", "--out", str(tmp_path / "b")]
    assert main(["benchmark", *bench, "--model", str(run), "--unsafe-pickle"]) == 0


# --- hostile run folders cannot exhaust memory or end in a traceback (issue 35, item 3) ---

SHIPPED = Path(__file__).parents[2] / "train" / "policies" / "sensorgym__BearingsManeuver-v0"


def _shipped_copy(
    tmp_path: Path,
    hyperparams: dict | None = None,
    tensors: Callable[[dict[str, torch.Tensor]], None] | None = None,
) -> Path:
    """A copy of a shipped run folder (valid weights) whose config has ``hyperparams`` set (a
    ``None`` value removes the entry) and whose tensors ``tensors`` edits in place."""
    from safetensors import safe_open
    from safetensors.torch import load_file, save_file

    source, run = SHIPPED / "ppo_seed0", tmp_path / "run"
    run.mkdir()
    config = yaml.safe_load((source / CONFIG_FILE).read_text())
    for key, value in (hyperparams or {}).items():
        if value is None:
            config["hyperparams"].pop(key, None)
        else:
            config["hyperparams"][key] = value
    (run / CONFIG_FILE).write_text(yaml.safe_dump(config))
    state = load_file(source / WEIGHTS_FILE)
    if tensors is not None:
        tensors(state)
    with safe_open(source / WEIGHTS_FILE, framework="pt") as f:
        metadata = f.metadata()
    save_file(state, run / WEIGHTS_FILE, metadata=metadata)
    return run


def _alias_bomb(levels: int) -> str:
    """A config whose aliases nest ``levels`` deep, 9 to a level: 9**levels strings."""
    names = "abcdefghij"
    lines = [f"env: {BEARINGS}", "algo: ppo", "a: &a [x,x,x,x,x,x,x,x,x]"]
    for prev, name in pairwise(names[:levels]):
        lines.append(f"{name}: &{name} [{','.join(['*' + prev] * 9)}]")
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("levels", [8, 9])
@pytest.mark.parametrize("command", ["benchmark", "render"])
def test_an_alias_bomb_is_refused_at_once_in_one_short_line(tmp_path, command, levels):
    run = _shipped_copy(tmp_path)
    text = _alias_bomb(levels)
    assert len(text) < 450  # a few hundred bytes standing for up to 9**9 = 387,420,489 strings
    (run / CONFIG_FILE).write_text(text)
    start = time.perf_counter()
    message = _exit_message(_commands(run, tmp_path)[command])
    assert time.perf_counter() - start < 1.0
    assert len(message) < 400, len(message)
    assert str(run / CONFIG_FILE) in message and "aliases" in message


@pytest.mark.parametrize(
    "text, words",
    [
        (f"env: {BEARINGS}\nalgo: ppo\nx: &a [1, *a]\n", ["recursive alias"]),
        (f"env: {BEARINGS}\nalgo: ppo\nx: {'[' * 3000}{']' * 3000}\n", ["nested too deeply"]),
        (f"env: {BEARINGS}\nalgo: ppo\nx: {'a' * 20_000}\n", ["longer than 10000"]),
        (f"env: {BEARINGS}\nalgo: ppo\nx: {'a' * 1_000_001}\n", ["larger than 1000000 bytes"]),
        (f"env: {BEARINGS}\nalgo: ppo\nseed: {'9' * 5000}\n", ["not valid YAML", "digits"]),
        (f"env: {BEARINGS}\nalgo: ppo\nseed: -1\n", ["seed -1"]),
        (f"env: {BEARINGS}\nalgo: [ppo, {'x' * 500}]\n", ["algo ['ppo', 'xxx"]),
        (f"env: {BEARINGS}\nalgo: ppo\nagents: maybe\n", ["agents 'maybe'"]),
        (f"env: {'y' * 5000}\nalgo: ppo\n", ["env 'yyy", "is not a registered id"]),
    ],
)
def test_configs_beyond_bounds_are_refused_in_one_short_line(tmp_path, text, words):
    run = _shipped_copy(tmp_path)
    (run / CONFIG_FILE).write_text(text)
    message = _exit_message(_commands(run, tmp_path)["render"])
    assert len(message) < 400, len(message)
    for word in [str(run / CONFIG_FILE), *words]:
        assert word in message, message


def test_a_config_that_is_not_utf8_is_named(tmp_path):
    run = _shipped_copy(tmp_path)
    (run / CONFIG_FILE).write_bytes(f"env: {BEARINGS}\nalgo: ppo\nname: ".encode() + b"\xff\xfe\n")
    for command in ("benchmark", "render"):
        message = _exit_message(_commands(run, tmp_path)[command])
        assert str(run / CONFIG_FILE) in message and "not UTF-8 text (byte 0xff" in message


def _first_weight(state: dict[str, torch.Tensor]) -> str:
    return next(k for k in state if k.endswith("weight"))


@pytest.mark.parametrize("value", [float("nan"), float("inf"), float("-inf")])
@pytest.mark.parametrize("command", ["benchmark", "render"])
def test_weights_that_are_not_finite_are_refused(tmp_path, command, value):
    def poison(state: dict[str, torch.Tensor]) -> None:
        state[_first_weight(state)].view(-1)[3] = value

    run = _shipped_copy(tmp_path, tensors=poison)
    message = _exit_message(_commands(run, tmp_path)[command])
    assert str(run / WEIGHTS_FILE) in message and "1 NaN or infinite values" in message


def test_weights_of_another_dtype_are_refused_not_cast(tmp_path):
    def to_int(state: dict[str, torch.Tensor]) -> None:
        name = _first_weight(state)
        state[name] = state[name].round().to(torch.int64)

    run = _shipped_copy(tmp_path, tensors=to_int)
    for command in ("benchmark", "render"):
        message = _exit_message(_commands(run, tmp_path)[command])
        assert "int64 values where the policy's are float32: refused, not cast" in message
    with pytest.raises(RunFolderError, match="refused, not cast"):
        load_model(run)


@pytest.mark.parametrize(
    "hyperparams, words",
    [
        # a private keyword of SB3's constructor (an AttributeError deep in SB3 before)
        ({"_init_setup_model": False}, ["'_init_setup_model'", "keyword of ppo"]),
        # a wrapper's keyword it does not take (a ValueError traceback from apply_wrappers)
        (
            {"wrappers": [{"name": "time-feature", "depth": 2}]},
            ["'time-feature' does not take ['depth']", "max_episode_steps"],
        ),
        ({"wrappers": [{"name": "frame-stack", "n_stack": "x"}]}, ["n_stack must be"]),
        # sizes that would allocate tens of GB to TB: refused before anything is allocated
        ({"policy_kwargs": {"net_arch": ["1e10"]}}, ["net_arch[0]", "integer >= 1", "'1e10'"]),
        ({"policy_kwargs": {"net_arch": [1e10]}}, ["net_arch[0]", "integer >= 1"]),
        ({"policy_kwargs": {"net_arch": [10**10]}}, ["net_arch[0]", "larger than 65536"]),
        ({"policy_kwargs": {"net_arch": [60_000] * 30}}, ["net_arch", "weights, more than"]),
        ({"n_steps": "1e12"}, ["n_steps: expected int, got '1e12'"]),
        ({"n_steps": 10**12}, ["n_steps: 1000000000000 would allocate", "TB"]),
        ({"wrappers": [{"name": "frame-stack", "n_stack": 10**9}]}, ["n_stack", "1024"]),
        ({"wrappers": [{"name": "frame-stack", "n_stack": 1e9}]}, ["n_stack", "1024"]),
    ],
)
@pytest.mark.parametrize("command", ["benchmark", "render"])
def test_hyperparams_that_would_fail_or_allocate_are_named(tmp_path, command, hyperparams, words):
    run = _shipped_copy(tmp_path, hyperparams)
    message = _exit_message(_commands(run, tmp_path)[command])
    assert len(message) <= 1100
    for word in [CONFIG_FILE, "hyperparams", *words]:
        assert word in message, message


def test_a_config_too_large_for_memory_in_its_params_is_refused(tmp_path):
    run = _shipped_copy(tmp_path)
    config = yaml.safe_load((run / CONFIG_FILE).read_text())
    config["params"] = {"bank_members": 10**15}
    with pytest.raises(RunFolderError, match=r"params: bank_members=10+: .* would need"):
        build_model(config)


def test_a_valid_shipped_copy_still_loads(tmp_path):
    """The control: the folder the hostile ones are made from loads and acts."""
    run = _shipped_copy(tmp_path)
    model = load_model(run)
    obs = np.zeros((1, *model.observation_space.shape), dtype=np.float32)
    assert np.all(np.isfinite(model.predict(obs, deterministic=True)[0]))
