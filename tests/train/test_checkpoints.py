"""``sensorgym train --checkpoint-every N`` and ``--resume RUN``: a run stopped midway continues
from its checkpoint into a complete run folder."""

from __future__ import annotations

import json

import pytest
import torch
from stable_baselines3.common.callbacks import BaseCallback

from sensorgym.cli.main import main
from sensorgym.train.checkpoints import read_checkpoint
from sensorgym.train.models import load_model, read_config
from sensorgym.train.trainer import resume_arguments, train

ENV = "sensorgym/BearingsManeuver-v0"


class _Stop(Exception):
    """The process dies here (a killed job, a lost node)."""


class _DieAt(BaseCallback):
    def __init__(self, at: int):
        super().__init__()
        self.at = at

    def _on_step(self) -> bool:
        if self.num_timesteps >= self.at:
            raise _Stop
        return True


def test_a_stopped_run_resumes_from_its_checkpoint_to_a_complete_run_folder(tmp_path):
    settings = {"seed": 3, "timesteps": 1920, "n_envs": 4, "eval_episodes": 4, "curve_points": 4}
    settings |= {"hyperparams": {"pretrain": None}, "progress": False, "out": tmp_path}
    with pytest.raises(_Stop):
        train(ENV, "ppo", checkpoint_every=480, callbacks=[_DieAt(1000)], **settings)
    run_dir = tmp_path / "sensorgym__BearingsManeuver-v0" / "ppo_seed3"
    assert not (run_dir / "config.yaml").exists()  # the run did not finish
    state = read_checkpoint(run_dir)
    assert state["timesteps"] == 960  # the last multiple of 480 reached (rollouts of 240)
    assert [p["timesteps"] for p in state["curve_points"]] == [0, 480, 960]
    args = resume_arguments(run_dir)
    assert args["seed"] == 3 and args["timesteps"] == 1920 and args["resume"] == run_dir
    # resumed from the command line: every setting is the checkpoint's
    assert main(["train", "--resume", str(run_dir), "--no-progress"]) == 0
    config = read_config(run_dir)
    assert config["seed"] == 3 and config["hyperparams"]["n_timesteps"] == 1920
    curve = json.loads((run_dir / "curve.json").read_text())
    assert [p["timesteps"] for p in curve["points"]] == [0, 480, 960, 1440, 1920]
    walls = [p["wall_s"] for p in curve["points"]]
    assert walls == sorted(walls)  # the clock went on from the checkpoint's
    cost = json.loads((run_dir / "cost.json").read_text())
    assert cost["resumed_at_timesteps"] == 960 and cost["samples"]["timesteps"] == 1920
    assert read_checkpoint(run_dir)["timesteps"] == 1920  # checkpointed to the end
    # the run's weights are the last checkpoint's
    from sensorgym.train.config import ALGORITHMS

    saved = load_model(run_dir).policy.state_dict()
    last = ALGORITHMS["ppo"].load(read_checkpoint(run_dir)["model"], device="cpu")
    assert last.num_timesteps == 1920
    for key, value in last.policy.state_dict().items():
        assert torch.equal(saved[key], value), key
    with pytest.raises(SystemExit, match="no checkpoint"):
        main(["train", "--resume", str(tmp_path), "--no-progress"])
