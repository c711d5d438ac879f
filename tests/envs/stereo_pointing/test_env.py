"""sensorgym/StereoPointing-v0: API conformance, shells against each other, geometry, reward,
tracker, rules."""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np
import pytest
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.evaluation import evaluate_policy

import sensorgym.envs  # noqa: F401  (registers the ids)
from sensorgym.agents.protocol import PolicyPredictor
from sensorgym.agents.stereo_pointing import (
    GreedyPointing,
    HoldStill,
    OrthogonalPairs,
    TrackNearest,
)
from sensorgym.envs.shells import tree_scatter, tree_where
from sensorgym.envs.stereo_pointing import simulation as core
from sensorgym.envs.stereo_pointing.simulation import PointingParams
from sensorgym.envs.stereo_pointing.stereo_pointing import (
    StereoPointingEnv,
    StereoPointingVectorEnv,
)
from sensorgym.trackers.geometry import angles_from_unit
from sensorgym.trackers.stereo.accuracy import position_crlb, triangulate_ml
from sensorgym.trackers.stereo.information import weighted_fix
from sensorgym.trackers.stereo.kalman import CVTrack, cv_predict, cv_prior, cv_update
from tests.conftest import assert_same_tree

ENV_ID = "sensorgym/StereoPointing-v0"


def _aim(params: PointingParams, points: np.ndarray, target: np.ndarray):
    """Azimuth, elevation ``(1, n)`` that put receiver ``k`` on ``points[target[k]]``."""
    d = points[target] - params.receiver_positions
    az, el = angles_from_unit(d / np.linalg.norm(d, axis=-1, keepdims=True))
    return az[None], el[None]


def _still(params: PointingParams, points, target, seed=0) -> core.PointingState:
    """One scenario: stationary drones at ``points (m, 3)``, receiver k aimed at drone
    ``target[k]`` (drones do not move, so the aim holds after the first step)."""
    p = np.asarray(points, dtype=np.float64)[None]
    az, el = _aim(params, p[0], np.asarray(target))
    return core.start(params, p, np.zeros_like(p), az, el, np.random.default_rng(seed))


# --- API conformance ---------------------------------------------------------------------------


def test_registration_sets_the_time_limit_and_the_vector_entry_point():
    env = gym.make(ENV_ID)
    assert env.spec.max_episode_steps == 150
    assert env.observation_space.shape == (52,) and env.action_space.shape == (8,)
    venv = gym.make_vec(ENV_ID, num_envs=3, vectorization_mode="vector_entry_point")
    assert isinstance(venv.unwrapped, StereoPointingVectorEnv)
    assert venv.unwrapped.max_episode_steps == 150
    obs, info = venv.reset(seed=1)
    assert obs.shape == (3, 52) and info["position_error"].shape == (3,)


def test_vector_env_of_one_reproduces_the_single_env_across_autoreset():
    """Gymnasium's vector-equivalence pattern: same seed, same actions (a tracking rule, so that
    the drones are seen and the tracker updates), step by step, over three episodes (the
    NEXT_STEP autoreset step is matched by an explicit reset of the single env)."""
    rule = OrthogonalPairs()
    single = gym.make(ENV_ID, max_episode_steps=12)
    vector = StereoPointingVectorEnv(num_envs=1, max_episode_steps=12)
    obs_s, _ = single.reset(seed=3)
    obs_v, _ = vector.reset(seed=3)
    np.testing.assert_array_equal(obs_v[0], obs_s)
    done, restarts, total = False, 0, 0.0
    for _ in range(36):
        a, _ = rule.predict(obs_s)
        obs_v, r_v, term_v, trunc_v, _ = vector.step(a[None])
        assert not term_v[0]
        if done:  # the vector env restarts on this step; the single env is reset by hand
            obs_s, _ = single.reset()
            assert r_v[0] == 0.0 and not trunc_v[0]
            done, restarts = False, restarts + 1
        else:
            obs_s, r_s, term_s, trunc_s, _ = single.step(a)
            assert r_v[0] == r_s and not term_s and trunc_v[0] == trunc_s
            done, total = trunc_s, total + r_s
        np.testing.assert_array_equal(obs_v[0], obs_s)
    assert restarts == 2
    assert total > -5.0 * 33  # some steps fixed a drone: the tracker path was exercised


