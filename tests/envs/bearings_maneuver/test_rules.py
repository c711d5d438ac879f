"""The rules' compiled plans equal a brute-force numpy evaluation of the same recursion."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from sensorgym.agents.bearings_maneuver import EstimateLookahead, GreedyManeuver, TruthLookahead
from sensorgym.envs.bearings_maneuver import simulation as core
from sensorgym.envs.bearings_maneuver.simulation import (
    ManeuverParams,
    ManeuverState,
    accuracy_of,
    advance_bound,
)
from sensorgym.envs.worlds.platform import PlatformWorldParams, fly
from sensorgym.trackers.bearings.models import cv_transition


def brute_force_plan_bounds(truth: TruthLookahead, s: ManeuverState) -> np.ndarray:
    """Every candidate held for the horizon with the numpy world (:func:`fly`, ``F x``) and the
    env's bound recursion (:func:`advance_bound`, :func:`accuracy_of`); ``(B, C)``."""
    p, w = truth.params, truth.params.world
    cand = truth.candidates()
    C = cand.shape[0]
    command = np.broadcast_to(cand * [w.max_turn_rate, w.max_speed_change], (s.batch_size, C, 2))
    pos = np.repeat(s.platform_position[:, :1], C, axis=1)
    heading = np.repeat(s.heading[:, :1], C, axis=1)
    speed = np.repeat(s.speed[:, :1], C, axis=1)
    target = s.target[:, None, :]
    L = np.repeat(s.bound_factor[:, None], C, axis=1)
    F = cv_transition(w.dt)
    too_close = np.zeros((s.batch_size, C), dtype=bool)
    for _ in range(truth.horizon):
        pos, heading, speed = fly(pos, heading, speed, command, w)
        target = target @ F.T
        L = advance_bound(p, L, np.broadcast_to(target, (*pos.shape[:-1], 4)), pos[..., None, :])
        d = target[..., :2] - pos
        too_close |= np.hypot(d[..., 0], d[..., 1]) < truth.safety * p.min_range
    return np.where(too_close, np.inf, accuracy_of(p, L, target, pos))


def _states(params: ManeuverParams, seed: int, batch: int = 64):
    """Seeded states along episodes under random actions (fresh, mid-episode, late)."""
    rng = np.random.default_rng(seed)
    state = core.reset(params, rng, batch)
    yield state
    for k in range(12):
        state, _, _ = core.step(params, state, rng.uniform(-1, 1, (batch, 1, 2)), rng)
        if k % 4 == 3:
            yield state


@pytest.mark.parametrize(
    "params",
    [
        ManeuverParams(),
        ManeuverParams(metric="relative_range", world=PlatformWorldParams(q_tilde=1e-3)),
        ManeuverParams(initial_range=(1_000.0, 4_000.0), min_range=600.0),
    ],
)
@pytest.mark.parametrize("horizon", [1, 5])
def test_truth_lookahead_plans_equal_the_numpy_recursion(params, horizon):
    for seed in (0, 1):
        for state in _states(params, seed):
            truth = TruthLookahead(lambda s=state: s, params, horizon=horizon)
            bounds = truth.plan_bounds(state)
            expected = brute_force_plan_bounds(truth, state)
            np.testing.assert_array_equal(np.isinf(bounds), np.isinf(expected))
            live = np.isfinite(expected)
            np.testing.assert_allclose(bounds[live], expected[live], rtol=1e-12)
            action, _ = truth.predict(core.observe_agents(params, state)[:, 0])
            chosen = truth.candidates()[np.argmin(expected, axis=1)].astype(np.float32)
            np.testing.assert_array_equal(action, chosen)


