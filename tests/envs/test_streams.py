"""One random stream per episode (``episode_streams=True``): a slot's ``k``-th episode is the
same scenario, drawn the same way, however the episodes before it ended — in every env, in both
autoreset modes."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import sensorgym.envs as envs
from sensorgym.envs.shells.normals import standard_normal_rows
from sensorgym.envs.shells.streams import EpisodeStreams, RowGenerator

SLOTS = 3


def _episodes(env_id: str, limit: int, mode: str, seed: int = 4) -> dict[tuple[int, int], list]:
    """Each slot's episodes under constant zero actions with time limit ``limit``: (slot,
    episode number) → the episode's observations."""
    env = gym.make_vec(env_id, num_envs=SLOTS, vectorization_mode="vector_entry_point",
                       autoreset_mode=mode, episode_streams=True,
                       max_episode_steps=limit)  # fmt: skip
    obs, _ = env.reset(seed=seed)
    action = np.zeros(env.action_space.shape, dtype=np.float32)
    rounds = np.zeros(SLOTS, dtype=int)
    out: dict[tuple[int, int], list] = {(i, 0): [obs[i]] for i in range(SLOTS)}
    fresh = np.zeros(SLOTS, dtype=bool)  # NEXT_STEP: this step's obs is a new episode's first
    for _ in range(13):
        obs, _, terminated, truncated, info = env.step(action)
        done = terminated | truncated
        for i in range(SLOTS):
            if mode == "SameStep" and done[i]:
                out[(i, rounds[i])].append(info["final_obs"][i])
                rounds[i] += 1
                out[(i, rounds[i])] = [obs[i]]
            elif fresh[i]:
                rounds[i] += 1
                out[(i, rounds[i])] = [obs[i]]
            else:
                out[(i, rounds[i])].append(obs[i])
        fresh = done if mode == "NextStep" else np.zeros(SLOTS, dtype=bool)
    env.close()
    return out


@pytest.mark.parametrize("mode", ["NextStep", "SameStep"])
@pytest.mark.parametrize("env_id", envs.ENV_IDS)
def test_an_episode_does_not_depend_on_when_the_others_ended(env_id: str, mode: str) -> None:
    short, long = _episodes(env_id, 2, mode), _episodes(env_id, 3, mode)
    # episode k of slot i: the same first observations, step for step, whatever the time limit
    for (i, k), a in short.items():
        if (i, k) in long and k > 0:
            b = long[(i, k)]
            n = min(len(a), len(b))
            np.testing.assert_array_equal(np.stack(a[:n]), np.stack(b[:n]), err_msg=f"{i}, {k}")
    # and the slots' first episodes differ from one another (independent streams; a
    # scanning episode's first observation is empty, its next ones are not)
    firsts = [np.stack(long[(i, 0)]) for i in range(SLOTS)]
    assert not np.array_equal(firsts[0], firsts[1])


def test_the_streams_are_keyed_by_seed_slot_and_episode() -> None:
    a, b = EpisodeStreams(3, seed=9), EpisodeStreams(3, seed=9)
    b.next_episode([1])
    assert a.generator(0).random() == b.generator(0).random()
    assert a.generator(1).random() != b.generator(1).random()  # slot 1 moved on in b
    a.next_episode(np.array([False, True, False]))
    a2 = EpisodeStreams(3, seed=9)
    a2.next_episode([1])
    assert a.generator(1).random() == a2.generator(1).random()
    assert (
        EpisodeStreams(3, seed=10).generator(0).random()
        != EpisodeStreams(3, 9).generator(0).random()
    )


def test_a_row_generator_draws_each_row_from_its_own_stream() -> None:
    gens = [np.random.default_rng(s) for s in (1, 2)]
    rows = RowGenerator([np.random.default_rng(s) for s in (1, 2)])
    x = rows.uniform(-1.0, 2.0, (2, 3))
    np.testing.assert_array_equal(x[1], gens[1].uniform(-1.0, 2.0, 3))
    np.testing.assert_array_equal(x[0], gens[0].uniform(-1.0, 2.0, 3))
    out = np.empty((2, 4, 3))
    standard_normal_rows(rows, out, 0, 2)
    np.testing.assert_array_equal(out[1], gens[1].standard_normal((4, 3)))
    assert rows.poisson(2.0, (2, 5)).dtype == np.int64
    with pytest.raises(ValueError, match="leading size of 2 rows"):
        rows.standard_normal((3, 2))
    with pytest.raises(ValueError, match="leading size"):
        rows.random()


def test_episode_streams_must_be_a_bool() -> None:
    with pytest.raises(TypeError, match="episode_streams"):
        gym.make_vec(envs.ENV_IDS[0], num_envs=2, vectorization_mode="vector_entry_point",
                     episode_streams=1)  # fmt: skip
