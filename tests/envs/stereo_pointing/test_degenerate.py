"""sensorgym/StereoPointing-v0 on degenerate inputs (issue 10, defects 3 and 4): exact fixes with
no process noise, (nearly) co-located receivers, a drone or a prediction exactly on a receiver,
and a seeded sweep of extreme settings. Every step must give finite rewards and observations
inside the observation space, never an exception."""

from __future__ import annotations

import dataclasses
import itertools

import gymnasium as gym
import numpy as np
import pytest

import sensorgym.envs  # noqa: F401  (registers the ids)
from sensorgym.agents.stereo_pointing import (
    GreedyPointing,
    HoldStill,
    OrthogonalPairs,
    TrackNearest,
)
from sensorgym.envs.stereo_pointing import simulation as core
from sensorgym.envs.stereo_pointing.simulation import PointingParams
from sensorgym.envs.stereo_pointing.stereo_pointing import StereoPointingVectorEnv
from sensorgym.envs.worlds.stereo_scene import perturb_directions
from sensorgym.trackers.geometry import angles_from_unit
from sensorgym.trackers.stereo.kalman import CVTrack

ENV_ID = "sensorgym/StereoPointing-v0"


def _check(space: gym.spaces.Box, obs: np.ndarray, reward: np.ndarray) -> None:
    assert np.all(np.isfinite(reward))
    assert obs.dtype == np.float32 and np.all(np.isfinite(obs))
    assert np.all(obs >= space.low) and np.all(obs <= space.high)


