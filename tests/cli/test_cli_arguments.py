"""Every bad argument ends in one line and a non-zero exit, before any work (issue 35, item 4):
seeds, counts, frame rates, output locations, ``--param`` values too deep or too large for the
machine, and ``SENSORGYM_THREADS``."""

from __future__ import annotations

import json
import math

import pytest

from sensorgym.cli import args as types
from sensorgym.envs.shells import rows
from sensorgym.train import benchmark as scoring
from sensorgym.train import trainer
from sensorgym.train.env_params import _traced_bytes, check_memory, memory_estimate
from tests.cli.test_cli_mistakes import _fails

BEARINGS = "sensorgym/BearingsManeuver-v0"
POINTING = "sensorgym/StereoPointing-v0"


@pytest.fixture
def no_work(monkeypatch):
    """Scoring and training fail the test if reached: the mistakes must be caught first."""

    def reached(*args, **kwargs):
        raise AssertionError("the command started its work before checking its arguments")

    monkeypatch.setattr(scoring, "score", reached)
    monkeypatch.setattr(trainer, "train", reached)


def _commands(tmp_path) -> dict[str, list[str]]:
    """A minimal valid command line per command (each with its own ``--out``)."""
    return {
        "benchmark": ["benchmark", "--env", BEARINGS, "--out", str(tmp_path / "b")],
        "render": ["render", "--env", BEARINGS, "--out", str(tmp_path / "r.gif")],
        "train": ["train", "--env", BEARINGS, "--out", str(tmp_path / "t")],
        "sweep": ["sweep", "--env", BEARINGS, "--out", str(tmp_path / "s")],
        "reproduce": ["reproduce", "paper002", "--out", str(tmp_path / "p")],
        "triangulate-demo": ["triangulate-demo"],
    }


@pytest.mark.parametrize("value", ["-1", "2147483648", "1e3", "seven"])
@pytest.mark.parametrize(
    "command", ["benchmark", "render", "train", "reproduce", "triangulate-demo"]
)
def test_a_bad_seed_is_refused_at_parsing(tmp_path, command, value, no_work):
    message = _fails([*_commands(tmp_path)[command], "--seed", value], "argument --seed")
    assert f"sensorgym {command}" in message or "sensorgym reproduce paper002" in message
    assert not any(tmp_path.iterdir())  # nothing was created


def test_sweep_seeds_are_checked_like_every_seed(tmp_path):
    _fails([*_commands(tmp_path)["sweep"], "--seeds", "0", "-1"], "argument --seeds", "-1")
    _fails([*_commands(tmp_path)["sweep"], "--search-seed", "-1"], "argument --search-seed")


@pytest.mark.parametrize(
    "command, flag, value",
    [
        ("benchmark", "--episodes", "0"),
        ("benchmark", "--n-envs", "-2"),
        ("render", "--every", "0"),
        ("train", "--timesteps", "0"),
        ("train", "--n-envs", "0"),
        ("train", "--eval-episodes", "-1"),
        ("train", "--curve-points", "-1"),
        ("train", "--torch-threads", "0"),
        ("sweep", "--samples", "0"),
        ("sweep", "--benchmark-episodes", "-1"),
        ("sweep", "--cpus-per-trial", "nan"),
        ("reproduce", "--runs", "0"),
        ("triangulate-demo", "--runs", "0"),
    ],
)
def test_counts_below_their_minimum_are_refused_at_parsing(tmp_path, command, flag, value):
    _fails([*_commands(tmp_path)[command], flag, value], f"argument {flag}", value)


@pytest.mark.parametrize("value", ["1e-9", "nan", "inf", "0", "-5", "1000", "fast"])
def test_render_fps_must_be_a_sane_finite_rate(tmp_path, value):
    _fails([*_commands(tmp_path)["render"], "--fps", value], "argument --fps")


def test_render_fps_at_the_ends_of_its_range_is_taken():
    lo, hi = types.FPS_RANGE
    assert types.fps(str(lo)) == lo and types.fps(str(hi)) == hi
    assert 1000 / hi >= 10 and 1000 / lo <= 655_350  # a GIF's delay: 10 ms to 655.35 s


@pytest.mark.parametrize("command", ["benchmark", "train", "sweep", "reproduce"])
def test_an_out_folder_that_is_a_file_fails_before_any_work(tmp_path, command, no_work):
    occupied = tmp_path / "occupied"
    occupied.write_text("a file where the output folder should go")
    argv = [*_commands(tmp_path)[command], "--out", str(occupied)]
    _fails(argv, "--out", str(occupied), "not a folder")
    _fails([*argv[:-1], str(occupied / "below")], "--out", "cannot create the folder")
    assert occupied.read_text().startswith("a file")


