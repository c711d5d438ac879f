"""The hindsight optimum (``sensorgym.envs.bearings_maneuver.bound``) bounds every rule and every
shipped policy on the episodes they played, keeps the stand-off and replays in the env."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

from sensorgym.envs.bearings_maneuver import bound
from sensorgym.envs.bearings_maneuver.bearings_maneuver import ENV_ID
from sensorgym.envs.bearings_maneuver.book import BOOK_ENV_ID

ENVS = (ENV_ID, BOOK_ENV_ID)


def _steps(env_id: str) -> int:
    return int(gym.spec(env_id).max_episode_steps)


def _policies(env_id: str) -> list[tuple[str, Any, dict[str, Any] | None]]:
    """Every registered rule and shipped policy: (name, factory of env → policy, config)."""
    from sensorgym.agents.registry import RULES
    from sensorgym.train.evaluation import env_params, simulator_state
    from sensorgym.train.models import load_model, read_config
    from sensorgym.train.shipped import shipped_policies

    out: list[tuple[str, Any, dict[str, Any] | None]] = []
    for name, make in RULES[env_id].items():
        out.append((name, lambda env, make=make: make(env_params(env), simulator_state(env)), None))
    for run, folder in shipped_policies(env_id).items():
        config = read_config(Path(folder))
        out.append((run, lambda env, folder=folder: load_model(Path(folder), env), config))
    return out


def _play(env_id: str, seed: int, make: Any, config: dict[str, Any] | None) -> tuple:
    """One episode (batch of 1, seeded ``seed``) of a policy: its actions ``(T, 2)`` (zeros
    after the episode ended) and its return."""
    from sensorgym.train.evaluation import make_sb3_env
    from sensorgym.train.models import wrappers_of

    agents = bool(config.get("agents", False)) if config else False
    wrappers = wrappers_of(config) if config else ()
    env = make_sb3_env(env_id, 1, seed, agents=agents, wrappers=wrappers)
    try:
        policy = make(env)
        env.seed(seed)
        obs = env.reset()
        T = _steps(env_id)
        actions, total, state, start = np.zeros((T, 2)), 0.0, None, np.ones(1, dtype=bool)
        for t in range(T):
            a, state = policy.predict(obs, state=state, episode_start=start, deterministic=True)
            actions[t] = np.reshape(a, (1, -1))[0, :2]
            obs, reward, done, _ = env.step(a)
            total += float(reward[0])
            start = done
            if done[0]:
                break
        return actions, total
    finally:
        env.close()


def _episode(env_id: str, seed: int) -> tuple:
    """The reset state, params, generator and target path of the seeded one-scenario episode
    the policies played (the SB3 env's draws replayed)."""
    from sensorgym.train.evaluation import env_params, make_sb3_env, simulator_state

    env = make_sb3_env(env_id, 1, seed, max_episode_steps=None)
    env.seed(seed)
    env.reset()
    params, state = env_params(env), simulator_state(env)()
    paths = bound.target_paths(params, state, _steps(env_id), env.get_attr("np_random")[0])
    env.close()
    return params, state, paths


def _replay(env_id: str, seed: int, actions: np.ndarray) -> float:
    """The return of ``actions (T, 2)`` played through the env (SB3 vector env, seeded), in
    float64: the optimum rides the stand-off (its closest approach can be micrometres above
    ``min_range``), so rounding its actions to float32 may cross it and end the episode."""
    from sensorgym.train.evaluation import make_sb3_env

    env = make_sb3_env(env_id, 1, seed, max_episode_steps=None)
    env.seed(seed)
    env.reset()
    total = 0.0
    for t in range(actions.shape[0]):
        _, reward, done, _ = env.step(np.asarray(actions[t][None], dtype=np.float64))
        total += float(reward[0])
        if done[0]:
            break
    env.close()
    return total


def _check_bounds_every_policy(env_id: str, seed: int) -> None:
    params, state, paths = _episode(env_id, seed)
    played = {name: _play(env_id, seed, make, config) for name, make, config in _policies(env_id)}
    names = list(played)
    starts = [played[n][0][None] for n in names]
    returns = np.array([played[n][1] for n in names])
    res = bound.hindsight_optimum(
        params, state, starts, restarts=1, seed=seed, paths=paths, polish=2
    )
    # the kernel's return of each policy's actions is the return the policy got in the env
    # (float32 rewards through SB3: tolerance for that only)
    np.testing.assert_allclose(res.start_values[0], returns, rtol=0.0, atol=1e-5)
    # the bound holds every rule and policy, by construction; the stand-off is kept
    assert np.all(res.value[0] >= res.start_values[0]), dict(zip(names, returns, strict=True))
    assert np.all(res.value[0] >= returns - 1e-5)
    assert res.standoff_ok[0] and res.closest[0] >= params.min_range
    assert res.gain[0] >= 0.0 and res.value[0] == res.best_start[0] + res.gain[0]
    # the optimum replays in the env
    assert _replay(env_id, seed, res.actions[0, :, 0]) == pytest.approx(res.value[0], abs=1e-5)


@pytest.mark.parametrize("env_id", ENVS)
def test_the_optimum_bounds_every_rule_and_shipped_policy(env_id: str) -> None:
    _check_bounds_every_policy(env_id, 20_001)


@pytest.mark.slow
@pytest.mark.parametrize("seed", [20_002, 20_003, 20_004])
@pytest.mark.parametrize("env_id", ENVS)
def test_the_optimum_bounds_every_policy_on_more_episodes(env_id: str, seed: int) -> None:
    _check_bounds_every_policy(env_id, seed)


def test_the_kernel_is_the_env_exactly_including_the_penalty() -> None:
    # Gymnasium env, float64 rewards: the recursion, termination and penalty bit for bit
    env = gym.make(ENV_ID, min_range=3_000.0)
    env.reset(seed=4)
    u = env.unwrapped
    params, state = u.params, u.simulator_state
    paths = bound.target_paths(params, state, 30)
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1.2, 1.2, (30, 2))  # outside [−1, 1]: the env clips, so do we
    total, steps = 0.0, 0
    for t in range(30):
        _, r, terminated, _, _ = env.step(actions[t])
        total, steps = total + r, steps + 1
        if terminated:
            break
    res = bound.episode_returns(params, state, [actions[None]], paths=paths)[0]
    assert res.value[0] == pytest.approx(total, abs=1e-12)
    assert res.ended[0] == steps and res.standoff_ok[0] == (steps == 30 and not terminated)


