"""One side of an A/B of StereoScanning's rows of the env-speed table, in CPU time.

The cases of ``benchmarks/env_throughput.py`` (``gym.make``, one scenario; the native vector
env at 1, 16 and 1024 scenarios: the same envs, seeds, actions and step loops) timed as the
process's CPU seconds (every thread) per scenario-step, best of ``--repeat`` after a warm-up:
on a machine shared with other work, CPU time moves less than the table's wall-clock rates.
Prints the four µs figures on one line. Run it alternately on the two trees compared (each made
importable as ``sensorgym`` by ``PYTHONPATH``) and compare the runs pair by pair.
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np

import sensorgym.envs  # noqa: F401  (registers the ids)

ENV_ID = "sensorgym/StereoScanning-v0"


def _cpu_seconds(env, actions) -> float:
    t0 = time.process_time()
    for a in actions:
        env.step(a)
    return time.process_time() - t0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=300)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    rng = np.random.default_rng(0)

    def best(env, actions) -> float:
        _cpu_seconds(env, actions)  # warm-up
        return min(_cpu_seconds(env, actions) for _ in range(args.repeat))

    env = gym.make(ENV_ID, max_episode_steps=-1)
    env.reset(seed=0)
    n_act = env.action_space.shape[0]
    actions = rng.uniform(-1, 1, (args.steps, n_act)).astype(np.float32)
    costs = [best(env, actions) / args.steps]
    for B in (1, 16, 1024):
        venv = gym.make_vec(ENV_ID, num_envs=B, vectorization_mode="vector_entry_point")
        venv.reset(seed=0)
        batch = rng.uniform(-1, 1, (args.steps, B, n_act)).astype(np.float32)
        costs.append(best(venv, batch) / (B * args.steps))
    print(" ".join(f"{c * 1e6:.3f}" for c in costs))


if __name__ == "__main__":
    main()
