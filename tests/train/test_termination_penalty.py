"""The training-only ``termination-penalty`` wrapper: it charges terminations, not time limits,
and never reaches evaluation."""

from __future__ import annotations

import numpy as np
import pytest

from sensorgym.train.config import check_overrides
from sensorgym.train.evaluation import make_sb3_env
from sensorgym.train.models import read_config
from sensorgym.train.trainer import train
from sensorgym.train.wrappers import TerminationPenalty, check_wrappers

ENV_ID = "sensorgym/BearingsManeuver-v0"
SHAPING = [{"name": "termination-penalty", "penalty": 7.0}]


def _steps(venv, actions, n):
    out = []
    venv.reset()
    for _ in range(n):
        venv.step_async(actions)
        out.append(venv.step_wait())
    return out


def test_penalty_charges_a_terminating_step_and_not_a_time_limit():
    # a platform that turns hard towards a close target breaks the stand-off; short episodes
    # also end by the time limit: both kinds of end occur among 16 slots over 20 steps
    kwargs = {"max_episode_steps": 5, "min_range": 4000.0}
    plain = make_sb3_env(ENV_ID, 16, seed=3, episode_streams=True, **kwargs)
    shaped = TerminationPenalty(
        make_sb3_env(ENV_ID, 16, seed=3, episode_streams=True, **kwargs), penalty=7.0
    )
    actions = np.tile(np.array([[1.0, 1.0]], dtype=np.float32), (16, 1))
    terminated = truncated = 0
    for (_, r0, d0, i0), (_, r1, d1, _) in zip(
        _steps(plain, actions, 20), _steps(shaped, actions, 20), strict=True
    ):
        np.testing.assert_array_equal(d0, d1)
        cut = np.array(
            [
                bool(d) and not i.get("TimeLimit.truncated", False)
                for d, i in zip(d0, i0, strict=True)
            ]
        )
        np.testing.assert_allclose(r1, r0 - 7.0 * cut, rtol=0, atol=1e-6)
        terminated += int(cut.sum())
        truncated += int(np.sum(d0 & ~cut))
    assert terminated > 0 and truncated > 0  # the test meets both kinds of episode end


@pytest.mark.parametrize("penalty", [-1.0, float("nan"), float("inf"), True, "5"])
def test_penalty_refuses_bad_values(penalty):
    with pytest.raises(ValueError, match="termination-penalty: penalty"):
        TerminationPenalty(make_sb3_env(ENV_ID, 2, seed=0), penalty=penalty)


def test_training_wrappers_are_checked_and_stay_out_of_the_policy(tmp_path):
    assert check_wrappers(SHAPING)[0]["name"] == "termination-penalty"
    with pytest.raises(ValueError, match="does not take"):
        check_overrides(
            "ppo", ENV_ID, {"training_wrappers": [{"name": "termination-penalty", "cost": 2}]}
        )
    result = train(
        ENV_ID,
        "ppo",
        seed=0,
        timesteps=512,
        out=tmp_path,
        eval_episodes=4,
        progress=False,
        n_envs=4,
        hyperparams={"training_wrappers": SHAPING, "n_steps": 128, "batch_size": 128},
    )
    hp = read_config(result.run_dir)["hyperparams"]
    assert hp["training_wrappers"] == SHAPING  # on record
    assert all(w["name"] != "termination-penalty" for w in hp.get("wrappers", []))
