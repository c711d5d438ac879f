"""Throughput of sensorgym/StereoPlacement-v0: env steps per second, single and vectorised.

Run: ``.venv/bin/python benchmarks/stereo_placement.py [--steps 300] [--repeat 3]``. Prints a
table of scenario-steps per second for the Gymnasium env (``gym.make``, one scenario per call),
the native vector env at several batch sizes, SB3's ``DummyVecEnv`` of 8 single envs for
comparison, and the placement rules' ``predict`` on a batch of 256 observations; writes
``benchmarks/results/stereo_placement.json``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import gymnasium as gym
import numpy as np
from stable_baselines3.common.env_util import make_vec_env
from timing import RESULTS, best_rate, write_results

import sensorgym.envs  # noqa: F401  (registers the ids)
from sensorgym.agents.placement_rules import CirclePlacement, GreedyInformation, HoldPosition
from sensorgym.envs.stereo_placement import StereoPlacementVectorEnv

ENV_ID = "sensorgym/StereoPlacement-v0"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=300, help="env steps per timed call")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--out", type=Path, default=RESULTS / "stereo_placement.json")
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    rows = []

    env = gym.make(ENV_ID)
    env.reset(seed=0)
    n_act = env.action_space.shape[0]
    actions = rng.uniform(-1, 1, (args.steps, n_act)).astype(np.float32)

    def single(_):
        for a in actions:
            _, _, term, trunc, _ = env.step(a)
            if term or trunc:
                env.reset()

    rows.append(
        {"case": "gym.make, 1 scenario", "per_s": best_rate(single, args.steps, args.repeat)}
    )

    sb3 = make_vec_env(ENV_ID, n_envs=8, seed=0)
    sb3.reset()

    def dummy(_):
        for a in actions:
            sb3.step(np.tile(a, (8, 1)))

    rows.append(
        {"case": "SB3 DummyVecEnv, 8", "per_s": best_rate(dummy, 8 * args.steps, args.repeat)}
    )

    for B in (16, 64, 256):
        venv = StereoPlacementVectorEnv(num_envs=B)
        venv.reset(seed=0)
        batch_actions = rng.uniform(-1, 1, (args.steps, B, n_act)).astype(np.float32)

        def vector(_, venv=venv, batch_actions=batch_actions):
            for a in batch_actions:
                venv.step(a)

        rows.append(
            {
                "case": f"native vector env, {B}",
                "per_s": best_rate(vector, B * args.steps, args.repeat),
            }
        )

    venv = StereoPlacementVectorEnv(num_envs=256)
    obs, _ = venv.reset(seed=0)
    for rule in (HoldPosition(), CirclePlacement(), GreedyInformation()):
        rows.append(
            {
                "case": f"{type(rule).__name__}.predict, 256",
                "per_s": best_rate(lambda _, rule=rule: rule.predict(obs), 256, 5 * args.repeat),
            }
        )

    print(f"{'case':<36} {'scenario-steps /s':>18}")
    print("-" * 55)
    for r in rows:
        print(f"{r['case']:<36} {r['per_s']:>18,.0f}")
    write_results(args.out, rows, steps=args.steps, repeat=args.repeat)


if __name__ == "__main__":
    main()
