"""PettingZoo envs: API and seed tests, equality with the single-agent envs on one core, and
one clear line for every bad joint action (issue 35)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from pettingzoo import AECEnv
from pettingzoo.test import api_test, parallel_api_test, parallel_seed_test, render_test
from pettingzoo.utils.wrappers import OrderEnforcingWrapper

from sensorgym.envs import (
    ENV_IDS,
    PARALLEL_ENVS,
    bearings_maneuver,
    gimbal_tracking,
    stereo_placement,
    stereo_pointing,
    stereo_scanning,
)
from sensorgym.envs.bearings_maneuver import book
from sensorgym.envs.bearings_maneuver.simulation import OBS_DIM, ManeuverParams
from sensorgym.envs.shells.contract import check_action
from sensorgym.envs.stereo_placement.simulation import PlacementParams
from sensorgym.envs.stereo_pointing import crowded
from sensorgym.envs.stereo_pointing.simulation import PointingParams


@pytest.mark.parametrize(
    "make",
    [
        lambda: bearings_maneuver.parallel_env(),
        lambda: bearings_maneuver.parallel_env(platforms=3, max_episode_steps=10),
        lambda: stereo_pointing.parallel_env(max_episode_steps=40),
        lambda: stereo_pointing.parallel_env(n_receivers=3, n_drones=1, max_episode_steps=20),
        lambda: stereo_placement.parallel_env(max_episode_steps=30),
        lambda: gimbal_tracking.parallel_env(max_episode_steps=40),
    ],
)
def test_pettingzoo_api_and_seed_tests_pass(make):
    parallel_api_test(make(), num_cycles=60)
    parallel_seed_test(make, num_cycles=60)


def test_one_platform_parallel_env_is_the_gymnasium_env():
    """Same core, same seed, same actions: the PettingZoo shell and the Gymnasium shell agree."""
    pz = bearings_maneuver.parallel_env(platforms=1, max_episode_steps=30)
    env = gym.make("sensorgym/BearingsManeuver-v0")
    obs_pz, _ = pz.reset(seed=11)
    obs_g, _ = env.reset(seed=11)
    np.testing.assert_array_equal(obs_pz["platform_0"], obs_g)
    for a in np.random.default_rng(0).uniform(-1, 1, (30, 2)).astype(np.float32):
        obs_pz, r_pz, term_pz, trunc_pz, _ = pz.step({"platform_0": a})
        obs_g, r_g, term_g, trunc_g, _ = env.step(a)
        np.testing.assert_array_equal(obs_pz["platform_0"], obs_g)
        assert r_pz["platform_0"] == r_g
        assert (term_pz["platform_0"], trunc_pz["platform_0"]) == (term_g, trunc_g)
    assert trunc_g and pz.agents == []
    with pytest.raises(RuntimeError, match="reset"):
        pz.step({"platform_0": a})


@pytest.mark.parametrize(
    "make_pz, env_id, params",
    [
        (
            stereo_pointing.parallel_env,
            "sensorgym/StereoPointing-v0",
            PointingParams(n_receivers=3, n_drones=2),
        ),
        (stereo_placement.parallel_env, "sensorgym/StereoPlacement-v0", PlacementParams()),
    ],
)
def test_receiver_agents_see_the_single_env_observation_and_their_index(make_pz, env_id, params):
    pz = make_pz(params=params)
    env = gym.make(env_id, params=params)
    obs_pz, _ = pz.reset(seed=4)
    obs_g, _ = env.reset(seed=4)
    actions = np.random.default_rng(1).uniform(-1, 1, (3, 2)).astype(np.float32)
    obs_pz, r_pz, *_ = pz.step({f"receiver_{k}": actions[k] for k in range(3)})
    obs_g, r_g, *_ = env.step(actions.reshape(-1))
    for k in range(3):
        o = obs_pz[f"receiver_{k}"]
        np.testing.assert_array_equal(o[: params.obs_dim], obs_g)
        np.testing.assert_array_equal(o[params.obs_dim :], np.eye(3)[k])
        assert r_pz[f"receiver_{k}"] == r_g
    assert pz.state().shape == (3 * (params.obs_dim + 3),)


def _final_bound_straight(platforms: int, seed: int) -> float:
    env = bearings_maneuver.parallel_env(
        params=ManeuverParams(platforms=platforms, formation_radius=5_000.0)
    )
    env.reset(seed=seed)
    while env.agents:
        _, _, _, _, infos = env.step({agent: np.zeros(2, np.float32) for agent in env.agents})
    return infos["platform_0"]["bound"]


def test_cross_bearings_make_range_observable_without_manoeuvres():
    """On straight courses a lone platform leaves the position bound at kilometres (range is
    unobservable); two separated platforms' crossing bearings pin it down."""
    one = np.median([_final_bound_straight(1, s) for s in range(6)])
    two = np.median([_final_bound_straight(2, s) for s in range(6)])
    assert two < one / 3.0


