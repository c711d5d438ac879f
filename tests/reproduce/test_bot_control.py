"""The textbook observer-control scenario: the env is the book's, and bot-control measures it."""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np
import pytest

from sensorgym.agents.book_maneuver import BOOK_OPTIMISED_TURNS, OpenLoop, book_leg_change
from sensorgym.envs.bearings_maneuver import BookManeuverParams, ManeuverParams
from sensorgym.envs.bearings_maneuver.book import BOOK_ENV_ID
from sensorgym.envs.bearings_maneuver.bound import episode_returns
from sensorgym.envs.bearings_maneuver.simulation import OBS_DIM
from sensorgym.envs.worlds.platform import rollout
from sensorgym.reproduce.experiments import bot_control
from sensorgym.reproduce.experiments.bot_benchmark import (
    pcrlb_of,
    pcrlb_position,
    prior_information,
    simulate,
)
from sensorgym.reproduce.experiments.bot_control import (
    BOOK,
    CEILING,
    FIXED_PLAN,
    STANDOFF,
    book_prior_factor,
    fly,
    format_report,
    nominal_paths,
    optimise_open_loop,
)
from sensorgym.trackers.bearings.crlb import bearing_information
from sensorgym.train.evaluation import make_sb3_env

#: the book's numbers and the optimiser's result, held to stated tolerances on any CPU
pytestmark = pytest.mark.arithmetic


def test_book_env_starts_in_the_books_scenario():
    env = gym.make(BOOK_ENV_ID)
    env.reset(seed=3)
    s = env.unwrapped.simulator_state
    x0 = BOOK.initial_state(1)
    np.testing.assert_allclose(s.target[0, :2] - s.platform_position[0, 0], BOOK.target_offset)
    np.testing.assert_allclose(s.target, x0.target, atol=1e-12)
    np.testing.assert_allclose(s.heading[0], x0.heading)
    np.testing.assert_allclose(s.speed[0], x0.speed)
    assert env.unwrapped.params.world == BOOK.world_params()
    assert env.spec.max_episode_steps == BOOK.n_bearings - 1
    assert env.unwrapped.params.min_range == STANDOFF


def test_default_scenario_draws_are_unchanged_by_the_new_fields():
    p = ManeuverParams()
    assert p.initial_heading == p.initial_bearing == p.target_course == (-np.pi, np.pi)
    with pytest.raises(ValueError, match="target_course"):
        ManeuverParams(target_course=(1.0, 0.0))
    with pytest.raises(ValueError, match="initial_heading"):
        BookManeuverParams(initial_heading=(0.0, np.inf))
    # the book params are ManeuverParams with other defaults only
    assert {f.name for f in dataclasses.fields(BookManeuverParams)} == {
        f.name for f in dataclasses.fields(ManeuverParams)
    }


def test_leg_change_through_the_env_is_bot_benchmarks_trajectory_and_bound():
    runs = 64
    env = make_sb3_env(BOOK_ENV_ID, runs, 5, max_episode_steps=None)
    flown = fly(book_leg_change(), env, runs, 5)
    env.close()
    assert not flown["broken"].any()
    # the observer flies the book's arcs exactly
    w = BOOK.world_params(q_tilde=0.0)
    ref = rollout(w, BOOK.initial_state(1), BOOK.actions())
    np.testing.assert_allclose(
        flown["pos"], np.broadcast_to(ref.platform_position, (runs, 33, 2)), atol=1e-6
    )
    # the book's PCRLB along the env's runs is bot-benchmark's (93 m with 1000 runs)
    result = bot_control._summarise("leg", "rule", flown)
    sim = simulate(BOOK, 256, np.random.default_rng(0))
    assert result.pcrlb_32min == pytest.approx(pcrlb_position(BOOK, sim)[-1], rel=0.05)
    assert 80.0 < result.pcrlb_32min < 110.0
    # one trajectory for all runs: averaging the information first changes little
    assert result.per_run_32min == pytest.approx(result.pcrlb_32min, rel=0.05)


