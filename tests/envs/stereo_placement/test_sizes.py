"""sensorgym/StereoPlacement-v0 at any number of receiver vehicles (issue 15): the n_receivers
field, the compiled general-n step, PettingZoo, rendering, and the coordinate-wise search of
the greedy rules against the exhaustive one."""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np
import pytest
from pettingzoo.test import parallel_api_test

import sensorgym.envs  # noqa: F401  (registers the ids)
from sensorgym.agents.registry import rules_for
from sensorgym.agents.stereo_placement import CirclePlacement, GreedyPlacement, HoldPosition
from sensorgym.envs import stereo_placement
from sensorgym.envs.stereo_placement import kernels
from sensorgym.envs.stereo_placement import simulation as core
from sensorgym.envs.stereo_placement.scan import solve_period
from sensorgym.envs.stereo_placement.simulation import PlacementParams
from sensorgym.trackers.stereo.conjugation import solve_conjugation
from sensorgym.trackers.stereo.conjugation_kernels import velocity_kernel

ENV_ID = "sensorgym/StereoPlacement-v0"


# --- the n_receivers field ---------------------------------------------------------------------


def test_n_receivers_sets_the_size_and_a_spread_of_delays():
    assert PlacementParams() == PlacementParams(n_receivers=3)
    assert PlacementParams() == PlacementParams(delays=(0.0, 0.25, 0.6))
    assert PlacementParams().delays_array.tolist() == [0.0, 0.25, 0.6]
    six = PlacementParams(n_receivers=6)
    assert six.n_receivers == 6 and six.delays is None
    np.testing.assert_allclose(six.delays_array, [0.0, 0.12, 0.24, 0.36, 0.48, 0.6])
    assert six.obs_dim == 5 * 6 + 9 + 15
    # the default spread follows a replaced count (what gym.make(..., n_receivers=6) does)
    assert dataclasses.replace(PlacementParams(), n_receivers=6) == six
    # explicit delays: their number is n, or must match n_receivers
    four = PlacementParams(delays=(0.0, 0.1, 0.2, 0.3))
    assert four.n_receivers == 4 and four == PlacementParams(
        n_receivers=4, delays=(0, 0.1, 0.2, 0.3)
    )
    assert four.delays_array.tolist() == [0.0, 0.1, 0.2, 0.3]
    with pytest.raises(ValueError, match="delays: 4 values for n_receivers = 6"):
        dataclasses.replace(four, n_receivers=6)


@pytest.mark.parametrize(
    "kwargs, error, message",
    [
        ({"n_receivers": 2}, ValueError, "n_receivers: need at least 3"),
        ({"n_receivers": 4.5}, TypeError, "n_receivers: must be an integer"),  # a count's type
        (
            {"n_receivers": 5, "delays": (0.0, 0.25, 0.6)},
            ValueError,
            "delays: 3 values for n_receivers = 5",
        ),
    ],
)
def test_n_receivers_is_validated(kwargs, error, message):
    with pytest.raises(error, match=message):
        PlacementParams(**kwargs)


# --- the env at 6 and 16 receivers -------------------------------------------------------------


@pytest.mark.parametrize("n", [4, 6, 16])
def test_the_compiled_step_equals_the_svd_solve(n):
    """The step's compiled normal equations (n ≥ 4) against the conjugation's generic SVD path
    on the same systems: the estimate and the reported accuracy agree to rounding."""
    params = PlacementParams(n_receivers=n)
    rng = np.random.default_rng(30 + n)
    state = core.reset(params, rng, 64)
    for _ in range(3):
        state, reward, _ = core.step(params, state, rng.uniform(-1, 1, (64, n, 2)), rng)
        assert np.all(np.isfinite(reward))
    action = rng.uniform(-1, 1, (64, n, 2))
    seed = int(rng.integers(1 << 30))
    new, reward, _ = core.step(params, state, action, np.random.default_rng(seed))
    # the same period re-solved with every system on the SVD path
    normals = np.random.default_rng(seed).standard_normal((64, n, 3))
    fix, _, _, bound, expected = solve_period(
        params.delays_array, params.period, params.sigma_ang, params.max_boresight_elevation,
        state.receivers, new.receivers, new.drone_position, new.drone_velocity, state.estimate,
        normals, params.sigma_ref, params.reward_clip,
    )  # fmt: skip
    np.testing.assert_array_equal(reward, expected)
    np.testing.assert_array_equal(new.bound, bound)
    np.testing.assert_array_equal(new.fix.position, fix.position)
    assert not new.fix.degenerate.any() and np.all(new.fix.condition < 1e4)


