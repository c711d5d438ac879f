"""Shared by the NEES probes in this folder: policies, NEES summaries and the result files.

The probes run as ``python research/nees/NAME.py``, so this module is imported by its plain name.
"""

from __future__ import annotations

import importlib.util
import json
import os
import platform
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

import sensorgym.envs  # noqa: F401  (registers the envs)

RESULTS = Path(__file__).parent / "results"
FloatArray = NDArray[np.float64]


def _benchmark() -> Any:
    """``benchmarks/nees.py`` as a module: the probes share its policies and NEES summaries."""
    path = Path(__file__).resolve().parents[2] / "benchmarks" / "nees.py"
    if str(path.parent) not in sys.path:  # it imports its sibling scripts by their plain names
        sys.path.append(str(path.parent))
    spec = importlib.util.spec_from_file_location("nees_benchmark", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


_NEES = _benchmark()


def policy(env_id: str, name: str, env: Any, seed: int) -> Callable[[Any, int], Any]:
    """``act(obs, step) -> actions`` exactly as ``benchmarks/nees.py`` plays: seeded uniform
    random actions (``seed + 1``), or a registered rule of :mod:`sensorgym.agents`."""
    return _NEES._policy(env_id, name, env, seed)


def summary(nees: FloatArray, d: int) -> dict[str, Any]:
    """``benchmarks/nees.py``'s summary of ``N`` NEES samples of dimension ``d`` (mean, its 95 %
    band, whether the mean lies inside, the fraction above the ``χ²_d`` 99 % quantile) and their
    median."""
    nees = np.asarray(nees, dtype=np.float64)
    out = _NEES.summary(nees, d)
    if out["n"]:
        out["median"] = float(np.median(nees))
    return out


def quadratic(e: FloatArray, P: FloatArray) -> FloatArray:
    """``eᵀ P⁻¹ e`` over the leading axes."""
    return np.einsum("...i,...i->...", e, np.linalg.solve(P, e[..., None])[..., 0])


def cell(s: dict[str, Any]) -> str:
    """``mean (tail %)`` of a summary, red when the mean is outside its 95 % band."""
    if not s["n"]:
        return "–"
    text = f"{s['mean']:.2f} ({100 * s['above_q99']:.1f} %)"
    return text if s["in_band"] else f"[red]{text}[/]"


def write(path: Path, results: Any, **settings: Any) -> None:
    """``{"machine", "settings", "results"}`` as JSON."""
    import numba
    import scipy

    machine = {
        "python": platform.python_version(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "numba": numba.__version__,
        "cpus": os.cpu_count(),
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    doc = {"machine": machine, "settings": settings, "results": results}
    path.write_text(json.dumps(doc, indent=1) + "\n")
    print(f"wrote {path}")
