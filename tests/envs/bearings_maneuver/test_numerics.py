"""BearingsManeuver-v0 across scales (issue 10, defects 2 and 7): the bound is carried in
square-root covariance form, so rewards are finite for bearing noise from 1e-8 to 1 rad and
steps up to 1e5 s, equal the former information-form rewards on well-scaled defaults, and the
truth plans on the very same recursion; every params field is checked by name."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import sensorgym.envs  # noqa: F401  (registers the ids)
from sensorgym.agents.bearings_maneuver import TruthLookahead
from sensorgym.envs.bearings_maneuver import simulation as core
from sensorgym.envs.bearings_maneuver.simulation import ManeuverParams
from sensorgym.envs.worlds.platform import PlatformWorldParams
from sensorgym.trackers.bearings.crlb import (
    bearing_information,
    crlb,
    position_rms_bound,
    predict_information,
    relative_range_bound,
)
from sensorgym.trackers.bearings.filters import range_bank_prior

ENV_ID = "sensorgym/BearingsManeuver-v0"


def _params(sigma: float = np.deg2rad(1.5), dt: float = 60.0, **kw) -> ManeuverParams:
    return ManeuverParams(world=PlatformWorldParams(sigma_bearing=sigma, dt=dt), **kw)


def test_issue_reproducers_give_finite_rewards():
    """σ = 1e-6 rad at seed 3 gave [0.007, −inf, nan]; σ = 1e-8 at seed 59 failed at reset."""
    env = gym.make(ENV_ID, params=_params(1e-6))
    _, info = env.reset(seed=3)
    first, total = info["bound"], 0.0
    for _ in range(30):
        _, r, term, trunc, info = env.step(np.zeros(2, np.float32))
        assert np.isfinite(r)
        total += r
    assert not term and trunc
    assert total == pytest.approx(np.log(first / info["bound"]), rel=1e-9, abs=1e-9)
    env = gym.make(ENV_ID, params=_params(1e-8))
    obs, info = env.reset(seed=59)
    assert np.all(np.isfinite(obs)) and np.isfinite(info["bound"]) and info["bound"] > 0.0


@pytest.mark.parametrize("sigma", [1e-8, 1e-6, 1e-3, 0.5])
@pytest.mark.parametrize("dt", [1.0, 60.0, 1e5])
def test_sweep_of_scales_gives_finite_rewards_inside_the_space(sigma, dt):
    """16 scenarios, 60 steps of seeded random actions (autoresets included): every reward is
    finite and every observation inside the observation space (RuntimeWarnings are errors)."""
    env = gym.make_vec(
        ENV_ID, 16, vectorization_mode="vector_entry_point", params=_params(sigma, dt)
    )
    obs, _ = env.reset(seed=11)
    assert env.observation_space.contains(obs)
    rng = np.random.default_rng(12)
    for _ in range(60):
        action = rng.uniform(-1.0, 1.0, env.action_space.shape).astype(np.float32)
        obs, reward, _, _, info = env.step(action)
        assert np.all(np.isfinite(reward)), reward
        assert env.observation_space.contains(obs)
        assert np.all(np.isfinite(info["bound"])) and np.all(info["bound"] > 0.0)


def test_many_badly_scaled_steps_stay_finite_and_telescope():
    """σ = 1e-7 rad (formerly 480 non-finite rewards in 5,982) and 1e5-s steps (8,000 in
    64,000): 64 scenarios × 30 steps each, rewards finite and summing to ln(m_0/m_T)."""
    for params in (_params(1e-7), _params(dt=1e5), _params(1e-8, 1e5, metric="relative_range")):
        rng = np.random.default_rng(5)
        state = core.reset(params, rng, 64)
        m0, total, ended = state.accuracy, np.zeros(64), np.zeros(64, bool)
        for a in np.random.default_rng(6).uniform(-1, 1, (30, 64, 2)):
            state, reward, term = core.step(params, state, a, rng)
            assert np.all(np.isfinite(reward))
            total += np.where(ended, 0.0, reward + params.close_penalty * term)
            ended |= term
        live = ~ended
        np.testing.assert_allclose(
            total[live], np.log(m0[live] / state.accuracy[live]), rtol=1e-9, atol=1e-9
        )


def _prior_information(params: ManeuverParams, state: core.ManeuverState) -> np.ndarray:
    """``J_0 = P_prior⁻¹ + Σ_{k≥2} I_k(x_0)`` the former way: the tracker's prior from platform
    1's first bearing, rebuilt with the arguments ``reset`` uses, inverted."""
    w = params.world
    speed_mean, speed_sigma = params.prior_speed_moments
    bank = range_bank_prior(
        state.bearing[:, 0], w.sigma_bearing, state.platform_position[:, 0], 0.0,
        range_min=params.prior_ranges[0], range_max=params.prior_ranges[1],
        n_members=params.bank_members, speed_mean=speed_mean, speed_sigma=speed_sigma,
        course_mean=state.bearing[:, 0], course_sigma=np.pi / np.sqrt(3.0),
        course_distribution="uniform", range_density="uniform",
    )  # fmt: skip
    J = np.linalg.inv(bank.estimate().P)
    others = state.platform_position[:, 1:]
    return J + bearing_information(state.target[:, None], others, w.sigma_bearing).sum(1)


