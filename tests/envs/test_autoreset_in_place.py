"""Autoreset writes the fresh scenarios into the state a step has just allocated: nothing
handed out before (states, observations, infos, the SAME_STEP final observation) changes."""

from __future__ import annotations

import copy

import gymnasium as gym
import numpy as np
import pytest

from sensorgym.envs.shells import contract

ENV_IDS = [
    "sensorgym/BearingsManeuver-v0",
    "sensorgym/StereoPointing-v0",
    "sensorgym/StereoPlacement-v0",
    "sensorgym/StereoScanning-v0",
    "sensorgym/GimbalTracking-v0",
]


def _run(env_id: str, mode: str, steps: int) -> list:
    """Every step's outputs, the objects themselves (not copies), with the state after it."""
    venv = gym.make_vec(
        env_id,
        6,
        vectorization_mode="vector_entry_point",
        autoreset_mode=mode,
        max_episode_steps=3,
    )
    venv.reset(seed=0)
    inner = venv.unwrapped
    rng = np.random.default_rng(1)
    out = []
    for i in range(steps):
        # a different number of scenarios ends on different steps: partial autoresets
        if i % 4 == 1:
            inner._steps[::2] = 3
        a = rng.uniform(-1, 1, venv.action_space.shape).astype(np.float32)
        out.append((venv.step(a), inner.simulator_state))
    return out


@pytest.mark.parametrize("mode", ["NextStep", "SameStep"])
@pytest.mark.parametrize("env_id", ENV_IDS)
def test_in_place_autoreset_changes_nothing_handed_out(env_id, mode, monkeypatch):
    steps = 9
    in_place = _run(env_id, mode, steps)
    snapshots = [copy.deepcopy(contract.tree_arrays(step)) for step in in_place]
    # the same seeded run with every autoreset copying the state (the reference)
    real = contract.tree_scatter
    monkeypatch.setattr(
        contract,
        "tree_scatter",
        lambda mask, fresh, old, **kw: real(mask, fresh, old, in_place=False),
    )
    copied = _run(env_id, mode, steps)
    for i, (step, snapshot, ref) in enumerate(zip(in_place, snapshots, copied, strict=True)):
        now, expected = contract.tree_arrays(step), contract.tree_arrays(ref)
        assert len(now) == len(snapshot) == len(expected)
        for a, b, c in zip(now, snapshot, expected, strict=True):
            # what step i returned is what it was then (later autoresets did not touch it)
            np.testing.assert_array_equal(a, b, err_msg=f"step {i} changed later")
            np.testing.assert_array_equal(a, c, err_msg=f"step {i} differs from copying")