def test_render_out_must_be_a_writable_file_path(tmp_path, no_work):
    occupied = tmp_path / "occupied"
    occupied.write_text("x")
    render = _commands(tmp_path)["render"]
    _fails([*render, "--out", str(occupied / "episode.gif")], "--out", "not a folder")
    (tmp_path / "folder.gif").mkdir()
    _fails([*render, "--out", str(tmp_path / "folder.gif")], "--out", "is a folder, not a file")


def test_train_tensorboard_folder_is_checked_before_training(tmp_path, no_work):
    occupied = tmp_path / "occupied"
    occupied.write_text("x")
    argv = [*_commands(tmp_path)["train"], "--tensorboard", str(occupied)]
    _fails(argv, "--tensorboard", "not a folder")


def test_benchmark_creates_out_before_scoring(tmp_path, monkeypatch):
    """The output folder exists by the time the first policy is scored."""
    out = tmp_path / "deep" / "out"

    def score(*args, **kwargs):
        assert out.is_dir()
        raise SystemExit("stop: the folder was there")

    monkeypatch.setattr(scoring, "score", score)
    _fails(["benchmark", "--env", BEARINGS, "--out", str(out), "--no-shipped"], "stop")


def test_benchmark_takes_fewer_episodes_than_its_default_batch(tmp_path):
    from sensorgym.cli.main import main

    out = tmp_path / "b"
    argv = ["benchmark", "--env", BEARINGS, "--episodes", "2", "--no-shipped", "--no-chart"]
    assert main([*argv, "--out", str(out)]) == 0
    settings = json.loads((out / "benchmark.json").read_text())["settings"]
    assert settings["episodes"] == 2 and settings["n_envs"] == 2
    # a batch said explicitly still may not exceed the episodes
    _fails([*argv, "--n-envs", "4", "--out", str(out)], "--episodes (2) must be >= --n-envs (4)")


@pytest.mark.parametrize("dashes", [5_000, 100_000])
@pytest.mark.parametrize("command", ["benchmark", "render", "train"])
def test_a_param_value_too_deep_or_long_is_named(tmp_path, command, dashes, no_work):
    value = "-" * dashes + "1"
    argv = [*_commands(tmp_path)[command], "--param", f"min_range={value}"]
    message = _fails(argv, "--param min_range")
    assert len(message) < 200
    assert ("nested too deeply" if dashes < 10_000 else "characters long") in message


@pytest.mark.parametrize("command", ["benchmark", "render", "train"])
def test_a_count_the_machine_cannot_hold_is_refused_with_its_estimate(tmp_path, command, no_work):
    argv = _commands(tmp_path)[command]
    argv[argv.index(BEARINGS)] = POINTING
    message = _fails([*argv, "--param", "n_drones=1000000000000"], "--param n_drones=1000000000000")
    assert "would need ~" in message and "PB" in message and "available" in message


def test_the_memory_estimate_is_close_and_the_check_compares_it():
    # n_drones = 300: beyond the probes (<= 256 drones), so extrapolated
    estimate = memory_estimate(POINTING, {"n_drones": 300})
    measured = _traced_bytes(POINTING, {"n_drones": 300})
    assert estimate is not None and measured / 2 < estimate < measured * 3
    check_memory(POINTING, {"n_drones": 300}, available=int(1e12))  # fits: no error
    with pytest.raises(ValueError, match=r"n_drones=300: .* would need ~.* for 16 scenarios"):
        check_memory(POINTING, {"n_drones": 300}, scenarios=16, available=int(estimate))
    check_memory(POINTING, {"n_drones": 8}, available=1)  # small counts are never probed


@pytest.mark.parametrize("value", ["abc", "0", "-3"])
def test_a_bad_thread_count_is_one_line(tmp_path, monkeypatch, value, no_work):
    monkeypatch.setenv("SENSORGYM_THREADS", value)
    _fails(_commands(tmp_path)["benchmark"], "SENSORGYM_THREADS", value)


@pytest.mark.parametrize("value", ["", "  "])
def test_an_empty_thread_count_counts_as_unset(monkeypatch, value):
    monkeypatch.delenv("SENSORGYM_THREADS", raising=False)
    unset = rows.threads()
    monkeypatch.setenv("SENSORGYM_THREADS", value)
    assert rows.threads() == unset >= 1


