"""The StereoScanning step split over threads gives the single thread's episodes bit for bit,
also where the direction noise is drawn row range by row range while the first chunk already
runs (``run_drawn_rows``), and leaves the Generator where one thread leaves it."""

from __future__ import annotations

import pytest

from sensorgym.envs.shells import rows
from sensorgym.envs.stereo_scanning import kernels
from sensorgym.envs.stereo_scanning.simulation import ScanningParams
from sensorgym.envs.stereo_scanning.stereo_scanning import StereoScanningVectorEnv
from tests.conftest import assert_same_tree, random_play
from tests.kernel_signatures import kernel_signatures

# 300 scenarios: split over two threads (at least MIN_ROWS_PER_THREAD rows each)
BATCH = 300
STEP_ROWS = kernels.step_rows


def _episodes(monkeypatch, threads: str, params: ScanningParams, mode: str):
    """Every output of 12 steps (episodes of 5: autoresets on the way), the row ranges of the
    step kernel, and the env Generator's next draw."""
    chunks: list = []

    def spy(lo, hi, *args):
        chunks.append((lo, hi))
        return STEP_ROWS(lo, hi, *args)

    monkeypatch.setenv("SENSORGYM_THREADS", threads)
    monkeypatch.setattr(kernels, "step_rows", spy)
    env = StereoScanningVectorEnv(
        num_envs=BATCH, params=params, max_episode_steps=5, autoreset_mode=mode
    )
    return random_play(env, 12), chunks, env.np_random.random()


@pytest.mark.parametrize("mode", ["NextStep", "SameStep"])
@pytest.mark.parametrize(
    "params",
    [
        ScanningParams(),  # direction noise only: drawn per chunk, pipelined
        ScanningParams(position_sigma=0.5, clutter_rate=1.0),  # every draw before the split
    ],
)
def test_two_threads_equal_one_bit_for_bit(monkeypatch, params, mode):
    assert BATCH >= 2 * rows.MIN_ROWS_PER_THREAD
    one, chunks_one, next_one = _episodes(monkeypatch, "1", params, mode)
    two, chunks_two, next_two = _episodes(monkeypatch, "2", params, mode)
    assert set(chunks_one) == {(0, BATCH)}
    assert len(chunks_two) == 2 * len(chunks_one) and all(hi > lo for lo, hi in chunks_two)
    assert_same_tree(one, two)
    assert next_one == next_two  # the same draws were taken from the stream


def test_the_pipelined_split_gives_the_calling_thread_the_last_rows(monkeypatch):
    """The pool thread runs the first rows as soon as they are drawn; after the first step the
    split follows the measured costs (any split: the same results, tested above)."""
    _, chunks, _ = _episodes(monkeypatch, "2", ScanningParams(), "SameStep")
    firsts = [c for c in chunks if c[0] == 0]
    lasts = [c for c in chunks if c[1] == BATCH]
    assert len(firsts) == len(lasts) == 12
    assert all(first[1] == last[0] for first, last in zip(firsts, lasts, strict=True))


def test_noise_settings_share_one_step_kernel():
    """Position noise and clutter pass drawn arrays where the default passes read-only zeros;
    the drawn ones are read-only too, so the step kernel is not compiled again for them (numba
    types read-only arrays apart: half a minute per mix on a fresh install)."""
    variants = [
        ScanningParams(),
        ScanningParams(position_sigma=0.5, clutter_rate=1.0),
        ScanningParams(clutter_rate=1.0),
        ScanningParams(position_sigma=0.5),
    ]
    counts = []
    for params in variants:
        env = StereoScanningVectorEnv(num_envs=4, params=params, max_episode_steps=5)
        random_play(env, 3)
        counts.append(kernel_signatures())
    assert counts == [counts[0]] * len(variants)