@pytest.mark.parametrize(
    "params",
    [
        ManeuverParams(),
        ManeuverParams(metric="relative_range"),
        ManeuverParams(world=PlatformWorldParams(q_tilde=1e-4)),
        ManeuverParams(platforms=2),
    ],
    ids=["default", "relative_range", "q_tilde", "two_platforms"],
)
def test_square_root_bound_equals_the_former_information_form_on_defaults(params):
    """On well-scaled defaults the square-root recursion is the former information recursion
    ``J_{k+1} = (I + J̄ Q)⁻¹ J̄ + Σ Hᵀ H/σ²``, ``J_0 = P_prior⁻¹ + Σ_{k≥2} I_k``, read through
    the former ``crlb``: bounds agree to 1e-9 relative over whole episodes."""
    rng = np.random.default_rng(21)
    B, K, w = 16, params.platforms, params.world
    state = core.reset(params, rng, B)
    J = _prior_information(params, state)

    def old_accuracy(J, s):
        P = crlb(J)
        if params.metric == "position":
            return position_rms_bound(P)
        return relative_range_bound(P, s.target[:, :2], s.platform_position[:, 0])

    np.testing.assert_allclose(state.accuracy, old_accuracy(J, state), rtol=1e-9)
    for a in np.random.default_rng(22).uniform(-1, 1, (30, B, K, 2)):
        old = state
        state, reward, term = core.step(params, state, a, rng)
        J = predict_information(J, w.dt, w.q_tilde) + bearing_information(
            state.target[:, None], state.platform_position, w.sigma_bearing
        ).sum(1)
        np.testing.assert_allclose(state.accuracy, old_accuracy(J, state), rtol=1e-9)
        old_reward = np.log(old.accuracy) - np.log(old_accuracy(J, state))
        np.testing.assert_allclose(reward + params.close_penalty * term, old_reward, atol=1e-8)


def test_truth_lookahead_plans_on_the_env_recursion_at_extreme_scales():
    """Horizon 1: the truth lookahead's plan bounds are the env's next bounds for every candidate, also
    where the information form failed (σ = 1e-8 rad, 1e5-s steps)."""
    for params in (_params(1e-8), _params(dt=1e5)):
        state = core.reset(params, np.random.default_rng(31), 4)
        truth = TruthLookahead(lambda s=state: s, params, horizon=1, safety=0.0)
        plans = truth.plan_bounds(state)
        nxt = np.stack(
            [
                core.step(params, state, np.tile(c, (4, 1)), np.random.default_rng(0))[0].accuracy
                for c in truth.candidates()
            ],
            axis=1,
        )
        assert np.all(np.isfinite(plans))
        np.testing.assert_allclose(plans, nxt, rtol=1e-9)


@pytest.mark.parametrize(
    "kw, error, name",
    [
        ({"prior_speed": (np.inf, 1.0)}, ValueError, "prior_speed"),
        ({"prior_speed": (5.0, np.nan)}, ValueError, "prior_speed"),
        ({"prior_speed": (5.0, -1.0)}, ValueError, "prior_speed"),
        ({"prior_speed": 5.0}, TypeError, "prior_speed"),
        ({"initial_range": (1_000.0, 2_000.0, 3_000.0)}, TypeError, "initial_range"),
        ({"initial_range": (np.nan, 2_000.0)}, ValueError, "initial_range"),
        ({"target_speed": ("slow", "fast")}, TypeError, "target_speed"),
        ({"target_speed": (1.0, np.inf)}, ValueError, "target_speed"),
        ({"bank_ranges": (1_000.0, np.inf)}, ValueError, "bank_ranges"),
        ({"bank_ranges": (3_000.0, 3_000.0)}, ValueError, "bank_ranges"),
        ({"bank_ranges": "wide"}, TypeError, "bank_ranges"),
        ({"initial_platform_speed": np.nan}, ValueError, "initial_platform_speed"),
        ({"formation_radius": np.inf}, ValueError, "formation_radius"),
        ({"min_range": "far"}, TypeError, "min_range"),
        ({"close_penalty": np.nan}, ValueError, "close_penalty"),
        ({"world": None}, TypeError, "world"),
    ],
)
def test_params_fields_are_checked_by_name(kw, error, name):
    with pytest.raises(error, match=name):
        ManeuverParams(**kw)


def test_prior_defaults_follow_the_generator():
    p = ManeuverParams()
    assert p.prior_ranges == p.initial_range == (5_000.0, 20_000.0)
    assert p.prior_speed_moments == pytest.approx((5.0, 6.0 / np.sqrt(12.0)))
    given = ManeuverParams(bank_ranges=(1_000.0, 30_000.0), prior_speed=(4.0, 2.0))
    assert given.prior_ranges == (1_000.0, 30_000.0) and given.prior_speed_moments == (4.0, 2.0)
    fixed = ManeuverParams(initial_range=(600.0, 600.0), target_speed=(3.0, 3.0))
    assert fixed.prior_ranges == pytest.approx((599.4, 600.6))
    assert fixed.prior_speed_moments == (3.0, 0.0)
    state = core.reset(fixed, np.random.default_rng(0), 3)  # a known speed still resets
    assert np.all(np.isfinite(state.accuracy))
