"""CPU cost of one scenario-step of every env's core on one thread (µs per scenario).

Load on a shared machine slows wall-clock rates (and the threads a batch is split over) far
more than the CPU time a step consumes, so this measures the simulation's ``step`` (the
compiled kernel and its Python wrapper, no autoreset) at ``--batch`` scenarios on one thread
(``SENSORGYM_THREADS=1``, set here) by the thread's CPU clock, best of ``--repeat`` steps,
chained from one seeded reset under one random action. Also the vector env's whole step (autoreset,
observation, infos) at the same batch, on one thread. Prints a table and writes
``benchmarks/results/step_cost.json`` (the throughput files quote wall-clock ratios against
CartPole-v1).

Run: ``.venv/bin/python benchmarks/step_cost.py [--batch 1024] [--repeat 200]``.
"""

from __future__ import annotations

import argparse
import os

os.environ["SENSORGYM_THREADS"] = "1"

import time

import gymnasium as gym
import numpy as np
from timing import RESULTS, write_results

import sensorgym.envs as envs


def _best(fn, repeat: int) -> float:
    fn()
    best = np.inf
    for _ in range(repeat):
        t0 = time.thread_time()
        fn()
        best = min(best, time.thread_time() - t0)
    return best


def env_costs(env_id: str, batch: int, repeat: int) -> tuple[float, float]:
    """Best CPU seconds of one core step and of one vector-env step at ``batch`` scenarios."""
    venv = gym.make_vec(env_id, num_envs=batch, vectorization_mode="vector_entry_point")
    venv.reset(seed=0)
    inner = venv.unwrapped
    rng = np.random.default_rng(0)
    action = rng.uniform(-1.0, 1.0, venv.action_space.shape).astype(np.float32)
    state = [inner.simulator_state]

    def core_step() -> None:
        state[0] = inner.core.step(state[0], action, rng)[0]

    return _best(core_step, repeat), _best(lambda: venv.step(action), repeat)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--batch", type=int, default=1024)
    parser.add_argument("--repeat", type=int, default=200)
    args = parser.parse_args()
    B = args.batch
    print(f"{'env':<36} {'core step, us/scen':>19} {'vector step, us/scen':>21}")
    print("-" * 78)
    rows = []
    for env_id in envs.ENV_IDS:
        c, v = env_costs(env_id, B, args.repeat)
        print(f"{env_id:<36} {c / B * 1e6:>19.3f} {v / B * 1e6:>21.3f}")
        rows.append({"env": env_id, "core_step_us": c / B * 1e6, "vector_step_us": v / B * 1e6})
    print(f"one thread, CPU time, best of {args.repeat} steps at {B} scenarios; 1-min load "
          f"{os.getloadavg()[0]:.1f}")  # fmt: skip
    write_results(
        RESULTS / "step_cost.json", rows, batch=B, repeat=args.repeat, threads=1, clock="thread CPU"
    )


if __name__ == "__main__":
    main()
