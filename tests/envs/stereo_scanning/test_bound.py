"""sensorgym.envs.stereo_scanning.bound: no rule, shipped policy or random action earns more than
the step bound in any period or the episode bound on any episode; the bound's three facts hold
on the env's own episodes."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import sensorgym.envs  # noqa: F401  (registers the ids)
from sensorgym.agents.registry import RULES, rules_for
from sensorgym.envs.stereo_scanning import bound
from sensorgym.envs.stereo_scanning import simulation as core
from sensorgym.envs.stereo_scanning.simulation import ScanningParams
from sensorgym.train.benchmark import PolicySpec, score
from sensorgym.train.bounds import bound_violations
from sensorgym.train.shipped import shipped_policies

ENV_ID = "sensorgym/StereoScanning-v0"
SEED = 10000
SCENARIOS = 8
STEPS = 40  # the registered time limit
FLOAT32 = 1e-6  # the rewards pass through float32 buffers on the SB3 path


def _slack(b: np.ndarray) -> np.ndarray:
    return FLOAT32 * np.maximum(np.abs(b), 1.0)


def _episodes(act, seed: int = SEED, **fields) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One episode of each of ``SCENARIOS`` scenarios of the native vector env: the rewards
    and ``parts[:, 0]`` (drones present) of every period ``(SCENARIOS, STEPS)`` (0 after
    the end), and the step bounds of the start state."""
    env = gym.make_vec(ENV_ID, num_envs=SCENARIOS, vectorization_mode="vector_entry_point",
                       **fields)  # fmt: skip
    obs, _ = env.reset(seed=seed)
    params, start = env.params, env.simulator_state
    steps = bound.step_bounds(params, start, STEPS)
    rewards, present = np.zeros((SCENARIOS, STEPS)), np.zeros((SCENARIOS, STEPS))
    live = np.ones(SCENARIOS, dtype=bool)
    for k in range(STEPS):
        obs, reward, terminated, truncated, _ = env.step(act(env, obs, k))
        rewards[live, k] = reward[live]
        present[live, k] = env.simulator_state.parts[live, 0]
        live &= ~(terminated | truncated)
    assert not live.any()  # every episode ends within the time limit
    env.close()
    return rewards, present, steps


def _rule(name: str):
    memory: list = [None]

    def act(env, obs, k):
        if k == 0:
            memory[:] = [rules_for(ENV_ID, env.params, lambda: env.simulator_state)[name], None]
        rule = memory[0]
        action, memory[1] = rule.predict(obs, memory[1], episode_start=np.full(SCENARIOS, k == 0))
        return action

    return act


def _assert_below(rewards: np.ndarray, steps: np.ndarray) -> None:
    assert np.all(rewards <= steps + _slack(steps)), np.max(rewards - steps)
    returns, total = rewards.sum(1), steps.sum(1)
    assert np.all(returns <= total + _slack(total))


@pytest.mark.parametrize("name", sorted(RULES[ENV_ID]))
def test_no_rule_exceeds_the_bound_in_any_period(name: str) -> None:
    rewards, present, steps = _episodes(_rule(name))
    _assert_below(rewards, steps)
    # fact 3: the drones present, the episode's end, are the same whatever the policy did
    assert np.array_equal(present > 0, steps != 0)


def test_random_actions_never_exceed_it() -> None:
    rng = np.random.default_rng(5)
    for scale in (1.0, 3.0):  # inside the box, and clipped to its faces and corners

        def act(env, obs, k, scale=scale):
            return scale * rng.uniform(-1.0, 1.0, env.action_space.shape)

        rewards, present, steps = _episodes(act, seed=77)
        _assert_below(rewards, steps)
        assert np.array_equal(present > 0, steps != 0)


@pytest.mark.parametrize("run", sorted(shipped_policies(ENV_ID)))
def test_no_shipped_policy_exceeds_its_episode_bound(run: str) -> None:
    spec = PolicySpec("model", str(shipped_policies(ENV_ID)[run]), shipped=True)
    result = score(ENV_ID, spec, 2 * SCENARIOS, SCENARIOS, SEED)  # two rounds: an autoreset
    assert len(result["bounds"]) == 2 * SCENARIOS
    assert bound_violations(result) == []


def test_no_confirmed_track_before_confirm_hits_periods() -> None:
    """Fact 2: every period before the ``h``-th pays ``−R`` where a drone is present (the
    bound is exact there), and with ``h = 1`` the bound has no such period."""
    for h in (1, 2, 3):
        rewards, present, steps = _episodes(_rule("greedy-information"), confirm_hits=h)
        early = present[:, : h - 1] > 0
        assert np.all(rewards[:, : h - 1][early] == -5.0)
        assert np.all(steps[:, : h - 1][early] == -5.0)
        assert np.all(steps[:, h - 1 :][present[:, h - 1 :] > 0] == 5.0)


def test_the_episode_bound_sums_the_periods_and_leaves_the_state_alone() -> None:
    params = ScanningParams()
    start = core.reset(params, np.random.default_rng(4), SCENARIOS)
    before = start.drone_position.copy(), start.exited.copy(), start.tracks.copy()
    total = bound.episode_bound(params, start)
    np.testing.assert_array_equal(total, bound.step_bounds(params, start, STEPS).sum(1))
    for a, b in zip(before, (start.drone_position, start.exited, start.tracks), strict=True):
        np.testing.assert_array_equal(a, b)
    # over more periods than the episode has, the bound can only grow (B_k ≥ 0 from k = h)
    assert np.all(bound.episode_bound(params, start, STEPS + 10) >= total)


def test_inside_an_episode_every_period_with_a_drone_is_bounded_by_the_clip() -> None:
    """From a state past the reset confirmed tracks may exist: no period is ``−R``; the
    bound still covers the rest of the episode's return."""
    params = ScanningParams()
    rng = np.random.default_rng(0)
    start = core.reset(params, rng, 4)
    later, _, _ = core.step(params, start, np.zeros((4, 3, 3)), rng)
    after = bound.step_bounds(params, later, STEPS - 1)
    assert np.all(np.isin(after, (0.0, 5.0)))
    np.testing.assert_array_equal(after != 0, bound.step_bounds(params, start, STEPS)[:, 1:] != 0)
    with pytest.raises(ValueError, match="steps"):
        bound.step_bounds(params, start, 0)
