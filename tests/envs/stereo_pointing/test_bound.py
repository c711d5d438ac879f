"""The StereoPointing bound (:mod:`sensorgym.envs.stereo_pointing.bound`) is a true upper
bound — no step of any rule, shipped policy or random pointing earns more, no episode returns
more — and it is attained where its choice of views can be pointed."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from sensorgym.agents.registry import RULES
from sensorgym.envs.stereo_pointing import simulation
from sensorgym.envs.stereo_pointing.bound import (
    bound_path,
    episode_bound,
    step_bound,
    step_bound_views,
)
from sensorgym.envs.stereo_pointing.simulation import PointingParams, PointingState
from sensorgym.trackers.stereo.information import (
    log_ratio_reward,
    observable,
    position_information,
    position_sigma,
)
from sensorgym.train.shipped import shipped_policies

ENV_ID = "sensorgym/StereoPointing-v0"
STEPS = 150
SCENARIOS = 8
#: float32 rounding of a reward of at most R = 5 (the SB3 stack may hand rewards on as float32)
TOL = 5.0 * 2.0**-23


def views_reward(params: PointingParams, state: PointingState, views: np.ndarray) -> np.ndarray:
    """``(B,)`` the env's reward of the step from ``state`` in which receiver ``k`` sees exactly
    the drones ``views[:, k, j]`` ``(B, n, m)``: ``(1/m) Σ_j clip(ln(σ_ref/σ_pos), −R, R)`` at
    the drones moved by ``dt``, by the env's primitives, summed in drone order."""
    moved = state.drone_position + state.drone_velocity * params.dt
    u, r = simulation.lines_of_sight(params, moved)  # (B, n, m, 3), (B, n, m)
    mask = np.swapaxes(views, 1, 2)  # (B, m, n)
    info = position_information(np.swapaxes(u, 1, 2), np.swapaxes(r, 1, 2), 1.0, mask)
    sigma = position_sigma(info, observable(info, mask), params.sigma_ang)
    f = log_ratio_reward(sigma, params.sigma_ref, params.reward_clip)  # (B, m)
    total = np.zeros(f.shape[0])
    for j in range(f.shape[1]):
        total += f[:, j]
    return total / params.n_drones


def _play(
    params: PointingParams,
    act: Callable[[PointingState, np.ndarray], np.ndarray],
    seed: int,
    batch: int,
    steps: int = STEPS,
) -> tuple[np.ndarray, np.ndarray]:
    """Play ``act(state, obs)`` on the simulation; check every step against the bound (and the
    env's reward against :func:`views_reward` of the views it made, bit for bit). Returns
    ``(returns, episode bounds)``."""
    rng = np.random.default_rng(seed)
    state = simulation.reset(params, rng, batch)
    ceiling = episode_bound(params, state, steps)
    path = bound_path(params, state, steps)
    total = np.zeros(batch)
    for t in range(steps):
        bound = step_bound(params, state)
        np.testing.assert_array_equal(bound, path[:, t])
        new, reward, _ = simulation.step(
            params, state, act(state, simulation.observe(params, state)), rng
        )
        np.testing.assert_array_equal(reward, views_reward(params, state, new.seen))
        assert np.all(reward <= bound), (t, (reward - bound).max())
        total += reward
        state = new
    assert np.all(total <= ceiling)
    return total, ceiling


def _random_slews(
    params: PointingParams, seed: int
) -> Callable[[PointingState, np.ndarray], np.ndarray]:
    """A policy of uniform random slews."""
    rng = np.random.default_rng(seed)
    return lambda state, obs: rng.uniform(-1.0, 1.0, (obs.shape[0], params.n_receivers, 2))


def test_random_pointing_at_the_crowded_layout() -> None:
    """4 receivers × 3 drones, uniform random slews: no step beats the bound; the env's reward
    is the bound's per-drone function of the views it made, bit for bit."""
    params = PointingParams(n_drones=3)
    returns, ceiling = _play(params, _random_slews(params, 7), seed=3, batch=16)
    assert np.all(ceiling - returns > 0.0)


def test_random_pointing_nine_receivers_four_drones() -> None:
    """The largest compiled variant, 9 × 4, on a shorter episode: the search stays exact."""
    params = PointingParams(n_receivers=9, n_drones=4)
    _play(params, _random_slews(params, 8), seed=4, batch=4, steps=20)


