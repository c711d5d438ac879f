"""Throughput of one registered env: what every ``benchmarks/<env>.py`` script measures.

Scenario-steps per second for the Gymnasium env (``gym.make``, one scenario per call), SB3's
``DummyVecEnv`` of 8 single envs, the native vector env at several batch sizes, and the
``predict`` of every rule registered for the env on a batch of 256 observations. Prints a table
and writes ``benchmarks/results/<name>.json``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import gymnasium as gym
import numpy as np
from stable_baselines3.common.env_util import make_vec_env
from timing import RESULTS, best_rate, write_results

import sensorgym.envs  # noqa: F401  (registers the ids)
from sensorgym.agents.registry import rules_for

BATCHES = (16, 64, 256)
RULE_BATCH = 256


def _rate_of_steps(env: object, actions: np.ndarray, count: int, repeat: int) -> float:
    def run(_: object) -> None:
        for a in actions:
            env.step(a)

    return best_rate(run, count, repeat)


def main(env_id: str, name: str, description: str) -> None:
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--steps", type=int, default=300, help="env steps per timed call")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--out", type=Path, default=RESULTS / f"{name}.json")
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    rows = []

    # no TimeLimit wrapper: the timed loop measures steps, never a reset
    env = gym.make(env_id, max_episode_steps=-1)
    env.reset(seed=0)
    n_act = env.action_space.shape[0]
    actions = rng.uniform(-1, 1, (args.steps, n_act)).astype(np.float32)
    rate = _rate_of_steps(env, actions, args.steps, args.repeat)
    rows.append({"case": "gym.make, 1 scenario", "per_s": rate})

    sb3 = make_vec_env(env_id, n_envs=8, seed=0)
    sb3.reset()
    tiled = np.repeat(actions[:, None], 8, axis=1)
    rows.append(
        {
            "case": "SB3 DummyVecEnv, 8",
            "per_s": _rate_of_steps(sb3, tiled, 8 * args.steps, args.repeat),
        }
    )

    for B in BATCHES:
        venv = gym.make_vec(env_id, num_envs=B, vectorization_mode="vector_entry_point")
        venv.reset(seed=0)
        batch_actions = rng.uniform(-1, 1, (args.steps, B, n_act)).astype(np.float32)
        rate = _rate_of_steps(venv, batch_actions, B * args.steps, args.repeat)
        rows.append({"case": f"native vector env, {B}", "per_s": rate})

    venv = gym.make_vec(env_id, num_envs=RULE_BATCH, vectorization_mode="vector_entry_point")
    obs, _ = venv.reset(seed=0)
    core_env = venv.unwrapped
    for rule_name, rule in rules_for(
        env_id, core_env.params, lambda: core_env.simulator_state
    ).items():
        rate = best_rate(lambda _, rule=rule: rule.predict(obs), RULE_BATCH, 5 * args.repeat)
        rows.append({"case": f"{rule_name}.predict, {RULE_BATCH}", "per_s": rate})

    print(f"{env_id}\n{'case':<40} {'scenario-steps /s':>18}")
    print("-" * 59)
    for r in rows:
        print(f"{r['case']:<40} {r['per_s']:>18,.0f}")
    write_results(args.out, rows, env=env_id, steps=args.steps, repeat=args.repeat)