def test_a_run_folder_error_anywhere_in_a_command_is_one_line(tmp_path, monkeypatch):
    """What no command catches itself, ``sensorgym`` prints as one bounded line (exit 1)."""
    from sensorgym.cli import render
    from sensorgym.train.models import MAX_MESSAGE_CHARS, RunFolderError

    def run(args):
        raise RunFolderError("config.yaml: " + "a very\nlong message " * 10_000)

    monkeypatch.setattr(render, "run", run)
    message = _fails(_commands(tmp_path)["render"], "sensorgym render: config.yaml: a very long")
    assert len(message) <= MAX_MESSAGE_CHARS + len("sensorgym render: ")


@pytest.mark.parametrize(
    "pair, words",
    [
        ("n_steps=1e12", ["n_steps: expected int"]),
        ("n_steps=1000000000000", ["n_steps: 1000000000000 would allocate"]),
        ("policy_kwargs.net_arch=[10000000000]", ["net_arch[0]", "larger than 65536"]),
        ("_init_setup_model=false", ["'_init_setup_model'", "keyword of ppo"]),
        ("n_envs=0", ["n_envs: must be an integer >= 1"]),
        ("wrappers=[{name: frame-stack, depth: 2}]", ["does not take ['depth']"]),
    ],
)
def test_train_hyperparams_are_checked_before_training(tmp_path, pair, words, no_work):
    _fails([*_commands(tmp_path)["train"], "--hyperparam", pair], "--hyperparam", *words)
    assert not (tmp_path / "t").exists()


def test_argument_types_accept_what_they_should():
    assert types.seed("0") == 0 and types.seed(str(types.MAX_SEED)) == types.MAX_SEED
    assert types.positive_int("3") == 3 and types.non_negative_int("0") == 0
    assert types.positive_float("0.5") == 0.5 and math.isclose(types.fps("2.5"), 2.5)


def test_benchmark_rule_scores_exactly_the_named_rules(tmp_path):
    """``--rule`` (repeatable) scores those rules, an ablation among them, and no other; the
    best rule is the best of them."""
    from sensorgym.agents.registry import ABLATIONS
    from sensorgym.cli.main import main

    env_id = "sensorgym/BearingsManeuverBook-v0"
    assert "paper002" in ABLATIONS[env_id]
    out = tmp_path / "b"
    argv = ["benchmark", "--env", env_id, "--episodes", "4", "--n-envs", "2", "--no-shipped",
            "--no-chart", "--rule", "paper002", "--rule", "straight-course", "--out", str(out)]  # fmt: skip
    assert main(argv) == 0
    doc = json.loads((out / f"{env_id.replace('/', '__')}.json").read_text())
    assert set(doc["results"]) == {"paper002", "straight-course"}
    assert doc["best_rule"] == max(doc["results"], key=lambda n: doc["results"][n]["mean"])
    assert all(r["episodes"] == 4 for r in doc["results"].values())


def test_benchmark_refuses_an_unknown_rule_and_lists_the_known_ones(tmp_path, no_work):
    from sensorgym.agents.registry import RULES

    argv = [*_commands(tmp_path)["benchmark"], "--rule", "plan-search"]
    message = _fails(argv, "--rule", "plan-search", "not registered for", BEARINGS, "known:")
    assert all(name in message for name in RULES[BEARINGS])
    # every name must hold for every env scored
    argv = ["benchmark", "--env", POINTING, "--env", BEARINGS, "--rule", "plan-search",
            "--out", str(tmp_path / "c")]  # fmt: skip
    _fails(argv, "--rule", "plan-search", "not registered for", BEARINGS)
    _fails([*_commands(tmp_path)["benchmark"], "--rule", "paper002", "--all-rules"], "--all-rules")


def test_every_option_with_a_default_states_it_in_its_help():
    import argparse

    from sensorgym.cli.main import build_parser

    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    checked = 0
    for name, parser in sub.choices.items():
        text = " ".join(parser.format_help().split())
        for action in parser._actions:
            default = action.default
            if not action.option_strings or action.help == argparse.SUPPRESS:
                continue
            if default in (None, False, argparse.SUPPRESS) or default == []:
                continue
            help_text = " ".join((action.help or "").split())
            assert "default" in help_text.lower() or f"(default: {default})" in text, (
                name,
                action.option_strings,
            )
            checked += 1
    assert checked >= 20


def test_record_writes_a_video_unless_told_otherwise():
    from sensorgym.cli.main import build_parser

    for command in ("render", "record", "enjoy"):
        assert build_parser().parse_args([command]).out.suffix == ".mp4"
