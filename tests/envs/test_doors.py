"""One shape for every env: the same keywords through every door, one registration, one contract.

Every params field is accepted, and lands, through ``gym.make``, ``gym.make_vec`` (native vector
env) and the env's PettingZoo ``parallel_env``; the episode length comes only from the
registration; each id's entry points live in the env's own package; every simulation module
implements the contract of :mod:`sensorgym.envs.shells.contract`.
"""

from __future__ import annotations

import dataclasses
import importlib
import inspect
import re

import gymnasium as gym
import numpy as np
import pytest

from sensorgym.envs import ENV_IDS, PARALLEL_ENVS
from sensorgym.envs.shells import Simulation
from sensorgym.envs.worlds.platform import PlatformWorldParams

#: a valid non-default value of every params field, per env
OTHER_VALUES: dict[str, dict[str, object]] = {
    "sensorgym/BearingsManeuver-v0": {
        "world": PlatformWorldParams(dt=30.0, sigma_bearing=0.02),
        "initial_range": (4_000.0, 9_000.0),
        "target_speed": (1.0, 3.0),
        "initial_platform_speed": 7.0,
        "platforms": 2,
        "formation_radius": 1_000.0,
        "bank_ranges": (1_000.0, 30_000.0),
        "bank_members": 5,
        "prior_speed": (4.0, 2.0),
        "metric": "relative_range",
        "min_range": 300.0,
        "close_penalty": 2.0,
        "initial_heading": (0.0, 1.0),
        "initial_bearing": (0.5, 0.5),
        "target_course": (-1.0, 2.0),
    },
    "sensorgym/BearingsManeuverBook-v0": {
        "world": PlatformWorldParams(dt=30.0, sigma_bearing=0.02),
        "initial_range": (4_000.0, 9_000.0),
        "target_speed": (1.0, 3.0),
        "initial_platform_speed": 2.0,
        "platforms": 2,
        "formation_radius": 1_000.0,
        "bank_ranges": (1_000.0, 30_000.0),
        "bank_members": 5,
        "prior_speed": (4.0, 2.0),
        "metric": "relative_range",
        "min_range": 300.0,
        "close_penalty": 2.0,
        "initial_heading": (0.0, 1.0),
        "initial_bearing": (0.5, 0.5),
        "target_course": (-1.0, 2.0),
    },
    "sensorgym/StereoPointing-v0": {
        "n_receivers": 3,
        "circle_radius": 40.0,
        "receiver_angles_deg": (0.0, 90.0, 180.0, 270.0),
        "n_drones": 3,
        "start_distance": (70.0, 120.0),
        "start_altitude": (20.0, 60.0),
        "drone_speed": (3.0, 9.0),
        "climb_rate": (-0.5, 0.5),
        "dt": 0.1,
        "fov": 0.2,
        "slew_rate": 1.0,
        "max_elevation": 1.2,
        "initial_elevation": (0.1, 0.2),
        "cued_start": False,
        "sigma_ang": 2e-3,
        "cue_sigma": (3.0, 1.0),
        "process_noise": 0.5,
        "sigma_ref": 0.5,
        "reward_clip": 3.0,
    },
    "sensorgym/StereoPlacement-v0": {
        "n_receivers": 4,
        "delays": (0.0, 0.2, 0.5),
        "period": 2.0,
        "max_speed": 4.0,
        "arena_radius": 150.0,
        "cluster_radius": 10.0,
        "start_distance": (50.0, 100.0),
        "start_altitude": (30.0, 60.0),
        "drone_speed": (4.0, 8.0),
        "sigma_ang": 2e-3,
        "cue_sigma": (3.0, 1.0),
        "max_boresight_elevation": 1.2,
        "sigma_ref": 0.5,
        "reward_clip": 3.0,
    },
    "sensorgym/StereoScanning-v0": {
        "n_receivers": 4,
        "receiver_azimuths": (0.0, 2.0, 4.0),
        "circle_radius": 100.0,
        "aim_height": 30.0,
        "n_drones": 3,
        "close_drones": 0,
        "late_drones": 0,
        "enter_window": (2.0, 5.0),
        "start_spread": 20.0,
        "start_altitude": (25.0, 50.0),
        "drone_speed": (1.0, 4.0),
        "climb_rate": (-0.2, 0.2),
        "max_acceleration": 0.1,
        "close_spacing": (3.0, 5.0),
        "scene_half_width": 70.0,
        "scene_height": 100.0,
        "scene_floor": 5.0,
        "period": 2.0,
        "sweep_time": 0.4,
        "scan_offsets": (0.0, 0.3, 0.5),
        "raster_lines": 50,
        "pixel_iterations": 3,
        "field_of_regard": 1.2,
        "sector_width": (0.1, 1.2),
        "noise_per_width": 2e-3,
        "sigma_ang_min": 1e-4,
        "position_sigma": 0.05,
        "clutter_rate": 0.5,
        "max_clutter": 1,
        "tracker": "alternative",
        "max_speed": 30.0,
        "gate_probability": 0.99,
        "fit_false_alarm": 1e-4,
        "confirm_hits": 3,
        "max_misses": 1,
        "ghost_misses": 1,
        "track_capacity": 16,
        "track_slots": 5,
        "cond_max": 1e6,
        "sigma_ref": 0.5,
        "reward_clip": 3.0,
        "false_track_penalty": 1.0,
        "truth_gate": 3.0,
    },
}


