"""The plan-acquire rule: the planner's return weighed by the chance that the receivers sent to
a drone find it on the tracker's prediction. With certain acquisition it is plan-horizon's
value; on the cue a near receiver's chance is low; its decisions are the argmax of the
acquisition-aware plan features; and on the scenario the diagnosis found (tuning seed 500,
episode 40) it fixes both drones where plan-horizon sends a receiver that misses one and
never fixes it."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from sensorgym.agents.registry import rules_for
from sensorgym.agents.stereo_pointing import (
    EPISODE_STEPS,
    acquired_values,
    acquisition_probability,
    all_assignments,
    geometry_values,
    plan_geometry,
    rule_view,
)
from sensorgym.agents.stereo_pointing_horizon import PlanHorizon
from sensorgym.envs.stereo_pointing import simulation
from sensorgym.envs.stereo_pointing.simulation import PointingParams
from sensorgym.train.env_wrappers.stereo_pointing import PlanFeatures
from sensorgym.train.evaluation import make_sb3_env

ENV_ID = "sensorgym/StereoPointing-v0"


def _cue_view(params: PointingParams, seed: int, batch: int):
    state = simulation.reset(params, np.random.default_rng(seed), batch)
    return state, rule_view(params, simulation.observe(params, state).astype(np.float64))


def test_certain_acquisition_is_the_plain_plan_and_doubt_costs_the_floor():
    params = PointingParams()
    _, view = _cue_view(params, 3, 6)
    flight = (view.azimuth, view.elevation, view.position, view.velocity, np.full(6, 90.0), 3)
    g = plan_geometry(params, *flight)
    plain = geometry_values(params, g)
    np.testing.assert_allclose(acquired_values(params, g, np.ones((6, 4, 2))), plain, atol=1e-9)
    # nobody finds anything: every drone earns the floor -R on each of the 90 steps
    np.testing.assert_allclose(
        acquired_values(params, g, np.zeros((6, 4, 2))), -params.reward_clip * 90.0
    )
    # a doubtful receiver lowers the value of exactly the candidates that send it
    p_see = np.ones((6, 4, 2))
    p_see[:, 1, 0] = 0.5
    v = acquired_values(params, g, p_see)
    uses = all_assignments(params)[:, 1] == 0
    np.testing.assert_allclose(v[:, ~uses], plain[:, ~uses], atol=1e-9)
    assert np.all(v[:, uses] <= plain[:, uses] + 1e-9)


def test_acquisition_probability_falls_with_the_track_error_over_the_range():
    params = PointingParams()
    _, view = _cue_view(params, 500, 128)
    p = acquisition_probability(params, view)
    assert p.shape == (128, 4, 2) and np.all((p > 0.0) & (p <= 1.0))
    # the same cue error (sigma equal for both drones) is a wider angle from a nearer receiver
    b = 40
    order = np.argsort(view.ranges[b, :, 0])
    assert np.all(np.diff(p[b, order, 0]) >= 0.0)
    # receiver 1 stands 53 m from drone 0, its cue 8.7 m RMS off: a third of the time it misses
    assert 0.55 < p[b, 1, 0] < 0.75 and p[b, 0, 0] > 0.95
    # a receiver that saw the drone keeps it
    seen = view.seen.copy()
    seen[b, 1, 0] = 1.0
    kept = acquisition_probability(params, replace(view, seen=seen))
    assert kept[b, 1, 0] == 1.0


def test_decisions_are_the_argmax_of_the_acquisition_features():
    params = PointingParams()
    rule = rules_for(ENV_ID, params, lambda: None)["plan-acquire"]
    assert isinstance(rule, PlanHorizon) and rule.acquisition
    env = PlanFeatures(make_sb3_env(ENV_ID, 8, 0), horizons=(100,), acquisition=True)
    env.seed(3)
    obs = env.reset()
    base, C, n = params.obs_dim, 16, params.n_receivers
    cand = all_assignments(params)
    state, start = None, np.ones(8, dtype=bool)
    for t in range(60):
        f = obs[:, base:].astype(np.float64)
        left = EPISODE_STEPS - t
        h, loss = (100, f[:, :C]) if left >= 100 else (left, f[:, 2 * C : 3 * C])
        want = cand[np.argmax(h * loss + rule.keep_bonus * n * f[:, 4 * C : 5 * C], axis=1)]
        np.testing.assert_array_equal(rule.assign(obs[:, :base], t), want)
        action, state = rule.predict(obs[:, :base], state=state, episode_start=start)
        obs, _, start, _ = env.step(action)


def test_it_keeps_the_pair_that_finds_the_drone_where_plan_horizon_loses_it():
    """Seed 500's scenario 40 (of a batch of 128, as the diagnosis played it): plan-horizon
    sends receivers 1 and 3 to drone 0, receiver 1 53 m from it with the cue 8.6° off (the
    field of view is 8°): drone 0 is never fixed. plan-acquire leaves receiver 1 on drone 1,
    and both drones are fixed."""
    params = PointingParams()
    choice, fixed = {}, {}
    for acquisition in (False, True):
        rule = PlanHorizon(params, acquisition=acquisition)
        rng = np.random.default_rng(500)
        state = simulation.reset(params, rng, 128)
        obs = simulation.observe(params, state)
        choice[acquisition] = rule.assign(obs, np.zeros(128, np.int64))[40].tolist()
        count = np.zeros(2)
        for t in range(40):
            target = rule.assign(obs, np.full(128, t))
            action = simulation.assignment_actions(params, obs, target)
            state, _, _ = simulation.step(params, state, action, rng)
            obs = simulation.observe(params, state)
            count += state.fixed[40]
        fixed[acquisition] = count
    assert choice[False] == [1, 0, 1, 0] and choice[True][1] == 1
    assert fixed[False][0] == 0 and fixed[True].min() >= 25


def test_plain_horizons_add_the_plain_plan_beside_the_acquisition_plan():
    """``plain_horizons`` blocks sit after the acquisition blocks and before the time left, and
    hold the plain plan (the plan-horizon evidence) at those horizons."""
    params = PointingParams()
    base = params.obs_dim
    both = PlanFeatures(
        make_sb3_env(ENV_ID, 4, 0), horizons=(100,), acquisition=True, plain_horizons=(50,)
    )
    plain = PlanFeatures(make_sb3_env(ENV_ID, 4, 0), horizons=(50,), time_left=False)
    acquire = PlanFeatures(make_sb3_env(ENV_ID, 4, 0), horizons=(100,), acquisition=True)
    obs = both.reset()[:, :base]
    t = np.zeros(4, np.int64)
    f, g, a = both.features(obs, t), plain.features(obs, t), acquire.features(obs, t)
    C = 16
    assert f.shape == (4, 7 * C) and both.observation_space.shape == (base + 7 * C,)
    np.testing.assert_array_equal(f[:, : 2 * C], a[:, : 2 * C])  # acquisition, 100 steps
    np.testing.assert_array_equal(f[:, 2 * C : 4 * C], g[:, : 2 * C])  # plain, 50 steps
    np.testing.assert_array_equal(f[:, 4 * C :], a[:, 2 * C :])  # time left (acquisition), kept
    with pytest.raises(ValueError, match="plain_horizons"):
        PlanFeatures(make_sb3_env(ENV_ID, 4, 0), plain_horizons=(50,))