@pytest.mark.parametrize("n", [4, 6, 16])
def test_the_general_n_kernel_matches_the_svd_path(n):
    """The compiled order-1 solve for n ≥ 4 against the weighted (SVD) path with W = I."""
    rng = np.random.default_rng(n)
    params = PlacementParams(n_receivers=n)
    state = core.reset(params, rng, 32)
    state, _, _ = core.step(params, state, rng.uniform(-1, 1, (32, n, 2)), rng)
    # the period's systems, as the step kernel builds them
    B, m = 32, n - 1
    arrays = dict(
        origins=np.empty((B, n, 3)), los=np.empty((B, n, 3)), ranges=np.empty((B, n)),
        R=np.empty((B, n, 3, 3)), a1=np.empty((B, 3)), ak=np.empty((B, m, 3)),
        P=np.empty((B, m, 3, 3)), b=np.empty((B, m, 3)), dt=np.empty((B, m)),
        e1=np.empty((B, 3)), ek=np.empty((B, m, 3)), X=np.empty((B, n + 3)), J=np.empty(B),
        Q=np.empty((B, n + 3, n + 3)), kappa=np.empty(B), M1=np.empty((B, 3)),
        Xe=np.empty((B, n + 3)), Qe=np.empty((B, n + 3, n + 3)), kappa_e=np.empty(B),
    )  # fmt: skip
    end = state.receivers + rng.uniform(-3, 3, state.receivers.shape) * [1.0, 0.0, 1.0]
    a = list(arrays.values())
    kernels.period_systems(
        (params.period, params.sigma_ang, params.max_boresight_elevation), params.delays_array,
        (state.receivers, end, state.drone_position, state.drone_velocity, state.estimate),
        rng.standard_normal((B, n, 3)), tuple(a[:3]), tuple(a[3:11]), tuple(a[11:]),
    )  # fmt: skip
    inputs = (arrays["a1"], arrays["ak"], arrays["P"], arrays["b"], arrays["dt"])
    generic = solve_conjugation(*inputs, order=1)  # the SVD path for n ≥ 4
    assert np.all(np.isfinite(arrays["kappa"]))  # every system solved by the kernel
    X, Q = arrays["X"], arrays["Q"]
    np.testing.assert_allclose(X[:, :n], generic.ranges, rtol=1e-9)
    np.testing.assert_allclose(X[:, n:], generic.velocity, rtol=1e-8, atol=1e-8)
    np.testing.assert_allclose(Q, generic.covariance, rtol=1e-7, atol=1e-12)
    np.testing.assert_allclose(arrays["kappa"], generic.condition, rtol=1e-9)
    # the noise-free system of the same period: solved as well
    exact = solve_conjugation(arrays["e1"], arrays["ek"], arrays["P"], arrays["b"], arrays["dt"],
                              order=1)  # fmt: skip
    np.testing.assert_allclose(arrays["Xe"][:, :n], exact.ranges, rtol=1e-9)
    np.testing.assert_allclose(arrays["kappa_e"], exact.condition, rtol=1e-9)


