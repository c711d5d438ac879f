"""Bad input gets a clear exception naming the argument at construction, or a finite result
(issue 10, defect 7): huge actions, non-integer counts, infinite noise, an unbounded clip, the
wrong params class."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from sensorgym.envs import (
    ENV_IDS,
    PARALLEL_ENVS,
    BearingsManeuverVectorEnv,
    ManeuverParams,
    PlacementParams,
    PointingParams,
)


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_huge_finite_actions_are_clipped_without_a_warning(env_id):
    # the suite turns RuntimeWarnings into errors: an overflow in the finite check would fail
    env = gym.make(env_id)
    env.reset(seed=0)
    obs, reward, *_ = env.step(np.full(env.action_space.shape, 1e308, dtype=np.float64))
    assert np.isfinite(reward) and env.observation_space.contains(obs)
    with pytest.raises(ValueError, match="action"):
        env.step(np.full(env.action_space.shape, np.inf))


@pytest.mark.parametrize(
    "make, field",
    [
        (lambda: ManeuverParams(bank_members=2.5), "bank_members"),
        (lambda: ManeuverParams(platforms=2.0), "platforms"),
        (lambda: ManeuverParams(platforms="2"), "platforms"),
        (lambda: PointingParams(n_drones=True), "n_drones"),
        (lambda: PointingParams(n_receivers=3.5), "n_receivers"),
    ],
)
def test_counts_must_be_integers(make, field):
    with pytest.raises(TypeError, match=field):
        make()


@pytest.mark.parametrize(
    "make, field",
    [
        (lambda: PointingParams(cue_sigma=(np.inf, 1.0)), "cue_sigma"),
        (lambda: PointingParams(reward_clip=1e308), "reward_clip"),
        (lambda: PlacementParams(reward_clip=1e308), "reward_clip"),
        (lambda: PlacementParams(cue_sigma=(1.0, np.nan)), "cue_sigma"),
    ],
)
def test_unbounded_settings_are_refused(make, field):
    with pytest.raises(ValueError, match=field):
        make()


def test_scenario_and_step_counts_are_checked_by_name():
    with pytest.raises(TypeError, match="num_envs"):
        BearingsManeuverVectorEnv(num_envs=2.0)
    with pytest.raises(TypeError, match="max_episode_steps"):
        PARALLEL_ENVS["sensorgym/StereoPointing-v0"](max_episode_steps="10")


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_the_wrong_params_class_is_named(env_id):
    with pytest.raises(TypeError, match="params"):
        gym.make(env_id, params=object())
