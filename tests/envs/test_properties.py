"""Property-based: params drawn across their ranges — tiny and huge noise, long steps, few and
many receivers, drones or platforms — give finite observations inside the space and finite
rewards for a few hundred steps, or a clear error naming the field at construction."""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sensorgym.envs import (
    GimbalParams,
    ManeuverParams,
    PlacementParams,
    PointingParams,
    ScanningParams,
)
from sensorgym.envs.worlds.platform import PlatformWorldParams

STEPS = 200
BATCH = 4
SETTINGS = settings(
    max_examples=12, deadline=None, derandomize=True, suppress_health_check=list(HealthCheck)
)


def log_uniform(lo: float, hi: float) -> st.SearchStrategy[float]:
    return st.floats(np.log10(lo), np.log10(hi)).map(lambda e: float(10.0**e))


def span(lo: float, hi: float) -> st.SearchStrategy[tuple[float, float]]:
    return st.tuples(st.floats(lo, hi), st.floats(lo, hi)).map(lambda t: (min(t), max(t)))


def _runs_finite_or_names_a_field(env_id: str, make_params) -> None:
    try:
        params = make_params()
    except (ValueError, TypeError) as exc:
        fields = {f.name for f in dataclasses.fields(ManeuverParams)}
        fields |= {f.name for f in dataclasses.fields(PointingParams)}
        fields |= {f.name for f in dataclasses.fields(PlacementParams)}
        fields |= {f.name for f in dataclasses.fields(ScanningParams)}
        fields |= {f.name for f in dataclasses.fields(PlatformWorldParams)}
        fields |= {f.name for f in dataclasses.fields(GimbalParams)}
        named = str(exc).split(":")[0].split("/")[0].split(".")[-1].split(" ")[0]
        assert named in fields or any(f in str(exc) for f in fields), str(exc)
        return
    env = gym.make_vec(env_id, BATCH, vectorization_mode="vector_entry_point", params=params)
    obs, _ = env.reset(seed=0)
    rng = np.random.default_rng(0)
    for _ in range(STEPS):
        action = rng.uniform(-1.5, 1.5, env.action_space.shape).astype(np.float32)
        obs, reward, *_ = env.step(action)
        assert np.all(np.isfinite(reward)), reward
        assert env.observation_space.contains(obs)


@SETTINGS
@given(
    sigma=log_uniform(1e-8, 1.0),
    dt=log_uniform(1.0, 1e5),
    q=st.one_of(st.just(0.0), log_uniform(1e-6, 1.0)),
    turn=st.floats(0.0, 0.1),
    ranges=span(100.0, 50_000.0),
    speeds=span(0.0, 30.0),
    platforms=st.integers(1, 3),
    members=st.integers(1, 12),
    metric=st.sampled_from(["position", "relative_range"]),
    min_range=st.floats(0.0, 2_000.0),
)
def test_bearings_maneuver_params(
    sigma, dt, q, turn, ranges, speeds, platforms, members, metric, min_range
):
    def make():
        world = PlatformWorldParams(dt=dt, sigma_bearing=sigma, q_tilde=q, max_turn_rate=turn)
        return ManeuverParams(
            world=world,
            initial_range=ranges,
            target_speed=speeds,
            platforms=platforms,
            bank_members=members,
            metric=metric,
            min_range=min_range,
        )

    _runs_finite_or_names_a_field("sensorgym/BearingsManeuver-v0", make)


@SETTINGS
@given(
    n=st.integers(2, 6),
    m=st.integers(1, 3),
    fov=st.floats(1e-3, 1.5),
    sigma=st.one_of(st.just(0.0), log_uniform(1e-7, 0.1)),
    q=st.one_of(st.just(0.0), log_uniform(1e-4, 100.0)),
    dt=log_uniform(0.01, 2.0),
    radius=log_uniform(1.0, 200.0),
    cued=st.booleans(),
)
def test_stereo_pointing_params(n, m, fov, sigma, q, dt, radius, cued):
    def make():
        return PointingParams(
            n_receivers=n,
            n_drones=m,
            fov=fov,
            sigma_ang=sigma,
            process_noise=q,
            dt=dt,
            circle_radius=radius,
            cued_start=cued,
        )

    _runs_finite_or_names_a_field("sensorgym/StereoPointing-v0", make)