def test_the_general_n_kernel_names_bad_inputs_and_leaves_singular_systems():
    rng = np.random.default_rng(3)
    a1 = np.tile([0.0, 0.0, 1.0], (2, 1))
    ak = np.tile([0.0, 0.0, 1.0], (2, 4, 1))  # every line of sight parallel: singular
    P = np.tile(np.eye(3), (2, 4, 1, 1))
    b = rng.normal(size=(2, 4, 3))
    dt = np.tile([0.1, 0.2, 0.3, 0.4], (2, 1))
    X, J, Q, kappa, M = (
        np.empty((2, 8)),
        np.empty(2),
        np.empty((2, 8, 8)),
        np.empty(2),
        np.empty((2, 3)),
    )
    assert velocity_kernel(a1, ak, P, b, dt, 1.0, True, 0, 2, X, J, Q, kappa, M) == 0
    assert np.all(kappa == np.inf)  # left to the SVD path
    b[1, 2, 0] = np.nan
    assert velocity_kernel(a1, ak, P, b, dt, 1.0, True, 0, 2, X, J, Q, kappa, M) == 4
    ak[0, 1] *= 2.0
    assert velocity_kernel(a1, ak, P, b, dt, 1.0, True, 0, 2, X, J, Q, kappa, M) == 2


@pytest.mark.parametrize("n", [6, 16])
def test_pettingzoo_api_at_many_receivers(n):
    parallel_api_test(stereo_placement.parallel_env(n_receivers=n, max_episode_steps=8), 10)


