"""``sensorgym sweep``: a tiny two-seed sweep on a local Ray instance, and its aggregation."""

from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from sensorgym.cli.main import main
from sensorgym.train.benchmark import PolicySpec, pool, score
from sensorgym.train.models import read_config
from sensorgym.train.sweep import aggregate, config_tag, join_with_token, parse_space

pytest.importorskip("ray")

ENV = "sensorgym/BearingsManeuver-v0"


@pytest.fixture
def short_tmp():
    """A temp folder with a short path (Ray's socket paths under it must fit 107 bytes)."""
    path = Path(tempfile.mkdtemp(prefix="sgray"))
    yield path
    shutil.rmtree(path, ignore_errors=True)


def test_two_seed_sweep_on_a_local_ray_instance(tmp_path, capsys, monkeypatch, short_tmp):
    # the cluster file a head that has gone left in Ray's temp folder is not joined: a local
    # sweep starts an instance of its own (Ray's temp folder moved to a short one of this test)
    (short_tmp / "ray").mkdir()
    (short_tmp / "ray" / "ray_current_cluster").write_text("127.0.0.1:1")
    monkeypatch.setenv("RAY_TMPDIR", str(short_tmp))
    monkeypatch.delenv("RAY_ADDRESS", raising=False)
    args = ["--seeds", "0", "1", "--timesteps", "2048", "--n-envs", "8", "--eval-episodes", "4"]
    args += ["--hyperparam", "pretrain.steps=2000"]  # a small imitation phase, set for every trial
    bench = ["--benchmark-episodes", "8", "--benchmark-chunk", "4"]  # 2 Ray tasks per policy
    assert main(["sweep", *args, *bench, "--num-cpus", "2", "--out", str(tmp_path)]) == 0
    printed = capsys.readouterr().out
    assert "yaml (best)" in printed and "±95 %" in printed
    assert f"  {tmp_path.resolve() / 'sweep.png'}\n" in printed  # whole, however long
    doc = json.loads((tmp_path / "sweep.json").read_text())
    assert doc["best"] == "yaml" and doc["incomplete"] == 0
    assert doc["settings"]["fixed"] == {"pretrain.steps": 2000}
    (config,) = doc["configs"].values()
    assert config["seeds"] == [0, 1]
    # every trial is an ordinary `sensorgym train` run folder, whose evaluation is aggregated
    returns = []
    for seed, run_dir in zip(config["seeds"], config["run_dirs"], strict=True):
        assert read_config(run_dir)["seed"] == seed
        assert read_config(run_dir)["hyperparams"]["n_timesteps"] == 2048
        assert read_config(run_dir)["hyperparams"]["pretrain"]["steps"] == 2000
        evaluation = json.loads((tmp_path / run_dir / "evaluation.json").read_text())
        returns.append(evaluation["results"]["trained"]["mean"])
    assert config["returns"] == returns
    # the rules, scored beside each trial's policy on the same episodes, are the chart's lines
    rules = json.loads((tmp_path / config["run_dirs"][0] / "evaluation.json").read_text())
    assert doc["rules"] == {k: v["mean"] for k, v in rules["results"].items() if k != "trained"}
    assert {"straight-course", "mpc-estimate"} <= set(doc["rules"])
    assert config["mean"] == pytest.approx(np.mean(returns))
    half = stats.t.ppf(0.975, 1) * np.std(returns, ddof=1) / np.sqrt(2)
    assert config["ci95"] == pytest.approx(half)
    assert (tmp_path / "sweep.png").read_bytes()[:4] == b"\x89PNG"
    # the benchmark fan-out: every rule and both seeds' runs, chunks on seeds 10000 and 10001
    benchmark = doc["benchmark"]
    assert {"paper002", "truth-lookahead", "model:ppo_seed0", "model:ppo_seed1"} <= set(benchmark)
    chunks = [
        score(ENV, PolicySpec("rule", "straight-course"), 4, 4, seed) for seed in (10_000, 10_001)
    ]
    pooled = pool(chunks)
    assert benchmark["straight-course"]["returns"] == pooled.pop("returns")
    assert benchmark["straight-course"]["tails"] == pooled.pop("tails")  # the tail in metres
    assert {k: benchmark["straight-course"][k] for k in pooled} == pytest.approx(pooled)
    assert all(r["episodes"] == 8 for r in benchmark.values())
    assert (tmp_path / "benchmark.png").is_file()


