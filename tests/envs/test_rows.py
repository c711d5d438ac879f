"""Row splitting over threads (:mod:`sensorgym.envs.shells.rows`)."""

from __future__ import annotations

import itertools
import multiprocessing as mp
import os
import time

import numpy as np
import pytest

from sensorgym.envs.shells import rows


def _square_rows(x: np.ndarray, out: np.ndarray, seen: list) -> None:
    def kernel_on(lo: int, hi: int) -> None:
        seen.append((lo, hi))
        out[lo:hi] = x[lo:hi] ** 2

    rows.run_rows(x.shape[0], kernel_on)


@pytest.mark.parametrize("batch", [1, 127, 256, 1000, 4097])
def test_every_row_once_in_contiguous_chunks(batch, monkeypatch):
    monkeypatch.setenv("SENSORGYM_THREADS", "3")
    x = np.random.default_rng(0).standard_normal(batch)
    out = np.full(batch, np.nan)
    seen: list = []
    _square_rows(x, out, seen)
    np.testing.assert_array_equal(out, x**2)
    chunks = sorted(seen)
    assert chunks[0][0] == 0 and chunks[-1][1] == batch
    assert all(a[1] == b[0] for a, b in itertools.pairwise(chunks))
    expected = max(1, min(3, batch // rows.MIN_ROWS_PER_THREAD))
    assert len(chunks) == expected


def test_one_thread_never_splits(monkeypatch):
    monkeypatch.setenv("SENSORGYM_THREADS", "1")
    seen: list = []
    _square_rows(np.ones(10_000), np.empty(10_000), seen)
    assert seen == [(0, 10_000)]


@pytest.mark.parametrize("value", ["0", "-2", "two"])
def test_bad_thread_count_is_named(value, monkeypatch):
    monkeypatch.setenv("SENSORGYM_THREADS", value)
    with pytest.raises(ValueError, match="SENSORGYM_THREADS"):
        rows.threads()


def test_chunk_exceptions_reach_the_caller(monkeypatch):
    monkeypatch.setenv("SENSORGYM_THREADS", "2")

    def kernel_on(lo: int, hi: int) -> None:
        if lo > 0:
            raise RuntimeError("chunk failed")

    with pytest.raises(RuntimeError, match="chunk failed"):
        rows.run_rows(1024, kernel_on)


def _child(queue) -> None:
    out = np.empty(1024)
    _square_rows(np.arange(1024.0), out, [])
    queue.put(float(out.sum()))


def test_a_forked_child_builds_its_own_pool(monkeypatch):
    monkeypatch.setenv("SENSORGYM_THREADS", "2")
    _square_rows(np.arange(1024.0), np.empty(1024), [])  # the parent's pool exists
    ctx = mp.get_context("fork")
    queue = ctx.Queue()
    p = ctx.Process(target=_child, args=(queue,))
    p.start()
    p.join(timeout=60)
    assert p.exitcode == 0
    assert queue.get(timeout=5) == float((np.arange(1024.0) ** 2).sum())


@pytest.mark.parametrize("threads", ["1", "2", "3"])
@pytest.mark.parametrize("batch", [5, 256, 1000])
def test_drawn_rows_are_drawn_in_order_before_their_kernel(threads, batch, monkeypatch):
    """``run_drawn_rows`` draws consecutive ranges covering the batch in order, and a chunk's
    kernel starts only once its rows are drawn."""
    monkeypatch.setenv("SENSORGYM_THREADS", threads)
    drawn = np.zeros(batch, dtype=bool)
    draws: list = []
    ran: list = []

    def draw(lo: int, hi: int) -> None:
        draws.append((lo, hi))
        drawn[lo:hi] = True

    def kernel_on(lo: int, hi: int) -> None:
        assert drawn[lo:hi].all()
        ran.append((lo, hi))

    for _ in range(3):  # the later calls are sized by the measured costs
        draws.clear(), ran.clear()
        drawn[:] = False
        rows.run_drawn_rows(batch, draw, kernel_on, key=f"test-{threads}-{batch}")
        assert draws[0][0] == 0 and draws[-1][1] == batch
        assert all(a[1] == b[0] for a, b in itertools.pairwise(draws))
        assert sorted(ran) == draws
        assert len(ran) == max(1, min(int(threads), batch // rows.MIN_ROWS_PER_THREAD))


def test_a_failed_draw_waits_for_the_started_chunks(monkeypatch):
    monkeypatch.setenv("SENSORGYM_THREADS", "2")
    finished: list = []

    def draw(lo: int, hi: int) -> None:
        if lo > 0:
            raise RuntimeError("draw failed")

    def kernel_on(lo: int, hi: int) -> None:
        time.sleep(0.05)
        finished.append((lo, hi))

    with pytest.raises(RuntimeError, match="draw failed"):
        rows.run_drawn_rows(1024, draw, kernel_on, key="test-failed-draw")
    assert len(finished) == 1  # the pool's chunk had ended before the error was raised


def test_unset_means_the_cpus_this_process_may_run_on(monkeypatch):
    monkeypatch.delenv("SENSORGYM_THREADS", raising=False)  # set to 1 in pytest-xdist workers
    assert rows.threads() == min(8, len(os.sched_getaffinity(0)))