def test_gymnasium_env_and_rendering_at_sixteen_receivers():
    env = gym.make(ENV_ID, n_receivers=16, render_mode="rgb_array")
    obs, _ = env.reset(seed=3)
    n = 16
    assert obs.shape == (5 * n + 9 + n * (n - 1) // 2,) and env.action_space.shape == (2 * n,)
    for _ in range(3):
        obs, reward, terminated, _, _ = env.step(env.action_space.sample())
        assert np.isfinite(reward) and np.all(np.isfinite(obs)) and not terminated
    frame = env.render()
    assert frame.shape == (528, 480, 3) and frame.std() > 0  # the legend below


# --- rules at many receivers ------------------------------------------------------------------


def test_every_rule_decides_at_sixteen_receivers_and_spreads_them_out():
    params = PlacementParams(n_receivers=16)
    rng = np.random.default_rng(5)
    state = core.reset(params, rng, 8)
    rules = rules_for(ENV_ID, params, lambda: state)
    assert not rules["greedy-information"].exhaustive
    totals = {}
    for name, rule in rules.items():
        s, total = state, 0.0
        for _ in range(10):
            action, _ = rule.predict(core.observe(params, s), deterministic=True)
            assert action.shape == (8, 32) and np.all(np.abs(action) <= 1.0)
            s, reward, _ = core.step(params, s, action, rng)
            total += reward.mean()
        totals[name] = total
    for name in ("circle-placement", "greedy-information", "truth-lookahead"):
        assert totals[name] > totals["hold-position"] + 5.0, totals


def test_circle_placement_beyond_every_permutation_keeps_the_receivers_order():
    """Past MAX_PERMUTED receivers the slots rotate the receivers' order of bearing around the
    circle: still one distinct slot per receiver."""
    params = PlacementParams(n_receivers=9, drone_speed=(0.0, 0.0))
    rule = CirclePlacement(params)
    state = core.reset(params, np.random.default_rng(2), 16)
    goal = rule.targets(core.observe(params, state))
    spacing = np.linalg.norm(goal[:, :, None] - goal[:, None], axis=-1) + 1e3 * np.eye(9)
    assert spacing.min() > 1.0  # every receiver its own slot
    assert HoldPosition(params).act(core.observe(params, state)).shape == (16, 18)


def test_greedy_solver_field_is_validated():
    params = PlacementParams(n_receivers=6)
    with pytest.raises(ValueError, match="exhaustive search"):
        GreedyPlacement(params, solver="exhaustive")
    with pytest.raises(ValueError, match="solver"):
        GreedyPlacement(params, solver="random")
    with pytest.raises(ValueError, match="max_sweeps"):
        GreedyPlacement(params, max_sweeps=0)
    assert GreedyPlacement(PlacementParams()).exhaustive  # the registered size: as before
    assert not GreedyPlacement(params).exhaustive
    # 9^4 = 6561 joint moves: "auto" goes coordinate-wise, "exhaustive" stays a reference
    four = PlacementParams(n_receivers=4)
    assert not GreedyPlacement(four).exhaustive
    assert GreedyPlacement(four, solver="exhaustive").exhaustive


def _random_instances(params: PlacementParams, rng: np.random.Generator, count: int, spread: float):
    """Receivers uniform within ``spread`` m of the origin, the drone as the env draws it."""
    n = params.n_receivers
    radius = spread * np.sqrt(rng.uniform(0.0, 1.0, (count, n)))
    angle = rng.uniform(-np.pi, np.pi, (count, n))
    o = np.stack([radius * np.sin(angle), np.zeros_like(radius), radius * np.cos(angle)], -1)
    dist = rng.uniform(*params.start_distance, count)
    bearing = rng.uniform(-np.pi, np.pi, count)
    height = rng.uniform(*params.start_altitude, count)
    p = np.stack([dist * np.sin(bearing), height, dist * np.cos(bearing)], -1)
    heading = rng.uniform(-np.pi, np.pi, count)
    speed = rng.uniform(*params.drone_speed, count)
    v = np.stack([speed * np.sin(heading), np.zeros(count), speed * np.cos(heading)], -1)
    return o, p, v


@pytest.mark.parametrize("n", [3, 4])
@pytest.mark.parametrize("horizon", [1, 3])
@pytest.mark.parametrize("spread", [15.0, 200.0])
def test_coordinate_search_against_the_exhaustive_optimum(n, horizon, spread, record_property):
    """On random instances (receivers clustered as the env starts them, or anywhere in the
    disc) the coordinate-wise search scores at most the exhaustive optimum and at least its
    start; its value is the score of the joint move it returns. How close it comes is
    reported, not asserted: the share of instances where it finds the optimum, and the ratio
    of the position bounds ``σ_pos`` it plans for to the optimum's, ``exp((optimum − value)/H)``
    (the objective is a sum of ``H`` rewards ``ln(σ_ref/σ_pos)``: a difference of scores is a
    ratio of bounds; the scores themselves can be negative)."""
    params = PlacementParams(n_receivers=n)
    rule = GreedyPlacement(params, horizon=horizon)
    rng = np.random.default_rng(100 + 10 * n + horizon + int(spread))
    o, p, v = _random_instances(params, rng, 400, spread)
    exact_moves, optimum, _ = rule.search(o, p, v, "exhaustive")
    moves, value, start = rule.search(o, p, v, "coordinate")
    assert np.all(value <= optimum) and np.all(value >= start)
    same = np.all(moves == exact_moves, axis=-1)
    np.testing.assert_array_equal(value[same], optimum[same])
    # the value is the score of the returned move: the exhaustive search over it alone
    scalars = (params.period, params.sigma_ang, params.sigma_ref, params.reward_clip,
               params.arena_radius)  # fmt: skip
    for i in np.flatnonzero(~same)[:20]:
        best, score = np.empty(1, np.int64), np.empty(1)
        kernels.plan_search(o[i : i + 1], p[i : i + 1], v[i : i + 1], rule._shifts,
                            moves[i : i + 1], scalars, horizon, best, score)  # fmt: skip
        assert score[0] == value[i]
    bound_ratio = np.exp((optimum - value) / horizon)
    summary = {
        "instances": len(value),
        "optimum_found": float(np.mean(same | (value == optimum))),
        "mean_bound_ratio": float(np.mean(bound_ratio)),
        "worst_bound_ratio": float(np.max(bound_ratio)),
        "start_bound_ratio": float(np.mean(np.exp((optimum - start) / horizon))),
    }
    record_property("coordinate_vs_exhaustive", summary)
    print(f"n = {n}, horizon = {horizon}, spread = {spread:g} m: {summary}")


def test_a_run_trained_at_six_receivers_builds_its_policy_at_that_size():
    """The run folder records ``--param n_receivers=6``; the policy it builds acts on the
    6-receiver spaces (per agent: the observation and the one-hot of 6)."""
    from sensorgym.train.models import build_model

    config = {"env": ENV_ID, "algo": "ppo", "seed": 0, "agents": True, "params": {"n_receivers": 6}}
    model = build_model(config)
    obs_dim = PlacementParams(n_receivers=6).obs_dim
    assert model.observation_space.shape == (obs_dim + 6,) and model.action_space.shape == (2,)