def _exhaustive(params: PointingParams, state: PointingState) -> np.ndarray:
    """The relaxed maximum by brute force: every receiver any subset of drones within ``2·fov``
    of each other (the empty set too), every combination scored by :func:`views_reward`."""
    import itertools

    n, m = params.n_receivers, params.n_drones
    moved = state.drone_position + state.drone_velocity * params.dt
    u, _ = simulation.lines_of_sight(params, moved)
    cos = np.einsum("bkic,bkjc->bkij", u, u)
    sets = [np.array([(s >> j) & 1 for j in range(m)], dtype=bool) for s in range(2**m)]
    best = np.full(state.t.shape[0], -np.inf)
    for combo in itertools.product(range(2**m), repeat=n):
        views = np.stack([sets[s] for s in combo])  # (n, m)
        both = views[:, :, None] & views[:, None, :]
        ok = np.all(~both[None] | (cos >= np.cos(2.0 * params.fov)), axis=(1, 2, 3))
        value = views_reward(params, state, np.broadcast_to(views, (len(best), n, m)))
        best = np.where(ok, np.maximum(best, value), best)
    return best


@pytest.mark.parametrize("n_drones", [2, 3])
def test_branch_and_bound_equals_brute_force(n_drones: int) -> None:
    """The search returns the relaxed maximum itself (3 receivers: every subset enumerated)."""
    params = PointingParams(n_receivers=3, n_drones=n_drones, start_distance=(60.0, 70.0))
    state = simulation.reset(params, np.random.default_rng(5), 32)
    for _ in range(3):
        np.testing.assert_allclose(
            step_bound(params, state), _exhaustive(params, state), atol=1e-12
        )
        rng = np.random.default_rng(0)
        state, _, _ = simulation.step(params, state, rng.uniform(-1, 1, (32, 3, 2)), rng)


