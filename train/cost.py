"""What a training run cost: wall-clock time per phase, samples and the machine it ran on.

``sensorgym train`` writes :data:`COST_FILE` into the run folder beside the weights (a file of
its own, like ``evaluation.json``: the loader of :mod:`.models` reads only the weights and
``config.yaml``, so a cost record can be added to a shipped run later, by
``benchmarks/training_cost.py``, without touching what loads). Every learning-curve point
(``curve.json``) and every ARS iteration (``search.json``) carries ``wall_s``: the seconds on
the run's :class:`RunClock` when it was taken.

The clock starts where training starts: after the envs, the model and the rules' evaluation
are set up, before imitation pre-training (if any); so ``wall_s`` of a curve point is what it
took to train the policy that point scores, the evaluations of the earlier curve points
included (``eval_s`` of the point says how much of it they were).
"""

from __future__ import annotations

import json
import os
import platform
import time
from datetime import datetime, timezone
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import Any

#: the run folder's record of the training cost
COST_FILE = "cost.json"
#: the layout of :data:`COST_FILE` (bumped when a key changes meaning)
COST_FORMAT = 1


class RunClock:
    """Wall-clock seconds (``time.perf_counter``) since :meth:`start`, and the seconds spent
    in evaluations since then (:meth:`evaluating` adds to them)."""

    def __init__(self) -> None:
        self.origin: float | None = None
        self.eval_s = 0.0

    def start(self) -> None:
        self.origin = time.perf_counter()
        self.eval_s = 0.0

    def elapsed(self) -> float:
        """Seconds since :meth:`start` (0 before it)."""
        return 0.0 if self.origin is None else time.perf_counter() - self.origin

    def add_eval(self, seconds: float) -> None:
        self.eval_s += seconds


def cpu_model() -> str:
    """The CPU's model name (``/proc/cpuinfo``), else ``platform.processor()``."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor()


def usable_cpus() -> int:
    """The CPUs this process may run on (its affinity mask; ``os.cpu_count()`` where the
    platform has none)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def load_average() -> float | None:
    """The 1-minute load average (``None`` where the platform has none)."""
    try:
        return float(os.getloadavg()[0])
    except (AttributeError, OSError):
        return None


def _version(package: str) -> str | None:
    try:
        return version(package)
    except PackageNotFoundError:
        return None


def machine_record() -> dict[str, Any]:
    """The machine and software a run's time was measured on."""
    import torch

    return {
        "cpu_count": os.cpu_count(),
        "usable_cpus": usable_cpus(),
        "torch_threads": torch.get_num_threads(),
        "cpu_model": cpu_model(),
        "machine": platform.machine(),
        "platform": platform.platform(),
        "python": platform.python_version(),
        "numpy": _version("numpy"),
        "numba": _version("numba"),
        "torch": _version("torch"),
        "stable_baselines3": _version("stable-baselines3"),
    }


def now_utc() -> str:
    """The current time, ISO 8601 in UTC, to the second."""
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


def write_cost(run_dir: Path, record: dict[str, Any]) -> Path:
    """Write ``record`` as :data:`COST_FILE` in ``run_dir``."""
    path = Path(run_dir) / COST_FILE
    path.write_text(json.dumps({"format": COST_FORMAT, **record}, indent=2) + "\n")
    return path


def read_cost(run_dir: Path) -> dict[str, Any] | None:
    """The cost record of a run folder, ``None`` when it has none (runs trained before it was
    recorded)."""
    path = Path(run_dir) / COST_FILE
    return json.loads(path.read_text()) if path.is_file() else None


def pretrain_samples(steps: int, rounds: int, n_envs: int) -> int:
    """Transitions the imitation phase collects (:func:`~.experts.collect` steps whole rounds
    of all ``n_envs`` scenarios, ``ceil(steps / n_envs)`` of them, per round)."""
    return rounds * -(-steps // n_envs) * n_envs


def first_beat(points: list[dict[str, Any]], threshold: float) -> dict[str, Any] | None:
    """The first curve point whose mean exceeds ``threshold`` (``None``: none does)."""
    for point in points:
        if point["mean"] > threshold:
            return point
    return None
