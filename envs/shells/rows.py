"""Scenario rows of a batch split over threads: the compiled step kernels release the GIL.

Every env's step is one compiled kernel looping over scenarios (rows of the batch); its random
draws are made beforehand with the env's Generator, so rows are independent and any split of
them gives bit-identical results. :func:`run_rows` runs ``kernel_on(lo, hi)`` over contiguous
row ranges, on :func:`threads` threads when the batch is large enough to pay for the hand-off
(about 20 µs), else in the calling thread.

Why threads and not numba's ``prange``: a ``parallel=True`` kernel adds seconds of cold compile
per env, and numba's OpenMP/TBB layers do not survive ``fork()`` (SB3's subprocess vector envs,
Ray workers). The pool here is created lazily in each process (a forked child builds its own),
and kernels compiled with ``nogil=True`` need nothing else.

``SENSORGYM_THREADS`` (environment variable) sets the thread count; ``1`` turns splitting off.
"""

from __future__ import annotations

import functools
import os
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

#: fewest scenarios per thread for a split to pay (a step costs about 1 µs per scenario and
#: the hand-off to a pool thread about 20 µs)
MIN_ROWS_PER_THREAD = 128

_pool: ThreadPoolExecutor | None = None
_pool_pid: int | None = None


def threads() -> int:
    """Threads a batch may be split over: ``SENSORGYM_THREADS``, else the CPUs this process
    may run on (at most 8)."""
    env = os.environ.get("SENSORGYM_THREADS")
    if env is not None:
        try:
            n = int(env)
        except ValueError:
            raise ValueError(f"SENSORGYM_THREADS: expected an integer, got {env!r}") from None
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
