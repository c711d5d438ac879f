"""sensorgym/StereoPlacement-v0: API conformance, shells against each other, conjugation tracker,
reward, degenerate geometry, actions, rules, PettingZoo."""

from __future__ import annotations

import dataclasses
import itertools

import gymnasium as gym
import numpy as np
import pytest
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.evaluation import evaluate_policy

import sensorgym.envs  # noqa: F401  (registers the ids)
from sensorgym.agents.protocol import PolicyPredictor
from sensorgym.agents.registry import rules_for
from sensorgym.agents.stereo_placement import CirclePlacement, GreedyPlacement, HoldPosition
from sensorgym.envs import stereo_placement
from sensorgym.envs.shells import tree_where
from sensorgym.envs.stereo_placement import kernels
from sensorgym.envs.stereo_placement import simulation as core
from sensorgym.envs.stereo_placement.scan import scan_period
from sensorgym.envs.stereo_placement.simulation import PlacementParams
from sensorgym.envs.stereo_placement.stereo_placement import StereoPlacementVectorEnv
from sensorgym.trackers.stereo.accuracy import position_crlb
from sensorgym.trackers.stereo.information import position_information

ENV_ID = "sensorgym/StereoPlacement-v0"


def _still_scene(params: PlacementParams, receivers, drone, velocity=(0.0, 0.0, 0.0), seed=0):
    """One scenario from hand-placed receivers ``(n, 3)`` and drone ``(3,)``."""
    p = np.asarray(drone, dtype=np.float64)[None]
    v = np.asarray(velocity, dtype=np.float64)[None]
    o = np.asarray(receivers, dtype=np.float64)[None]
    return core.start(params, o, p, v, np.random.default_rng(seed))


# --- API conformance ---------------------------------------------------------------------------


def test_registration_sets_the_time_limit_and_the_vector_entry_point():
    env = gym.make(ENV_ID)
    assert env.spec.max_episode_steps == 60
    assert env.observation_space.shape == (27,) and env.action_space.shape == (6,)
    venv = gym.make_vec(ENV_ID, num_envs=3, vectorization_mode="vector_entry_point")
    assert isinstance(venv.unwrapped, StereoPlacementVectorEnv)
    assert venv.unwrapped.max_episode_steps == 60
    obs, info = venv.reset(seed=1)
    assert obs.shape == (3, 27) and info["bound"].shape == (3,)
    assert set(rules_for(ENV_ID, PlacementParams(), lambda: None)) == {
        "hold-position",
        "circle-placement",
        "greedy-information",
        "lookahead-information",
        "truth-lookahead",
    }


def test_where_swaps_only_the_masked_scenarios():
    params = PlacementParams()
    old = core.reset(params, np.random.default_rng(1), 5)
    old, _, _ = core.step(params, old, np.ones((5, 6)), np.random.default_rng(2))
    new = core.reset(params, np.random.default_rng(3), 5)
    mask = np.array([True, False, True, False, False])
    mixed = tree_where(mask, new, old)
    obs = core.observe(params, mixed)
    np.testing.assert_array_equal(obs[mask], core.observe(params, new)[mask])
    np.testing.assert_array_equal(obs[~mask], core.observe(params, old)[~mask])
    np.testing.assert_array_equal(mixed.fix.condition[~mask], old.fix.condition[~mask])
    np.testing.assert_array_equal(mixed.t, np.where(mask, 0.0, params.period))
    with pytest.raises(ValueError, match="mask"):
        tree_where(mask[:3], new, old)


# --- the conjugation tracker --------------------------------------------------------------------


def test_noise_free_conjugation_recovers_the_moving_drone_exactly():
    """σ_ang = 0: receivers driving during the period, a moving drone, distinct delays; the
    velocity-aware conjugation (frames P_k ≠ I, base vectors at the fix times) is exact."""
    params = PlacementParams(sigma_ang=0.0)
    rng = np.random.default_rng(11)
    state = core.reset(params, rng, 64)
    rule = CirclePlacement(params)
    for _ in range(8):
        action, _ = rule.predict(core.observe(params, state))
        assert np.abs(action).max() > 0.5  # the receivers really move during the periods
        state, reward, _ = core.step(params, state, action, rng)
        assert not state.fix.degenerate.any()
        np.testing.assert_allclose(state.fix.position, state.drone_position, rtol=0, atol=1e-6)
        np.testing.assert_allclose(state.fix.velocity, state.drone_velocity, rtol=0, atol=1e-6)
        np.testing.assert_array_equal(state.fix.range_sigma, 0.0)
        np.testing.assert_array_equal(reward, params.reward_clip)  # σ_pos = 0 earns +R
    # the receivers' frames are not aligned: the test exercised P_k ≠ I
    from sensorgym.envs.stereo_placement.scan import boresight_rotations

    R = boresight_rotations(state.geometry.origins, state.estimate[:, :3], np.deg2rad(80.0))
    assert np.abs(R[:, 0] - R[:, 1]).max() > 0.1