@SETTINGS
@given(
    delays=st.lists(st.floats(0.0, 1.0), min_size=3, max_size=5),
    period=log_uniform(0.1, 5.0),
    sigma=st.one_of(st.just(0.0), log_uniform(1e-7, 0.1)),
    speed=log_uniform(0.1, 50.0),
    arena=log_uniform(10.0, 1_000.0),
    altitude=span(1.0, 200.0),
    drone_speed=span(0.0, 40.0),
)
def test_stereo_placement_params(delays, period, sigma, speed, arena, altitude, drone_speed):
    def make():
        return PlacementParams(
            delays=tuple(d * period for d in delays),
            period=period,
            sigma_ang=sigma,
            max_speed=speed,
            arena_radius=arena,
            cluster_radius=min(15.0, arena),
            start_altitude=altitude,
            drone_speed=drone_speed,
        )

    _runs_finite_or_names_a_field("sensorgym/StereoPlacement-v0", make)


@SETTINGS
@given(
    kappa=st.one_of(st.just(0.0), log_uniform(1e-7, 0.1)),
    position_sigma=st.one_of(st.just(0.0), log_uniform(1e-4, 10.0)),
    period=log_uniform(0.05, 20.0),
    drones=st.integers(1, 6),
    clutter=st.one_of(st.just(0.0), log_uniform(0.01, 5.0)),
    speed=span(0.0, 60.0),
    radius=log_uniform(5.0, 2_000.0),
    tracker=st.sampled_from(["proposed", "alternative"]),
)
def test_stereo_scanning_params(kappa, position_sigma, period, drones, clutter, speed, radius,
                                tracker):  # fmt: skip
    def make():
        return ScanningParams(
            noise_per_width=kappa,
            position_sigma=position_sigma,
            period=period,
            sweep_time=0.4 * period,
            scan_offsets=(0.0, 0.25 * period, 0.5 * period),
            n_drones=drones,
            close_drones=min(1, drones - 1),
            late_drones=min(1, drones),
            clutter_rate=clutter,
            drone_speed=speed,
            circle_radius=radius,
            tracker=tracker,
        )

    _runs_finite_or_names_a_field("sensorgym/StereoScanning-v0", make)


@SETTINGS
@given(
    fov=log_uniform(1e-3, 0.5),
    rate=log_uniform(0.01, 5.0),
    noise=st.one_of(st.just(0.0), log_uniform(1e-7, 1e-2)),
    contrast=st.lists(log_uniform(0.1, 100.0), min_size=1, max_size=4),
    ranges=span(200.0, 30_000.0),
    speeds=span(1.0, 600.0),
    turn=span(0.0, 0.5),
    window=st.integers(1, 30).map(lambda n: 2 * n),
    gimbals=st.integers(1, 3),
    sector=st.one_of(st.just(None), span(-np.pi, np.pi)),
)
def test_gimbal_tracking_params(
    fov, rate, noise, contrast, ranges, speeds, turn, window, gimbals, sector
):
    def make():
        n = len(contrast)
        return GimbalParams(
            n_gimbals=gimbals,
            gimbal_sectors=() if sector is None else (sector,) * gimbals,
            field_of_view=fov,
            max_rate=rate,
            sensor_noise=noise,
            channel_contrast=tuple(contrast),
            channel_noise=(1.0,) * n,
            lose_probability=(0.05,) * n,
            return_probability=(0.2,) * n,
            aspect_change_probability=(0.02,) * n,
            start_range=ranges,
            target_speed=speeds,
            turn_rate=turn,
            predictor_window=window,
        )

    _runs_finite_or_names_a_field("sensorgym/GimbalTracking-v0", make)
