"""Mistakes on the command line end in one clear line naming the argument or file, and a
non-zero exit (issue 10, defect 6): never a traceback, never a silently dropped model."""

from __future__ import annotations

import contextlib
import io

import pytest
import yaml

from sensorgym.cli.main import main
from sensorgym.train.models import CONFIG_FILE, WEIGHTS_FILE

BEARINGS = "sensorgym/BearingsManeuver-v0"
PLACEMENT = "sensorgym/StereoPlacement-v0"


def _run_folder(tmp_path, config, model: bool = True):
    run = tmp_path / "run"
    run.mkdir()
    (run / CONFIG_FILE).write_text(config if isinstance(config, str) else yaml.safe_dump(config))
    if model:
        (run / WEIGHTS_FILE).write_bytes(b"not read: the checks come first")
    return run


def _fails(argv: list[str], *words: str) -> str:
    """The one line ``sensorgym ARGV`` fails with: its ``SystemExit`` message, or what the
    argument parser printed (status 2); every one of ``words`` must be in it."""
    stderr = io.StringIO()
    with pytest.raises(SystemExit) as exc, contextlib.redirect_stderr(stderr):
        main(argv)
    assert exc.value.code not in (0, None)
    if isinstance(exc.value.code, int):  # the parser's error, printed
        assert exc.value.code == 2
        message = stderr.getvalue().removesuffix("\n")
    else:
        message = str(exc.value.code)
    assert message and "\n" not in message, message
    for word in words:
        assert word in message, message
    return message


def test_benchmark_refuses_a_model_of_another_env(tmp_path):
    run = _run_folder(tmp_path, {"env": BEARINGS, "algo": "ppo"})
    _fails(["benchmark", "--env", PLACEMENT, "--model", str(run)], "trained on", BEARINGS)


def test_render_refuses_a_model_of_another_env(tmp_path):
    run = _run_folder(tmp_path, {"env": BEARINGS, "algo": "ppo"})
    out = str(tmp_path / "x.gif")
    _fails(["render", "--env", PLACEMENT, "--model", str(run), "--out", out], "trained on")


@pytest.mark.parametrize(
    "config, model, words",
    [
        ("", True, [CONFIG_FILE, "mapping"]),
        ({"env": BEARINGS, "algo": "dqn"}, True, [CONFIG_FILE, "dqn"]),
        ({"env": "sensorgym/Nope-v0", "algo": "ppo"}, True, [CONFIG_FILE, "Nope"]),
        ({"algo": "ppo"}, True, [CONFIG_FILE, "'env'"]),
        ({"env": BEARINGS, "algo": "ppo"}, False, [WEIGHTS_FILE, "no such weights file"]),
    ],
)
@pytest.mark.parametrize("command", ["benchmark", "render"])
def test_broken_run_folders_are_named(tmp_path, command, config, model, words):
    run = _run_folder(tmp_path, config, model)
    extra = ["--out", str(tmp_path / "x.gif")] if command == "render" else []
    _fails([command, "--env", BEARINGS, "--model", str(run), *extra], "--model", *words)


@pytest.mark.parametrize("name", [WEIGHTS_FILE, "model.zip"])
def test_a_model_file_path_names_its_folder(tmp_path, name):
    run = _run_folder(tmp_path, {"env": BEARINGS, "algo": "ppo"}, model=False)
    _fails(["benchmark", "--env", BEARINGS, "--model", str(run / name)], str(run / WEIGHTS_FILE))


@pytest.mark.parametrize("command", ["benchmark", "render", "train"])
def test_unknown_env_ids_are_named(tmp_path, command):
    extra = {"render": ["--out", str(tmp_path / "x.gif")], "train": ["--out", str(tmp_path)]}
    _fails([command, "--env", "sensorgym/Nope-v0", *extra.get(command, [])], "sensorgym/Nope-v0")


@pytest.mark.parametrize(
    "extra, words",
    [
        (["--space", "gamma"], ["--space", "NAME=KIND:ARGS"]),
        (["--space", "lr=loguniform:1e-3:1e-4"], ["--space", "LO < HI"]),
        (["--space", "gamma=normal:0:1"], ["--space", "normal"]),
        (["--env", "sensorgym/Nope-v0"], ["--env", "sensorgym/Nope-v0"]),
        (["--samples", "0"], ["--samples"]),
    ],
)
def test_sweep_mistakes_are_named_before_ray_starts(extra, words, tmp_path):
    pytest.importorskip("ray")
    _fails(["sweep", *extra, "--out", str(tmp_path)], *words)
