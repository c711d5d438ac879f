"""The polynomial assignment solver against the exhaustive search on random small instances,
and the pointing rules at 16 receivers × 10 drones, where only the polynomial solver runs.

The ratios are printed (``pytest -s``); what is asserted is what theory guarantees: the
sequential greedy comes within half of the best assignment's information gain (the
submodular gain under a partition matroid, Fisher, Nemhauser & Wolsey 1978), no solver beats
the exhaustive optimum, and the coordinate-wise ascent stops at a local optimum of the rule's
own objective.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from pettingzoo.test import parallel_api_test

from sensorgym.agents.assignment_solver import (
    MAX_ASSIGNMENTS,
    MIN_RISE,
    SeparableObjective,
    assignments,
    best_of,
    exhaustive,
    improve,
    sequential_greedy,
)
from sensorgym.agents.registry import rules_for
from sensorgym.agents.stereo_pointing import (
    GreedyPointing,
    OrthogonalPairs,
    PlanEstimate,
    TruthPlan,
    _one_step,
    hysteresis_bonus,
    plan_values,
    rule_view,
)
from sensorgym.envs import stereo_pointing
from sensorgym.envs.stereo_pointing.simulation import PointingParams, lines_of_sight
from sensorgym.envs.stereo_pointing.stereo_pointing import StereoPointingVectorEnv
from sensorgym.trackers.stereo import kernels

ENV_ID = "sensorgym/StereoPointing-v0"
SMALL = [(4, 3), (5, 3)]


def _index(choice: np.ndarray, m: int) -> np.ndarray:
    """Row of each assignment ``(N, n)`` in :func:`assignments` (lexicographic, base ``m``)."""
    n = choice.shape[1]
    return (choice * m ** np.arange(n)[::-1]).sum(axis=1)


@pytest.mark.parametrize(("n", "m"), SMALL)
def test_sequential_greedy_gets_at_least_half_the_best_information_gain(n, m):
    """Random drones around the receivers, random prior accuracies: the greedy gain over the
    exhaustive optimum of the submodular gain lies in [1/2, 1]."""
    rng = np.random.default_rng(100 * n + m)
    N = 200
    params = PointingParams(n_receivers=n, n_drones=m)
    drones = rng.uniform([-150.0, 20.0, -150.0], [150.0, 80.0, 150.0], (N, m, 3))
    los, r = lines_of_sight(params, drones)
    w = 1.0 / (params.sigma_ang * r) ** 2
    prior = 1.0 / rng.uniform(0.1, 10.0, (N, m)) ** 2
    objective = _one_step(kernels.GAIN, los, w, prior, ())
    cand = assignments(n, m)
    every = objective.gains(np.tile(cand, (N, 1)), np.repeat(np.arange(N), len(cand)))
    best = every.reshape(N, len(cand)).max(axis=1)
    greedy = objective.gains(sequential_greedy(objective))
    ratio = greedy / best
    print(f"\n{n}x{m} greedy/optimal information gain: min {ratio.min():.4f}"
          f" mean {ratio.mean():.4f}, optimal in {np.mean(ratio > 1 - 1e-12):.0%}")  # fmt: skip
    assert np.all(best > 0.0)
    assert np.all(ratio >= 0.5) and np.all(ratio <= 1.0 + 1e-12)


def _plain_ascent(objective: SeparableObjective, start: np.ndarray, bonus: np.ndarray):
    """The coordinate-wise ascent spelled out on the objective's marginals, one scenario at a
    time, every drone's marginals recomputed after every move (no cache)."""
    B, n, m = objective.shape
    out = start.copy()
    for b in range(B):
        a = out[b : b + 1]
        for _ in range(n * m):
            cols = np.arange(m)[None, :]
            value = objective.marginals(a, np.array([b]), np.arange(n), cols)[0] + bonus[b]
            rise = (value - value[np.arange(n), a[0]][:, None]).ravel()
            best = int(np.argmax(rise))
            if not rise[best] > MIN_RISE:
                break
            a[0, best // m] = best % m
    return out


@pytest.mark.parametrize(
    "kind", [kernels.LOG_DET, kernels.GAIN, kernels.REWARD, kernels.ORTHOGONALITY]
)
def test_compiled_ascent_makes_the_moves_of_the_plain_ascent(kind):
    """The compiled ascent (only the two drones a move touches re-scored, drone columns kept
    per receiver set across the starts) ends where the plain ascent ends, from every start;
    ``best_of`` keeps the end of the highest objective plus bonus."""
    rng = np.random.default_rng(40 + kind)
    N, S, n, m = 24, 3, 7, 4
    u = rng.normal(size=(N, S, n, m, 3))
    u /= np.linalg.norm(u, axis=-1, keepdims=True)
    objective = SeparableObjective(
        kind=kind,
        u=u,
        w=rng.uniform(0.5, 2.0, (N, S, n, m)),
        ready=rng.uniform(size=(N, S, n, m)) < 0.8,
        prior=rng.uniform(0.1, 1.0, (N, m)),
        weight=rng.uniform(0.5, 1.5, (N, S)),
        consts=np.array([2.0, 5.0]) if kind == kernels.REWARD else np.array([30.0]),
    )
    bonus = rng.uniform(0.0, 0.2, (N, n, m))
    starts = [rng.integers(0, m, (N, n)) for _ in range(3)]
    ends = [_plain_ascent(objective, s, bonus) for s in starts]
    for s, end in zip(starts, ends, strict=True):
        np.testing.assert_array_equal(improve(objective, s, bonus), end)
    score = np.stack(
        [objective.gains(e) + bonus[np.arange(N)[:, None], np.arange(n), e].sum(-1) for e in ends]
    )
    pick = np.argmax(score - MIN_RISE * np.arange(3)[:, None], axis=0)
    np.testing.assert_array_equal(
        best_of(objective, starts, bonus), np.stack(ends)[pick, np.arange(N)]
    )


def test_a_broadcast_bonus_solves_alike_and_compiles_no_second_signature():
    """A bonus given per receiver and drone ``(n, m)`` is broadcast to every scenario (a
    read-only view): the solvers take it through ``kernel_array``, so it gives the result of
    the full array and the kernels keep one compiled signature (a read-only array is another
    numba type: a second compile of the ascent costs seconds on a fresh install)."""
    rng = np.random.default_rng(3)
    N, S, n, m = 5, 2, 4, 3
    u = rng.normal(size=(N, S, n, m, 3))
    u /= np.linalg.norm(u, axis=-1, keepdims=True)
    objective = SeparableObjective(
        kind=kernels.GAIN,
        u=u,
        w=rng.uniform(0.5, 2.0, (N, S, n, m)),
        ready=np.ones((N, S, n, m), bool),
        prior=rng.uniform(0.1, 1.0, (N, m)),
        weight=np.ones((N, S)),
        consts=np.array([30.0]),
    )
    per_pair = rng.uniform(0.0, 0.5, (n, m))
    full = np.tile(per_pair, (N, 1, 1))
    start = rng.integers(0, m, (N, n))
    np.testing.assert_array_equal(
        improve(objective, start, per_pair), improve(objective, start, full)
    )
    np.testing.assert_array_equal(
        sequential_greedy(objective, per_pair), sequential_greedy(objective, full)
    )
    assert len(kernels.assignment_ascent_batch.signatures) == 1
    assert len(kernels.assignment_greedy_batch.signatures) == 1


def test_trace_of_the_inverse_is_the_inverses_diagonal_bit_for_bit():
    """``position_sigma`` reads ``tr I⁻¹`` off the column solves of the inverse: the same bits
    as summing the diagonal of :func:`~sensorgym.trackers.stereo.kernels.inverse3`."""
    rng = np.random.default_rng(7)
    M = rng.normal(size=(2000, 3, 3)) * 10.0 ** rng.integers(-6, 6, (2000, 1, 1))
    A = np.concatenate([M, M @ np.swapaxes(M, 1, 2)])
    LU, piv, inv = np.empty((3, 3)), np.empty(3, np.int64), np.empty((3, 3))
    for a in A:
        kernels.inverse3(a, LU, piv, inv)
        assert kernels.trace_inverse3(a, LU, piv) == inv[0, 0] + inv[1, 1] + inv[2, 2]


def test_set_scores_match_the_factorised_bound():
    """The solvers' set score reads ``tr I⁻¹`` off the principal minors: the env's reward from
    the LU-based ``position_sigma`` to 1e-11 at weights within 1e±3 (both err by about κ·ε
    in ``σ²``), ``−R`` where unobservable (one view, parallel lines of sight); ``ln det`` the
    bits of ``det3``; joining a receiver equals summing its projection."""
    rng = np.random.default_rng(11)
    consts_reward, consts_det = np.array([3.0, 5.0]), np.array([30.0])
    for trial in range(600):
        views = int(rng.integers(1, 5))
        u = rng.normal(size=(views + 1, 3))
        if trial % 10 == 0:  # parallel lines of sight: no fix
            u[:] = u[0]
        u /= np.linalg.norm(u, axis=1, keepdims=True)
        w = 10.0 ** rng.uniform(-3, 3, views + 1)
        info = np.zeros((3, 3))
        for k in range(views):
            kernels.add_projection(u[k], w[k], info)
        ok = np.empty(1, dtype=np.bool_)
        kernels.observable_batch(info[None], np.array([views]), ok)
        sigma = np.empty(1)
        kernels.position_sigma_batch(info[None], ok, np.ones(1), sigma)
        expected = np.empty(1)
        kernels.log_ratio_reward_batch(sigma, 3.0, 5.0, expected)
        got = kernels.information_score(kernels.REWARD, info, views, 0.0, consts_reward)
        np.testing.assert_allclose(got, expected[0], rtol=0.0, atol=1e-11)
        if not ok[0]:
            assert got == -5.0
        d = kernels.det3(info)
        log_det = np.log(d) if views >= 2 and d > 0.0 else -30.0
        assert kernels.information_score(kernels.LOG_DET, info, views, 0.0, consts_det) == log_det
        joined = info.copy()
        kernels.add_projection(u[views], w[views], joined)
        for kind, consts in ((kernels.LOG_DET, consts_det), (kernels.REWARD, consts_reward)):
            assert kernels.joined_score(
                kind, info, u[views], w[views], views, 0.0, consts
            ) == kernels.information_score(kind, joined, views + 1, 0.0, consts)


def _states(params: PointingParams, seed: int, N: int = 48):
    """Observations (and the simulator) after a few random steps: drones partly seen."""
    venv = StereoPointingVectorEnv(num_envs=N, params=params)
    obs, _ = venv.reset(seed=seed)
    venv.action_space.seed(seed)
    for _ in range(4):
        obs, *_ = venv.step(venv.action_space.sample())
    return venv, obs.astype(np.float64)


def _rule_objective(rule, params: PointingParams, obs: np.ndarray, venv) -> np.ndarray:
    """The rule's own objective of every assignment ``(N, C)``, from the exhaustive scores."""
    view = rule_view(params, obs)
    cand = assignments(params.n_receivers, params.n_drones)
    out = np.empty((len(obs), len(cand)))
    if isinstance(rule, OrthogonalPairs):
        kernels.assignment_orthogonality_batch(view.los, cand, out)
        return out + hysteresis_bonus(view, cand, rule.keep_bonus)
    if isinstance(rule, GreedyPointing):
        sigma = max(params.sigma_ang, 1e-9)
        kernels.assignment_log_det_batch(
            view.los, view.ranges, sigma, cand, float(rule.no_fix_cost), out
        )
        return out + hysteresis_bonus(view, cand, rule.keep_bonus)
    if isinstance(rule, PlanEstimate):
        left = np.full(len(obs), float(rule.horizon))
        return plan_values(
            params, view.azimuth, view.elevation, view.position, view.velocity, left, rule.stride
        )
    return rule.values(venv.simulator_state)


@pytest.mark.parametrize(("n", "m"), SMALL)
@pytest.mark.parametrize("name", ["orthogonal-pairs", "greedy-information", "plan-estimate", "truth-plan"])  # fmt: skip
def test_polynomial_rules_stop_at_a_local_optimum_never_above_the_exhaustive_one(name, n, m):
    params = PointingParams(n_receivers=n, n_drones=m)
    venv, obs = _states(params, seed=10 * n + m)
    rules = {}
    for solver in ("exhaustive", "greedy"):  # the registered rule with either solver
        rule = rules_for(ENV_ID, params, lambda: venv.simulator_state)[name]
        if isinstance(rule, TruthPlan):
            rule.solver = solver
            rules[solver] = rule
        else:
            rules[solver] = dataclasses.replace(rule, solver=solver)
    value = _rule_objective(rules["exhaustive"], params, obs, venv)
    exact = rules["exhaustive"].assign(obs)
    choice = rules["greedy"].assign(obs)
    N = len(obs)
    best = value[np.arange(N), _index(exact, m)]
    got = value[np.arange(N), _index(choice, m)]
    np.testing.assert_array_equal(best, value.max(axis=1))  # the exhaustive rule is exact
    assert np.all(got <= best + 1e-9)
    # no single receiver can move to another drone and raise the objective
    for k in range(n):
        for j in range(m):
            moved = choice.copy()
            moved[:, k] = j
            assert np.all(value[np.arange(N), _index(moved, m)] <= got + MIN_RISE + 1e-9)
    worst = value.min(axis=1)
    share = (got - worst) / np.maximum(best - worst, 1e-300)
    print(f"\n{name} {n}x{m}: greedy optimal in {np.mean(got >= best - 1e-9):.0%},"
          f" (F - F_min)/(F_opt - F_min) mean {share.mean():.3f} min {share.min():.3f}")  # fmt: skip


def test_auto_is_exhaustive_up_to_the_limit_and_polynomial_beyond():
    assert exhaustive("auto", 6, 4) and 4**6 == MAX_ASSIGNMENTS
    assert not exhaustive("auto", 7, 4) and exhaustive("exhaustive", 7, 4)
    assert not exhaustive("greedy", 2, 2)
    with pytest.raises(ValueError, match="solver"):
        OrthogonalPairs(PointingParams(), solver="fast")
    params = PointingParams(n_receivers=16, n_drones=10)
    _, obs = _states(params, seed=3, N=4)
    with pytest.raises(ValueError, match="exceed 4096"):
        PlanEstimate(params, solver="exhaustive").assign(obs)
    for rule in (OrthogonalPairs(params), GreedyPointing(params), PlanEstimate(params)):
        choice = rule.assign(obs)
        assert choice.shape == (4, 16) and choice.min() >= 0 and choice.max() < 10


def test_every_rule_drives_16_receivers_and_10_drones():
    """Every registered rule through a short episode at 16 × 10: actions in bounds, finite
    rewards; the assignment rules keep a pair of receivers on at least one drone."""
    params = PointingParams(n_receivers=16, n_drones=10)
    venv = StereoPointingVectorEnv(num_envs=4, params=params, max_episode_steps=6)
    for name, rule in rules_for(ENV_ID, params, lambda: venv.simulator_state).items():
        obs, _ = venv.reset(seed=5)
        for _ in range(6):
            action, _ = rule.predict(obs)
            assert action.shape == (4, 32) and np.all(np.abs(action) <= 1.0), name
            obs, reward, *_ = venv.step(action)
            assert np.all(np.isfinite(reward)), name
        if hasattr(rule, "assign"):
            counts = np.stack([np.bincount(a, minlength=10) for a in rule.assign(obs)])
            assert np.all(counts.max(axis=1) >= 2), name


def test_pettingzoo_api_at_16_receivers_and_10_drones():
    parallel_api_test(stereo_pointing.parallel_env(n_receivers=16, n_drones=10), num_cycles=20)
