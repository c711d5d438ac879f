"""Splitting a batch's scenario rows over threads (``SENSORGYM_THREADS``) changes nothing: the
native vector env gives bit-identical episodes on one thread and on two, across autoresets."""

from __future__ import annotations

import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

from sensorgym.envs.shells import rows
from sensorgym.envs.stereo_placement.stereo_placement import StereoPlacementVectorEnv
from tests.conftest import assert_same_tree

B = 320  # two chunks of at least rows.MIN_ROWS_PER_THREAD


def _episodes(autoreset_mode: AutoresetMode) -> list:
    venv = StereoPlacementVectorEnv(num_envs=B, max_episode_steps=4, autoreset_mode=autoreset_mode)
    obs, info = venv.reset(seed=5)
    out = [obs, info]
    actions = np.random.default_rng(6).uniform(-1.2, 1.2, (11, B, 6))
    for a in actions:
        out.append(venv.step(a))
    return out


@pytest.mark.parametrize("autoreset_mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
def test_two_threads_equal_one_bit_for_bit(monkeypatch, autoreset_mode):
    assert B >= 2 * rows.MIN_ROWS_PER_THREAD
    monkeypatch.setenv("SENSORGYM_THREADS", "1")
    one = _episodes(autoreset_mode)
    monkeypatch.setenv("SENSORGYM_THREADS", "2")
    assert min(rows.threads(), B // rows.MIN_ROWS_PER_THREAD) == 2  # really split
    two = _episodes(autoreset_mode)
    assert_same_tree(one, two)
    # every scenario was truncated after 4 steps and restarted (twice in 11 steps)
    truncated = np.array([step[3] for step in two[2:]])
    ends = [3, 8] if autoreset_mode is AutoresetMode.NEXT_STEP else [3, 7]
    assert truncated[ends].all() and truncated.sum() == 2 * B
