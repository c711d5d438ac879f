"""The step kernel split over threads (``run_rows``) gives the single thread's episodes bit for
bit: rows are independent and every draw is made before the split."""

from __future__ import annotations

import numpy as np
import pytest

from sensorgym.envs.bearings_maneuver.bearings_maneuver import BearingsManeuverVectorEnv
from sensorgym.envs.bearings_maneuver.simulation import ManeuverParams
from sensorgym.envs.shells.rows import MIN_ROWS_PER_THREAD
from sensorgym.envs.worlds.platform import PlatformWorldParams
from tests.conftest import assert_same_tree, random_play

# 300 scenarios: split over two threads (at least MIN_ROWS_PER_THREAD rows each)
BATCH = 300


def _episodes(monkeypatch, threads: str, params: ManeuverParams, mode: str) -> list:
    monkeypatch.setenv("SENSORGYM_THREADS", threads)
    env = BearingsManeuverVectorEnv(
        num_envs=BATCH, params=params, max_episode_steps=7, autoreset_mode=mode
    )
    return random_play(env, 20)


@pytest.mark.parametrize("mode", ["NextStep", "SameStep"])
@pytest.mark.parametrize(
    "params",
    [
        # scenarios started inside min_range end at once: terminations and time limits mix
        ManeuverParams(initial_range=(5_000.0, 11_000.0), min_range=6_000.0),
        ManeuverParams(platforms=2, world=PlatformWorldParams(q_tilde=1e-3)),
    ],
)
def test_two_threads_equal_one_bit_for_bit(monkeypatch, params, mode):
    assert BATCH >= 2 * MIN_ROWS_PER_THREAD
    one = _episodes(monkeypatch, "1", params, mode)
    two = _episodes(monkeypatch, "2", params, mode)
    assert_same_tree(one, two)
    terminated = np.concatenate([one[3 + 5 * k + 2] for k in range(20)])
    assert terminated.any()  # autoresets happened within the run
