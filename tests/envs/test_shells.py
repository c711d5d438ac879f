"""The shells' generic machinery: scenario selection and autoreset of only the ended scenarios."""

from __future__ import annotations

from types import SimpleNamespace

import gymnasium as gym
import numpy as np
import pytest

from sensorgym.envs.shells import tree_scatter, tree_where


def _states(env_id: str, batch: int, seed: int):
    env = gym.make_vec(env_id, batch, vectorization_mode="vector_entry_point")
    env.reset(seed=seed)
    return env.unwrapped


@pytest.mark.parametrize(
    "env_id",
    ["sensorgym/StereoPointing-v0", "sensorgym/StereoPlacement-v0", "sensorgym/StereoScanning-v0"],
)
def test_scatter_puts_the_fresh_scenarios_in_order(env_id):
    old = _states(env_id, 5, 1).simulator_state
    fresh = _states(env_id, 2, 2).simulator_state
    mask = np.array([False, True, False, False, True])
    mixed = tree_scatter(mask, fresh, old)
    np.testing.assert_array_equal(mixed.t, old.t)
    np.testing.assert_array_equal(mixed.drone_position[mask], fresh.drone_position)
    np.testing.assert_array_equal(mixed.drone_position[~mask], old.drone_position[~mask])
    # as tree_where with the fresh scenarios spread over the masked places
    spread = tree_scatter(mask, fresh, old)
    assert np.array_equal(tree_where(mask, spread, old).drone_position, mixed.drone_position)
    with pytest.raises(ValueError, match="fresh shape"):
        tree_scatter(mask, _states(env_id, 3, 3).simulator_state, old)
    with pytest.raises(ValueError, match="mask"):
        tree_scatter(mask[:3], fresh, old)


def test_scatter_refuses_a_different_shared_clock():
    env = _states("sensorgym/BearingsManeuver-v0", 3, 0)
    old = env.simulator_state
    env.step(np.zeros((3, 2), np.float32))
    fresh = gym.make_vec(
        "sensorgym/BearingsManeuver-v0", 1, vectorization_mode="vector_entry_point"
    )
    fresh.reset(seed=5)
    with pytest.raises(ValueError, match="shared value"):
        tree_scatter(
            np.array([True, False, False]), fresh.unwrapped.simulator_state, env.simulator_state
        )
    assert old.batch_size == 3


def test_autoreset_draws_only_the_ended_scenarios():
    # close targets end some episodes early (termination), the others run on
    venv = gym.make_vec(
        "sensorgym/BearingsManeuver-v0",
        6,
        vectorization_mode="vector_entry_point",
        initial_range=(600.0, 3_000.0),
        target_speed=(5.0, 8.0),
        min_range=800.0,
        autoreset_mode="SameStep",
    )
    venv.reset(seed=0)
    inner = venv.unwrapped
    sizes = []
    reset = inner.core.simulation.reset

    def counting(params, rng, batch, like=None):
        sizes.append(batch)
        return reset(params, rng, batch, like)

    inner.core.simulation = SimpleNamespace(**{**vars(inner.core.simulation), "reset": counting})
    ended = []
    for _ in range(25):
        _, _, terminated, truncated, _ = venv.step(np.zeros((6, 2), np.float32))
        done = terminated | truncated
        if done.any() and not done.all():
            ended.append(int(done.sum()))
    assert ended, "no partial ending in this scenario set"
    assert sizes[: len(ended)] == ended