def test_degenerate_fix_is_not_trusted_and_the_tracker_coasts():
    """Equal delays: every solve is degenerate, so the tracker only coasts its cue. With an
    exact cue (``cue_sigma = 0``) coasting keeps it exactly on the moving drone."""
    params = PlacementParams(delays=(0.3, 0.3, 0.3), cue_sigma=(0.0, 0.0))
    o = [[0, 0, 0], [40, 0, 0], [0, 0, 40]]
    state = _still_scene(params, o, [60.0, 40.0, 90.0], velocity=(4.0, 0.0, -2.0))
    assert state.fix.degenerate[0]
    truth = np.concatenate([state.drone_position, state.drone_velocity], -1)
    np.testing.assert_allclose(state.estimate, truth, atol=1e-9)
    for _ in range(3):
        state, reward, _ = core.step(params, state, np.zeros((1, 6)), np.random.default_rng(0))
        assert state.fix.degenerate[0] and reward[0] == -params.reward_clip
        truth = np.concatenate([state.drone_position, state.drone_velocity], -1)
        np.testing.assert_allclose(state.estimate, truth, atol=1e-9)
        assert np.all(np.isfinite(core.observe(params, state)))


# --- reward -------------------------------------------------------------------------------------


def test_reward_is_the_crlb_of_the_true_geometry():
    """Hand-built geometry: stationary receivers and drone; the reward is
    ln(σ_ref/√tr CRLB) with the CRLB from ``position_crlb`` of the true lines of sight."""
    params = PlacementParams()
    o = np.array([[0.0, 0.0, 0.0], [80.0, 0.0, 10.0], [20.0, 0.0, 90.0]])
    drone = np.array([40.0, 50.0, 60.0])
    state = _still_scene(params, o, drone)
    new, reward, _ = core.step(params, state, np.zeros((1, 6)), np.random.default_rng(1))
    d = drone - o
    r = np.linalg.norm(d, axis=-1)
    sigma_pos = np.sqrt(np.trace(position_crlb(d / r[:, None], r, params.sigma_ang)))
    np.testing.assert_allclose(new.bound[0], sigma_pos, rtol=1e-10)
    np.testing.assert_allclose(reward[0], np.log(params.sigma_ref / sigma_pos), rtol=1e-10)
    assert not new.fix.degenerate[0] and 0.0 < reward[0] < params.reward_clip


@pytest.mark.parametrize(
    "params, receivers, drone",
    [
        # receivers on a line and the drone on it: parallel lines of sight
        (PlacementParams(), [[0, 0, 0], [10, 0, 0], [20, 0, 0]], [100.0, 0.0, 0.0]),
        # receivers on a line and the drone above it: coplanar lines of sight (OC-3)
        (PlacementParams(), [[0, 0, 0], [30, 0, 0], [60, 0, 0]], [100.0, 40.0, 0.0]),
        # equal delays: the velocity is unobservable
        (PlacementParams(delays=(0.2, 0.2, 0.2)), [[0, 0, 0], [40, 0, 0], [0, 0, 40]], [50.0, 40.0, 80.0]),
    ],
)  # fmt: skip
@pytest.mark.parametrize("sigma_ang", [0.0, 1e-3])
def test_degenerate_geometry_gives_minus_r_and_no_nan(params, receivers, drone, sigma_ang):
    """−R whether or not noise hides the degeneracy from the tracker's own solve; without
    noise the tracker flags it (pseudo-inverse) and coasts."""
    params = dataclasses.replace(params, sigma_ang=sigma_ang)
    state = _still_scene(params, receivers, drone, velocity=(3.0, 0.0, 0.0))
    for _ in range(3):
        state, reward, _ = core.step(params, state, np.zeros((1, 6)), np.random.default_rng(2))
        assert state.geometry.degenerate[0] and reward[0] == -params.reward_clip
        obs = core.observe(params, state)
        assert np.all(np.isfinite(obs)) and np.all(np.isfinite(state.estimate))
        if sigma_ang == 0.0:
            assert state.fix.degenerate[0] and obs[0, -1] == 1.0


# --- actions and parameters ---------------------------------------------------------------------


