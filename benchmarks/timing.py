"""Timing and result files shared by the benchmark scripts in this folder.

The scripts run as ``python benchmarks/NAME.py``, so this module is imported by its plain name.
"""

from __future__ import annotations

import json
import os
import platform
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numba
import numpy as np

RESULTS = Path(__file__).parent / "results"


def best_rate(
    fn: Callable[[Any], object],
    count: int,
    repeat: int,
    setup: Callable[[], Any] = lambda: None,
) -> float:
    """Items per second of the fastest of ``repeat`` timed calls ``fn(setup())``, after a warm-up.

    ``setup`` runs untimed before every call (e.g. a fresh filter state); ``count`` is the
    number of items one call processes.
    """
    fn(setup())
    best = np.inf
    for _ in range(repeat):
        arg = setup()
        t0 = time.perf_counter()
        fn(arg)
        best = min(best, time.perf_counter() - t0)
    return count / best


def machine() -> dict[str, Any]:
    """What the numbers were measured on, including the load that slows them."""
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else None
    return {
        "python": platform.python_version(),
        "numpy": np.__version__,
        "numba": numba.__version__,
        "machine": platform.machine(),
        "cpus": os.cpu_count(),
        "load_average_1min": load,
    }


def write_results(path: Path, results: Any, **settings: Any) -> None:
    """Write ``{"machine": …, "settings": …, "results": …}`` as JSON and say where."""
    path.parent.mkdir(parents=True, exist_ok=True)
    doc = {"machine": machine(), "settings": settings, "results": results}
    path.write_text(json.dumps(doc, indent=2) + "\n")
    load = doc["machine"]["load_average_1min"]
    if load is not None:
        print(
            f"1-min load average {load:.2f} on {doc['machine']['cpus']} CPUs (other work slows every row)"
        )
    print(f"wrote {path}")