def _aim_views(
    params: PointingParams, state: PointingState, views: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Boresights that show receiver ``k`` the drones ``views[:, k]`` at the next step (the
    normalised sum of their lines of sight; straight down where it holds none)."""
    moved = state.drone_position + state.drone_velocity * params.dt
    u, _ = simulation.lines_of_sight(params, moved)  # (B, n, m, 3)
    aim = np.einsum("bkj,bkjc->bkc", views.astype(float), u)
    none = ~views.any(axis=2)
    aim[none] = (0.0, -1.0, 0.0)
    points = params.receiver_positions[None] + aim
    B = state.t.shape[0]
    zero = np.zeros((B, params.n_receivers))
    return simulation.aim_at(params, points, zero, zero)


@pytest.mark.parametrize("close", [False, True])
def test_the_bound_is_attained_where_its_views_can_be_pointed(close: bool) -> None:
    """Two drones (far apart, or close enough for one receiver to hold both): the receivers
    started on the views the bound chose and held still earn exactly the bound."""
    params = PointingParams()
    B = 64
    rng = np.random.default_rng(11)
    p = np.empty((B, 2, 3))
    p[:, 0] = rng.uniform((-40.0, 30.0, 70.0), (40.0, 60.0, 120.0), (B, 3))
    if close:  # 1–4 m apart, some 100 m out: within 2·fov of each other from every receiver
        p[:, 1] = p[:, 0] + rng.uniform(-4.0, 4.0, (B, 3))
    else:
        p[:, 1] = p[:, 0] * np.array([-1.0, 1.0, -1.0])  # across the circle
    v = rng.uniform(-10.0, 10.0, (B, 2, 3))
    az = np.zeros((B, params.n_receivers))
    state = simulation.start(params, p, v, az, az, rng)
    bound, views = step_bound_views(params, state)
    np.testing.assert_array_equal(views_reward(params, state, views), bound)
    if close:
        assert np.all(views.sum(axis=2) == 2)  # every receiver holds both drones
    azimuth, elevation = _aim_views(params, state, views)
    aimed = simulation.start(params, p, v, azimuth, elevation, rng)
    new, reward, _ = simulation.step(params, aimed, np.zeros((B, params.n_receivers, 2)), rng)
    np.testing.assert_array_equal(new.seen, views)
    np.testing.assert_array_equal(reward, bound)


def test_a_view_that_spoils_the_conditioning_is_left_out() -> None:
    """A drone 10 µm above receiver 0: seen by it, the information is ill-conditioned (the test
    of §4.3 fails: −R); the bound keeps the value without that view, which the env earns."""
    params = PointingParams()
    o = params.receiver_positions
    p = np.array([[o[0] + (0.0, 1e-5, 0.0), (0.0, 60.0, 100.0)]])  # (1, 2, 3)
    v = np.zeros((1, 2, 3))
    zero = np.zeros((1, params.n_receivers))
    state = simulation.start(params, p, v, zero, zero, np.random.default_rng(0))
    everyone = np.zeros((1, params.n_receivers, 2), dtype=bool)
    everyone[:, :, 0] = True
    without_0 = everyone.copy()
    without_0[:, 0, 0] = False
    spoilt, kept = views_reward(params, state, everyone), views_reward(params, state, without_0)
    assert spoilt[0] == -params.reward_clip and kept[0] > spoilt[0]  # f_j is not monotone here
    bound, views = step_bound_views(params, state)
    assert not views[0, 0, 0]
    assert bound[0] >= kept[0]


def _sb3_episodes(env: Any, policy: Any, params: PointingParams) -> None:
    """One episode of every scenario of an SB3 env from ``make_sb3_env``: every step's reward
    at most the bound of the state the action was taken in, every return at most its episode's
    bound."""
    from sensorgym.train.evaluation import agents_per_scenario

    state_of = lambda: env.get_attr("simulator_state")[0]  # noqa: E731
    obs = env.reset()
    state = state_of()
    ceiling = episode_bound(params, state, STEPS)
    per_agent = agents_per_scenario(env)
    total, bounds = np.zeros(state.t.shape[0]), np.zeros(state.t.shape[0])
    start, memory = np.ones(env.num_envs, dtype=bool), None
    for t in range(STEPS):
        bound = step_bound(params, state_of())
        action, memory = policy.predict(obs, state=memory, episode_start=start, deterministic=True)
        obs, reward, done, _ = env.step(action)
        start[:] = False
        r = np.asarray(reward, dtype=np.float64)[::per_agent]
        assert np.all(r <= bound + TOL), (t, (r - bound).max())
        total += r
        bounds += bound
        assert np.all(done) == (t == STEPS - 1)
    np.testing.assert_allclose(bounds, ceiling, rtol=1e-12)
    assert np.all(total <= ceiling + STEPS * TOL), (total - ceiling).max()


@pytest.mark.parametrize("rule", sorted(RULES[ENV_ID]))
def test_no_rule_beats_the_bound(rule: str) -> None:
    from sensorgym.train.evaluation import env_params, make_sb3_env, simulator_state

    env = make_sb3_env(ENV_ID, SCENARIOS, seed=10000)
    try:
        params = env_params(env)
        _sb3_episodes(env, RULES[ENV_ID][rule](params, simulator_state(env)), params)
    finally:
        env.close()


@pytest.mark.parametrize("run", sorted(shipped_policies(ENV_ID)))
def test_no_shipped_policy_beats_the_bound(run: str) -> None:
    from sensorgym.train.evaluation import env_params, make_sb3_env
    from sensorgym.train.models import load_model, read_config, run_dir_of, wrappers_of

    folder = shipped_policies(ENV_ID)[run]
    config = read_config(run_dir_of(folder))
    env = make_sb3_env(
        ENV_ID,
        SCENARIOS,
        seed=10001,
        agents=bool(config.get("agents", False)),
        wrappers=wrappers_of(config),
    )
    try:
        _sb3_episodes(env, load_model(folder, env), env_params(env))
    finally:
        env.close()


def test_one_drone_per_receiver_is_below_the_bound() -> None:
    """``max_drones_per_receiver=1`` (a diagnostic) never exceeds the bound, and equals it when
    the drones are far apart."""
    params = PointingParams(n_drones=3)
    state = simulation.reset(params, np.random.default_rng(2), 64)
    full = bound_path(params, state, 30)
    single = bound_path(params, state, 30, max_drones_per_receiver=1)
    assert np.all(single <= full)
    far = dataclasses.replace(params, fov=1e-3)
    np.testing.assert_array_equal(
        bound_path(far, state, 5), bound_path(far, state, 5, max_drones_per_receiver=1)
    )
