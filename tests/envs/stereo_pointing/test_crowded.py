"""``sensorgym/StereoPointingCrowded-v0``: StereoPointing with three drones for four receivers.

Its defaults are the crowded layout and nothing else; every StereoPointing rule plays it and
none beats the StereoPointing bound (:mod:`sensorgym.envs.stereo_pointing.bound`), which holds
for any ``n`` and ``m``.
"""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import pytest

from sensorgym.agents.registry import RULES
from sensorgym.envs.stereo_pointing import CrowdedPointingParams, PointingParams
from sensorgym.envs.stereo_pointing.crowded import CROWDED_ENV_ID
from sensorgym.train.bounds import EPISODE_BOUNDS, PASSIVE_RULES
from tests.envs.stereo_pointing.test_bound import _sb3_episodes

POINTING_ID = "sensorgym/StereoPointing-v0"
#: a few seeded scenarios per rule
SCENARIOS = 4


def test_the_defaults_are_three_drones_for_four_receivers() -> None:
    params = CrowdedPointingParams()
    assert params.n_drones == 3 and params.n_receivers == 4
    assert params.n_drones > params.n_receivers // 2  # fewer than two receivers per drone
    # every other default is StereoPointing's
    two = dataclasses.replace(params, n_drones=2)
    assert dataclasses.astuple(two) == dataclasses.astuple(PointingParams())
    env = gym.make(CROWDED_ENV_ID)
    assert env.unwrapped.params == params
    assert env.spec.max_episode_steps == gym.spec(POINTING_ID).max_episode_steps
    assert env.action_space.shape == (8,) and env.observation_space.shape == (72,)


def test_it_is_wired_as_a_stereo_pointing_env() -> None:
    # every StereoPointing rule, and the crowded env's own: plan-search searching every
    # assignment (at 4 x 2 plan-search does already)
    assert list(RULES[CROWDED_ENV_ID]) == [*RULES[POINTING_ID], "plan-search-exhaustive"]
    assert EPISODE_BOUNDS[CROWDED_ENV_ID] == EPISODE_BOUNDS[POINTING_ID]
    assert PASSIVE_RULES[CROWDED_ENV_ID] == PASSIVE_RULES[POINTING_ID]


@pytest.mark.parametrize("rule", sorted(RULES[CROWDED_ENV_ID]))
def test_every_pointing_rule_plays_it_below_the_bound(rule: str) -> None:
    from sensorgym.train.evaluation import env_params, make_sb3_env, simulator_state

    env = make_sb3_env(CROWDED_ENV_ID, SCENARIOS, seed=10000)
    try:
        params = env_params(env)
        assert params == CrowdedPointingParams()
        _sb3_episodes(env, RULES[CROWDED_ENV_ID][rule](params, simulator_state(env)), params)
    finally:
        env.close()
