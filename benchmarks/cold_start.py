"""Compile time paid once: every registered env started in one fresh process, cold and warm.

A fresh interpreter imports sensorgym, then for each registered env in turn makes the Gymnasium
env and a native vector env of 4 scenarios, resets and steps both (so every kernel the env
needs is compiled or loaded). It runs twice on one numba cache directory: first empty (*cold*:
every kernel compiles and is written to the cache), then again (*warm*: every kernel loads from
the cache). Per env the seconds are those its first reset and step took (an env that shares
kernels with one before it pays less), plus the import: wall seconds and the CPU seconds of the
process (``time.process_time``; compilation is single-threaded, so on an idle machine the two
agree, and on a loaded one the CPU seconds are the figure to compare). The cold run also
counts, from numba's ``numba:compile`` events, the sensorgym functions each env compiled and
the compiles beyond one per function: a second specialisation of one kernel (for a literal
argument, a read-only or otherwise laid-out array) costs seconds of every cold start and is
a defect unless deliberate; the warm run's count must be zero. Then the same for
``sensorgym compile`` on another empty cache, and again warm: every env *and every registered
rule* (one short episode each), one process per env package on all CPUs — what the set-up
scripts run once after an install (CPU seconds: those of its worker processes). Prints a table
and writes ``benchmarks/results/cold_start.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from timing import RESULTS, write_results

_CHILD = """
import collections, json, time
import numba.core.event as event

compiles = collections.Counter()  # numba:compile events per sensorgym function


class Count(event.Listener):
    def on_start(self, ev):
        f = ev.data["dispatcher"].py_func
        if f.__module__.startswith("sensorgym."):
            compiles[f.__module__ + "." + f.__qualname__] += 1

    def on_end(self, ev):
        pass


event.register("numba:compile", Count())
t0, c0 = time.perf_counter(), time.process_time()
import gymnasium as gym
import numpy as np
import sensorgym.envs as envs
out = {"import": (time.perf_counter() - t0, time.process_time() - c0, len(compiles),\n                  sum(compiles.values()) - len(compiles))}
for env_id in envs.ENV_IDS:
    t, c = time.perf_counter(), time.process_time()
    compiles.clear()
    env = gym.make(env_id)
    env.reset(seed=0)
    env.step(np.zeros(env.action_space.shape, np.float32))
    v = gym.make_vec(env_id, 4, vectorization_mode="vector_entry_point")
    v.reset(seed=0)
    v.step(np.zeros(v.action_space.shape, np.float32))
    extra = sum(compiles.values()) - len(compiles)
    out[env_id] = (time.perf_counter() - t, time.process_time() - c, len(compiles), extra)
out["total"] = (time.perf_counter() - t0, time.process_time() - c0, None, None)
print(json.dumps(out))
"""


def _run(cache: str) -> dict[str, list[float | None]]:
    """Per case: wall and CPU seconds, the sensorgym functions numba compiled and how many
    times more than once (a second specialisation: other argument types, a literal, a
    read-only array)."""
    env = {**os.environ, "NUMBA_CACHE_DIR": cache}
    out = subprocess.run([sys.executable, "-c", _CHILD], env=env, capture_output=True, text=True)
    if out.returncode != 0:
        raise RuntimeError(out.stderr)
    return json.loads(out.stdout.strip().splitlines()[-1])


def _compile(cache: str) -> tuple[float, float]:
    """Wall and children's CPU seconds of ``sensorgym compile`` on the numba cache ``cache``."""
    env = {**os.environ, "NUMBA_CACHE_DIR": cache}
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    command = [sys.executable, "-m", "sensorgym.cli.main", "compile", "--quiet"]
    out = subprocess.run(command, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if out.returncode != 0:
        raise RuntimeError(out.stderr)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
    return wall, cpu


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=RESULTS / "cold_start.json")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as cache:
        cold = _run(cache)
        warm = _run(cache)
    with tempfile.TemporaryDirectory() as cache:
        case = f"`sensorgym compile` (envs and rules, {len(os.sched_getaffinity(0))} CPUs)"
        cold[case] = (*_compile(cache), None, None)
        warm[case] = (*_compile(cache), None, None)
    rows = [
        {
            "case": k,
            "cold_s": cold[k][0],
            "cold_cpu_s": cold[k][1],
            "warm_s": warm[k][0],
            "warm_cpu_s": warm[k][1],
            "functions_compiled": cold[k][2],
            "second_specialisations": cold[k][3],
            "compiled_when_warm": warm[k][2],
        }
        for k in cold
    ]
    print(
        f"{'':<36} {'cold, s':>9} {'CPU s':>7} {'warm, s':>9} {'CPU s':>7}"
        f" {'compiled':>9} {'twice+':>7}"
    )
    print("-" * 90)
    for r in rows:
        compiled = "" if r["functions_compiled"] is None else r["functions_compiled"]
        again = "" if r["second_specialisations"] is None else r["second_specialisations"]
        print(
            f"{r['case']:<36} {r['cold_s']:>9.1f} {r['cold_cpu_s']:>7.1f}"
            f" {r['warm_s']:>9.2f} {r['warm_cpu_s']:>7.2f} {compiled:>9} {again:>7}"
        )
    write_results(args.out, rows)


if __name__ == "__main__":
    main()