def _aim(params: PointingParams, point: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Azimuth, elevation ``(1, n)`` that put every receiver on ``point``."""
    n = params.n_receivers
    points = np.broadcast_to(np.asarray(point, dtype=np.float64), (1, n, 3))
    return core.aim_at(params, points, np.zeros((1, n)), np.zeros((1, n)))


# --- defect 3: both noises zero -----------------------------------------------------------------


def test_exact_fixes_without_process_noise_run_a_whole_episode():
    """The reproducer: σ_ang = 0 and q = 0 made S = H P Hᵀ + R singular at step 6."""
    env = gym.make(ENV_ID, sigma_ang=0.0, process_noise=0.0)
    obs, _ = env.reset(seed=0)
    steps, fixed = 0, 0.0
    truncated = False
    while not truncated:
        obs, reward, terminated, truncated, info = env.step(np.zeros(8, dtype=np.float32))
        _check(env.observation_space, obs[None], np.array([reward]))
        assert not terminated
        steps, fixed = steps + 1, fixed + info["drones_fixed"]
    assert steps == 150 and fixed > 6  # the fix path ran past the old crash


def test_noise_free_track_is_the_truth_whenever_two_receivers_see_the_drone():
    """σ_ang = 0, q = 0, receivers tracking their drones: after every fixed step the track
    position is the true position (the fix itself), also once the track is certain (S = 0)."""
    params = PointingParams(sigma_ang=0.0, process_noise=0.0, fov=1.0)
    rng = np.random.default_rng(3)
    state = core.reset(params, rng, 32)
    rule = GreedyPointing(params)
    fixed_steps = 0
    for _ in range(60):
        action, _ = rule.predict(core.observe(params, state))
        state, reward, _ = core.step(params, state, action, rng)
        assert np.all(np.isfinite(reward)) and np.all(np.isfinite(state.track.x))
        err = np.linalg.norm(state.track.position - state.drone_position, axis=-1)
        assert np.all(err[state.fixed] < 1e-8)
        fixed_steps += int(state.fixed.all(axis=-1).sum())
    assert fixed_steps > 32 * 40
    # the velocity is exact too after two fixes of a straight line
    verr = np.linalg.norm(state.track.velocity - state.drone_velocity, axis=-1)
    assert np.all(verr[state.fixed] < 1e-6)


def test_a_certain_track_takes_the_exact_fix():
    """Hand-made: a track with zero covariance and a fix that disagrees with it by 1 m."""
    params = PointingParams(sigma_ang=0.0, process_noise=0.0, n_drones=1)
    drone = np.array([[[30.0, 50.0, 100.0]]])
    velocity = np.array([[[2.0, 0.0, -3.0]]])
    az, el = _aim(params, drone[0, 0] + params.dt * velocity[0, 0])
    state = core.start(params, drone, velocity, az, el, np.random.default_rng(0))
    x = np.concatenate([drone + np.array([1.0, 0.0, 0.0]), velocity], -1)
    state = dataclasses.replace(state, track=CVTrack(x, np.zeros((1, 1, 6, 6))))
    new, reward, _ = core.step(params, state, np.zeros(8), np.random.default_rng(1))
    assert new.fixed.all() and reward[0] == params.reward_clip
    np.testing.assert_allclose(new.track.position, new.drone_position, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(new.track.velocity, velocity)
    assert np.all(np.isfinite(new.track.P))


# --- defect 4: degenerate receiver geometry -----------------------------------------------------


def test_duplicate_receiver_places_are_refused():
    for angles in ((0.0, 0.0, 90.0, 180.0), (10.0, 90.0, 370.0, 200.0), (0.0, 90.0, -270.0, 5.0)):
        with pytest.raises(ValueError, match="receiver_angles_deg"):
            PointingParams(receiver_angles_deg=angles)
    with pytest.raises(ValueError, match="receiver_angles_deg"):
        gym.make(ENV_ID, receiver_angles_deg=(0, 0, 0, 0), fov=1.5)
    PointingParams(receiver_angles_deg=(0.0, 0.001, 0.002, 0.003))  # close but distinct: allowed


def test_nearly_co_located_receivers_run_200_steps():
    """The reproducer (with distinct angles, equal ones are refused): noisy near-parallel lines
    of sight crossed at the receivers and the tracker jumped onto one, crashing step 13."""
    venv = gym.make_vec(
        ENV_ID,
        num_envs=64,
        vectorization_mode="vector_entry_point",
        receiver_angles_deg=(0, 0.001, 0.002, 0.003),
        fov=1.5,
    )
    venv.reset(seed=0)
    space = venv.unwrapped.single_observation_space
    for _ in range(200):
        obs, reward, _, _, info = venv.step(np.zeros((64, 8), dtype=np.float32))
        _check(space, obs, reward)
        assert np.all(np.isfinite(info["position_error"]))
    venv.close()


def test_fixes_behind_or_on_a_receiver_are_not_trusted():
    """Two receivers 1 mm apart see a drone 100 m away: the noisy lines of sight cross within a
    few metres of them or behind them, so no fix reaches the track near the receivers."""
    params = PointingParams(n_receivers=2, receiver_angles_deg=(0.0, 0.001), n_drones=1, fov=1.0)
    drone = np.array([[[0.0, 40.0, 150.0]]])
    az, el = _aim(params, drone[0, 0])
    rng = np.random.default_rng(4)
    state = core.start(params, np.repeat(drone, 256, 0), np.zeros((256, 1, 3)),
                       np.repeat(az, 256, 0), np.repeat(el, 256, 0), rng)  # fmt: skip
    new, reward, _ = core.step(params, state, np.zeros((256, 4)), rng)
    assert new.seen.all() and np.all(np.isfinite(reward))
    ranges = np.linalg.norm(new.track.position[:, 0, None] - params.receiver_positions, axis=-1)
    assert np.all(np.isfinite(new.track.x)) and ranges.min() > 1e-2
    assert not new.fixed.all()  # some fixes fell behind the receivers and were refused


def test_a_drone_flying_through_a_receiver_steps_without_error():
    """Receiver 0 stands at (0, 0, 50); drone 0 flies along the Z axis through it at 10 m/s and
    is exactly on it after one step (52 − 10·0.2 = 50). The receiver does not see it there; the
    others do and the reward stays finite."""
    params = PointingParams(fov=1.2)
    o = params.receiver_positions
    assert np.array_equal(o[0], [0.0, 0.0, 50.0])
    p = np.array([[[0.0, 0.0, 52.0], [60.0, 40.0, 90.0]]])
    v = np.array([[[0.0, 0.0, -10.0], [1.0, 0.0, -2.0]]])
    az, el = _aim(params, [0.0, 0.0, 0.0])  # every receiver looks at the circle centre
    rng = np.random.default_rng(5)
    state = core.start(params, p, v, az, el, rng)
    on_receiver = 0
    for _ in range(12):
        state, reward, _ = core.step(params, state, np.zeros(8), rng)
        _check(gym.spaces.Box(-10, 10, (params.obs_dim,)), core.observe(params, state), reward)
        _, r = core.lines_of_sight(params, state.drone_position)
        if r[0, 0, 0] == 0.0:
            on_receiver += 1
            assert not state.seen[0, 0, 0] and state.seen[0, 1:, 0].any()
        assert np.all(np.isfinite(state.track.x)) and np.all(
            np.isfinite(state.bound) | ~state.fixed
        )
    assert on_receiver == 1
    info = core.info(params, state)
    assert all(np.all(np.isfinite(value)) for value in info.values())


def test_a_prediction_on_a_receiver_is_observed_and_followed_finitely():
    """The tracker's prediction exactly on receiver 0 (circle radius = length scale, so that the
    rules decode it exactly): zero pointing offset, finite observation, finite rule actions."""
    params = PointingParams(circle_radius=150.0, start_distance=(160.0, 200.0))
    state = core.reset(params, np.random.default_rng(6), 2)
    x = state.track.x.copy()
    x[:, 0, :3] = params.receiver_positions[0]
    x[:, 0, 3:] = 0.0
    state = dataclasses.replace(state, track=CVTrack(x, state.track.P))
    pred = core.predicted_track(params, state).position
    u, r = core.lines_of_sight(params, pred)
    assert np.all(r[:, 0, 0] == 0.0) and np.all(u[:, 0, 0] == 0.0)
    offsets = core.pointing_offsets(params, state.azimuth, state.elevation, pred)
    np.testing.assert_array_equal(offsets[:, 0, 0], 0.0)
    obs = core.observe(params, state)
    _check(gym.spaces.Box(-10, 10, (params.obs_dim,)), obs, np.zeros(1))
    decoded = core.split_observation(params, obs)[2][:, 0, :3] * params.length_scale
    np.testing.assert_array_equal(decoded, np.broadcast_to(params.receiver_positions[0], (2, 3)))
    for rule in (HoldStill(params), TrackNearest(params), OrthogonalPairs(params),
                 GreedyPointing(params)):  # fmt: skip
        action, _ = rule.predict(obs)
        assert np.all(np.isfinite(action)) and np.all(np.abs(action) <= 1.0)
        _, reward, _ = core.step(params, state, action, np.random.default_rng(7))
        assert np.all(np.isfinite(reward))


def test_perturbing_a_zero_line_of_sight_gives_zero_and_keeps_the_stream():
    rng_a, rng_b = np.random.default_rng(8), np.random.default_rng(8)
    u = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 0.0], [0.6, 0.8, 0.0]])
    got = perturb_directions(u, 1e-2, rng_a)
    want = perturb_directions(np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.6, 0.8, 0.0]]),
                              1e-2, rng_b)  # fmt: skip
    np.testing.assert_array_equal(got[1], 0.0)
    np.testing.assert_array_equal(got[[0, 2]], want[[0, 2]])
    np.testing.assert_array_equal(perturb_directions(np.zeros((2, 3)), 0.0, rng_a), 0.0)
    with pytest.raises(ValueError, match="a: direction vectors must have unit length"):
        perturb_directions(np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 2.0]]), 1e-2, rng_a)
    with pytest.raises(ValueError, match="a: contains NaN"):
        perturb_directions(np.array([[0.0, 0.0, 0.0], [0.0, np.nan, 1.0]]), 1e-2, rng_a)


def test_a_cue_on_a_receiver_keeps_the_initial_pointing():
    """The cued start aims receiver k at its cue; a cue exactly on the receiver has no
    direction, and the receiver keeps its random draw."""
    params = PointingParams(n_drones=1)
    points = np.array([[[10.0, 40.0, 120.0]] * 4])
    points[0, 2] = params.receiver_positions[2]
    az0, el0 = np.full((1, 4), 0.7), np.full((1, 4), 0.1)
    az, el = core.aim_at(params, points, az0, el0)
    assert az[0, 2] == 0.7 and el[0, 2] == 0.1
    u, _ = core.lines_of_sight(params, points[:, :1])
    want_az, want_el = angles_from_unit(u[:, :, 0])
    np.testing.assert_array_equal(np.delete(az, 2), np.delete(want_az, 2))
    np.testing.assert_array_equal(np.delete(el, 2), np.delete(want_el, 2))


# --- seeded sweep of extreme settings -----------------------------------------------------------

#: two extreme levels of every swept field
LEVELS: dict[str, tuple[object, object]] = {
    "sigma_ang": (0.0, 1e-1),
    "process_noise": (0.0, 100.0),
    "fov": (1e-4, 1.5),
    "n_receivers": (2, 6),
    "n_drones": (1, 4),  # 4⁶ = 4096 = MAX_ASSIGNMENTS: the assignment rules still run
    "dt": (0.01, 2.0),
}
#: a strength-3 covering array: every combination of levels of any three fields appears in some
#: row (checked below), plus the all-low and all-high corners
ROWS = [
    (1, 1, 0, 1, 1, 0), (0, 1, 1, 0, 1, 1), (1, 0, 0, 0, 0, 1), (0, 0, 1, 1, 0, 0),
    (0, 1, 0, 0, 0, 0), (1, 0, 1, 0, 1, 0), (0, 0, 0, 1, 1, 1), (1, 1, 1, 1, 0, 1),
    (0, 0, 0, 0, 1, 0), (0, 1, 0, 1, 0, 1), (1, 0, 1, 1, 1, 1), (1, 1, 1, 0, 0, 0),
    (0, 0, 0, 0, 0, 0), (1, 1, 1, 1, 1, 1),
]  # fmt: skip
SWEEP = [
    PointingParams(**{name: LEVELS[name][level] for name, level in zip(LEVELS, row, strict=True)})
    for row in ROWS
]


def test_the_sweep_covers_every_three_way_combination_of_levels():
    k = len(LEVELS)
    for cols in itertools.combinations(range(k), 3):
        seen = {tuple(row[c] for c in cols) for row in ROWS}
        assert len(seen) == 8, cols


@pytest.mark.parametrize("kind", ["random", "extreme"])
@pytest.mark.parametrize("index", range(len(SWEEP)))
def test_extreme_settings_give_finite_rewards_and_observations_in_the_space(index, kind):
    params = SWEEP[index]
    venv = StereoPointingVectorEnv(num_envs=16, params=params)
    venv.action_space.seed(index)
    rng = np.random.default_rng(index)
    obs, _ = venv.reset(seed=index)
    space = venv.single_observation_space
    _check(space, obs, np.zeros(16))
    shape = venv.action_space.shape
    for _ in range(100):
        if kind == "random":
            action = venv.action_space.sample()
        else:  # ±1e6, clipped to ±1
            action = rng.choice(np.array([-1e6, 1e6], dtype=np.float32), size=shape)
        obs, reward, terminated, _, info = venv.step(action)
        _check(space, obs, reward)
        assert not terminated.any()
        assert all(np.all(np.isfinite(info[key])) for key in ("position_error", "views"))
    venv.close()


@pytest.mark.parametrize("index", [0, 7, 12, 13])
def test_rules_drive_extreme_settings_finitely(index):
    params = SWEEP[index]
    venv = StereoPointingVectorEnv(num_envs=4, params=params)
    obs, _ = venv.reset(seed=index)
    for rule in (TrackNearest(params), OrthogonalPairs(params), GreedyPointing(params)):
        for _ in range(25):
            action, _ = rule.predict(obs)
            assert np.all(np.isfinite(action)) and np.all(np.abs(action) <= 1.0)
            obs, reward, _, _, _ = venv.step(action)
            _check(venv.single_observation_space, obs, reward)
    venv.close()
