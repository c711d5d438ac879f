"""Scenario rows of a batch split over threads: the compiled step kernels release the GIL.

Every env's step is one compiled kernel looping over scenarios (rows of the batch); its random
draws are made with the env's Generator before the kernel runs the rows they belong to, so rows
are independent and any split of them gives bit-identical results. :func:`run_rows` runs
``kernel_on(lo, hi)`` over contiguous row ranges, on :func:`threads` threads when the batch is
large enough to pay for the hand-off to a pool thread, else in the calling thread.
:func:`run_drawn_rows` also makes the draws, range by range in the stream's order, so that the
pool's chunks run while the calling thread still draws the later rows (StereoScanning: 480
normal draws per scenario at 16 receivers × 10 drones, a sizeable share of its step when drawn
first).

Why threads and not numba's ``prange``: a ``parallel=True`` kernel adds seconds of cold compile
per env, and numba's OpenMP/TBB layers do not survive ``fork()`` (SB3's subprocess vector envs,
Ray workers). The pool here is created lazily in each process (a forked child builds its own),
and kernels compiled with ``nogil=True`` need nothing else.

``SENSORGYM_THREADS`` (environment variable) sets the thread count; ``1`` turns splitting off.
"""

from __future__ import annotations

import functools
import itertools
import os
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor, wait
from dataclasses import dataclass

import numpy as np

#: fewest scenarios per thread for a split to pay (the hand-off to a pool thread costs as much
#: as many scenarios' steps)
MIN_ROWS_PER_THREAD = 128

#: per key of :func:`run_drawn_rows`: the last call's costs (what the next split is sized by)
_costs: dict[str, _Costs] = {}

_pool: ThreadPoolExecutor | None = None
_pool_pid: int | None = None


def threads() -> int:
    """Threads a batch may be split over: ``SENSORGYM_THREADS``, else the CPUs this process
    may run on (at most 8). An empty ``SENSORGYM_THREADS`` counts as unset; anything else but
    an integer >= 1 raises ``ValueError`` naming the variable."""
    env = os.environ.get("SENSORGYM_THREADS", "").strip()
    if env:
        try:
            n = int(env)
        except ValueError:
            raise ValueError(f"SENSORGYM_THREADS: expected an integer, got {env[:40]!r}") from None
        if n < 1:
            raise ValueError(f"SENSORGYM_THREADS: must be >= 1, got {n}")
        return n
    return _cpus()


@functools.cache
def _cpus() -> int:
    try:
        cpus = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        cpus = os.cpu_count() or 1
    return max(1, min(cpus, 8))


def _executor(workers: int) -> ThreadPoolExecutor:
    """This process's pool (rebuilt after a fork: a child inherits no threads)."""
    global _pool, _pool_pid
    pid = os.getpid()
    if _pool is None or _pool_pid != pid or _pool._max_workers < workers:
        _pool = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="sensorgym-rows")
        _pool_pid = pid
    return _pool


