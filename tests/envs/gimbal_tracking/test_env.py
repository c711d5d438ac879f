"""sensorgym/GimbalTracking-v0: API conformance, determinism, noiseless geometry, bad input,
refused params, the rules, and paper 001's scenario through the env (issue 40)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from pettingzoo.test import parallel_api_test, parallel_seed_test
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import sensorgym.envs  # noqa: F401  (registers the ids)
from sensorgym.agents.gimbal_tracking import KalmanServo, Paper001Servo, rate_action
from sensorgym.agents.registry import RULES
from sensorgym.envs import gimbal_tracking
from sensorgym.envs.gimbal_tracking import reference
from sensorgym.envs.gimbal_tracking import simulation as core
from sensorgym.envs.gimbal_tracking.simulation import GimbalParams
from sensorgym.trackers.geometry import unit_from_zup_angles

ENV_ID = "sensorgym/GimbalTracking-v0"
#: a quiet world: no carrier motion, no turn, no occlusion, no view changes
CALM = {
    "roll_amplitude": (),
    "roll_period": (),
    "pitch_amplitude": (),
    "pitch_period": (),
    "yaw_amplitude": (),
    "yaw_period": (),
    "turn_rate": (0.0, 0.0),
    "occlusion_length": (0, 0),
    "lose_probability": (0.0, 0.0),
    "aspect_change_probability": (0.0, 0.0),
}


def _episode(params: GimbalParams, rule, batch: int, steps: int, seed: int):
    """Roll ``batch`` scenarios of the core for ``steps`` frames under ``rule``; the infos of
    every frame ``(steps, B)`` and the return of each scenario up to its termination."""
    rng = np.random.default_rng(seed)
    state = core.reset(params, rng, batch)
    alive, total, infos, memory = np.ones(batch, bool), np.zeros(batch), [], None
    for _ in range(steps):
        action, memory = rule.predict(core.observe(params, state), memory)
        state, reward, terminated = core.step(params, state, action[:, None, :], rng)
        total += np.where(alive, reward, 0.0)
        alive &= ~terminated
        infos.append(core.info(params, state))
    return {k: np.array([i[k] for i in infos]) for k in infos[0]}, total, alive


# --- API conformance ---------------------------------------------------------------------------


def test_gymnasium_and_sb3_checkers_pass():
    check_env(gym.make(ENV_ID, render_mode="rgb_array").unwrapped, skip_render_check=False)
    sb3_check_env(gym.make(ENV_ID), warn=True)


def test_pettingzoo_api_and_seed_tests_pass():
    parallel_api_test(gimbal_tracking.parallel_env(max_episode_steps=40), num_cycles=60)
    parallel_seed_test(lambda: gimbal_tracking.parallel_env(max_episode_steps=40), num_cycles=60)


def test_spaces_and_registration():
    env = gym.make(ENV_ID)
    assert env.action_space.shape == (2,)
    assert env.observation_space.shape == (GimbalParams().obs_dim,) == (23,)
    assert env.spec.max_episode_steps == 500
    three = gym.make(
        ENV_ID,
        channel_contrast=(4.0, 3.0, 2.0),
        channel_noise=(1.0, 1.0, 1.0),
        lose_probability=(0.02, 0.02, 0.02),
        return_probability=(0.2, 0.2, 0.2),
        aspect_change_probability=(0.0, 0.0, 0.0),
    )
    assert three.observation_space.shape == (24,)


def test_same_seed_same_episode_and_the_vector_env_of_one_is_the_single_env():
    def roll(make):
        env = make()
        obs, _ = env.reset(seed=5)
        rng = np.random.default_rng(0)
        out = [obs]
        for _ in range(30):
            obs, reward, *_ = env.step(
                rng.uniform(-1, 1, env.action_space.shape).astype(np.float32)
            )
            out += [obs, np.atleast_1d(reward)]
        return out

    a = roll(lambda: gym.make(ENV_ID))
    b = roll(lambda: gym.make(ENV_ID))
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x, y)
    v = roll(lambda: gym.make_vec(ENV_ID, num_envs=1, vectorization_mode="vector_entry_point"))
    for x, y in zip(a, v, strict=True):
        np.testing.assert_array_equal(np.asarray(x).reshape(-1), np.asarray(y).reshape(-1))
    c = gym.make(ENV_ID)
    assert not np.array_equal(c.reset(seed=6)[0], a[0])


def test_render_draws_a_frame():
    env = gym.make(ENV_ID, render_mode="rgb_array")
    env.reset(seed=0)
    env.step(env.action_space.sample())
    frame = env.render()
    assert frame.ndim == 3 and frame.shape[2] == 3 and frame.dtype == np.uint8


# --- bad input ---------------------------------------------------------------------------------


def test_bad_actions_raise_a_clear_error_and_large_ones_are_clipped():
    env = gym.make(ENV_ID)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="NaN"):
        env.step(np.array([np.nan, 0.0], np.float32))
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros(3, np.float32))
    params = GimbalParams()
    state = core.reset(params, np.random.default_rng(0), 2)
    with pytest.raises(ValueError, match="NaN or infinite"):
        core.step(
            params, state, np.array([[[np.inf, 0.0]], [[0.0, 0.0]]]), np.random.default_rng(0)
        )
    with pytest.raises(ValueError, match="expected 4 values"):
        core.step(params, state, np.zeros((2, 3)), np.random.default_rng(0))
    big, _, _ = core.step(params, state, np.full((2, 1, 2), 50.0), np.random.default_rng(1))
    one, _, _ = core.step(params, state, np.full((2, 1, 2), 1.0), np.random.default_rng(1))
    np.testing.assert_array_equal(big.gimbal_angles, one.gimbal_angles)


@pytest.mark.parametrize(
    "fields, name",
    [
        ({"field_of_view": 0.0}, "field_of_view"),
        ({"max_rate": -1.0}, "max_rate"),
        ({"roll_period": (8.0,)}, "roll_period"),
        ({"channel_noise": (1.0,)}, "channel_noise"),
        ({"lose_probability": (0.9, 0.05), "aspect_change_probability": (0.2, 0.02)}, "lose"),
        ({"predictor_window": 7}, "predictor_window"),
        ({"residual_correlation": 1.0}, "residual_correlation"),
        ({"occlusion_gap": (0, 5)}, "occlusion_gap"),
        ({"gate_pixels": True}, "gate_pixels"),
        ({"elevation_limits": (0.5, 0.2)}, "elevation_limits"),
    ],
)
def test_bad_params_are_refused_naming_the_field(fields, name):
    with pytest.raises((TypeError, ValueError), match=name):
        GimbalParams(**fields)


# --- geometry and the tracker ------------------------------------------------------------------


def test_frames_and_offsets_invert_each_other():
    rng = np.random.default_rng(0)
    attitude = rng.uniform(-0.2, 0.2, (50, 3))
    angles = np.stack([rng.uniform(-np.pi, np.pi, 50), rng.uniform(-1.2, 1.2, 50)], -1)
    level = reference.level_direction(angles, attitude)
    np.testing.assert_allclose(np.linalg.norm(level, axis=-1), 1.0, atol=1e-12)
    back = reference.body_angles(level, attitude)
    np.testing.assert_allclose(np.angle(np.exp(1j * (back[:, 0] - angles[:, 0]))), 0, atol=1e-12)
    np.testing.assert_allclose(back[:, 1], angles[:, 1], atol=1e-12)
    offsets = rng.uniform(-0.05, 0.05, (50, 2))
    seen = reference.from_tangent_offsets(angles, offsets)
    u = unit_from_zup_angles(seen[:, 0], seen[:, 1])
    np.testing.assert_allclose(reference.tangent_offsets(u, angles), offsets, atol=1e-12)
    # a zero attitude is no rotation
    np.testing.assert_allclose(reference.body_to_level(np.zeros(3)), np.eye(3), atol=1e-15)


def test_noiseless_tracking_recovers_the_line_of_sight_exactly():
    """No angle-sensor noise, (nearly) noiseless images, a straight target in view: paper 001's
    prediction is exact (theory §12.6 AT-6), the gate sits on the target, the fused offset is 0
    and the tracker's direction is the true one — through the carrier's motion too."""
    params = GimbalParams(
        sensor_noise=0.0,
        channel_noise=(1e-9, 1e-9),
        turn_rate=(0.0, 0.0),
        occlusion_length=(0, 0),
        lose_probability=(0.0, 0.0),
    )
    infos, _, alive = _episode(params, Paper001Servo(params), batch=6, steps=120, seed=3)
    assert alive.all() and infos["in_view"].all() and infos["detected"].all()
    assert np.max(np.abs(infos["estimate_error_azimuth"])) < 1e-9
    assert np.max(np.abs(infos["estimate_error_elevation"])) < 1e-9
    assert np.max(infos["los_error"]) < 1e-9


def test_a_loss_coasts_on_the_predictor_and_the_bound_grows():
    """Frames 20–49 occluded (info row = frame − 1); the channels never lose the target by
    themselves (lose probability 0): the tracker still declares the loss, since its view chain
    folds the occlusions in."""
    params = GimbalParams(**{**CALM, "occlusion_gap": (20, 20), "occlusion_length": (30, 30)})
    infos, _, _ = _episode(params, Paper001Servo(params), batch=4, steps=60, seed=1)
    occluded = infos["occluded"].astype(bool)
    assert occluded[19:49].all() and not occluded[:19].any() and not occluded[49:].any()
    assert not infos["detected"][19:49].any() and infos["detected"][:19].all()
    sigma = infos["sigma_los"]
    assert np.all(np.diff(sigma[19:49], axis=0) > 0.0)  # paper 004's variance grows: D = R²d + d₀
    assert np.all(sigma[59] < sigma[48])  # and shrinks once the target is seen again
    assert np.max(infos["los_error"][19:49]) < 1e-3  # paper 001's coast stays on the target


def test_out_of_view_gives_minus_r_and_ends_the_episode_after_the_limit():
    params = GimbalParams(reacquire_limit=5)
    env = gym.make(ENV_ID, params=params)
    env.reset(seed=0)
    rewards, terminated = [], False
    for _ in range(200):  # slew away at full rate: the target leaves the 1.5° field
        _, reward, terminated, _, info = env.step(np.array([1.0, 0.0], np.float32))
        rewards.append(reward)
        if terminated:
            break
    assert terminated and info["in_view"] == 0.0
    assert rewards[-6:] == [-params.reward_clip] * 6


# --- rules -------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", sorted(RULES[ENV_ID]))
def test_every_rule_runs_through_the_vector_env(name):
    venv = gym.make_vec(ENV_ID, num_envs=3, vectorization_mode="vector_entry_point")
    obs, _ = venv.reset(seed=0)
    rule = RULES[ENV_ID][name](venv.unwrapped.params, lambda: venv.unwrapped.simulator_state)
    state, start = None, np.ones(3, bool)
    for _ in range(20):
        action, state = rule.predict(obs, state, start)
        assert action.shape == (3, 2) and action.dtype == np.float32
        assert np.all(np.abs(action) <= 1.0)
        obs, _, term, trunc, _ = venv.step(action)
        start = term | trunc
    single, _ = rule.predict(obs[0])
    assert single.shape == (2,)


def test_the_servo_beats_holding_still_on_a_seeded_batch():
    params = GimbalParams()
    _, servo, servo_alive = _episode(params, Paper001Servo(params), batch=16, steps=200, seed=11)
    hold = RULES[ENV_ID]["hold-still"](params, None)
    _, still, still_alive = _episode(params, hold, batch=16, steps=200, seed=11)
    assert np.mean(servo) > np.mean(still) + 100.0
    assert servo_alive.sum() > still_alive.sum()


def test_rate_action_is_deadbeat_and_clipped():
    params = GimbalParams()
    T, w = params.frame_period, params.max_rate
    np.testing.assert_allclose(
        rate_action(params, np.array([[0.1 * w * T, -0.5 * w * T]])), [[0.1, -0.5]]
    )
    np.testing.assert_array_equal(rate_action(params, np.array([[1.0, -1.0]])), [[1.0, -1.0]])
    with pytest.raises(ValueError, match="measurement_std"):
        KalmanServo(params, measurement_std=0.0)


# --- paper 001 through the env -----------------------------------------------------------------


@pytest.mark.slow
def test_paper_001_scenario_predicts_like_the_reproduction():
    """Theory §8.7: X₀ = −5700 m, Y₀ = 1000 m, Z₀ = 500 m, 5.7 m/frame, 30° climb, σ = 0.001°,
    N = 50, memory 10, the image lost after frame 400. The env's predictor, fed its fused
    directions, errs k frames into the loss as ``sensorgym reproduce paper001``'s A-B-C does,
    within Monte Carlo error (the images are near noiseless, so the angle sensors' σ rules)."""
    from sensorgym.reproduce.experiments.paper001 import reproduce

    runs, loss = 300, 400
    params = GimbalParams(
        **{**CALM, "occlusion_gap": (loss + 1, loss + 1), "occlusion_length": (200, 200)},
        channel_noise=(0.01, 0.01),
        sensor_noise=float(np.deg2rad(0.001)),
    )
    speed = 5.7 / params.frame_period
    beta = np.deg2rad(30.0)
    p = np.tile([-5700.0, 1000.0, 500.0], (runs, 1))
    v = np.tile([speed * np.cos(beta), 0.0, speed * np.sin(beta)], (runs, 1))
    rng = np.random.default_rng(2)
    state = core.start(params, p, v, rng)
    servo = Paper001Servo(params)
    horizons = (1, 25, 100)
    errors = {}
    for frame in range(1, loss + max(horizons) + 1):
        action, _ = servo.predict(core.observe(params, state))
        state, _, _ = core.step(params, state, action[:, None, :], rng)
        if frame - loss in horizons:
            info = core.info(params, state)
            errors[frame - loss] = (
                info["estimate_error_azimuth"],
                info["estimate_error_elevation"],
            )
        if frame == loss:
            assert state.detected.all() and state.in_view.all()
    assert not state.detected.any()
    ref = reproduce(runs=runs, seed=0, loss_frame=loss, gate=max(horizons), turn_rates_deg=())
    abc = ref["errors"]["abc"]
    for k in horizons:
        for ours, key in zip(errors[k], ("azimuth", "elevation"), strict=True):
            rms_env = np.degrees(np.sqrt(np.mean(ours**2)))
            rms_rep = abc[f"rms_{key}_deg"][k - 1]
            # RMS of n Gaussian errors: relative standard error ≈ 1/√(2n), each side
            tol = 4.0 * np.hypot(rms_env, rms_rep) / np.sqrt(2 * runs)
            assert abs(rms_env - rms_rep) < tol, (k, key, rms_env, rms_rep)


def test_a_long_loss_moves_the_gate_to_the_boresight():
    """After ``search_after`` frames without detection the gate searches at the boresight
    (frames 10–49 occluded, search from frame 15): pointed at the target (truth-servo), the
    tracker re-acquires it on the first frame the occlusion is over."""
    params = GimbalParams(
        **{**CALM, "occlusion_gap": (10, 10), "occlusion_length": (40, 40)}, search_after=5
    )
    rng = np.random.default_rng(4)
    state = core.reset(params, rng, 3)
    truth = RULES[ENV_ID]["truth-servo"](params, lambda: state)
    for frame in range(1, 51):
        before = state
        action, _ = truth.predict(core.observe(params, state))
        state, _, _ = core.step(params, state, action[:, None, :], rng)
        attitude, _ = core.carrier_attitude(params, state)
        axis = reference.level_direction(state.gimbal_angles[:, 0], attitude)
        on_axis = reference.tangent_offsets(axis, state.reference[:, 0])
        if 16 <= frame <= 49:  # searching: the gate on the gimbal's axis, not the prediction
            assert np.all(before.since_detection >= params.search_after)
            np.testing.assert_allclose(on_axis, 0.0, atol=1e-12)
            assert np.all(np.abs(state.reference[:, 0] - before.predicted).max(-1) > 0.0)
        if frame <= 14:  # not yet: the gate on paper 001's prediction
            np.testing.assert_array_equal(state.reference[:, 0], before.predicted)
    assert state.detected.all() and not state.occluded.any()


def test_more_weak_channels_track_better_than_one():
    """Paper 004's claim 4 (theory §9.5), qualitatively, through the env: channels each too weak
    to hold the target alone (contrast 1.2: q ≈ 3.4, the view lost 10 % of the frames) hold it
    together — more frames detected, a smaller σ_LOS."""

    def run(n: int) -> tuple[float, float]:
        params = GimbalParams(
            **{**CALM, "lose_probability": (0.1,) * n, "aspect_change_probability": (0.0,) * n},
            channel_contrast=(1.2,) * n,
            channel_noise=(1.0,) * n,
            return_probability=(0.3,) * n,
        )
        infos, _, _ = _episode(params, Paper001Servo(params), batch=16, steps=150, seed=8)
        return float(infos["detected"].mean()), float(np.median(infos["sigma_los"]))

    one, three = run(1), run(3)
    assert three[0] > one[0] + 0.05
    assert three[1] < 0.8 * one[1]