OTHER_VALUES["sensorgym/GimbalTracking-v0"] = {
    "frame_period": 0.02,
    "field_of_view": 0.03,
    "max_rate": 1.5,
    "max_acceleration": 6.0,
    "elevation_limits": (-0.1, 1.4),
    "roll_amplitude": (0.05, 0.0),
    "roll_period": (7.0, 3.0),
    "pitch_amplitude": (0.02, 0.01),
    "pitch_period": (5.0, 2.0),
    "yaw_amplitude": (0.0, 0.01),
    "yaw_period": (12.0, 4.0),
    "start_range": (3000.0, 5000.0),
    "start_azimuth": (-0.5, 0.5),
    "start_elevation": (0.1, 0.3),
    "target_speed": (50.0, 100.0),
    "target_aspect": (0.5, 2.5),
    "target_climb": (0.0, 0.1),
    "turn_rate": (0.05, 0.2),
    "turn_start": (10, 20),
    "turn_length": (5, 10),
    "occlusion_gap": (3, 8),
    "occlusion_length": (1, 3),
    "cue_error": 0.001,
    "channel_contrast": (4.0, 2.0),
    "channel_noise": (1.0, 1.5),
    "lose_probability": (0.1, 0.2),
    "return_probability": (0.5, 0.3),
    "aspect_change_probability": (0.1, 0.05),
    "target_size": 0.003,
    "blur": 0.0007,
    "pixel_pitch": 0.0002,
    "gate_pixels": 40,
    "vignetting": 0.3,
    "residual_std": 0.003,
    "residual_correlation": 0.95,
    "sensor_noise": 0.0,
    "predictor_window": 20,
    "predictor_memory": 5.0,
    "sigma_ref": 0.002,
    "reward_clip": 3.0,
    "search_after": 5,
    "relock": False,
    "reacquire_limit": 10,
    "n_gimbals": 2,
    "gimbal_sectors": ((-1.0, 1.0),),
}


# the crowded variant: StereoPointing's values, but 2 drones (3 is its own default)
OTHER_VALUES["sensorgym/StereoPointingCrowded-v0"] = {
    **OTHER_VALUES["sensorgym/StereoPointing-v0"],
    "n_drones": 2,
}


def _doors(env_id: str, **fields):
    """The params an env gets through each door, after a reset and one step."""
    single = gym.make(env_id, **fields)
    single.reset(seed=0)
    single.step(single.action_space.sample())
    vector = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point", **fields)
    vector.reset(seed=0)
    vector.step(vector.action_space.sample())
    parallel = importlib.import_module(type(single.unwrapped).__module__).parallel_env(**fields)
    parallel.reset(seed=0)
    parallel.step({a: parallel.action_space(a).sample() for a in parallel.agents})
    return {
        "gym.make": single.unwrapped.params,
        "gym.make_vec": vector.unwrapped.params,
        "parallel_env": parallel.params,
    }


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_every_params_field_has_a_value_to_check(env_id):
    params_type = type(gym.make(env_id).unwrapped.params)
    assert set(OTHER_VALUES[env_id]) == {f.name for f in dataclasses.fields(params_type)}