def test_pooled_statistics_equal_those_of_all_episodes():
    rng = np.random.default_rng(0)
    x = rng.normal(size=50)
    parts = [x[:20], x[20:23], x[23:]]
    pooled = pool(
        [{"mean": p.mean(), "std": p.std(ddof=1), "episodes": p.size, "mean_length": 30.0}
         for p in parts]
    )  # fmt: skip
    assert pooled["mean"] == pytest.approx(x.mean()) and pooled["episodes"] == 50
    assert pooled["std"] == pytest.approx(x.std(ddof=1))
    assert pooled["ci95"] == pytest.approx(1.96 * x.std(ddof=1) / np.sqrt(50))


def test_search_space_specs():
    from ray import tune

    name, domain = parse_space("learning_rate=loguniform:1e-4:1e-3")
    assert name == "learning_rate" and isinstance(domain, tune.search.sample.Float)
    assert parse_space("gamma=grid:0.95,0.99")[1] == {"grid_search": [0.95, 0.99]}
    for bad in ("gamma", "gamma=choice", "gamma=normal:0:1", "lr=uniform:3:1", "lr=loguniform:0:1"):
        with pytest.raises(ValueError, match="space"):
            parse_space(bad)


def test_aggregate_groups_configurations_over_seeds():
    a, b = {"gamma": 0.9}, {"gamma": 0.99}
    trials = [
        {"seed": 1, "hyperparams": a, "tag": config_tag(a), "eval_return": 2.0, "run_dir": "r1"},
        {"seed": 0, "hyperparams": a, "tag": config_tag(a), "eval_return": 1.0, "run_dir": "r0"},
        {"seed": 0, "hyperparams": b, "tag": config_tag(b), "eval_return": 5.0, "run_dir": "s0"},
        {"seed": 1, "hyperparams": b, "tag": None, "eval_return": None, "run_dir": None},
    ]
    doc = aggregate(trials)
    assert doc["incomplete"] == 1 and doc["best"] == config_tag(b)
    ca = doc["configs"][config_tag(a)]
    assert ca["seeds"] == [0, 1] and ca["returns"] == [1.0, 2.0] and ca["mean"] == 1.5
    assert ca["ci95"] == pytest.approx(stats.t.ppf(0.975, 1) * np.std([1, 2], ddof=1) / 2**0.5)
    assert doc["configs"][config_tag(b)]["ci95"] is None  # one seed: no interval
    assert config_tag({}) == "yaml" and config_tag(a) != config_tag(b)


def test_sweep_refuses_names_the_recipe_cannot_take_before_starting_ray(tmp_path):
    with pytest.raises(SystemExit, match=r"--space: \['learnin_rate'\]"):
        main(["sweep", "--space", "learnin_rate=grid:1e-3", "--out", str(tmp_path)])
    with pytest.raises(SystemExit, match=r"--hyperparam: .*not a mapping"):
        main(["sweep", "--hyperparam", "n_steps.size=3", "--out", str(tmp_path)])
    assert not any(tmp_path.iterdir())  # nothing was started or written


def test_pooling_keeps_each_episodes_bound_and_tail_in_order():
    parts = [
        {"mean": 1.0, "std": 0.0, "episodes": 2, "mean_length": 3.0, "returns": [1.0, 1.0],
         "bounds": [2.0, 3.0], "tails": {"final_error": [10.0, 20.0], "other": [1.0, 2.0]}},
        {"mean": 2.0, "std": 0.0, "episodes": 1, "mean_length": 3.0, "returns": [2.0],
         "bounds": [4.0], "tails": {"final_error": [30.0]}},
    ]  # fmt: skip
    pooled = pool(parts)
    assert pooled["returns"] == [1.0, 1.0, 2.0] and pooled["bounds"] == [2.0, 3.0, 4.0]
    assert pooled["tails"] == {"final_error": [10.0, 20.0, 30.0]}  # only what every part has
    del parts[1]["bounds"]
    assert "bounds" not in pool(parts)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _processes_naming(text: str) -> list[int]:
    """pids of the processes whose command line contains ``text``, and of their children."""
    table = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                cmd = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="ignore")
                ppid = int((entry / "stat").read_text().rsplit(")", 1)[1].split()[1])
            except (OSError, ValueError, IndexError):
                continue
            table[int(entry.name)] = (cmd, ppid)
    ours = {pid for pid, (cmd, _) in table.items() if text in cmd}
    return sorted(ours | {pid for pid, (_, ppid) in table.items() if ppid in ours})


