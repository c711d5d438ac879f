"""Every rule at any number of platforms: the frames, the sequential choices, the shapes."""

from __future__ import annotations

import numpy as np
import pytest
from pettingzoo.test import parallel_api_test

from sensorgym.agents.bearings_maneuver import (
    GreedyManeuver,
    TruthLookahead,
    platform_views,
    relative_headings,
)
from sensorgym.agents.registry import RULES
from sensorgym.envs import bearings_maneuver
from sensorgym.envs.bearings_maneuver import simulation as core
from sensorgym.envs.bearings_maneuver.simulation import (
    ManeuverParams,
    ManeuverState,
    accuracy_of,
    advance_bound,
)
from sensorgym.envs.worlds.platform import fly
from sensorgym.trackers.bearings.models import cv_transition
from sensorgym.train.evaluation import env_params, make_sb3_env, simulator_state


def _states(params: ManeuverParams, seed: int, batch: int = 48):
    """Seeded states along episodes under random actions (fresh, mid-episode, late)."""
    rng = np.random.default_rng(seed)
    state = core.reset(params, rng, batch)
    yield state
    for k in range(9):
        action = rng.uniform(-1, 1, (batch, params.platforms, 2))
        state, _, _ = core.step(params, state, action, rng)
        if k % 4 == 3:
            yield state


def _wrap(angle: np.ndarray) -> np.ndarray:
    return (angle + np.pi) % (2 * np.pi) - np.pi


def test_relative_headings_are_the_true_heading_differences():
    params = ManeuverParams(platforms=4)
    for state in _states(params, 0):
        views = platform_views(params, core.observe(params, state).astype(np.float64))
        delta = relative_headings(params, views)
        truth = state.heading - state.heading[:, :1]
        np.testing.assert_allclose(_wrap(delta - truth), 0.0, atol=1e-5)


def numpy_sequential_greedy(rule: GreedyManeuver, state: ManeuverState) -> np.ndarray:
    """Sequential greedy on the true frames (headings from the simulator, not the views): each
    platform's candidates flown in its own frame, ``hᵀ P h`` in the world frame with ``P`` the
    estimate's position covariance, updated by each chosen bearing; ``(B, K)`` indices."""
    p, w = rule.params, rule.params.world
    cand = rule.candidates()
    views = platform_views(p, core.observe(p, state).astype(np.float64))
    B, K = views.shape[:2]
    sd = np.exp(views[:, 0, 7:9]) * p.range_scale
    cov = sd[:, 0] * sd[:, 1] * views[:, 0, 9]
    # platform 1's frame → world: P_world = R₁ᵀ P₁ R₁ with R = [[c, −s], [s, c]]
    P1 = np.stack([np.stack([sd[:, 0] ** 2, cov], -1), np.stack([cov, sd[:, 1] ** 2], -1)], -2)
    s1, c1 = np.sin(state.heading[:, 0]), np.cos(state.heading[:, 0])
    R1 = np.stack([np.stack([c1, -s1], -1), np.stack([s1, c1], -1)], -2)
    P = np.swapaxes(R1, -1, -2) @ P1 @ R1
    choice = np.empty((B, K), dtype=np.int64)
    for k in range(K):
        obs = views[:, k]
        v = obs[:, 2] * w.max_speed
        d = obs[:, 3:5] * p.range_scale
        v_target = obs[:, 5:7] * p.speed_scale + np.stack([np.zeros_like(v), v], -1)
        pos, _, _ = fly(
            np.zeros((B, len(cand), 2)),
            np.zeros((B, len(cand))),
            np.repeat(v[:, None], len(cand), 1),
            np.broadcast_to(cand * [w.max_turn_rate, w.max_speed_change], (B, len(cand), 2)),
            w,
        )
        n = (d + v_target * w.dt)[:, None, :] - pos  # (B, C, 2), platform k's frame
        r = np.hypot(n[..., 0], n[..., 1])
        normal_k = np.stack([n[..., 1], -n[..., 0]], -1) / r[..., None]
        s, c = np.sin(state.heading[:, k]), np.cos(state.heading[:, k])
        Rk = np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)
        h = np.einsum("bji,bcj->bci", Rk, normal_k) / r[..., None]  # world frame
        gain = np.einsum("bci,bij,bcj->bc", h, P, h)
        gain = np.where(r < rule.safety * p.min_range, -np.inf, gain)
        choice[:, k] = np.argmax(gain, axis=1)
        hb = h[np.arange(B), choice[:, k]]
        Ph = np.einsum("bij,bj->bi", P, hb)
        P = (
            P
            - Ph[:, :, None]
            * Ph[:, None, :]
            / (np.einsum("bi,bi->b", hb, Ph) + w.sigma_bearing**2)[:, None, None]
        )
    return choice


