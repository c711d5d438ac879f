"""sensorgym.envs.gimbal_tracking.bound: no rule or random action earns more than the frame
bound in any frame or the episode bound on any episode; the tracker's variance never falls
below the bound's least variance; where nothing is lost and the gimbal is on the target a
policy reaches the bound."""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np
import pytest

import sensorgym.envs  # noqa: F401  (registers the ids)
from sensorgym.agents.registry import RULES, rules_for
from sensorgym.envs.gimbal_tracking import bound

ENV_ID = "sensorgym/GimbalTracking-v0"
SEED = 10000
SCENARIOS = 6
FRAMES = 160  # a prefix of the 500-frame episode: the bound holds for any number of frames
FLOAT32 = 1e-6  # the rewards pass through float32 buffers


def _episodes(act, frames: int = FRAMES, seed: int = SEED, **fields):
    """``frames`` frames of ``SCENARIOS`` scenarios of the native vector env: the rewards
    ``(SCENARIOS, frames)`` (NaN after an episode's end), the tracker's posterior variances
    ``(SCENARIOS, frames, G, 2)``, the frame bounds from the start state and its episode bound
    over ``frames`` frames."""
    env = gym.make_vec(ENV_ID, num_envs=SCENARIOS, vectorization_mode="vector_entry_point",
                       **fields)  # fmt: skip
    obs, _ = env.reset(seed=seed)
    params, start = env.params, env.simulator_state
    steps = bound.step_bounds(params, start, frames)
    total = bound.episode_bound(params, start, frames)
    least = bound.least_variance(params, start.fusion_variance, frames)
    rewards, variance = (
        np.full((SCENARIOS, frames), np.nan),
        np.full((SCENARIOS, frames, *start.fusion_variance.shape[1:]), np.inf),
    )
    live = np.ones(SCENARIOS, dtype=bool)
    for k in range(frames):
        obs, reward, terminated, truncated, _ = env.step(act(env, obs, k))
        rewards[live, k] = reward[live]
        variance[live, k] = env.simulator_state.fusion_variance[live]
        live &= ~(terminated | truncated)
    env.close()
    return rewards, variance, steps, total, least


def _rule(name: str):
    memory: list = [None, None]

    def act(env, obs, k):
        if k == 0:
            memory[:] = [rules_for(ENV_ID, env.params, lambda: env.simulator_state)[name], None]
        action, memory[1] = memory[0].predict(
            obs, memory[1], episode_start=np.full(SCENARIOS, k == 0)
        )
        return action

    return act


def _assert_below(rewards, variance, steps, total, least) -> None:
    played = ~np.isnan(rewards)
    slack = FLOAT32 * np.maximum(np.abs(steps), 1.0)
    assert np.all(rewards[played] <= (steps + slack)[played]), np.nanmax(rewards - steps)
    returns = np.nansum(rewards, 1)
    assert np.all(returns <= total + FLOAT32 * np.maximum(np.abs(total), 1.0))
    # the induction of the module docstring, frame by frame
    assert np.all(variance[played] >= least[played] * (1.0 - 1e-12))


@pytest.mark.parametrize("name", sorted(RULES[ENV_ID]))
def test_no_rule_exceeds_the_bound_in_any_frame(name: str) -> None:
    _assert_below(*_episodes(_rule(name)))


def test_random_actions_never_exceed_it() -> None:
    rng = np.random.default_rng(5)

    def act(env, obs, k):
        return rng.uniform(-1.5, 1.5, env.action_space.shape).astype(np.float32)

    _assert_below(*_episodes(act))


#: several gimbals (theory §11.8.2): two with the default sectors, and two splitting the circle
#: at dead ahead with targets starting near it (hand-overs)
GIMBALS = {
    "two gimbals": {"n_gimbals": 2},
    "hand-over": {
        "n_gimbals": 2,
        "gimbal_sectors": ((-np.pi, 0.02), (-0.02, np.pi)),
        "start_azimuth": (-0.3, 0.3),
    },
}


