"""The training-only ``final-error-penalty`` wrapper: it charges every episode end (time limit
or termination) the squared final error read from the env's final info, and nothing else."""

from __future__ import annotations

import numpy as np
import pytest

from sensorgym.train.evaluation import make_sb3_env
from sensorgym.train.wrappers import FinalErrorPenalty, check_wrappers

ENV_ID = "sensorgym/BearingsManeuver-v0"
KWARGS = {"max_episode_steps": 5, "min_range": 4000.0}


def _steps(venv, actions, n):
    venv.reset()
    for _ in range(n):
        venv.step_async(actions)
        yield venv.step_wait()


def test_penalty_charges_the_squared_final_error_at_every_episode_end():
    # hard turns at a close target break the stand-off; the short time limit ends the rest
    plain = make_sb3_env(ENV_ID, 16, seed=3, episode_streams=True, **KWARGS)
    shaped = FinalErrorPenalty(
        make_sb3_env(ENV_ID, 16, seed=3, episode_streams=True, **KWARGS), weight=2.0, scale=500.0
    )
    actions = np.tile(np.array([[1.0, 1.0]], dtype=np.float32), (16, 1))
    ends = {"terminated": 0, "truncated": 0}
    for (_, r0, d0, i0), (_, r1, d1, _) in zip(
        _steps(plain, actions, 20), _steps(shaped, actions, 20), strict=True
    ):
        np.testing.assert_array_equal(d0, d1)
        error = np.array(
            [i["final_info"]["position_error"] if d else 0.0 for d, i in zip(d0, i0, strict=True)]
        )
        assert np.all(error[d0] > 0.0)  # a real tracker error, not a default
        np.testing.assert_allclose(r1, r0 - 2.0 * (error / 500.0) ** 2 * d0, rtol=1e-6, atol=1e-5)
        for d, i in zip(d0, i0, strict=True):
            if d:
                ends["truncated" if i["TimeLimit.truncated"] else "terminated"] += 1
    assert ends["terminated"] > 0 and ends["truncated"] > 0  # both kinds of end were charged


def test_time_limit_only_leaves_terminations_uncharged():
    # a bound that a termination makes small must not pay for breaking the stand-off
    plain = make_sb3_env(ENV_ID, 16, seed=3, episode_streams=True, **KWARGS)
    shaped = FinalErrorPenalty(
        make_sb3_env(ENV_ID, 16, seed=3, episode_streams=True, **KWARGS),
        weight=1.0,
        scale=100.0,
        key="position_bound",
        time_limit_only=True,
    )
    actions = np.tile(np.array([[1.0, 1.0]], dtype=np.float32), (16, 1))
    charged = spared = 0
    for (_, r0, d0, i0), (_, r1, _, _) in zip(
        _steps(plain, actions, 20), _steps(shaped, actions, 20), strict=True
    ):
        limit = np.array(
            [bool(d) and i["TimeLimit.truncated"] for d, i in zip(d0, i0, strict=True)]
        )
        bound = np.array(
            [
                i["final_info"]["position_bound"] if d else 0.0
                for d, i in zip(limit, i0, strict=True)
            ]
        )
        np.testing.assert_allclose(r1, r0 - (bound / 100.0) ** 2 * limit, rtol=1e-6, atol=1e-5)
        charged += int(limit.sum())
        spared += int(np.sum(d0 & ~limit))
    assert charged > 0 and spared > 0


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"weight": -1.0}, "weight must be finite and >= 0"),
        ({"weight": float("nan")}, "weight must be finite"),
        ({"weight": True}, "weight must be a number"),
        ({"scale": 0.0}, "scale must be finite and > 0"),
        ({"scale": "1km"}, "scale must be a number"),
        ({"key": ""}, "key must be an info key"),
        ({"time_limit_only": 1}, "time_limit_only must be true or false"),
    ],
)
def test_penalty_refuses_bad_values(kwargs, match):
    with pytest.raises(ValueError, match=f"final-error-penalty: {match}"):
        FinalErrorPenalty(make_sb3_env(ENV_ID, 2, seed=0), **kwargs)


def test_a_key_the_env_does_not_report_names_the_keys_it_does():
    venv = FinalErrorPenalty(make_sb3_env(ENV_ID, 2, seed=0, **KWARGS), weight=1.0, key="miss")
    with pytest.raises(KeyError, match=r"no 'miss'.*position_error"):
        for _ in _steps(venv, np.zeros((2, 2), dtype=np.float32), 6):
            pass


def test_it_is_a_named_training_wrapper():
    spec = [{"name": "final-error-penalty", "weight": 0.5, "scale": 1000.0}]
    assert check_wrappers(spec)[0]["name"] == "final-error-penalty"