@pytest.mark.parametrize("K", [1, 3])
def test_greedy_is_sequential_greedy_on_the_shared_estimate(K):
    params = ManeuverParams(platforms=K)
    rule = GreedyManeuver(params)
    cand = rule.candidates()
    agree = []
    for seed in (0, 1):
        for state in _states(params, seed):
            action, _ = rule.predict(core.observe(params, state))
            expected = cand[numpy_sequential_greedy(rule, state)].reshape(action.shape[0], -1)
            agree.append(np.all(action == expected.astype(np.float32), axis=1))
    # ties between near-equal gains may resolve either way at rounding level
    assert np.mean(np.concatenate(agree)) >= 0.98


def brute_force_joint_plans(truth: TruthLookahead, s: ManeuverState) -> np.ndarray:
    """The sequential plans in numpy: each platform in turn tries every candidate held for the
    horizon, the others flying their plans (chosen, or straight on), every bearing fused by
    the env's recursion (:func:`advance_bound`); ``(B, K)`` command indices."""
    p, w = truth.params, truth.params.world
    cand = truth.candidates()
    command = cand * [w.max_turn_rate, w.max_speed_change]
    B, K = s.heading.shape
    C = len(cand)
    F = cv_transition(w.dt)
    choice = np.full((B, K), -1)
    straight = int(np.flatnonzero(np.all(cand == 0.0, axis=1))[0])
    for k in range(K):
        # (B, C, K, 2) commands: candidate j for platform k, the others' plans
        plan = np.repeat(np.where(choice < 0, straight, choice)[:, None, :], C, axis=1)
        plan[:, :, k] = np.arange(C)
        cmd = command[plan]
        pos = np.repeat(s.platform_position[:, None], C, axis=1)
        heading = np.repeat(s.heading[:, None], C, axis=1)
        speed = np.repeat(s.speed[:, None], C, axis=1)
        target = np.repeat(s.target[:, None], C, axis=1)
        L = np.repeat(s.bound_factor[:, None], C, axis=1)
        close = np.zeros((B, C), dtype=bool)
        for _ in range(truth.horizon):
            pos, heading, speed = fly(pos, heading, speed, cmd, w)
            target = target @ F.T
            L = advance_bound(p, L, target, pos)
            d = target[..., :2] - pos[:, :, k]
            close |= np.hypot(d[..., 0], d[..., 1]) < truth.safety * p.min_range
        bound = np.where(close, np.inf, accuracy_of(p, L, target, pos[:, :, 0]))
        choice[:, k] = np.argmin(bound, axis=1)
    return choice


def test_joint_plans_equal_a_brute_force_sequential_search():
    params = ManeuverParams(platforms=3, formation_radius=8_000.0)
    agree = []
    for seed in (0, 1):
        for state in _states(params, seed, batch=24):
            truth = TruthLookahead(lambda s=state: s, params, horizon=4)
            action, _ = truth.predict(core.observe(params, state))
            expected = truth.candidates()[brute_force_joint_plans(truth, state)]
            expected = expected.reshape(action.shape[0], -1).astype(np.float32)
            agree.append(np.all(action == expected, axis=1))
    assert np.mean(np.concatenate(agree)) >= 0.95


def test_one_platform_joint_plan_is_the_single_platform_plan():
    params = ManeuverParams()
    for state in _states(params, 2):
        truth = TruthLookahead(lambda s=state: s, params)
        action, _ = truth.predict(core.observe(params, state))
        chosen = truth.candidates()[np.argmin(truth.plan_bounds(state), axis=1)]
        np.testing.assert_array_equal(action, chosen.astype(np.float32))


@pytest.mark.parametrize(
    "env_id", ["sensorgym/BearingsManeuver-v0", "sensorgym/BearingsManeuverBook-v0"]
)
def test_every_rule_acts_for_every_platform(env_id):
    K = 5
    env = make_sb3_env(env_id, 6, seed=3, platforms=K)
    obs = env.reset()
    assert obs.shape == (6, K * (core.OBS_DIM + 2 * (K - 1)))
    for name, make in RULES[env_id].items():
        rule = make(env_params(env), simulator_state(env))
        state, start = None, np.ones(6, dtype=bool)
        for _ in range(3):
            action, state = rule.predict(obs, state, start)
            assert action.shape == (6, 2 * K), name
            assert np.all(np.abs(action) <= 1.0), name
            obs = env.step(action)[0]
            start = np.zeros(6, dtype=bool)
    env.close()


def test_rules_steer_sixteen_platforms_apart():
    """At K = 16 the information rules do not all copy platform 1: the sequential choice
    spreads the platforms' commands."""
    params = ManeuverParams(platforms=16)
    state = next(_states(params, 4, batch=16))
    action, _ = GreedyManeuver(params).predict(core.observe(params, state))
    turns = action.reshape(16, 16, 2)[..., 0]
    assert np.mean(np.ptp(turns, axis=1) > 0.0) > 0.5


def test_sixteen_platform_pettingzoo_env_passes_the_api_test():
    parallel_api_test(bearings_maneuver.parallel_env(platforms=16), num_cycles=40)
