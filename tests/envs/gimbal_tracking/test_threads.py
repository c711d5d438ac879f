"""The step kernel split over threads (``run_rows``) gives the single thread's episodes bit for
bit: rows are independent and every draw is made before the split."""

from __future__ import annotations

import pytest

from sensorgym.envs.gimbal_tracking.gimbal_tracking import GimbalTrackingVectorEnv
from sensorgym.envs.gimbal_tracking.simulation import GimbalParams
from sensorgym.envs.shells.rows import MIN_ROWS_PER_THREAD
from tests.conftest import assert_same_tree, random_play

# 300 scenarios: split over two threads (at least MIN_ROWS_PER_THREAD rows each)
BATCH = 300


def _episodes(monkeypatch, threads: str, params: GimbalParams, mode: str) -> list:
    monkeypatch.setenv("SENSORGYM_THREADS", threads)
    env = GimbalTrackingVectorEnv(
        num_envs=BATCH, params=params, max_episode_steps=9, autoreset_mode=mode
    )
    return random_play(env, 24)


@pytest.mark.parametrize("mode", ["NextStep", "SameStep"])
@pytest.mark.parametrize(
    "params",
    [
        # random rates lose the target at once: terminations after 3 frames out of view and
        # time limits mix
        GimbalParams(reacquire_limit=3),
        GimbalParams(channel_contrast=(4.0,), channel_noise=(1.0,), lose_probability=(0.05,),
                     return_probability=(0.3,), aspect_change_probability=(0.05,)),
        GimbalParams(n_gimbals=3, reacquire_limit=3),  # the gimbal loop of every row
    ],
)  # fmt: skip
def test_two_threads_equal_one_bit_for_bit(monkeypatch, params, mode):
    assert BATCH >= 2 * MIN_ROWS_PER_THREAD
    one = _episodes(monkeypatch, "1", params, mode)
    two = _episodes(monkeypatch, "2", params, mode)
    assert_same_tree(one, two)