def test_open_loop_counts_steps_per_env_and_checks_its_turns():
    policy = book_leg_change()
    obs = np.zeros((2, OBS_DIM), dtype=np.float32)
    a, k = policy.predict(obs)
    for _ in range(12):
        a, k = policy.predict(obs, k, np.array([False, False]))
    assert a[:, 0].tolist() == [-1.0, -1.0] and k.tolist() == [13, 13]
    a, k = policy.predict(obs, k, np.array([True, False]))  # env 0 starts a new episode
    assert a[:, 0].tolist() == [0.0, -1.0] and k.tolist() == [1, 14]
    with pytest.raises(ValueError, match="turns"):
        OpenLoop((0.0, 1.5))


def test_optimised_open_loop_beats_the_leg_change_and_keeps_the_standoff():
    opt = optimise_open_loop(restarts=1, seed=0)
    leg = np.exp(bot_control._final_log_bound(np.asarray([book_leg_change().turns]))[0][0])
    assert opt.pcrlb_noise_free < 0.9 * leg
    assert opt.min_range >= STANDOFF + bot_control.STANDOFF_MARGIN - 1.0
    assert np.all(np.abs(opt.turns) <= 1.0)


def test_the_shipped_optimised_turns_are_the_ceiling_they_claim():
    log_bound, ranges = bot_control._final_log_bound(np.asarray([BOOK_OPTIMISED_TURNS]))
    assert np.exp(log_bound[0]) == pytest.approx(48.5, abs=0.1)
    assert ranges.min() >= STANDOFF + bot_control.STANDOFF_MARGIN - 1.0


def test_the_ceilings_recursion_is_the_books_pcrlb_and_the_envs_paths():
    # the hindsight optimum's bound from the book's prior is bot-benchmark's PCRLB per run,
    # on the target paths the env produces (replayed from its noise stream)
    runs = 6
    env = make_sb3_env(BOOK_ENV_ID, runs, 7, max_episode_steps=None)
    flown = fly(book_leg_change(), env, runs, 7)
    params, state, paths = nominal_paths(env, 7)
    env.close()
    np.testing.assert_array_equal(paths, flown["target"])
    L0 = book_prior_factor(state)
    res = episode_returns(params, state, [flown["actions"]], paths=paths, prior_factor=L0)
    m0 = np.sqrt(np.trace((L0 @ L0.T)[:2, :2]))
    ours = np.array([m0 * np.exp(-r.value[0]) for r in res])
    J0 = prior_information(BOOK, paths[0, 0], flown["pos"][0, 0])
    info = bearing_information(flown["target"], flown["pos"], BOOK.sigma)
    theirs = pcrlb_of(BOOK, J0, info, final_only=True)[:, -1]
    np.testing.assert_allclose(ours, theirs, rtol=1e-8)


def test_bot_control_runs_and_lists_a_missing_trained_policy(monkeypatch):
    monkeypatch.setattr("sensorgym.train.shipped.shipped_policies", lambda env_id: {})
    res = bot_control.run_bot_control(runs=4, seed=1, restarts=0, polish=1)
    names = [p.name for p in res.policies]
    assert names[0] == "no manoeuvre" and "greedy information" in names
    assert res.missing_trained
    report = format_report(res)
    assert "missing" in report and "gap" in report
    by = {p.name: p for p in res.policies}
    leg = by["book leg change 140->20 deg, min 13-16"].pcrlb_32min
    # without a manoeuvre range stays poorly observed; the fixed plan beats the book's turn
    assert by["no manoeuvre"].pcrlb_32min > leg
    assert by[FIXED_PLAN].pcrlb_32min < leg and by[FIXED_PLAN].kind == "rule"
    # the ceiling: each run at least as good as every start (every policy's own turns), the
    # stand-off kept, at or below 35 m (issue 36)
    ceiling = by[CEILING]
    assert ceiling.standoff_broken == 0 and ceiling.min_range >= STANDOFF
    assert ceiling.pcrlb_32min <= 35.0
    c = res.ceiling
    assert np.all(np.asarray(c.pcrlb_32min_per_run) <= np.asarray(c.best_start_per_run))
    assert c.gain_mean >= 0.0
    for p in res.policies:
        # NaN where every run broke the stand-off (greedy information, here)
        assert p.gap_m == pytest.approx(p.pcrlb_32min - ceiling.pcrlb_32min, nan_ok=True)
        assert p.ratio == pytest.approx(p.pcrlb_32min / ceiling.pcrlb_32min, nan_ok=True)
        if p.standoff_broken == 0 and p.shifted_runs == 0:
            assert p.per_run_32min >= ceiling.per_run_32min - 1e-9
