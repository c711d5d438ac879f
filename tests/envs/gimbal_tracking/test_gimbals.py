"""Several gimbals on one carrier (``n_gimbals``, issue 40): their clear sectors, spaces, doors,
checkers, the measuring gimbal, the rules' pre-pointing and a hand-over that keeps the target
a single gimbal loses."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from pettingzoo.test import parallel_api_test, parallel_seed_test
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import sensorgym.envs  # noqa: F401  (registers the ids)
from sensorgym.agents.gimbal_tracking import (
    CarrierFeedForward,
    HoldStill,
    Paper001Servo,
    gimbal_rows,
    pre_point,
)
from sensorgym.agents.registry import RULES
from sensorgym.envs import gimbal_tracking
from sensorgym.envs.gimbal_tracking import reference
from sensorgym.envs.gimbal_tracking import simulation as core
from sensorgym.envs.gimbal_tracking.simulation import SECTOR_OVERLAP, GimbalParams

ENV_ID = "sensorgym/GimbalTracking-v0"

#: a still carrier, a straight target, no losses (as in test_env.py)
CALM = {
    **{f"{a}_{k}": () for a in ("roll", "pitch", "yaw") for k in ("amplitude", "period")},
    "turn_rate": (0.0, 0.0),
    "occlusion_length": (0, 0),
    "lose_probability": (0.0, 0.0),
    "aspect_change_probability": (0.0, 0.0),
}
#: gimbal 0 clear to port of dead ahead, gimbal 1 to starboard, sharing 0.04 rad about it
EDGE = 0.02
SPLIT = ((-np.pi, EDGE), (-EDGE, np.pi))


# --- params and sectors ------------------------------------------------------------------------


@pytest.mark.parametrize("G", [2, 3, 4])
def test_default_sectors_cover_the_circle_and_overlap_for_the_hand_over(G: int):
    params = GimbalParams(n_gimbals=G)
    low, width = params.sectors.T
    np.testing.assert_allclose(width, 2 * np.pi / G + 2 * SECTOR_OVERLAP)
    assert np.all((-np.pi <= low) & (low <= np.pi))
    azimuth = np.linspace(-np.pi, np.pi, 3601)
    clear = reference.in_sector(params, azimuth[:, None])  # (A, G)
    assert clear.any(-1).all()
    # each boundary between neighbours lies inside both, with the overlap on either side
    for k in range(G):
        edge = low[k] + width[k] - SECTOR_OVERLAP
        near = edge + np.array([-0.9, 0.0, 0.9]) * SECTOR_OVERLAP
        assert reference.in_sector(params, near[:, None]).sum(-1).min() == 2
    assert np.array_equal(reference.in_sector(params, np.zeros((1, G))), np.eye(G)[:1] > 0)


def test_one_gimbal_sees_the_whole_circle_and_an_explicit_circle_changes_nothing():
    params = GimbalParams()
    assert params.n_gimbals == 1 and params.gimbal_sectors == ()
    np.testing.assert_array_equal(params.sectors, [[-np.pi, 2 * np.pi]])
    explicit = GimbalParams(gimbal_sectors=((-np.pi, np.pi),))
    got = _vector_episode(explicit, seed=3)
    want = _vector_episode(params, seed=3)
    for a, b in zip(got, want, strict=True):
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize(
    "fields, name",
    [
        ({"n_gimbals": 0}, "n_gimbals"),
        ({"n_gimbals": 2.0}, "n_gimbals"),
        ({"n_gimbals": True}, "n_gimbals"),
        ({"n_gimbals": 2, "gimbal_sectors": ((-1.0, 1.0),)}, "gimbal_sectors"),
        ({"gimbal_sectors": ((-1.0, 1.0), (1.0, 2.0))}, "gimbal_sectors"),
        ({"gimbal_sectors": ((1.0, 1.0),)}, "gimbal_sectors"),
        ({"gimbal_sectors": ((1.0, 0.5),)}, "gimbal_sectors"),
        ({"gimbal_sectors": ((-4.0, 0.0),)}, "gimbal_sectors"),
        ({"gimbal_sectors": ((0.0, 7.0),)}, "gimbal_sectors"),
        ({"gimbal_sectors": ((0.0, np.nan),)}, "gimbal_sectors"),
        ({"gimbal_sectors": ((0.0,),)}, "gimbal_sectors"),
        ({"gimbal_sectors": (0.0, 1.0)}, "gimbal_sectors"),
    ],
)
def test_bad_gimbal_params_are_refused_naming_the_field(fields, name):
    with pytest.raises((ValueError, TypeError), match=f"^{name}:"):
        GimbalParams(**fields)
    with pytest.raises((ValueError, TypeError), match=f"^{name}:"):
        gym.make(ENV_ID, **fields)


# --- spaces, doors, checkers -------------------------------------------------------------------


def test_spaces_have_one_agent_per_gimbal():
    params = GimbalParams(n_gimbals=3)
    N = params.n_channels
    spaces = core.spaces(params)
    assert spaces.agents == ("gimbal_0", "gimbal_1", "gimbal_2")
    assert spaces.agent_action.shape == (2,) and spaces.action.shape == (6,)
    assert spaces.agent_observation.shape == (26 + N,)
    assert spaces.observation.shape == (3 * (26 + N),)
    one = core.spaces(GimbalParams())
    assert one.agents == ("gimbal_0",) and one.observation.shape == (21 + N,)
    assert one.action.shape == (2,) and one.agent_observation.shape == (21 + N,)
    env = gym.make(ENV_ID, n_gimbals=2)
    assert env.action_space.shape == (4,) and env.observation_space.shape == (2 * (26 + N),)
    par = gimbal_tracking.parallel_env(n_gimbals=2)
    assert par.possible_agents == ["gimbal_0", "gimbal_1"]
    assert par.observation_space("gimbal_1").shape == (26 + N,)
    assert par.action_space("gimbal_1").shape == (2,)


def test_gymnasium_and_sb3_checkers_pass_with_two_gimbals():
    check_env(gym.make(ENV_ID, n_gimbals=2, render_mode="rgb_array").unwrapped)
    sb3_check_env(gym.make(ENV_ID, n_gimbals=2), warn=True)


def test_pettingzoo_api_and_seed_tests_pass_with_two_gimbals():
    parallel_api_test(
        gimbal_tracking.parallel_env(n_gimbals=2, max_episode_steps=40), num_cycles=60
    )
    parallel_seed_test(lambda: gimbal_tracking.parallel_env(n_gimbals=2, max_episode_steps=40))


def test_two_gimbals_are_deterministic_under_a_seed_and_the_agents_share_a_team_reward():
    params = GimbalParams(n_gimbals=2)
    a, b = _vector_episode(params, seed=7), _vector_episode(params, seed=7)
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x, y)
    par = gimbal_tracking.parallel_env(n_gimbals=2)
    par.reset(seed=1)
    _, rewards, *_ = par.step({agent: np.zeros(2, np.float32) for agent in par.agents})
    assert rewards["gimbal_0"] == rewards["gimbal_1"]


def test_each_agent_sees_its_own_drives_and_sector_and_the_shared_track():
    params = GimbalParams(n_gimbals=2, gimbal_sectors=SPLIT)
    state = core.reset(params, np.random.default_rng(2), 5)
    obs = core.observe_agents(params, state)  # (B, G, A)
    N = params.n_channels
    shared = np.r_[4:10, 14:19, 19 + N : 21 + N]
    np.testing.assert_array_equal(obs[:, 0, shared], obs[:, 1, shared])
    np.testing.assert_allclose(obs[:, :, 0] * np.pi, state.gimbal_angles[..., 0], atol=1e-6)
    edges = np.array(SPLIT) / np.pi
    np.testing.assert_allclose(obs[:, :, 22 + N : 24 + N], np.broadcast_to(edges, (5, 2, 2)))
    # the prediction is in exactly the sectors that hold its body azimuth
    attitude, _ = core.carrier_attitude(params, state)
    u = reference.unit_from_zup_angles(state.predicted[:, 0], state.predicted[:, 1])
    az = reference.body_angles(u, attitude)[:, None, 0]
    np.testing.assert_array_equal(obs[:, :, 21 + N] > 0.5, reference.in_sector(params, az))
    np.testing.assert_array_equal(core.observe(params, state), obs.reshape(5, -1))


# --- the physics of several gimbals ------------------------------------------------------------


def test_a_gimbal_on_the_target_outside_its_sector_does_not_see_it():
    """One gimbal cued onto a target at body azimuth 0.5 rad: clear over the whole circle it
    sees it; with a sector ending at 0.4 rad it neither sees it nor is cued onto it (it waits
    at the sector's edge)."""
    p = np.array([[5000.0 * np.sin(0.5), 5000.0 * np.cos(0.5), 300.0]])
    v = np.array([[0.0, -100.0, 0.0]])
    for sectors, seen in (((), True), (((-1.0, 0.4),), False)):
        params = GimbalParams(**CALM, gimbal_sectors=sectors, cue_error=0.0)
        state = core.start(params, p, v, np.random.default_rng(0))
        assert bool(state.in_view[0]) is seen
        state, reward, _ = core.step(params, state, np.zeros((1, 1, 2)), np.random.default_rng(1))
        assert bool(state.in_view[0]) is seen and state.visible.any() is np.bool_(seen)
        assert (reward[0] == -params.reward_clip) is not seen
    np.testing.assert_allclose(state.gimbal_angles[0, 0, 0], 0.4)


def test_the_track_measures_the_detecting_gimbal_of_least_variance():
    variance = np.array([[[1.0, 1.0], [0.5, 0.4], [0.2, 0.2]]] * 3)  # (3, G=3, 2)
    detected = np.array([[True, True, False], [False, False, False], [True, False, False]])
    np.testing.assert_array_equal(reference.measuring_gimbal(variance, detected), [1, 2, 0])
    equal = np.ones((1, 3, 2))
    np.testing.assert_array_equal(reference.measuring_gimbal(equal, np.ones((1, 3), bool)), [0])
    # in the env: σ_LOS is that gimbal's, and the estimate follows its measurement
    params = GimbalParams(n_gimbals=2)
    state = core.reset(params, np.random.default_rng(4), 16)
    rule = Paper001Servo(params)
    rng = np.random.default_rng(5)
    for _ in range(30):
        state, _, _ = core.step(params, state, rule.predict(core.observe(params, state))[0], rng)
        best = reference.measuring_gimbal(
            state.fusion_variance, reference.gimbal_detections(state.view_posterior)
        )
        chosen = state.fusion_variance[np.arange(16), best]
        np.testing.assert_allclose(state.sigma_los, reference.los_sigma(params, chosen))
        own = reference.los_sigma(params, state.fusion_variance)  # (B, G)
        assert np.all(state.sigma_los >= own.min(-1))


def test_the_rules_pre_point_to_the_nearer_edge_of_their_sector():
    params = GimbalParams(n_gimbals=2, gimbal_sectors=SPLIT)
    state = core.reset(params, np.random.default_rng(0), 1)
    rows = gimbal_rows(params, core.observe(params, state).astype(np.float64))
    gimbal = rows[:, :2] * np.array([np.pi, np.pi / 2])  # the angles the rule reads
    for aim, want in (
        (0.5, (EDGE, 0.5)),  # to starboard: gimbal 0 waits at its edge 0.02
        (-0.5, (-0.5, -EDGE)),  # to port: gimbal 1 waits at its edge −0.02
        (3.0, (-np.pi, 3.0)),  # astern to starboard: gimbal 0's edge −π (= π) is nearer
        (-3.1, (-3.1, np.pi)),  # astern to port: gimbal 1's edge π is nearer than −0.02
    ):
        change = np.stack([aim - gimbal[:, 0], np.zeros(2)], -1)
        got = gimbal[:, 0] + pre_point(params, rows, change)[:, 0]
        np.testing.assert_allclose(reference.wrap_angle(got - np.array(want)), 0.0, atol=1e-12)


@pytest.mark.parametrize("rule", [Paper001Servo, CarrierFeedForward])
def test_the_hand_over_keeps_the_target_a_single_gimbal_loses(rule):
    """A target crossing dead ahead from port to starboard (0.04 rad/s at 5 km): two gimbals,
    one clear to port and one to starboard of it with 0.04 rad in common, keep it in view of
    some gimbal on every frame under the servo with pre-pointing — the starboard gimbal waits
    at its sector's edge and takes the target over — while the port gimbal alone loses it once
    it has crossed and the episode ends (its track coasts, undetected)."""
    # the tracker's model must be able to lose the target (a calm model never does: the gimbal
    # left behind would go on "detecting" it), so the channels lose their views now and then
    calm = {**CALM, "lose_probability": (0.01, 0.01)}
    two = GimbalParams(**calm, n_gimbals=2, gimbal_sectors=SPLIT)
    one = GimbalParams(**calm, gimbal_sectors=SPLIT[:1])
    in_view, ended, measured_by = _crossing(two, rule(two))
    assert in_view.all() and not ended.any()
    assert np.all(measured_by[0] == 0) and np.all(measured_by[-1] == 1)  # handed over
    in_view, ended, _ = _crossing(one, rule(one))
    assert in_view[:40].all() and not in_view[-1].any() and ended.all()


@pytest.mark.parametrize("name", sorted(RULES[ENV_ID]))
def test_every_rule_runs_with_three_gimbals(name: str):
    env = gym.make_vec(ENV_ID, 3, vectorization_mode="vector_entry_point", n_gimbals=3)
    obs, _ = env.reset(seed=0)
    rule = RULES[ENV_ID][name](env.unwrapped.params, lambda: env.unwrapped.simulator_state)
    memory = None
    for _ in range(20):
        action, memory = rule.predict(obs, memory)
        assert action.shape == (3, 6) and np.all(np.abs(action) <= 1.0)
        obs, reward, *_ = env.step(action)
        assert np.all(np.isfinite(reward))


def test_hold_still_commands_every_gimbal_to_rest():
    params = GimbalParams(n_gimbals=2)
    action = HoldStill(params).predict(core.observe(params, core.reset(params, _rng(), 2)))[0]
    assert action.shape == (2, 4) and not action.any()


def test_render_draws_two_gimbals():
    env = gym.make(ENV_ID, n_gimbals=2, render_mode="rgb_array")
    env.reset(seed=0)
    env.step(env.action_space.sample())
    frame = env.render()
    assert frame.ndim == 3 and frame.shape[-1] == 3
    env.close()


# --- helpers -----------------------------------------------------------------------------------


def _rng() -> np.random.Generator:
    return np.random.default_rng(0)


def _vector_episode(params: GimbalParams, seed: int, steps: int = 60):
    env = gym.make_vec(ENV_ID, 3, vectorization_mode="vector_entry_point", params=params)
    obs, _ = env.reset(seed=seed)
    actions = np.random.default_rng(seed).uniform(-1, 1, (steps, *env.action_space.shape))
    out = [obs]
    for a in actions:
        obs, reward, terminated, truncated, _ = env.step(a.astype(np.float32))
        out += [obs, reward, terminated, truncated]
    return out


def _crossing(params: GimbalParams, rule, frames: int = 250, batch: int = 3):
    """The crossing of :func:`test_the_hand_over_keeps_the_target_a_single_gimbal_loses`:
    ``in_view (frames, B)``, whether each episode ended, and the measuring gimbal
    ``(frames, B)``."""
    rng = np.random.default_rng(3)
    az, el, r = -0.1, 0.05, 5000.0
    p = np.tile(
        [r * np.cos(el) * np.sin(az), r * np.cos(el) * np.cos(az), r * np.sin(el)], (batch, 1)
    )
    v = np.tile([200.0 * np.cos(az), -200.0 * np.sin(az), 0.0], (batch, 1))
    state = core.start(params, p, v, rng)
    in_view, by, ended = [], [], np.zeros(batch, bool)
    for _ in range(frames):
        action, _ = rule.predict(core.observe(params, state))
        state, _, terminated = core.step(params, state, action, rng)
        ended |= terminated
        in_view.append(state.in_view)
        detected = reference.gimbal_detections(state.view_posterior)
        by.append(reference.measuring_gimbal(state.fusion_variance, detected))
    return np.array(in_view), ended, np.array(by)


def test_the_agent_view_of_the_vector_env_is_the_joint_view_split_per_gimbal():
    kwargs = {"vectorization_mode": "vector_entry_point", "n_gimbals": 2}
    joint = gym.make_vec(ENV_ID, 3, **kwargs)
    agents = gym.make_vec(ENV_ID, 3, agent_view=True, **kwargs)
    obs, _ = joint.reset(seed=4)
    per_agent, _ = agents.reset(seed=4)
    assert per_agent.shape == (3, 2, joint.unwrapped.params.agent_obs_dim)
    np.testing.assert_array_equal(per_agent.reshape(3, -1), obs)
    action = np.random.default_rng(0).uniform(-1, 1, (3, 4)).astype(np.float32)
    _, r_joint, *_ = joint.step(action)
    _, r_agents, *_ = agents.step(action.reshape(3, 2, 2))
    np.testing.assert_array_equal(r_joint, r_agents)
