"""One side of an A/B of BearingsManeuver's planners: the rules that run its planning kernels.

Prints the best thread-CPU milliseconds of one ``predict`` on 256 scenarios, on one thread, for
``greedy-information``, ``lookahead-estimate`` and ``truth-lookahead``, at one platform and at
three.
"""

from __future__ import annotations

import os

os.environ["SENSORGYM_THREADS"] = "1"

import time

import gymnasium as gym

import sensorgym.envs  # noqa: F401  (registers the ids)
from sensorgym.agents.registry import RULES

ENV_ID = "sensorgym/BearingsManeuver-v0"
NAMES = ("greedy-information", "lookahead-estimate", "truth-lookahead")


def main() -> None:
    out = []
    for platforms in (1, 3):
        venv = gym.make_vec(
            ENV_ID, num_envs=256, vectorization_mode="vector_entry_point", platforms=platforms
        )
        obs, _ = venv.reset(seed=0)
        inner = venv.unwrapped
        for name in NAMES:
            rule = RULES[ENV_ID][name](inner.params, lambda inner=inner: inner.simulator_state)
            rule.predict(obs)
            best = float("inf")
            for _ in range(5):
                t0 = time.thread_time()
                rule.predict(obs)
                best = min(best, time.thread_time() - t0)
            out.append(best * 1e3)
    print(" ".join(f"{ms:.3f}" for ms in out))


if __name__ == "__main__":
    main()