def test_vector_env_truncates_together_and_restarts_every_scenario():
    venv = StereoPointingVectorEnv(num_envs=4, max_episode_steps=3)
    first, _ = venv.reset(seed=4)
    for k in range(3):
        _, _, term, trunc, _ = venv.step(np.zeros((4, 8), dtype=np.float32))
        assert not term.any() and trunc.all() == (k == 2)
    obs, reward, term, trunc, _ = venv.step(np.zeros((4, 8), dtype=np.float32))
    assert np.all(reward == 0.0) and not term.any() and not trunc.any()
    assert np.all(venv._steps == 0) and not np.array_equal(obs, first)


def test_where_swaps_only_the_masked_scenarios():
    params = PointingParams()
    old = core.reset(params, np.random.default_rng(1), 5)
    old, _, _ = core.step(params, old, np.zeros((5, 8)), np.random.default_rng(2))
    new = core.reset(params, np.random.default_rng(3), 5)
    mask = np.array([True, False, True, False, False])
    mixed = tree_where(mask, new, old)
    obs = core.observe(params, mixed)
    np.testing.assert_array_equal(obs[mask], core.observe(params, new)[mask])
    np.testing.assert_array_equal(obs[~mask], core.observe(params, old)[~mask])
    np.testing.assert_array_equal(mixed.t, np.where(mask, 0.0, params.dt))
    with pytest.raises(ValueError, match="mask"):
        tree_where(mask[:3], new, old)


def test_scatter_gives_the_observation_and_info_of_the_merged_state():
    """The step's observation and info travel with its state; a state merged from two
    (the shells' autoreset) must show its own, not the stepped state's."""
    params = PointingParams()
    old = core.reset(params, np.random.default_rng(1), 5)
    old, _, _ = core.step(params, old, np.zeros((5, 8)), np.random.default_rng(2))
    core.observe(params, old)
    fresh = core.reset(params, np.random.default_rng(3), 2)
    mask = np.array([False, True, False, False, True])
    merged = tree_scatter(mask, fresh, old)
    obs, info = core.observe(params, merged), core.info(params, merged)
    np.testing.assert_array_equal(obs[mask], core.observe(params, fresh))
    np.testing.assert_array_equal(obs[~mask], core.observe(params, old)[~mask])
    for key, value in core.info(params, fresh).items():
        np.testing.assert_array_equal(info[key][mask], value)
        np.testing.assert_array_equal(info[key][~mask], core.info(params, old)[key][~mask])


# --- geometry, measurement, reward --------------------------------------------------------------


