"""One side of an A/B of the cold compile; run it with an empty ``NUMBA_CACHE_DIR``.

A fresh process makes the env, resets and steps it (single, and a vector env of 4); for
BearingsManeuver the three rules that run its planning kernels then decide once. Prints the
process CPU seconds after the env and after the rules. Run it alternately on the two trees
compared, each time on a new empty cache directory, and compare the runs pair by pair.
"""

from __future__ import annotations

import argparse
import time

T0 = time.process_time()

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402

import sensorgym.envs  # noqa: E402, F401  (registers the ids)
from sensorgym.agents.registry import RULES  # noqa: E402

PLANNING_RULES = ("greedy-information", "lookahead-estimate", "truth-lookahead")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", default="sensorgym/BearingsManeuver-v0")
    env_id = parser.parse_args().env
    env = gym.make(env_id)
    env.reset(seed=0)
    env.step(np.zeros(env.action_space.shape, np.float32))
    venv = gym.make_vec(env_id, 4, vectorization_mode="vector_entry_point")
    obs, _ = venv.reset(seed=0)
    venv.step(np.zeros(venv.action_space.shape, np.float32))
    t_env = time.process_time() - T0
    inner = venv.unwrapped
    for name in PLANNING_RULES if "BearingsManeuver" in env_id else ():
        RULES[env_id][name](inner.params, lambda: inner.simulator_state).predict(obs)
    print(f"{t_env:.2f} {time.process_time() - T0:.2f}")


if __name__ == "__main__":
    main()