@pytest.fixture
def ray_head(monkeypatch, short_tmp):
    """A Ray head started by ``ray start --head`` (token auth on, as Ray >= 2.59 starts it) in
    a temp folder of its own; stopped at the end by its own processes' pids (``ray stop`` would
    stop every Ray instance on the machine, a parallel test's too)."""
    if not Path("/proc/self/cmdline").exists():
        pytest.skip("needs /proc to find the head's processes")
    port, temp = _free_port(), str(short_tmp)
    for key in ("RAY_AUTH_MODE", "RAY_ADDRESS"):  # set (so the teardown restores) and remove
        monkeypatch.setenv(key, "")
        monkeypatch.delenv(key)
    ray_cli = Path(sys.executable).parent / "ray"
    start = [str(ray_cli), "start", "--head", f"--port={port}", "--num-cpus=2"]
    start += [f"--temp-dir={temp}", "--include-dashboard=false", "--disable-usage-stats"]
    subprocess.run(start, check=True, capture_output=True, timeout=180)
    try:
        yield f"127.0.0.1:{port}"
    finally:
        for sig in (signal.SIGTERM, signal.SIGKILL):
            for pid in _processes_naming(temp):
                try:
                    os.kill(pid, sig)
                except ProcessLookupError:
                    pass
            deadline = time.monotonic() + 10
            while _processes_naming(temp) and time.monotonic() < deadline:
                time.sleep(0.2)


def test_an_ars_sweep_joins_a_head_started_with_token_auth(ray_head, tmp_path):
    # a fresh process, as a user starts it (Ray reads its auth mode once per process), with no
    # RAY_AUTH_MODE in its environment: the sweep turns token mode on to join the head
    env = "sensorgym/StereoPointing-v0"
    args = ["--env", env, "--algo", "ars", "--seeds", "0", "--timesteps", "1", "--n-envs", "2"]
    args += ["--eval-episodes", "2", "--hyperparam", "episodes=2", "--hyperparam", "n_directions=1"]
    cli = Path(sys.executable).parent / "sensorgym"
    environ = {k: v for k, v in os.environ.items() if not k.startswith("RAY_AUTH")}
    done = subprocess.run(
        [str(cli), "sweep", *args, "--address", ray_head, "--out", str(tmp_path)],
        env=environ,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-4000:]
    doc = json.loads((tmp_path / "sweep.json").read_text())
    assert doc["settings"]["algo"] == "ars" and doc["incomplete"] == 0
    (config,) = doc["configs"].values()
    (run_dir,) = config["run_dirs"]
    assert read_config(run_dir)["algo"] == "ars"
    evaluation = json.loads((tmp_path / run_dir / "evaluation.json").read_text())
    assert config["returns"] == [evaluation["results"]["trained"]["mean"]]


def test_token_mode_is_set_only_to_join_a_cluster_with_a_token_at_hand(monkeypatch, tmp_path):
    monkeypatch.setenv("RAY_AUTH_MODE", "")
    monkeypatch.delenv("RAY_AUTH_MODE")
    monkeypatch.delenv("RAY_AUTH_TOKEN", raising=False)
    monkeypatch.delenv("RAY_AUTH_TOKEN_PATH", raising=False)
    monkeypatch.setattr("sensorgym.train.sweep.RAY_TOKEN_FILE", tmp_path / "none")
    assert not join_with_token(None)  # a local instance of our own
    assert not join_with_token("127.0.0.1:6379")  # no token anywhere: as Ray would
    assert "RAY_AUTH_MODE" not in os.environ
    monkeypatch.setenv("RAY_AUTH_TOKEN", "secret")
    assert join_with_token("127.0.0.1:6379") and os.environ["RAY_AUTH_MODE"] == "token"
    monkeypatch.setenv("RAY_AUTH_MODE", "disabled")  # the user's choice stands
    assert not join_with_token("auto") and os.environ["RAY_AUTH_MODE"] == "disabled"