def test_a_predicted_drone_on_the_boresight_has_zero_offset():
    """Noise-free geometry: aim every receiver at the tracker's prediction of drone 0; its
    offsets read zero, and drone 1's offsets equal independently computed world angles."""
    params = PointingParams()
    state = core.reset(params, np.random.default_rng(6), 1)
    x = state.track.x.copy()
    x[0, 0, :3] = [30.0, 40.0, 90.0]
    x[0, 0, 3:] = [5.0, 1.0, -10.0]
    state = dataclasses.replace(state, track=CVTrack(x, state.track.P))
    predicted = x[0, :, :3] + params.dt * x[0, :, 3:]
    az, el = _aim(params, predicted, np.zeros(4, dtype=int))
    state = dataclasses.replace(state, azimuth=az, elevation=el)
    _, pairs, drones = core.split_observation(params, core.observe(params, state))
    np.testing.assert_allclose(pairs[0, :, 0, :2], 0.0, atol=1e-6)
    np.testing.assert_allclose(drones[0, :, :3] * params.length_scale, predicted, rtol=1e-6)
    d = predicted[1] - params.receiver_positions
    az1, el1 = angles_from_unit(d / np.linalg.norm(d, axis=-1, keepdims=True))
    want = np.stack([np.angle(np.exp(1j * (az1 - az[0]))), el1 - el[0]], -1) / params.fov
    np.testing.assert_allclose(pairs[0, :, 1, :2], np.clip(want, -10, 10), atol=1e-5)
    # the velocity block: the filter's velocity (unchanged by the CV prediction) and ln σ̂_v
    np.testing.assert_allclose(drones[0, :, 4:7] * params.velocity_scale, x[0, :, 3:], rtol=1e-6)
    P = core.predicted_track(params, state).P[0]
    sigma_v = np.sqrt(np.trace(P[:, 3:, 3:], axis1=1, axis2=2))
    np.testing.assert_allclose(drones[0, :, 7], np.log(sigma_v / params.sigma_ref), rtol=1e-6)


def test_a_receiver_sees_exactly_the_drones_inside_its_cone():
    """Tilt receiver 0 off the drone by just under and just over the half-angle."""
    params = PointingParams(n_drones=1, sigma_ang=0.0)
    drone = np.array([[20.0, 50.0, 110.0]])
    for tilt, inside in ((params.fov - 1e-6, True), (params.fov + 1e-6, False)):
        state = _still(params, drone, [0, 0, 0, 0])
        el = state.elevation.copy()
        el[0, 0] += tilt
        state = dataclasses.replace(state, elevation=el)
        new, _, _ = core.step(params, state, np.zeros(8), np.random.default_rng(0))
        assert bool(new.seen[0, 0, 0]) is inside
        assert new.seen[0, 1:, 0].all()


def test_noise_free_fix_is_the_truth_and_the_filter_takes_it():
    """σ_ang = 0: the triangulated fix equals the true position to 1e-9 m, and so does the
    filter after its update (R = 0)."""
    params = PointingParams(sigma_ang=0.0)
    drones = np.array([[80.0, 40.0, 60.0], [-50.0, 70.0, -120.0]])
    state = _still(params, drones, [0, 0, 1, 1])
    new, _, _ = core.step(params, state, np.zeros(8), np.random.default_rng(1))
    assert new.fixed.all()
    np.testing.assert_allclose(new.track.position[0], drones, rtol=0, atol=1e-9)
    # the fix alone, on random geometries and random masks of at least two views
    rng = np.random.default_rng(2)
    M = rng.normal(size=(50, 3)) * 50.0 + [0.0, 60.0, 100.0]
    o = rng.normal(size=(50, 5, 3)) * 60.0
    u = M[:, None] - o
    u /= np.linalg.norm(u, axis=-1, keepdims=True)
    seen = rng.random((50, 5)) < 0.6
    seen[:, :2] = True
    fix, _, ok = weighted_fix(o, u, seen)
    assert ok.all()
    np.testing.assert_allclose(fix, M, rtol=0, atol=1e-9)