@pytest.mark.parametrize(
    "env_id, field, value",
    [(env_id, f, v) for env_id, values in OTHER_VALUES.items() for f, v in values.items()],
)
def test_every_params_field_passes_through_every_door(env_id, field, value):
    fields = {field: value}
    default = getattr(type(gym.make(env_id).unwrapped.params)(), field)
    assert value != default
    for door, params in _doors(env_id, **fields).items():
        assert getattr(params, field) == value, door


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_unknown_keywords_name_the_params_fields(env_id):
    with pytest.raises(TypeError, match="fields"):
        gym.make(env_id, no_such_field=1)
    with pytest.raises(TypeError, match="fields"):
        PARALLEL_ENVS[env_id](no_such_field=1)


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_episode_length_comes_from_the_registration_only(env_id):
    steps = gym.spec(env_id).max_episode_steps
    env = gym.make(env_id)
    vector_type = type(gym.make_vec(env_id, 1, vectorization_mode="vector_entry_point").unwrapped)
    assert vector_type(num_envs=2).max_episode_steps == steps  # constructed directly
    assert PARALLEL_ENVS[env_id]().max_episode_steps == steps
    assert env.spec.max_episode_steps == steps


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_entry_points_lie_in_the_envs_own_package(env_id):
    spec = gym.spec(env_id)
    package = spec.entry_point.split(":")[0].rsplit(".", 1)[0]
    assert package.startswith("sensorgym.envs.") and package != "sensorgym.envs.shells"
    assert spec.vector_entry_point.split(":")[0].rsplit(".", 1)[0] == package
    assert PARALLEL_ENVS[env_id].__module__.rsplit(".", 1)[0] == package
    simulation = importlib.import_module(f"{package}.simulation")
    assert gym.make(env_id).unwrapped.simulation is simulation


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_every_simulation_follows_the_one_contract(env_id):
    simulation = gym.make(env_id).unwrapped.simulation
    for name, member in inspect.getmembers(Simulation, inspect.isfunction):
        if name.startswith("_"):
            continue
        expected = [p for p in inspect.signature(member).parameters if p != "self"]
        got = list(inspect.signature(getattr(simulation, name)).parameters)
        assert got == expected, f"{simulation.__name__}.{name}{got}"
    # nothing else of the shells' business: autoreset selection is generic
    assert not hasattr(simulation, "where")


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_joint_and_agent_views_come_from_one_state(env_id):
    vector = gym.make_vec(env_id, 3, vectorization_mode="vector_entry_point")
    agents = gym.make_vec(env_id, 3, vectorization_mode="vector_entry_point", agent_view=True)
    obs, _ = vector.reset(seed=4)
    per_agent, _ = agents.reset(seed=4)
    n = agents.unwrapped.n_agents
    assert per_agent.shape == (3, n, *agents.unwrapped.single_observation_space.shape)
    assert agents.observation_space.contains(per_agent)
    # the joint view is every agent's view in turn, or the view they share (before the index)
    d = obs.shape[1]
    joint = per_agent.reshape(3, -1) if per_agent[0].size == d else per_agent[:, 0, :d]
    np.testing.assert_array_equal(obs, joint)
    action = np.random.default_rng(0).uniform(-1, 1, (3, *vector.single_action_space.shape))
    _, r_joint, *_ = vector.step(action.astype(np.float32))
    _, r_agents, *_ = agents.step(action.reshape(3, n, -1).astype(np.float32))
    np.testing.assert_array_equal(r_joint, r_agents)


def test_the_package_docstring_names_each_envs_real_doors():
    # the table a user reads in ``sensorgym.envs``: id, package, PettingZoo constructors' module
    import sensorgym.envs as envs

    rows = re.findall(
        r"^\| ``(sensorgym/[^`]+)`` \| :mod:`\.([\w.]+)` \| ``([\w.]+)`` \|$", envs.__doc__, re.M
    )
    assert sorted(r[0] for r in rows) == sorted(ENV_IDS)
    for env_id, package, constructors in rows:
        module = importlib.import_module(f"sensorgym.envs.{package}")
        holder = importlib.import_module(f"sensorgym.envs.{constructors}")
        assert holder.parallel_env is PARALLEL_ENVS[env_id]
        assert callable(holder.env) and callable(holder.raw_env)
        assert gym.spec(env_id).entry_point.split(":")[0].startswith(module.__name__)
