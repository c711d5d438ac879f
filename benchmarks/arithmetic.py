"""How far the recorded numbers move when the arithmetic's last bits do: the measurements behind
the tolerances of ``tests/arithmetic.py``.

``python benchmarks/arithmetic.py`` writes ``benchmarks/results/arithmetic.json`` with two
measurements:

* **Golden episodes** (``tests/golden_record.py``: 40 seeded steps of every door of every
  env): every action nudged by a relative ``ε`` (random sign); per env, the largest change of
  the recorded observations and rewards as a fraction of each array's scale, and whether any
  episode end flipped. ``amplification = change / ε``.
* **Shipped policies on another BLAS path**: every shipped policy re-scored on the committed
  scenarios (``docs/scores``) in a child process under ``MKL_CBWR=COMPATIBLE`` (MKL's other
  summation order for torch's matmuls); per policy, the largest relative change of an
  episode's return among the episodes that kept their ends, the episodes beyond the 5 %
  tolerance (path flips), and the mean's change as a fraction of its 95 % half-width.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
from rich.console import Console
from rich.table import Table
from timing import RESULTS, write_results

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

EPSILONS = (1e-12, 1e-9, 1e-6)


def golden_sensitivity(eps: float) -> dict[str, dict[str, Any]]:
    """Per env: the largest change of the golden arrays (a fraction of each array's scale)
    with every action nudged by ``eps``, and the number of flipped episode ends."""
    import sensorgym.envs as envs
    import tests.golden_record as record
    from tests.test_golden import PARALLEL_FACTORIES

    plain = record._actions
    recorded = dict(np.load(record.GOLDEN / "episodes.npz"))

    def nudged(seed: int, steps: int, shape: tuple[int, ...]) -> np.ndarray:
        a = plain(seed, steps, shape)
        return a * (1.0 + eps * np.random.default_rng(seed + 99).choice([-1.0, 1.0], a.shape))

    record._actions = nudged
    try:
        out: dict[str, dict[str, Any]] = {}
        for env_id in envs.ENV_IDS:
            name = env_id.split("/")[1]
            change, flips = 0.0, 0
            for seed in record.SEEDS:
                runs = {
                    "single": record.single_episodes(env_id, seed),
                    "vector": record.vector_episodes(env_id, seed),
                    "parallel": record.parallel_episodes(PARALLEL_FACTORIES[env_id], seed),
                }
                for kind, got in runs.items():
                    for key, value in got.items():
                        want = recorded[f"{name}/{kind}/{seed}/{key}"]
                        if value.dtype == bool:
                            flips += int(np.sum(value != want))
                            continue
                        scale = max(float(np.max(np.abs(want))), 1e-300)
                        change = max(change, float(np.max(np.abs(value - want))) / scale)
            out[env_id] = {"change": change, "amplification": change / eps, "end_flips": flips}
        return out
    finally:
        record._actions = plain


def rescore_all() -> dict[str, dict[str, Any]]:
    """Every shipped policy re-scored on its committed scenarios (this process's arithmetic)."""
    from sensorgym.train.benchmark import PolicySpec, registered_envs, score
    from sensorgym.train.shipped import shipped_policies

    out = {}
    for env_id in registered_envs():
        doc = json.loads((ROOT / "docs/scores" / f"{env_id.replace('/', '__')}.json").read_text())
        s = doc["settings"]
        for run, folder in shipped_policies(env_id).items():
            spec = PolicySpec("model", str(folder), shipped=True)
            again = score(env_id, spec, s["episodes"], s["n_envs"], s["seed"])
            out[f"{env_id} {run}"] = {"mean": again["mean"], "returns": again["returns"]}
    return out


def blas_path_drift(env: dict[str, str]) -> dict[str, dict[str, Any]]:
    """Per shipped policy: how its re-scored returns under ``env`` differ from the committed."""
    from tests.arithmetic import EPISODE_RETURN_RTOL

    child = subprocess.run(
        [sys.executable, __file__, "--rescore"],
        env={**os.environ, **env},
        capture_output=True,
        text=True,
        check=True,
    )
    again = json.loads(child.stdout)
    out = {}
    for key, res in again.items():
        env_id, run = key.split()
        doc = json.loads((ROOT / "docs/scores" / f"{env_id.replace('/', '__')}.json").read_text())
        committed = doc["results"].get(f"shipped:{run}") or doc["results"][f"model:{run}"]
        r0, r1 = np.asarray(committed["returns"]), np.asarray(res["returns"])
        drift = np.abs(r1 - r0) / np.maximum(np.abs(r0), 1.0)
        kept = drift <= EPISODE_RETURN_RTOL
        out[key] = {
            "episode_drift": float(drift[kept].max()) if kept.any() else None,
            "flipped": int(np.sum(~kept)),
            "episodes": int(r0.size),
            "mean_change_in_ci95": abs(res["mean"] - committed["mean"]) / committed["ci95"],
        }
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=RESULTS / "arithmetic.json")
    parser.add_argument("--rescore", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.rescore:  # the child: print the re-scored returns as JSON
        print(json.dumps(rescore_all()))
        return
    os.environ.setdefault("SENSORGYM_THREADS", "1")
    console = Console()
    golden = {f"{eps:g}": golden_sensitivity(eps) for eps in EPSILONS}
    table = Table(title="golden episodes: every action nudged by a relative ε")
    for column in ("env", *(f"ε = {e}: change / ε" for e in golden), "end flips"):
        table.add_column(column, justify="left" if column == "env" else "right")
    for env_id in next(iter(golden.values())):
        amps = [f"{g[env_id]['amplification']:.3g}" for g in golden.values()]
        flips = sum(g[env_id]["end_flips"] for g in golden.values())
        table.add_row(env_id, *amps, str(flips))
    console.print(table)
    blas = blas_path_drift({"MKL_CBWR": "COMPATIBLE"})
    table = Table(title="shipped policies re-scored under MKL_CBWR=COMPATIBLE")
    for column in ("policy", "largest episode drift", "flipped episodes", "mean change / ci95"):
        table.add_column(column, justify="left" if column == "policy" else "right")
    for key, r in blas.items():
        drift = "" if r["episode_drift"] is None else f"{r['episode_drift']:.2e}"
        table.add_row(key, drift, f"{r['flipped']} of {r['episodes']}",
                      f"{r['mean_change_in_ci95']:.3f}")  # fmt: skip
    console.print(table)
    write_results(
        args.out,
        {"golden": golden, "blas_path": {"MKL_CBWR=COMPATIBLE": blas}},
        epsilons=list(EPSILONS),
    )


if __name__ == "__main__":
    main()
