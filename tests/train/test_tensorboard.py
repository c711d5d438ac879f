"""``sensorgym train --tensorboard DIR``: event files with SB3's scalars and the env's metrics."""

from __future__ import annotations

import numpy as np
import pytest

from sensorgym.cli.main import main
from sensorgym.train.evaluation import make_sb3_env


def _scalars(folder) -> dict[str, list[float]]:
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    (events,) = folder.rglob("events.out.tfevents.*")
    acc = EventAccumulator(str(events.parent))
    acc.Reload()
    return {tag: [e.value for e in acc.Scalars(tag)] for tag in acc.Tags()["scalars"]}


def test_train_writes_event_files_with_sb3_and_env_metrics(tmp_path):
    tb = tmp_path / "tb"
    args = ["--timesteps", "1024", "--n-envs", "4", "--eval-episodes", "4", "--no-progress"]
    assert main(["train", *args, "--out", str(tmp_path), "--tensorboard", str(tb)]) == 0
    (run,) = [p for p in tb.iterdir() if p.is_dir()]
    assert run.name == "sensorgym__BearingsManeuver-v0_ppo_seed0_1"
    scalars = _scalars(run)
    assert "train/value_loss" in scalars and "rollout/ep_rew_mean" in scalars  # SB3's own
    for key in ("bound", "position_error", "range"):  # the env's info at each episode's end
        values = scalars[f"episode/{key}"]
        assert values and all(np.isfinite(values)) and min(values) > 0.0
    # the learning curve's points beside the rules' returns on the same scenarios, and the
    # imitation phase's loss per epoch
    import json

    curve = json.loads(next(tmp_path.rglob("curve.json")).read_text())
    means = [p["mean"] for p in curve["points"]]
    assert scalars["eval/mean_return"] == pytest.approx(means, rel=1e-6)  # float32 events
    evaluation = json.loads(next(tmp_path.rglob("evaluation.json")).read_text())["results"]
    for rule in ("mpc-estimate", "straight-course"):
        assert scalars[f"eval/{rule}"] == pytest.approx(
            [evaluation[rule]["mean"]] * len(means), rel=1e-6
        )
    assert scalars["pretrain/loss"] == pytest.approx(curve["pretrain_loss"], rel=1e-6)


def test_final_info_is_the_ending_step_s_info():
    env = make_sb3_env("sensorgym/StereoPlacement-v0", 2, seed=3, agents=True)
    env.reset()
    action = np.zeros((env.num_envs, *env.action_space.shape), dtype=np.float32)
    last = None
    for _ in range(200):
        _, _, dones, infos = env.step(action)
        if dones.any():
            break
        last = infos
    assert dones.all()  # every agent of every scenario ends at the time limit together
    for i, info in enumerate(infos):
        final = info["final_info"]
        assert set(final) == set(last[i]) and final.keys() >= {"bound", "position_error"}
        # the final step's values, not the reset values of the next episode
        assert final["bound"] == pytest.approx(final["bound"]) and final != {
            k: info[k] for k in final
        }
    env.close()