def run_rows(batch: int, kernel_on: Callable[[int, int], object]) -> None:
    """``kernel_on(lo, hi)`` over rows ``[0, batch)``: in one call when the batch is small,
    else over contiguous chunks, one per thread (the calling thread takes the first).

    ``kernel_on`` must write disjoint rows only (a compiled ``nogil`` kernel on row slices);
    exceptions of any chunk are raised here.
    """
    n = min(threads(), batch // MIN_ROWS_PER_THREAD)
    if n <= 1:
        kernel_on(0, batch)
        return
    edges = [batch * i // n for i in range(n + 1)]
    pool = _executor(n - 1)
    futures = [pool.submit(kernel_on, edges[i], edges[i + 1]) for i in range(1, n)]
    kernel_on(edges[0], edges[1])
    for f in futures:
        f.result()


def run_drawn_rows(
    batch: int,
    draw: Callable[[int, int], object],
    kernel_on: Callable[[int, int], object],
    key: str,
) -> None:
    """:func:`run_rows` for a kernel whose rows need random draws made first, pipelined.

    ``draw(lo, hi)`` makes rows ``lo..hi``'s draws; it is called on consecutive ranges that
    cover ``[0, batch)`` in order (so a Generator's stream is consumed as by one call over all
    rows), each before ``kernel_on`` runs those rows. With threads, the pool's chunks are the
    first rows: each starts as soon as its rows are drawn, while the calling thread draws the
    rest, then runs the last chunk. The chunks are sized so that all end together on the costs
    measured on the last call with the same ``key`` (:func:`_calling_rows`; equal chunks the
    first time). Any split gives the same rows, so the sizing only moves time.
    """
    n = min(threads(), batch // MIN_ROWS_PER_THREAD)
    if n <= 1:
        draw(0, batch)
        kernel_on(0, batch)
        return
    last = _costs.get(key)
    y = _calling_rows(batch, n, last) if last is not None else batch // n
    first = batch - y
    edges = [first * i // (n - 1) for i in range(n)] + [batch]

    def timed(lo: int, hi: int) -> float:
        kernel_on(lo, hi)
        return time.perf_counter()

    pool = _executor(n - 1)
    futures, submitted = [], []
    try:
        t0 = time.perf_counter()
        for i in range(n - 1):
            draw(edges[i], edges[i + 1])
            submitted.append(time.perf_counter())
            futures.append(pool.submit(timed, edges[i], edges[i + 1]))
        draw(edges[-2], batch)
        t1 = time.perf_counter()
        kernel_on(edges[-2], batch)
        t2 = time.perf_counter()
    finally:  # no chunk may still write when this returns or raises
        wait(futures)
    ends = [f.result() for f in futures]
    rows = [max(hi - lo, 1) for lo, hi in itertools.pairwise(edges)]
    # kernel seconds per row of each chunk; a pool chunk's includes its hand-off
    density = [(e - s) / r for e, s, r in zip(ends, submitted, rows[:-1], strict=True)]
    density.append((t2 - t1) / rows[-1])
    _costs[key] = _Costs(batch, (t1 - t0) / batch, tuple(edges), tuple(density))


@dataclass(frozen=True)
class _Costs:
    """What one call of :func:`run_drawn_rows` measured."""

    batch: int
    """Rows of the call."""
    draw: float
    """Seconds per row of the draws."""
    edges: tuple[int, ...]
    """The chunks' row edges."""
    density: tuple[float, ...]
    """Kernel seconds per row of each chunk (a pool chunk's with its hand-off)."""


def _calling_rows(batch: int, n: int, last: _Costs) -> int:
    """Rows of the calling thread's chunk (the last) that make the ``n`` chunks end together
    on ``last``'s costs: the kernel cost of rows ``0..r`` is piecewise linear between the
    measured chunks' edges; pool chunk ``j``, the ``(n − 1)``-th part of the rows before the
    calling thread's, starts once its rows are drawn and ends at ``d·hi_j + K(lo_j, hi_j)``;
    the calling thread ends at ``d·B + K(B − y, B)``."""
    if last.batch != batch:
        return batch // n
    knots = np.asarray(last.edges, dtype=np.float64)
    cum = np.concatenate([[0.0], np.cumsum(np.diff(knots) * np.asarray(last.density))])

    def K(r: int) -> float:
        return float(np.interp(r, knots, cum))

    def late(y: int) -> tuple[float, float]:
        first = batch - y
        e = [first * i // (n - 1) for i in range(n)]
        pool = max(last.draw * hi + K(hi) - K(lo) for lo, hi in itertools.pairwise(e))
        return pool, last.draw * batch + K(batch) - K(first)

    lo, hi = max(batch // (4 * n), 1), batch - (n - 1)
    while lo < hi:  # the smallest y at which the calling thread ends last
        mid = (lo + hi) // 2
        pool, calling = late(mid)
        if calling >= pool:
            hi = mid
        else:
            lo = mid + 1
    if lo > max(batch // (4 * n), 1) and max(late(lo - 1)) < max(late(lo)):
        return lo - 1
    return lo
