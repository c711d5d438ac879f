"""Shared by the NEES probes in this folder: policies, NEES summaries and the result files.

The probes run as ``python research/nees/NAME.py``, so this module is imported by its plain name.
"""

from __future__ import annotations

import json
import os
import platform
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.stats import chi2

import sensorgym.envs  # noqa: F401  (registers the envs)
from sensorgym.agents.registry import rules_for

RESULTS = Path(__file__).parent / "results"
FloatArray = NDArray[np.float64]


def policy(env_id: str, name: str, env: Any, seed: int) -> Callable[[Any, int], Any]:
    """``act(obs, step) -> actions`` as in ``benchmarks/nees.py``: seeded uniform random
    actions (``seed + 1``), or a registered rule of :mod:`sensorgym.agents` with its SB3-style
    state kept here (``episode_start`` at step 0)."""
    if name == "random":
        rng = np.random.default_rng(seed + 1)
        return lambda obs, k: rng.uniform(-1.0, 1.0, env.action_space.shape).astype(np.float32)
    rule = rules_for(env_id, env.params, lambda: env.simulator_state)[name]
    memory: list[Any] = [None]

    def act(obs: Any, k: int) -> Any:
        action, memory[0] = rule.predict(
            obs, memory[0], episode_start=np.full(env.num_envs, k == 0)
        )
        return action

    return act


def summary(nees: FloatArray, d: int) -> dict[str, Any]:
    """Mean NEES of ``N`` samples of dimension ``d``; its 95 % band (the mean of ``N`` draws of
    ``χ²_d`` lies in ``χ²_{Nd}`` quantiles ``/N``); the fraction above the ``χ²_d`` 99 % quantile
    (1 % expected)."""
    nees = np.asarray(nees, dtype=np.float64)
    n = int(nees.size)
    if n == 0:
        return {"n": 0, "d": d}
    lo, hi = chi2.ppf([0.025, 0.975], n * d) / n
    mean = float(nees.mean())
    return {
        "n": n,
        "d": d,
        "mean": mean,
        "median": float(np.median(nees)),
        "band": [float(lo), float(hi)],
        "in_band": bool(lo <= mean <= hi),
        "above_q99": float(np.mean(nees > chi2.ppf(0.99, d))),
    }


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