def test_weighted_fix_with_every_view_is_triangulate_ml():
    rng = np.random.default_rng(3)
    M = rng.normal(size=(20, 3)) * 40.0 + [0.0, 50.0, 100.0]
    o = rng.normal(size=(20, 4, 3)) * 60.0
    u = M[:, None] - o
    u = u / np.linalg.norm(u, axis=-1, keepdims=True) + rng.normal(size=u.shape) * 1e-3
    u /= np.linalg.norm(u, axis=-1, keepdims=True)
    fix, G, ok = weighted_fix(o, u, np.ones((20, 4), dtype=bool))
    ml, cov = triangulate_ml(o, u, 1e-3)
    assert ok.all()
    np.testing.assert_allclose(fix, ml, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(1e-6 * np.linalg.inv(G), cov, rtol=1e-9)


def test_reward_is_the_crlb_of_the_receivers_that_see_each_drone():
    """Hand-built geometry: drone 0 seen by receivers 0, 1, 2; drone 1 by receiver 3 alone."""
    params = PointingParams(sigma_ang=2e-3)
    drones = np.array([[70.0, 35.0, 90.0], [-100.0, 60.0, -40.0]])
    state = _still(params, drones, [0, 0, 0, 1])
    new, reward, _ = core.step(params, state, np.zeros(8), np.random.default_rng(4))
    np.testing.assert_array_equal(new.seen[0], [[1, 0], [1, 0], [1, 0], [0, 1]])
    d = drones[0] - params.receiver_positions[:3]
    r = np.linalg.norm(d, axis=-1)
    sigma_pos = np.sqrt(np.trace(position_crlb(d / r[:, None], r, 2e-3)))
    want = 0.5 * (np.clip(np.log(1.0 / sigma_pos), -5, 5) - 5.0)
    assert reward[0] == pytest.approx(want, rel=1e-12)
    assert new.fixed[0].tolist() == [True, False]
    # both drones fixed, and a tight σ_ref clips the reward at −R for both
    state = _still(params, drones, [0, 0, 1, 1])
    _, reward, _ = core.step(params, state, np.zeros(8), np.random.default_rng(4))
    tight = dataclasses.replace(params, sigma_ref=1e-6)
    _, low, _ = core.step(tight, state, np.zeros(8), np.random.default_rng(4))
    assert -5.0 < reward[0] < 5.0 and low[0] == -5.0


def test_no_view_gives_minus_r_and_noise_free_views_give_plus_r():
    params = PointingParams(sigma_ang=0.0)
    drones = np.array([[80.0, 40.0, 60.0], [-50.0, 70.0, -120.0]])
    state = _still(params, drones, [0, 0, 1, 1])
    _, reward, _ = core.step(params, state, np.zeros(8), np.random.default_rng(5))
    assert reward[0] == 5.0
    away = dataclasses.replace(state, elevation=state.elevation - 0.5)
    new, reward, _ = core.step(params, away, np.zeros(8), np.random.default_rng(5))
    assert reward[0] == -5.0 and not new.seen.any() and not new.fixed.any()


def test_slew_is_scaled_clipped_and_bounded_in_elevation():
    params = PointingParams()
    state = core.reset(params, np.random.default_rng(7), 2)
    a = np.zeros((2, 4, 2))
    a[:, :, 0] = [0.5, -1.0, 3.0, 0.0]
    a[:, :, 1] = [0.0, 0.0, 0.0, 1.0]
    new, _, _ = core.step(params, state, a, np.random.default_rng(8))
    step = params.slew_rate * params.dt
    turn = np.angle(np.exp(1j * (new.azimuth - state.azimuth)))
    np.testing.assert_allclose(turn, np.tile([0.5 * step, -step, step, 0.0], (2, 1)), atol=1e-12)
    np.testing.assert_allclose(new.elevation[:, 3], state.elevation[:, 3] + step, atol=1e-12)
    for _ in range(20):
        new, _, _ = core.step(params, new, np.tile([0.0, 1.0], (2, 4)), np.random.default_rng(9))
    np.testing.assert_allclose(new.elevation, params.max_elevation)


def test_out_of_range_actions_are_clipped_and_bad_actions_raise():
    a, b = gym.make(ENV_ID), gym.make(ENV_ID)
    a.reset(seed=6)
    b.reset(seed=6)
    big = np.array([5.0, -7.0, 0.5, 2.0, -3.0, 0.0, 1.0, -1.0])
    oa = a.step(big)
    ob = b.step(np.clip(big, -1.0, 1.0))
    np.testing.assert_array_equal(oa[0], ob[0])
    assert oa[1] == ob[1]
    with pytest.raises(ValueError, match="action: contains NaN"):
        a.step(np.array([np.nan] + [0.0] * 7))
    with pytest.raises(ValueError, match="action: expected shape"):
        a.step(np.zeros(3))
    with pytest.raises(ValueError, match="action"):
        core.step(PointingParams(), core.reset(PointingParams(), np.random.default_rng(0), 1),
                  np.zeros(5), np.random.default_rng(0))  # fmt: skip
    with pytest.raises(RuntimeError, match="reset"):
        StereoPointingEnv().step(np.zeros(8))
    venv = StereoPointingVectorEnv(num_envs=2)
    venv.reset(seed=0)
    with pytest.raises(ValueError, match="action: expected shape"):
        venv.step(np.zeros(8))


def test_params_are_validated():
    with pytest.raises(ValueError, match="n_receivers"):
        PointingParams(n_receivers=1)
    with pytest.raises(ValueError, match="receiver_angles_deg"):
        PointingParams(receiver_angles_deg=(0.0, 90.0))
    with pytest.raises(ValueError, match="fov"):
        PointingParams(fov=2.0)
    with pytest.raises(ValueError, match="start_distance"):
        PointingParams(start_distance=(150.0, 60.0))
    with pytest.raises(ValueError, match="sigma_ang"):
        PointingParams(sigma_ang=-1.0)
    with pytest.raises(ValueError, match="num_envs"):
        StereoPointingVectorEnv(num_envs=0)
    with pytest.raises(ValueError, match="render_mode"):
        StereoPointingEnv(render_mode="ansi")


def test_observation_holds_no_ground_truth():
    """Two scenarios with the same cue and pointing but different true drones observe alike."""
    params = PointingParams()
    state = core.reset(params, np.random.default_rng(10), 1)
    moved = dataclasses.replace(state, drone_position=state.drone_position + 7.0)
    np.testing.assert_array_equal(core.observe(params, state), core.observe(params, moved))


# --- tracker ------------------------------------------------------------------------------------


def test_fix_scatter_matches_its_covariance():
    """Monte Carlo: the fix's error covariance is σ² G⁻¹ (the CRLB, attained to first order)."""
    from sensorgym.envs.worlds.stereo_scene import perturb_directions

    rng = np.random.default_rng(11)
    M = np.array([30.0, 50.0, 110.0])
    o = PointingParams().receiver_positions[:3]
    u = (M - o) / np.linalg.norm(M - o, axis=-1, keepdims=True)
    z = perturb_directions(np.broadcast_to(u, (4000, 3, 3)), 1e-3, rng)
    fix, G, ok = weighted_fix(np.broadcast_to(o, z.shape), z, np.ones((4000, 3), dtype=bool))
    err = fix - M
    sample = err.T @ err / len(err)
    crlb = 1e-6 * np.linalg.inv(G.mean(axis=0))
    assert ok.all()
    np.testing.assert_allclose(np.trace(sample), np.trace(crlb), rtol=0.08)
    np.testing.assert_allclose(np.abs(err.mean(axis=0)), 0.0, atol=0.02)


def test_kalman_filter_is_consistent_on_a_straight_track():
    """NEES of a CV filter fed unbiased 3-D fixes stays inside its 95 % chi-square band."""
    rng = np.random.default_rng(12)
    runs, steps, dt, sigma = 400, 30, 0.2, 0.5
    p, v = rng.normal(size=(runs, 3)) * 50.0, rng.normal(size=(runs, 3)) * 8.0
    track = cv_prior(p + rng.normal(size=p.shape) * 5.0, v + rng.normal(size=v.shape) * 2.0,
                     5.0, 2.0)  # fmt: skip
    R = np.broadcast_to(sigma**2 * np.eye(3), (runs, 3, 3))
    for _ in range(steps):
        p = p + v * dt
        track = cv_predict(track, dt, 0.0)
        track = cv_update(track, p + rng.normal(size=p.shape) * sigma, R, np.ones(runs, bool))
    e = track.x - np.concatenate([p, v], -1)
    nees = np.einsum("ri,rij,rj->r", e, np.linalg.inv(track.P), e).mean()
    # mean of 400 χ²₆ draws: 6 ± 1.96·√(12/400)
    assert abs(nees - 6.0) < 1.96 * np.sqrt(12.0 / runs) * 1.2
    held = cv_update(track, np.zeros((runs, 3)), R, np.zeros(runs, bool))
    np.testing.assert_array_equal(held.x, track.x)


# --- heuristic rules ---------------------------------------------------------------------------


def test_rules_follow_the_sb3_predict_protocol():
    params = PointingParams()
    obs = core.observe(params, core.reset(params, np.random.default_rng(13), 3))
    for rule in (HoldStill(), TrackNearest(), OrthogonalPairs(), GreedyPointing()):
        assert isinstance(rule, PolicyPredictor)
        action, _ = rule.predict(obs)
        assert action.shape == (3, 8) and action.dtype == np.float32
        assert np.all(np.abs(action) <= 1.0)
        one, _ = rule.predict(obs[0])
        assert one.shape == (8,)
        np.testing.assert_array_equal(one, action[0])
    with pytest.raises(ValueError, match="observation"):
        TrackNearest().predict(np.zeros(4))
    # beyond 4096 assignments only the exhaustive solver refuses; auto turns polynomial
    large = PointingParams(n_receivers=9, n_drones=4)
    obs = core.observe(large, core.reset(large, np.random.default_rng(13), 3))
    with pytest.raises(ValueError, match="assignments"):
        OrthogonalPairs(large, solver="exhaustive").predict(obs)
    assert OrthogonalPairs(large).predict(obs)[0].shape == (3, 18)


def test_slewing_rules_put_the_prediction_on_the_boresight():
    """A receiver within one step of its drone's prediction lands exactly on it (the nearest
    drone does not depend on the pointing)."""
    params = PointingParams()
    state = core.reset(params, np.random.default_rng(14), 1)
    pred = core.predicted_track(params, state).position[0]
    target = TrackNearest().assign(core.observe(params, state)[0])
    ranges = np.linalg.norm(pred[None] - params.receiver_positions[:, None], axis=-1)
    np.testing.assert_array_equal(target, ranges.argmin(axis=1))
    az, el = _aim(params, pred, target)
    state = dataclasses.replace(state, azimuth=az - 0.05, elevation=el + 0.03)
    action, _ = TrackNearest().predict(core.observe(params, state))
    new, _, _ = core.step(params, state, action, np.random.default_rng(0))
    np.testing.assert_allclose(np.angle(np.exp(1j * (new.azimuth - az))), 0.0, atol=1e-6)
    np.testing.assert_allclose(new.elevation, el, atol=1e-6)


@pytest.fixture(scope="module")
def scores():
    venv = make_vec_env(ENV_ID, n_envs=4, seed=0)
    rules = {
        "hold": HoldStill(),
        "nearest": TrackNearest(),
        "orthogonal": OrthogonalPairs(),
        "greedy": GreedyPointing(),
    }
    return {
        name: evaluate_policy(rule, venv, n_eval_episodes=8, deterministic=True)[0]
        for name, rule in rules.items()
    }


def test_rules_beat_holding_still(scores):
    """Holding still on the cue sees the drones only until they leave the narrow fields of view
    (−R every step after that, −750 at worst); every rule keeps tracking."""
    assert -750.0 <= scores["hold"] < -600.0
    for name in ("nearest", "orthogonal", "greedy"):
        assert scores[name] > scores["hold"] + 300.0, name


def test_random_start_points_anywhere_and_holding_still_sees_nothing():
    params = PointingParams(cued_start=False)
    venv = make_vec_env(ENV_ID, n_envs=2, seed=0, env_kwargs={"params": params})
    hold = evaluate_policy(HoldStill(params), venv, n_eval_episodes=4, deterministic=True)[0]
    assert hold == pytest.approx(-5.0 * 150)


def test_orthogonal_pairs_beat_track_nearest_when_nearest_pairs_are_collinear():
    """OC-3's bad layout (two clusters of two receivers) and each drone beyond a cluster on the
    line through it: the nearest receivers see it along almost the same line (OC-1)."""
    params = PointingParams(receiver_angles_deg=(0.0, 20.0, 180.0, 200.0), drone_speed=(0, 0))
    o = params.receiver_positions
    line = (o[1] - o[0]) / np.linalg.norm(o[1] - o[0])
    A = o[1] + 60.0 * line + [0.0, 1.0, 0.0]
    drones = np.stack([A, A * [-1.0, 1.0, -1.0]])
    returns = {}
    for rule in (TrackNearest(params), OrthogonalPairs(params), GreedyPointing(params)):
        rng = np.random.default_rng(15)
        p = drones[None]
        state = core.start(params, p, np.zeros_like(p), np.zeros((1, 4)), np.zeros((1, 4)), rng)
        total = 0.0
        for _ in range(40):
            a, _ = rule.predict(core.observe(params, state))
            state, r, _ = core.step(params, state, a, rng)
            total += r[0]
        returns[type(rule).__name__] = total
    nearest = TrackNearest(params).assign(core.observe(params, state)[0])
    assert nearest.tolist() == [0, 0, 1, 1]  # the clusters: nearly parallel lines of sight
    assert returns["OrthogonalPairs"] > returns["TrackNearest"] + 40.0
    assert returns["GreedyPointing"] > returns["TrackNearest"] + 40.0


# --- scenario rows over threads -----------------------------------------------------------------


def _threaded_run(threads: str, autoreset: str) -> tuple[list, list]:
    """A 300-scenario vector env stepped 14 times with ``SENSORGYM_THREADS=threads`` (episodes of
    5 steps: autoresets on the way); every output, and the row ranges the step kernel ran."""
    from sensorgym.envs.stereo_pointing import kernels

    chunks: list = []
    step_kernel = kernels.step_kernel

    def spy(lo, hi, *args):
        chunks.append((lo, hi))
        return step_kernel(lo, hi, *args)

    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("SENSORGYM_THREADS", threads)
        patch.setattr(kernels, "step_kernel", spy)
        venv = StereoPointingVectorEnv(num_envs=300, max_episode_steps=5, autoreset_mode=autoreset)
        out = [venv.reset(seed=3)]
        rng = np.random.default_rng(4)
        for _ in range(14):
            out.append(venv.step(rng.uniform(-1.2, 1.2, venv.action_space.shape)))
    return out, chunks


@pytest.mark.parametrize("autoreset", ["NextStep", "SameStep"])
def test_two_threads_give_the_one_thread_results_bit_for_bit(autoreset):
    one, chunks_one = _threaded_run("1", autoreset)
    two, chunks_two = _threaded_run("2", autoreset)
    assert set(chunks_one) == {(0, 300)} and len(chunks_two) == 2 * len(chunks_one)
    # per step the pool thread's chunk (the first rows, sized by the measured costs) and the rest
    steps = [sorted(chunks_two[i : i + 2]) for i in range(0, len(chunks_two), 2)]
    assert all(a[0] == 0 and 0 < a[1] == b[0] < 300 and b[1] == 300 for a, b in steps)
    assert "views" in one[-1][-1]
    assert_same_tree(one, two)


def test_a_bad_action_in_a_later_chunk_raises(monkeypatch):
    monkeypatch.setenv("SENSORGYM_THREADS", "2")
    state = core.reset(PointingParams(), np.random.default_rng(0), 300)
    action = np.zeros((300, 4, 2))
    action[299, 3, 1] = np.inf
    with pytest.raises(ValueError, match="action: contains NaN"):
        core.step(PointingParams(), state, action, np.random.default_rng(1))