def test_actions_are_scaled_speed_limited_clipped_and_kept_in_the_disc():
    params = PlacementParams()
    o = np.array([[0.0, 0.0, 0.0], [50.0, 0.0, 0.0], [198.0, 0.0, 0.0]])
    state = _still_scene(params, o, [60.0, 40.0, 90.0])
    action = np.array([[0.5, 0.0, 1.0, 1.0, 7.0, 0.0]])
    new, _, _ = core.step(params, state, action, np.random.default_rng(0))
    moved = new.receivers[0] - o
    np.testing.assert_allclose(moved[0], [2.5, 0.0, 0.0])  # a · max_speed · τ
    np.testing.assert_allclose(np.linalg.norm(moved[1]), 5.0)  # speed capped, not 5√2
    np.testing.assert_allclose(new.receivers[0, 2], [200.0, 0.0, 0.0])  # held on the edge
    assert np.all(new.receivers[..., 1] == 0.0)


def test_bad_actions_raise():
    env = gym.make(ENV_ID)
    env.reset(seed=0)
    for bad in (np.full(6, np.nan), np.full(6, np.inf), np.zeros(5), "go"):
        with pytest.raises(ValueError, match="action"):
            env.step(bad)
    venv = StereoPlacementVectorEnv(num_envs=2)
    venv.reset(seed=0)
    with pytest.raises(ValueError, match="action"):
        venv.step(np.full((2, 6), np.nan))
    pz = stereo_placement.parallel_env()
    pz.reset(seed=0)
    with pytest.raises(ValueError, match="action"):
        pz.step({agent: np.array([np.nan, 0.0]) for agent in pz.agents})
    with pytest.raises(ValueError, match="action"):
        core.step(PlacementParams(), core.reset(PlacementParams(), np.random.default_rng(0), 1), np.zeros(4), np.random.default_rng(0))  # fmt: skip


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"delays": (0.0, 0.5)}, "delays"),
        ({"delays": (0.0, 0.5, 2.0)}, "delays"),
        ({"max_speed": 0.0}, "max_speed"),
        ({"arena_radius": -1.0}, "arena_radius"),
        ({"cluster_radius": 300.0}, "cluster_radius"),
        ({"start_altitude": (0.0, 10.0)}, "start_altitude"),
        ({"drone_speed": (10.0, 5.0)}, "drone_speed"),
        ({"sigma_ang": -1e-3}, "sigma_ang"),
        ({"cue_sigma": (float("nan"), 1.0)}, "cue_sigma"),
        ({"reward_clip": 0.0}, "reward_clip"),
    ],
)
def test_params_are_validated(kwargs, name):
    with pytest.raises(ValueError, match=name):
        PlacementParams(**kwargs)


def _observation_of(params: PlacementParams, state: core.PlacementState) -> np.ndarray:
    """The observation recomputed from the receivers, the estimate and the fix (the observation
    kernel takes nothing else: no ground truth)."""
    out = np.empty((state.batch_size, params.obs_dim), np.float32)
    fix = state.fix
    kernels.observe_kernel(
        np.arange(state.batch_size), params.kernel_settings, params.pairs_array,
        state.receivers, state.estimate, fix.range_sigma, fix.velocity_sigma, fix.condition,
        fix.degenerate, out,
    )  # fmt: skip
    return out


def test_observation_holds_no_ground_truth():
    params = PlacementParams()
    rng = np.random.default_rng(6)
    state = core.reset(params, rng, 2)
    state, _, _ = core.step(params, state, rng.uniform(-1, 1, (2, 6)), rng)
    np.testing.assert_array_equal(core.observe(params, state), _observation_of(params, state))