def test_observations_place_the_other_platforms_in_the_own_frame():
    env = bearings_maneuver.parallel_env(platforms=3)
    obs, _ = env.reset(seed=2)
    state = env.simulator_state
    for k in range(3):
        others = obs[f"platform_{k}"][OBS_DIM:].reshape(2, 2) * env.params.range_scale
        dist = np.linalg.norm(others, axis=1)
        j = [i for i in range(3) if i != k]
        want = np.linalg.norm(state.platform_position[0, j] - state.platform_position[0, k], axis=1)
        np.testing.assert_allclose(dist, want, rtol=1e-5)


def test_bad_joint_actions_are_refused():
    env = bearings_maneuver.parallel_env()
    env.reset(seed=0)
    with pytest.raises(ValueError, match="no action"):
        env.step({"platform_0": np.zeros(2)})
    with pytest.raises(ValueError, match="NaN"):
        env.step({"platform_0": np.zeros(2), "platform_1": np.array([np.nan, 0.0])})
    with pytest.raises(ValueError, match="max_episode_steps"):
        bearings_maneuver.parallel_env(max_episode_steps=0)


# --- issue 35 item 5: bad joint actions get one clear line at every env's PettingZoo door -------


def _live(env_id: str):
    env = PARALLEL_ENVS[env_id]()
    env.reset(seed=0)
    return env, {agent: env.action_space(agent).sample() for agent in env.agents}


@pytest.mark.parametrize("env_id", ENV_IDS)
@pytest.mark.parametrize("actions", [None, [], (0.0, 0.0), np.zeros(3), "receiver_0"])
def test_a_joint_action_that_is_no_dict_is_refused(env_id, actions):
    env, _ = _live(env_id)
    if isinstance(actions, list):  # a list of per-agent actions, in agent order
        actions = [env.action_space(agent).sample() for agent in env.agents]
    with pytest.raises(TypeError) as caught:
        env.step(actions)
    message = str(caught.value)
    assert "\n" not in message and "dict {agent: action}" in message, message
    assert str(env.agents) in message, message


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_an_unknown_agent_is_named_with_the_live_agents(env_id):
    env, actions = _live(env_id)
    with pytest.raises(ValueError) as caught:
        env.step({**actions, "intruder_7": actions[env.agents[0]]})
    message = str(caught.value)
    assert "unknown agents ['intruder_7']" in message and str(env.agents) in message, message
    # a typo: the real agent is missing and the key unknown, both named in one line
    first = env.agents[0]
    typo = {(k + "x" if k == first else k): a for k, a in actions.items()}
    with pytest.raises(ValueError) as caught:
        env.step(typo)
    message = str(caught.value)
    assert (
        f"no action for [{first!r}]" in message and f"unknown agents [{first + 'x'!r}]" in message
    )
    assert "\n" not in message
    env.step(actions)  # nothing was stepped by the refused calls: the env still works


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_every_live_agent_must_act(env_id):
    env, actions = _live(env_id)
    missing = env.agents[-1]
    del actions[missing]
    with pytest.raises(ValueError, match=rf"^actions: no action for \[{missing!r}\] \(live agents"):
        env.step(actions)
    with pytest.raises(ValueError, match="no action for"):
        env.step({})


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_a_bad_agent_action_gets_the_gymnasium_doors_error(env_id):
    """Wrong shape, NaN, inf, text: the PettingZoo door runs the Gymnasium door's own check,
    the same message prefixed with the agent."""
    env, actions = _live(env_id)
    agent = env.agents[-1]
    shape = env.action_space(agent).shape
    for bad in (np.zeros(shape[0] + 1), np.full(shape, np.nan), np.full(shape, np.inf), "left"):
        with pytest.raises(ValueError) as want:
            check_action(bad, shape)
        with pytest.raises(ValueError) as caught:
            env.step({**actions, agent: bad})
        assert str(caught.value) == f"actions[{agent!r}]: {want.value}"
    # the NaN message is the very one gym.make's env gives for its joint action
    single = gym.make(env_id)
    single.reset(seed=0)
    with pytest.raises(ValueError) as gym_door:
        single.step(np.full(single.action_space.shape, np.nan))
    with pytest.raises(ValueError) as caught:
        env.step({**actions, agent: np.full(shape, np.nan)})
    assert str(caught.value).endswith(str(gym_door.value))
    obs, *_ = env.step(actions)
    assert set(obs) == set(env.possible_agents)


