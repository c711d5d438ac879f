"""`--param NAME=VALUE`: any params field from the command line, recorded in runs and checked."""

from __future__ import annotations

import json

import pytest
import yaml

from sensorgym.cli.main import main
from sensorgym.train.env_params import check_same_env, parse_params
from sensorgym.train.trainer import train

ENV_ID = "sensorgym/BearingsManeuver-v0"


def test_values_are_parsed_like_the_fields_and_checked_by_the_params():
    fields = parse_params(
        ENV_ID,
        ["initial_range=(4000, 9000)", "platforms=3", "min_range=400", "bank_ranges=None"],
    )
    assert fields == {
        "initial_range": (4000.0, 9000.0),
        "platforms": 3,
        "min_range": 400.0,
        "bank_ranges": None,
    }
    assert isinstance(fields["min_range"], float) and isinstance(fields["platforms"], int)
    assert parse_params(ENV_ID, ["initial_range=[5000, 6000]"])["initial_range"] == (
        5000.0,
        6000.0,
    )
    with pytest.raises(ValueError, match=r"not a parameter of .*platforms"):
        parse_params(ENV_ID, ["n_platforms=2"])
    with pytest.raises(ValueError, match="initial_range: need 0 < low <= high"):
        parse_params(ENV_ID, ["initial_range=(9000, 4000)"])
    with pytest.raises(ValueError, match="NAME=VALUE"):
        parse_params(ENV_ID, ["platforms"])
    check_same_env(ENV_ID, {"platforms": 1}, {}, "x")  # the default, said or not
    with pytest.raises(ValueError, match="platforms: trained with 2, asked for 3"):
        check_same_env(ENV_ID, {"platforms": 2}, {"platforms": 3}, "the model")


def test_commands_take_params_and_a_policy_refuses_another_size(tmp_path, capsys):
    result = train(
        ENV_ID,
        seed=0,
        timesteps=64,
        n_envs=2,
        out=tmp_path,
        eval_episodes=2,
        progress=False,
        # the YAML's imitation phase, made small (its 60,000 expert steps were most of the time)
        hyperparams={
            "n_steps": 32,
            "batch_size": 64,
            "pretrain": {"expert": "rule:lookahead-estimate", "steps": 64, "epochs": 1},
        },
        curve_points=0,
        params={"bank_members": 4},
    )
    config = yaml.safe_load((result.run_dir / "config.yaml").read_text())
    assert config["params"] == {"bank_members": 4}
    run = str(result.run_dir)
    bench = ["benchmark", "--env", ENV_ID, "--episodes", "2", "--n-envs", "2", "--no-chart"]
    out = tmp_path / "bench"
    assert main([*bench, "--param", "bank_members=4", "--model", run, "--out", str(out)]) == 0
    doc = json.loads((out / "sensorgym__BearingsManeuver-v0.json").read_text())
    assert doc["settings"]["params"] == {"bank_members": 4}
    assert {"model:ppo_seed0", "greedy-information"} <= set(doc["results"])
    with pytest.raises(SystemExit, match="bank_members: trained with 4, asked for 8"):
        main([*bench, "--model", run, "--out", str(out)])
    with pytest.raises(SystemExit, match="name the env"):
        main(["benchmark", "--param", "platforms=2"])
    with pytest.raises(SystemExit, match="not a parameter"):
        main([*bench, "--param", "drones=2"])
    gif = tmp_path / "play.png"
    render = ["render", "--env", ENV_ID, "--model", run, "--out", str(gif)]
    assert main([*render, "--param", "bank_members=4"]) == 0
    with pytest.raises(SystemExit, match="bank_members"):
        main(render)