def numpy_greedy_act(rule: GreedyManeuver, obs: np.ndarray) -> np.ndarray:
    """The greedy rule in numpy (the implementation before it was compiled): exact arcs of every
    candidate from the platform's frame, ``hᵀ P h`` at the predicted relative position."""
    p, w = rule.params, rule.params.world
    cand = rule.candidates()
    v = obs[:, 2] * w.max_speed
    d = obs[:, 3:5] * p.range_scale  # estimated target − platform
    v_rel = obs[:, 5:7] * p.speed_scale
    v_target = v_rel + np.stack([np.zeros_like(v), v], -1)
    omega = cand[:, 0] * w.max_turn_rate
    speed = np.clip(v[:, None] + cand[None, :, 1] * w.max_speed_change, w.min_speed, w.max_speed)
    half = 0.5 * omega * w.dt
    chord = speed * w.dt * np.sinc(half / np.pi)  # (n, C)
    dp = chord[..., None] * np.stack([np.sin(half), np.cos(half)], -1)
    d_next = (d + v_target * w.dt)[:, None, :] - dp  # (n, C, 2)
    r = np.hypot(d_next[..., 0], d_next[..., 1])
    normal = np.stack([d_next[..., 1], -d_next[..., 0]], -1) / np.maximum(r, 1e-9)[..., None]
    sd = np.exp(obs[:, 7:9]) * p.range_scale
    cov = sd[:, 0] * sd[:, 1] * obs[:, 9]
    P = np.stack([np.stack([sd[:, 0] ** 2, cov], -1), np.stack([cov, sd[:, 1] ** 2], -1)], -2)
    gain = np.einsum("nci,nij,ncj->nc", normal, P, normal) / np.maximum(r, 1e-9) ** 2
    gain = np.where(r < rule.safety * p.min_range, -np.inf, gain)
    return cand[np.argmax(gain, axis=-1)]


@pytest.mark.parametrize(
    "params",
    [
        ManeuverParams(),
        ManeuverParams(world=PlatformWorldParams(min_speed=2.0, max_speed=9.0)),
        ManeuverParams(initial_range=(1_000.0, 4_000.0), min_range=600.0),
    ],
)
def test_greedy_actions_equal_the_numpy_rule(params):
    rule = GreedyManeuver(params)
    for seed in (0, 1, 2):
        for state in _states(params, seed, batch=256):
            obs = core.observe(params, state).astype(np.float64)
            np.testing.assert_array_equal(rule.act(obs), numpy_greedy_act(rule, obs))


def estimated_world(rule: EstimateLookahead, obs: np.ndarray) -> SimpleNamespace:
    """What the estimate-lookahead plans on, rebuilt from the observation table by hand: the
    platform at the origin of its own frame (heading 0 = ahead), the estimated target, the
    bound's square root from the estimate's position and velocity covariances (block-diagonal:
    the observation holds no cross-covariance)."""
    p, w = rule.params, rule.params.world
    n = obs.shape[0]
    v = obs[:, 2] * w.max_speed
    target = np.concatenate(
        [obs[:, 3:5] * p.range_scale, obs[:, 5:7] * p.speed_scale + np.stack([0 * v, v], -1)], -1
    )
    P = np.zeros((n, 4, 4))
    for i, scale in ((0, p.range_scale), (2, p.speed_scale)):
        sd = np.exp(obs[:, 7 + 3 * i // 2 : 9 + 3 * i // 2]) * scale
        c = sd[:, 0] * sd[:, 1] * np.clip(obs[:, 9 + 3 * i // 2], -0.999, 0.999)
        P[:, i, i], P[:, i + 1, i + 1] = sd[:, 0] ** 2, sd[:, 1] ** 2
        P[:, i, i + 1] = P[:, i + 1, i] = c
    return SimpleNamespace(
        batch_size=n,
        platform_position=np.zeros((n, 1, 2)),
        heading=np.zeros((n, 1)),
        speed=v[:, None],
        target=target,
        bound_factor=np.linalg.cholesky(P),
    )


@pytest.mark.parametrize(
    "params",
    [ManeuverParams(), ManeuverParams(initial_range=(1_000.0, 4_000.0), min_range=600.0)],
)
@pytest.mark.parametrize("horizon", [2, 8])
def test_estimate_lookahead_plans_the_truth_recursion_on_the_estimate(params, horizon):
    rule = EstimateLookahead(params, horizon=horizon)
    # the same recursion as the truth lookahead's, on the estimated world instead of the true one
    truth = TruthLookahead(lambda: None, params, horizon=horizon, safety=rule.safety)
    for seed in (0, 1):
        for state in _states(params, seed):
            obs = core.observe(params, state).astype(np.float64)
            expected = brute_force_plan_bounds(truth, estimated_world(rule, obs))
            chosen = rule.candidates()[np.argmin(expected, axis=1)].astype(np.float32)
            action, _ = rule.predict(obs.astype(np.float32))
            # ties between near-equal plans may resolve either way at rounding level
            agree = np.all(action == chosen, axis=1)
            assert agree.mean() >= 0.98


def test_estimate_lookahead_rejects_what_it_cannot_plan():
    with pytest.raises(ValueError, match="horizon"):
        EstimateLookahead(ManeuverParams(), horizon=0)