def test_the_fused_step_equals_the_generic_path():
    """The one-kernel step (closed form, observation and diagnostics) against the stages run
    separately on the generic path (the SVD fallback for every scenario that needs it)."""
    params = PlacementParams()
    rng = np.random.default_rng(21)
    B = 64
    state = core.reset(params, rng, B)
    # four scenarios whose receivers stand on one spot: degenerate, the generic path's
    o = state.receivers.copy()
    o[:4] = o[:4, :1]
    state = core.start(params, o, state.drone_position, state.drone_velocity, rng)
    for _ in range(5):
        action = rng.uniform(-1.5, 1.5, (B, 3, 2))
        action[:4] = 0.0
        seed = int(rng.integers(1 << 30))
        new, reward, _ = core.step(params, state, action, np.random.default_rng(seed))
        end = np.empty_like(state.receivers)
        kernels.drive_batch(
            state.receivers, action, params.period, params.max_speed, params.arena_radius, end
        )
        p = state.drone_position + params.period * state.drone_velocity
        fix, geometry, estimate, bound, expected = scan_period(
            params.delays_array, params.period, params.sigma_ang, params.max_boresight_elevation,
            state.receivers, end, p, state.drone_velocity, state.estimate,
            np.random.default_rng(seed),
            params.sigma_ref, params.reward_clip,
        )  # fmt: skip
        np.testing.assert_array_equal(reward, expected)
        np.testing.assert_array_equal(new.receivers, end)
        np.testing.assert_array_equal(new.drone_position, p)
        np.testing.assert_array_equal(new.estimate, estimate)
        np.testing.assert_array_equal(new.bound, bound)
        for name in ("position", "velocity", "range_sigma", "velocity_sigma", "condition"):
            np.testing.assert_array_equal(getattr(new.fix, name), getattr(fix, name))
        np.testing.assert_array_equal(new.fix.degenerate, fix.degenerate)
        assert new.geometry.degenerate[:4].all() and not new.geometry.degenerate[4:].any()
        np.testing.assert_array_equal(new.geometry.los, geometry.los)
        np.testing.assert_array_equal(new.geometry.degenerate, geometry.degenerate)
        np.testing.assert_array_equal(new.t, state.t + params.period)
        np.testing.assert_array_equal(core.observe(params, new), _observation_of(params, new))
        error = np.linalg.norm(new.estimate[:, :3] - p, axis=-1)
        np.testing.assert_allclose(core.info(params, new)["position_error"], error, rtol=1e-12)
        angles = core.los_angles(params, new.receivers, p).min(axis=-1)
        np.testing.assert_array_equal(core.info(params, new)["min_los_angle"], angles)
        state = new


def test_observation_layout_round_trips_through_split_observation():
    params = PlacementParams()
    state = core.reset(params, np.random.default_rng(7), 3)
    view = core.split_observation(params, core.observe(params, state))
    np.testing.assert_allclose(view["receivers"], state.receivers, atol=1e-4)
    np.testing.assert_allclose(view["position"], state.estimate[:, :3], rtol=1e-6, atol=1e-4)
    np.testing.assert_allclose(view["velocity"], state.estimate[:, 3:], rtol=1e-6, atol=1e-5)
    angles = core.los_angles(params, state.receivers, state.estimate[:, :3])
    np.testing.assert_allclose(view["angles"], angles, atol=1e-6)


# --- PettingZoo ---------------------------------------------------------------------------------


# --- rules --------------------------------------------------------------------------------------


def test_rules_follow_the_sb3_predict_protocol():
    params = PlacementParams()
    obs = core.observe(params, core.reset(params, np.random.default_rng(8), 4))
    for rule in (HoldPosition(), CirclePlacement(), GreedyPlacement()):
        assert isinstance(rule, PolicyPredictor)
        batch, state = rule.predict(obs)
        one, _ = rule.predict(obs[0])
        assert state is None and batch.shape == (4, 6) and batch.dtype == np.float32
        np.testing.assert_array_equal(one, batch[0])
        assert np.all(np.abs(batch) <= 1.0)
    with pytest.raises(ValueError, match="observation"):
        HoldPosition().predict(obs[:, :5])


def _circle_targets_reference(params: PlacementParams, obs: np.ndarray) -> np.ndarray:
    """CirclePlacement's slots searched with numpy over every phase and assignment at once."""
    view = core.split_observation(params, obs)
    o, p, v = view["receivers"], view["position"], view["velocity"]
    n = params.n_receivers
    centre = p + params.period * v
    centre[:, 1] = 0.0
    rho = np.sqrt(2.0) * np.maximum(p[:, 1], 1.0)
    rel = o - centre[:, None, :]
    phase = np.arctan2(rel[..., 0], rel[..., 2])
    slot = phase[:, :, None] + 2.0 * np.pi * np.arange(n) / n
    pts = np.stack([np.sin(slot), np.zeros_like(slot), np.cos(slot)], -1)
    pts = core.in_arena(params, centre[:, None, None, :] + rho[:, None, None, None] * pts, 1.0)
    perms = np.array(list(itertools.permutations(range(n))))
    goal = pts[:, :, perms]
    dist = np.linalg.norm(goal - o[:, None, None], axis=-1)
    cost = (dist.max(axis=-1) + 1e-3 * dist.sum(axis=-1)).reshape(obs.shape[0], -1)
    best = np.argmin(cost, axis=-1)
    return goal.reshape(obs.shape[0], -1, n, 3)[np.arange(obs.shape[0]), best]


