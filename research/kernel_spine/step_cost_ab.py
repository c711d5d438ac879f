"""One side of an A/B of the env step's CPU cost (BearingsManeuver's two envs, or ``--env NAME``).

Prints, on one line, the core step's best thread-CPU µs per scenario-step at 1 and at 1024
scenarios for each env of the pair, on one thread. Run it alternately on the two trees compared
(each made importable as ``sensorgym`` by ``PYTHONPATH``), several times, and compare the runs
pair by pair.
"""

from __future__ import annotations

import argparse
import os

os.environ["SENSORGYM_THREADS"] = "1"

import time

import gymnasium as gym
import numpy as np

import sensorgym.envs  # noqa: F401  (registers the ids)

PAIRS = {
    "bearings": ("sensorgym/BearingsManeuver-v0", "sensorgym/BearingsManeuverBook-v0"),
    "pointing": ("sensorgym/StereoPointing-v0", "sensorgym/StereoPointingCrowded-v0"),
    "placement": ("sensorgym/StereoPlacement-v0",),
    "scanning": ("sensorgym/StereoScanning-v0",),
}


def core_step_cost(env_id: str, batch: int, repeat: int) -> float:
    """Best thread-CPU µs per scenario of one core step, chained from one seeded reset."""
    venv = gym.make_vec(env_id, num_envs=batch, vectorization_mode="vector_entry_point")
    venv.reset(seed=0)
    inner = venv.unwrapped
    rng = np.random.default_rng(0)
    action = rng.uniform(-1, 1, venv.action_space.shape).astype(np.float32)
    state = inner.simulator_state
    best = np.inf
    for i in range(repeat + 1):
        t0 = time.thread_time()
        state = inner.core.step(state, action, rng)[0]
        if i:
            best = min(best, time.thread_time() - t0)
    return best / batch * 1e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", default="bearings", choices=sorted(PAIRS))
    args = parser.parse_args()
    costs = [
        core_step_cost(env_id, batch, repeat)
        for env_id in PAIRS[args.env]
        for batch, repeat in ((1, 2000), (1024, 200))
    ]
    print(" ".join(f"{c:.4f}" for c in costs))


if __name__ == "__main__":
    main()