ENV_MODULES = [
    bearings_maneuver, book, stereo_pointing, crowded, stereo_placement, stereo_scanning,
    gimbal_tracking,
]  # fmt: skip


@pytest.mark.parametrize("module", ENV_MODULES, ids=lambda m: m.__name__.rsplit(".", 1)[1])
def test_every_env_module_has_pettingzoos_three_constructors(module):
    """``env()`` (AEC, order-checked), ``raw_env()`` (AEC) and ``parallel_env()`` of every env
    pass PettingZoo's own tests, rendering included (``human`` draws and returns ``None``)."""
    api_test(module.env(), num_cycles=20)
    render_test(module.env)
    parallel_api_test(module.parallel_env(render_mode="rgb_array"), num_cycles=20)
    parallel_seed_test(module.parallel_env)
    raw = module.raw_env()
    assert isinstance(raw, AECEnv) and not isinstance(raw, OrderEnforcingWrapper)
    assert isinstance(module.env(), OrderEnforcingWrapper)
    assert type(module.parallel_env()).metadata["name"].endswith("_v0")


def test_the_parallel_frame_is_the_gymnasium_frame():
    """Same core, seed and actions: the PettingZoo env draws the Gymnasium env's frame."""
    pz = bearings_maneuver.parallel_env(platforms=1, render_mode="rgb_array")
    env = gym.make("sensorgym/BearingsManeuver-v0", render_mode="rgb_array")
    pz.reset(seed=5)
    env.reset(seed=5)
    np.testing.assert_array_equal(pz.render(), env.render())
    for a in np.random.default_rng(1).uniform(-1, 1, (3, 2)).astype(np.float32):
        pz.step({"platform_0": a})
        env.step(a)
    frame = pz.render()
    assert frame.ndim == 3 and frame.shape[2] == 3 and frame.dtype == np.uint8
    np.testing.assert_array_equal(frame, env.render())
    with pytest.raises(ValueError, match="render_mode"):
        bearings_maneuver.parallel_env(render_mode="ansi")
    assert bearings_maneuver.parallel_env().render() is None  # no mode: a warning, no frame
    for fresh in (  # both shells refuse to draw before the first reset
        bearings_maneuver.parallel_env(render_mode="rgb_array"),
        gym.make("sensorgym/BearingsManeuver-v0", render_mode="rgb_array").unwrapped,
    ):
        with pytest.raises(RuntimeError, match="reset"):
            fresh.render()
