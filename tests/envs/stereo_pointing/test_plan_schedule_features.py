"""The schedule block of ``plan-features`` (issue 37): per candidate assignment the
re-acquisition evidence of the drones it leaves without a pair, read by the linear residual of
the ``CandidatePolicy``; off by default (the observation is today's), and zero weights on it
leave the untrained policy the exhaustive planner."""

from __future__ import annotations

import numpy as np
import torch as th

from sensorgym.agents.registry import RULES
from sensorgym.agents.stereo_pointing import all_assignments, rule_view, slew_steps
from sensorgym.agents.stereo_pointing_schedule import (
    MAX_DEADLINE,
    SCHEDULE_FEATURES,
    SLACK_SCALE,
    Schedule,
    forced_drone,
    reacquire_steps,
    schedule_features,
)
from sensorgym.envs.stereo_pointing import simulation
from sensorgym.envs.stereo_pointing.crowded import CROWDED_ENV_ID, CrowdedPointingParams
from sensorgym.train.candidate_policy import LINEAR_FLAG_SCALE, CandidatePolicy
from sensorgym.train.config import ALGORITHMS, load_hyperparams, split_run_settings
from sensorgym.train.env_wrappers.stereo_pointing import PlanFeatures
from sensorgym.train.evaluation import evaluate, make_sb3_env

S = len(SCHEDULE_FEATURES)


def test_a_candidate_leaving_the_urgent_drone_unpaired_shows_it():
    """On the cue of seeded scenarios (drones seen by one receiver each, RMS of metres), with a
    schedule that forces every drone whose deadline lies ahead: a candidate pairs the forced
    drone (``urgent_paired`` 1) exactly when it sends two receivers to it; one that leaves it
    unpaired counts its urgency ``exp(−max(slack, 0) / SLACK_SCALE)`` among the unpaired
    ones; a lost drone is never urgent; every feature lies in ``[0, m]``."""
    params = CrowdedPointingParams()
    obs = simulation.observe(params, simulation.reset(params, np.random.default_rng(7), 16))
    view = rule_view(params, obs.astype(np.float64))
    schedule = Schedule(lead=MAX_DEADLINE)
    f = schedule_features(params, view, schedule)
    cand = all_assignments(params)
    assert f.shape == (16, 81, S) and SCHEDULE_FEATURES[1] == "urgent_paired"
    assert np.all((f >= 0.0) & (f <= params.n_drones))
    deadline = reacquire_steps(params, view, schedule.reach)
    transit = np.sort(slew_steps(params, view.azimuth, view.elevation, view.position), axis=1)
    slack = deadline - transit[:, 1]
    forced = forced_drone(params, view, schedule)
    assert (forced >= 0).sum() >= 8
    for row, j in enumerate(forced):
        pairs = (cand == max(j, 0)).sum(axis=1) >= 2  # (C,)
        if j < 0:
            assert np.all(f[row, :, 1] == 0.0)
            continue
        np.testing.assert_array_equal(f[row, :, 1], pairs.astype(float))
        urgency = np.exp(-max(slack[row, j], 0.0) / SLACK_SCALE)
        assert urgency > 0.0
        assert np.all(f[row, ~pairs, 0] >= urgency - 1e-12)
    # exactly: the urgency of every live drone the candidate leaves unpaired, a lost one none
    urgency = np.where(deadline > 0, np.exp(-np.maximum(slack, 0.0) / SLACK_SCALE), 0.0)
    unpaired = np.stack([(cand == j).sum(axis=1) < 2 for j in range(params.n_drones)], axis=1)
    np.testing.assert_allclose(f[..., 0], urgency @ unpaired.T, rtol=1e-12)


def _features(schedule, seed=3, n=4, steps=3):
    env = PlanFeatures(
        make_sb3_env(CROWDED_ENV_ID, n, 0), horizons=(15, 100), acquisition=True, schedule=schedule
    )
    env.seed(seed)
    out = [env.reset()]
    for _ in range(steps):
        out.append(env.step(np.zeros((n, 8), dtype=np.float32))[0])
    return env, np.stack(out)


def test_schedule_off_leaves_the_observation_as_today_and_on_appends_the_block():
    default = PlanFeatures(make_sb3_env(CROWDED_ENV_ID, 2, 0), horizons=(15, 100))
    assert default.schedule is None
    off_env, off = _features(None)
    on_env, on = _features(Schedule())
    C = 81
    assert off.shape[-1] == CrowdedPointingParams().obs_dim + C * (2 * 3 + 1)
    assert on.shape[-1] == off.shape[-1] + C * S
    np.testing.assert_array_equal(on[..., : off.shape[-1]], off)
    for env, obs in ((off_env, off), (on_env, on)):
        assert np.all(obs >= env.observation_space.low) and np.all(
            obs <= env.observation_space.high
        )
    params = CrowdedPointingParams()
    view = rule_view(params, on[-1, :, : params.obs_dim].astype(np.float64))
    want = schedule_features(params, view).reshape(4, -1)
    np.testing.assert_allclose(on[-1, :, off.shape[-1] :], want, rtol=1e-6)


def _crowded_ars(n_envs=2, **overrides):
    hp = load_hyperparams("ars", CROWDED_ENV_ID)
    hp.update(overrides)
    run, kwargs = split_run_settings(hp)
    env = make_sb3_env(CROWDED_ENV_ID, n_envs, 0, wrappers=run["wrappers"])
    return ALGORITHMS["ars"](run["policy"], env, seed=0, **kwargs)


def test_the_linear_residual_weighs_the_schedule_block_and_starts_as_the_planner():
    """The crowded ars.yml entry reads the schedule block: the linear features end with
    ``LINEAR_FLAG_SCALE`` times it, the search vector has a zero weight for each; the untrained
    policy plays exactly as ``plan-search-exhaustive`` on 2 seeded episodes, and a weight on
    the urgent-pair flag changes its choices."""
    model = _crowded_ars(episodes=2)
    policy = model.policy
    assert isinstance(policy, CandidatePolicy) and policy.layout.schedule_inputs == S
    assert np.array_equal(model.theta, np.zeros(2 * 4 + 1 + S))
    obs = model.env.reset()
    x = th.as_tensor(obs)
    lin = policy.mlp_extractor.linear_features(x)
    assert lin.shape == (2, 81, 2 * 4 + 1 + S)
    block = policy.layout.schedule_block(x)
    th.testing.assert_close(lin[..., -S:], LINEAR_FLAG_SCALE * block)
    rule = RULES[CROWDED_ENV_ID]["plan-search-exhaustive"](CrowdedPointingParams(), None)
    theirs = evaluate(rule, make_sb3_env(CROWDED_ENV_ID, 2, 0), 2, 21)
    assert evaluate(model, model.env, 2, 21).returns == theirs.returns
    theta = np.zeros_like(model.theta)
    theta[-S + 1] = 10.0  # urgent_paired: +100 return units
    model.set_theta(theta)
    assert evaluate(model, model.env, 2, 21).returns != theirs.returns