def test_target_paths_replay_the_envs_noise_stream() -> None:
    env = gym.make(BOOK_ENV_ID)
    env.reset(seed=9)
    u = env.unwrapped
    paths = bound.target_paths(u.params, u.simulator_state, 32, copy.deepcopy(u.np_random))
    seen = [u.simulator_state.target[0]]
    for _ in range(32):
        env.step(np.array([0.3, 0.0]))
        seen.append(u.simulator_state.target[0])
    np.testing.assert_array_equal(paths[0], np.array(seen))
    with pytest.raises(ValueError, match="rng"):
        bound.target_paths(u.params, u.simulator_state, 32)


def test_the_optimum_of_two_platforms_and_speed_changes_keeps_the_best_start() -> None:
    # two platforms, turn and speed: the optimiser varies all 4 entries and keeps the standoff
    env = gym.make(ENV_ID, platforms=2)
    env.reset(seed=11)
    u = env.unwrapped
    params, state = u.params, u.simulator_state
    straight = np.zeros((30, 2, 2))
    res = bound.hindsight_optimum(
        params, state, [straight], restarts=1, seed=0, steps=30, polish=1, maxiter=30
    )
    assert res.actions.shape == (1, 30, 2, 2)
    assert res.value[0] >= res.start_values[0, 0] and res.standoff_ok[0]
    assert np.any(res.actions[0, :, :, 1] != 0.0)  # speed changes were used
    replay = bound.episode_returns(params, state, [res.actions], steps=30)[0]
    assert replay.value[0] == res.value[0]


@pytest.mark.parametrize("env_id", ENVS)
def test_a_benchmark_episode_is_rebuilt_from_its_stream_alone(env_id: str) -> None:
    """The vector env with one stream per episode: slot ``i``'s ``k``-th episode starts in the
    state :func:`bound.benchmark_episode` rebuilds, and its target follows the rebuilt path
    (two rounds of ``steps`` steps, NEXT_STEP autoreset between them, random actions)."""
    seed, slots, steps = 321, 3, 6
    env = gym.make_vec(env_id, num_envs=slots, vectorization_mode="vector_entry_point",
                       episode_streams=True, max_episode_steps=steps)  # fmt: skip
    env.reset(seed=seed)
    params = env.params
    rng = np.random.default_rng(0)
    starts, paths = [], []
    for _ in range(2):
        starts.append(env.simulator_state)
        path = [env.simulator_state.target]
        for _ in range(steps):
            _, _, terminated, truncated, _ = env.step(rng.uniform(-1, 1, env.action_space.shape))
            path.append(env.simulator_state.target)
        assert truncated.all() and not terminated.any()
        paths.append(np.stack(path, axis=1))  # (slots, steps + 1, 4)
        env.step(np.zeros(env.action_space.shape))  # NEXT_STEP: the next episodes' resets
    for k, (start, path) in enumerate(zip(starts, paths, strict=True)):
        for i in range(slots):
            state, rebuilt = bound.benchmark_episode(params, seed, i, k, steps)
            np.testing.assert_array_equal(state.target[0], start.target[i])
            np.testing.assert_array_equal(state.bound_factor[0], start.bound_factor[i])
            np.testing.assert_array_equal(state.platform_position[0], start.platform_position[i])
            np.testing.assert_allclose(rebuilt[0], path[i], rtol=0.0, atol=1e-9)
    env.close()
