"""The training cost on the record: ``cost.json``, wall-clock on curve points and ARS
iterations, the wall-clock axis of ``curve.png`` and the docs' training-cost table."""

from __future__ import annotations

import importlib.util
import json
import os
import time
from pathlib import Path

import matplotlib
import numpy as np
import pytest
import yaml

from sensorgym.train.cost import COST_FILE, RunClock, first_beat, pretrain_samples, read_cost
from sensorgym.train.curves import wall_clock_axis, write_curve
from sensorgym.train.trainer import train

matplotlib.use("Agg")

ROOT = Path(__file__).resolve().parents[2]
BOOK = "sensorgym/BearingsManeuverBook-v0"


def _module(name: str):
    spec = importlib.util.spec_from_file_location(name, ROOT / "benchmarks" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_a_training_run_records_its_cost_and_the_wall_clock_of_its_curve(tmp_path):
    # the recipe imitates book-optimised-plan: the token imitation of conftest, 256 transitions
    result = train(
        BOOK, "ppo", seed=1, timesteps=256, n_envs=4, out=tmp_path, eval_episodes=4,
        progress=False, curve_points=2, hyperparams={"n_steps": 32, "batch_size": 64},
    )  # fmt: skip
    cost = read_cost(result.run_dir)
    assert cost is not None and cost["format"] == 1
    wall = cost["wall_s"]
    assert all(v >= 0.0 for v in wall.values())
    assert wall["training"] == pytest.approx(wall["pretrain"] + wall["learn"], abs=2e-3)
    assert wall["curve_evaluation"] <= wall["training"] <= wall["total"]
    assert wall["rules_evaluation"] + wall["training"] + wall["final_evaluation"] <= wall["total"]
    samples = cost["samples"]
    assert samples["timesteps"] == result.model.num_timesteps >= 256
    assert samples["pretrain"] == pretrain_samples(256, 1, 4) == 256
    assert samples["total"] == samples["timesteps"] + samples["pretrain"]
    machine = cost["machine"]
    assert machine["cpu_count"] == os.cpu_count()
    assert 1 <= machine["usable_cpus"] <= machine["cpu_count"]
    assert machine["torch_threads"] == 1  # train()'s default, as the run had it
    assert machine["python"] and machine["numpy"] == np.__version__ and machine["torch"]
    assert all(v is None or v >= 0.0 for v in cost["load_average_1min"].values())
    assert cost["started_utc"] <= cost["finished_utc"]

    points = json.loads((result.run_dir / "curve.json").read_text())["points"]
    walls = [p["wall_s"] for p in points]
    evals = [p["eval_s"] for p in points]
    assert walls == sorted(walls) and evals == sorted(evals) and evals[0] == 0.0
    assert walls[0] >= wall["pretrain"] - 1e-3  # the first point scores the imitated policy
    assert walls[-1] <= wall["training"] and evals[-1] <= wall["curve_evaluation"]
    assert all(e <= w for e, w in zip(evals, walls, strict=True))
    # the loader of a run folder ignores the record
    config = yaml.safe_load((result.run_dir / "config.yaml").read_text())
    assert "cost" not in config


def test_ars_iterations_carry_the_runs_clock():
    from tests.train.test_ars import _model

    model = _model(n_envs=2, episodes=2, n_directions=1)
    clock = RunClock()
    clock.start()
    clock.origin -= 100.0  # the run's clock started 100 s before learning
    model.clock = clock
    model.learn(1)
    assert len(model.history) == 1 and model.history[0]["wall_s"] >= 100.0
    model = _model(n_envs=2, episodes=2, n_directions=1)  # on its own: a clock of its own
    model.learn(1)
    assert 0.0 <= model.history[0]["wall_s"] < 100.0


def _points(wall: bool) -> list[dict]:
    points = [
        {"timesteps": t, "mean": m, "ci95": 0.1}
        for t, m in [(0, 1.0), (1000, 2.0), (2000, 2.5), (2016, 2.6)]
    ]
    if wall:
        for i, p in enumerate(points):
            p["wall_s"], p["eval_s"] = 4.0 + 10.0 * i, 0.5 * i
    return points


@pytest.mark.parametrize("wall", [True, False])
def test_the_curve_draws_with_and_without_wall_clock(tmp_path, wall):
    json_path, png_path = write_curve(tmp_path, "t", _points(wall), {"rule": 2.2})
    assert png_path.stat().st_size > 1000
    assert ("wall_s" in json.loads(json_path.read_text())["points"][0]) is wall

    import matplotlib.pyplot as plt

    fig, ax = plt.subplots()
    top = wall_clock_axis(ax, _points(wall))
    if not wall:
        assert top is None
    else:  # ticks at points, labelled with their recorded seconds; the crowded third left out
        assert list(top.get_xticks()) == [0.0, 1000.0, 2016.0]
        assert [t.get_text() for t in top.get_xticklabels()] == ["4", "14", "34"]
    plt.close(fig)


def test_first_beat_is_the_first_point_above_the_rule():
    points = _points(True)
    assert first_beat(points, 1.5)["timesteps"] == 1000
    assert first_beat(points, 2.0)["timesteps"] == 2000  # equal is not above
    assert first_beat(points, 9.0) is None


def _run_folder(folder: Path, name: str, cost: dict | None, wall: bool) -> None:
    run = folder / "sensorgym__BearingsManeuverBook-v0" / name
    run.mkdir(parents=True)
    hp = {"n_envs": 16, "n_timesteps": 2000, "pretrain": {"steps": 100, "rounds": 2}}
    (run / "config.yaml").write_text(yaml.safe_dump({"algo": "ppo", "hyperparams": hp}))
    (run / "evaluation.json").write_text(json.dumps({"seed": 500}))
    # the env's best rule as the committed scores name it, its mean on the curve's scenarios
    scores = ROOT / "docs" / "scores" / "sensorgym__BearingsManeuverBook-v0.json"
    best = json.loads(scores.read_text())["best_rule"]
    curve = {"points": _points(wall), "rules": {best: 1.5}}
    (run / "curve.json").write_text(json.dumps(curve))
    if cost is not None:
        (run / COST_FILE).write_text(json.dumps(cost))


def test_the_cost_table_says_not_recorded_for_runs_without_a_record(tmp_path):
    tables = _module("tables")
    cost = {
        "wall_s": {"training": 40.0, "total": 52.0},
        "samples": {"timesteps": 2016, "pretrain": 224},
        "machine": {"usable_cpus": 2, "cpu_count": 4, "torch_threads": 1},
        "load_average_1min": {"start": 1.04, "end": 2.5},
    }
    _run_folder(tmp_path, "ppo_seed0", None, wall=False)
    _run_folder(tmp_path, "ppo_seed1", cost, wall=True)
    rows = {
        line.split(" | ")[1]: line
        for line in tables.training_cost(tmp_path).splitlines()
        if "BearingsManeuverBook" in line
    }
    old, new = rows["`ppo_seed0`"], rows["`ppo_seed1`"]
    # samples are on record in curve.json and config.yaml (2 rounds of 112 = 7 steps x 16)
    assert "| 2 016 + 224 |" in old and old.count("not recorded") == 4
    assert "| 1 000 + 224 (2.000) | not recorded |" in old
    assert "not recorded" not in new
    assert "| 40 s (52 s) | 2 of 4, 1 | 1.0 → 2.5 | 500 |" in new
    assert new.endswith("| 1 000 + 224 (2.000) | 14 s |")
    assert "none shipped" in tables.training_cost(tmp_path).splitlines()[-1]


def test_retraining_compares_weights_tensor_by_tensor(tmp_path):
    from safetensors.numpy import save_file

    training_cost = _module("training_cost")
    w = {"a": np.arange(6, dtype=np.float32).reshape(2, 3), "b": np.ones(2, dtype=np.float32)}
    save_file(w, tmp_path / "x.safetensors", metadata={"env": "e", "algo": "ppo"})
    save_file(w, tmp_path / "y.safetensors", metadata={"algo": "ppo", "env": "e"})
    assert training_cost.compare_weights(tmp_path / "x.safetensors", tmp_path / "y.safetensors")[
        "identical"
    ]
    w["a"] = w["a"].copy()
    w["a"][1, 2] += 1e-3
    save_file(w, tmp_path / "z.safetensors", metadata={"env": "e", "algo": "ppo"})
    report = training_cost.compare_weights(tmp_path / "x.safetensors", tmp_path / "z.safetensors")
    assert not report["identical"] and set(report["tensors"]) == {"a"}
    assert report["tensors"]["a"]["max_abs_diff"] == pytest.approx(1e-3, rel=1e-3)
    assert report["tensors"]["a"]["differing_share"] == pytest.approx(1 / 6)


def test_the_clock_counts_from_its_start():
    clock = RunClock()
    assert clock.elapsed() == 0.0
    clock.start()
    time.sleep(0.01)
    clock.add_eval(0.5)
    assert clock.elapsed() >= 0.01 and clock.eval_s == 0.5