def _greedy_actions_reference(rule: GreedyPlacement, obs: np.ndarray) -> np.ndarray:
    """GreedyPlacement's choice scored with numpy for every joint candidate at once: the sum
    over the horizon of the env's reward at the receivers' move ends and the drone coasted."""
    params = rule.params
    view = core.split_observation(params, obs)
    o, p, v = view["receivers"], view["position"], view["velocity"]
    n = params.n_receivers
    joint = np.array(list(itertools.product(range(len(rule.moves)), repeat=n)))
    a = rule.moves[joint]
    step = params.max_speed * params.period * a
    shift = np.stack([step[..., 0], np.zeros(step.shape[:-1]), step[..., 1]], -1)
    cand = np.broadcast_to(o[:, None], (obs.shape[0], len(joint), n, 3))
    score = np.zeros((obs.shape[0], len(joint)))
    for h in range(1, rule.horizon + 1):
        cand = core.in_arena(params, cand + shift[None])
        d = (p + h * params.period * v)[:, None, None, :] - cand
        r = np.linalg.norm(d, axis=-1)
        info = position_information(d / r[..., None], r)
        sigma = params.sigma_ang * np.sqrt(np.trace(np.linalg.inv(info), axis1=-2, axis2=-1))
        score += np.clip(np.log(params.sigma_ref / sigma), -params.reward_clip, params.reward_clip)
    return a[np.argmax(score, axis=-1)].reshape(obs.shape[0], -1)


def test_compiled_rules_choose_what_the_numpy_search_chooses():
    """The rules' compiled searches against the same search written with numpy over all
    candidates at once, receivers near the disc's edge included: the same choices (the circle's
    slots agree to rounding: numpy's vectorised sine and libm's may differ in the last bit)."""
    params = PlacementParams(arena_radius=60.0, cluster_radius=15.0)
    rng = np.random.default_rng(17)
    state = core.reset(params, rng, 128)
    observations = []
    for _ in range(12):
        observations.append(core.observe(params, state))
        state, _, _ = core.step(params, state, rng.uniform(-1, 1, (128, 6)), rng)
    obs = np.concatenate(observations).astype(np.float64)
    circle = CirclePlacement(params)
    np.testing.assert_allclose(
        circle.targets(obs), _circle_targets_reference(params, obs), rtol=0.0, atol=1e-9
    )
    for horizon in (1, 3):
        greedy = GreedyPlacement(params, horizon=horizon)
        chosen, reference = greedy.act(obs), _greedy_actions_reference(greedy, obs)
        # the same choice up to rounding ties (near-equal scores of different candidates)
        assert np.mean(np.all(chosen == reference, axis=-1)) > 0.99


@pytest.fixture(scope="module")
def scores():
    venv = make_vec_env(ENV_ID, n_envs=4, seed=0)
    rules = {"hold": HoldPosition(), "circle": CirclePlacement(), "greedy": GreedyPlacement()}
    return {
        name: evaluate_policy(rule, venv, n_eval_episodes=8, deterministic=True)[0]
        for name, rule in rules.items()
    }


def test_rules_beat_holding_position(scores):
    """Clustered receivers fix the drone from a 15 m baseline; spreading them out pays."""
    assert scores["hold"] < 0.0
    for name in ("circle", "greedy"):
        assert scores[name] > scores["hold"] + 60.0, (name, scores)


def test_circle_placement_ends_with_near_orthogonal_lines_of_sight():
    params = PlacementParams(drone_speed=(0.0, 0.0))
    rng = np.random.default_rng(9)
    state = core.reset(params, rng, 16)
    rule = CirclePlacement(params)
    for _ in range(60):
        action, _ = rule.predict(core.observe(params, state))
        state, reward, _ = core.step(params, state, action, rng)
    angles = core.los_angles(params, state.receivers, state.drone_position)
    np.testing.assert_allclose(np.rad2deg(angles), 90.0, atol=3.0)
    # and on the √2·h circle around the drone
    offset = (state.receivers - state.drone_position[:, None])[..., [0, 2]]
    radius = np.linalg.norm(offset, axis=-1)
    np.testing.assert_allclose(radius, np.sqrt(2.0) * state.drone_position[:, [1, 1, 1]], rtol=0.05)
    assert reward.min() > 1.5


def test_greedy_information_moves_the_receivers_apart():
    params = PlacementParams(drone_speed=(0.0, 0.0))
    rng = np.random.default_rng(10)
    state = core.reset(params, rng, 8)
    first = state.bound.copy()
    rule = GreedyPlacement(params)
    for _ in range(20):
        action, _ = rule.predict(core.observe(params, state))
        state, _, _ = core.step(params, state, action, rng)
    assert np.all(state.bound < 0.5 * first)