@pytest.mark.parametrize("fields", list(GIMBALS))
@pytest.mark.parametrize("name", sorted(RULES[ENV_ID]))
def test_no_rule_exceeds_the_bound_with_several_gimbals(name: str, fields: str) -> None:
    _assert_below(*_episodes(_rule(name), **GIMBALS[fields]))


@pytest.mark.parametrize("fields", list(GIMBALS))
def test_random_actions_never_exceed_it_with_several_gimbals(fields: str) -> None:
    rng = np.random.default_rng(6)

    def act(env, obs, k):
        return rng.uniform(-1.5, 1.5, env.action_space.shape).astype(np.float32)

    _assert_below(*_episodes(act, **GIMBALS[fields]))


def test_with_several_gimbals_the_bound_is_the_least_gimbals():
    """The frame bound of two gimbals is that of the one whose least variance is smaller: a
    gimbal that starts sure of the target sets it."""
    env = gym.make_vec(ENV_ID, num_envs=2, vectorization_mode="vector_entry_point", n_gimbals=2)
    env.reset(seed=0)
    params, start = env.params, env.simulator_state
    sure = dataclasses.replace(start, fusion_variance=start.fusion_variance * [[[1.0], [0.01]]])
    alone = dataclasses.replace(
        start, fusion_variance=sure.fusion_variance[:, 1:]
    )  # the sure gimbal alone
    np.testing.assert_array_equal(
        bound.step_bounds(params, sure, 50), bound.step_bounds(params, alone, 50)
    )
    assert np.all(bound.step_bounds(params, sure, 50) >= bound.step_bounds(params, start, 50))


def test_an_episode_that_ends_early_is_bounded_by_its_best_partial_sum() -> None:
    """Slewing away loses the target and terminates after ``reacquire_limit`` frames out of
    view; with a reward reference so strict that every frame bound is negative, summing the
    whole time limit would undercut those short returns: the bound is the largest partial sum."""

    def away(env, obs, k):
        return np.ones(env.action_space.shape, dtype=np.float32)

    rewards, variance, steps, total, least = _episodes(away, sigma_ref=1e-6, reacquire_limit=5)
    assert np.all(steps < 0.0)
    assert np.all(np.isnan(rewards[:, -1]))  # every episode ended
    assert np.all(np.nansum(rewards, 1) > steps.sum(1))  # the whole-limit sum would not bound them
    _assert_below(rewards, variance, steps, total, least)
    assert np.allclose(total, steps[:, 0])  # the best partial sum is the first frame's


def test_a_tracker_sure_of_the_target_on_axis_reaches_the_bound() -> None:
    """No view losses, no occlusions, no vignetting, high contrast, the gimbal driven onto the
    true direction: every channel's posterior is certain of the object, and the rewards are
    the frame bounds."""
    fields = {
        "lose_probability": (0.0, 0.0),
        "aspect_change_probability": (0.0, 0.0),
        "occlusion_length": (0, 0),
        "vignetting": 0.0,
        "channel_contrast": (20.0, 20.0),
    }
    rewards, variance, steps, _, least = _episodes(_rule("truth-servo"), frames=60, **fields)
    np.testing.assert_allclose(rewards, steps, rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(variance, least, rtol=1e-9)


def test_the_least_variance_decreases_to_the_stationary_one() -> None:
    """From the reset's variance (one pixel squared, above the stationary value) ``d*_k``
    falls monotonically to the fixed point of its recursion."""
    env = gym.make_vec(ENV_ID, num_envs=2, vectorization_mode="vector_entry_point")
    env.reset(seed=0)
    params, start = env.params, env.simulator_state
    d = bound.least_variance(params, start.fusion_variance, 400)
    assert np.all(np.diff(d, axis=1) <= 0.0)
    model = params.fusion_tracker.model
    R2, d0 = model.correlation**2, model.transition_variance
    info = np.sum(np.max(model.fisher_information, axis=1))
    fixed = d[:, -1]
    np.testing.assert_allclose(fixed, 1.0 / (1.0 / (R2 * fixed + d0) + info), rtol=1e-12)


def test_bad_steps_raise() -> None:
    env = gym.make_vec(ENV_ID, num_envs=1, vectorization_mode="vector_entry_point")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="steps"):
        bound.step_bounds(env.params, env.simulator_state, 0)
