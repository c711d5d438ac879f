"""Soak every env: many vector steps with random and extreme actions, counting what goes wrong.

For each registered env, ``--steps`` scenario-steps (default 10⁶) of the native vector env
(``--batch`` scenarios, NEXT_STEP autoreset, registered episode length) with actions drawn from
a mix: uniform in the Box, uniform far outside it (clipped by the envs), exactly ±1, zeros and
huge finite values (±1e38, near the float32 limit). Counts non-finite rewards, non-finite observations, observations
outside the observation space and exceptions (an exception restarts the env). Every
PettingZoo env and the agent view are soaked for a tenth of the steps the same way. Prints a
table and writes ``benchmarks/results/soak.json``; the docs quote that file.
"""

from __future__ import annotations

import argparse
import time
import traceback
from pathlib import Path

import gymnasium as gym
import numpy as np
from timing import RESULTS, write_results

from sensorgym.envs import ENV_IDS


def _actions(rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
    kind = rng.integers(5)
    if kind == 0:
        return rng.uniform(-1.0, 1.0, shape)
    if kind == 1:
        return rng.uniform(-50.0, 50.0, shape)
    if kind == 2:
        return rng.choice([-1.0, 1.0], shape)
    if kind == 3:
        return np.zeros(shape)
    return rng.choice([-1e38, 1e38], shape)  # near the float32 limit


def soak(env_id: str, steps: int, batch: int, seed: int, agent_view: bool = False) -> dict:
    """Counts over ``steps`` scenario-steps of one env."""
    rng = np.random.default_rng(seed)
    env = gym.make_vec(
        env_id, num_envs=batch, vectorization_mode="vector_entry_point", agent_view=agent_view
    )
    space = env.observation_space
    counts = {"steps": 0, "episodes": 0, "nonfinite_reward": 0, "nonfinite_obs": 0}
    counts |= {"obs_outside_space": 0, "exceptions": 0}
    first_error = ""
    obs, _ = env.reset(seed=seed)
    start = time.perf_counter()
    while counts["steps"] < steps:
        try:
            obs, reward, terminated, truncated, _ = env.step(
                _actions(rng, env.action_space.shape).astype(np.float32)
            )
        except Exception:  # counted and reported; the soak goes on
            counts["exceptions"] += 1
            first_error = first_error or traceback.format_exc(limit=2)
            obs, _ = env.reset(seed=int(rng.integers(2**31)))
            continue
        counts["steps"] += batch
        counts["episodes"] += int(np.sum(terminated | truncated))
        counts["nonfinite_reward"] += int(np.sum(~np.isfinite(reward)))
        counts["nonfinite_obs"] += int(np.sum(~np.isfinite(obs)))
        counts["obs_outside_space"] += int(not space.contains(obs))
    counts["seconds"] = round(time.perf_counter() - start, 1)
    counts["first_error"] = first_error
    return counts


def soak_parallel(env_id: str, steps: int, seed: int) -> dict:
    """The PettingZoo env, one scenario at a time."""
    from sensorgym.envs import PARALLEL_ENVS

    rng = np.random.default_rng(seed)
    env = PARALLEL_ENVS[env_id]()
    counts = {"steps": 0, "nonfinite_reward": 0, "nonfinite_obs": 0, "exceptions": 0}
    first_error = ""
    env.reset(seed=seed)
    while counts["steps"] < steps:
        if not env.agents:
            env.reset(seed=int(rng.integers(2**31)))
        shape = env.action_space(env.agents[0]).shape
        try:
            obs, rewards, *_ = env.step({a: _actions(rng, shape) for a in env.agents})
        except Exception:  # counted and reported
            counts["exceptions"] += 1
            first_error = first_error or traceback.format_exc(limit=2)
            env.reset(seed=int(rng.integers(2**31)))
            continue
        counts["steps"] += 1
        counts["nonfinite_reward"] += sum(not np.isfinite(r) for r in rewards.values())
        counts["nonfinite_obs"] += sum(int(np.sum(~np.isfinite(o))) for o in obs.values())
    counts["first_error"] = first_error
    return counts


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--steps", type=int, default=1_000_000, help="scenario-steps per env")
    parser.add_argument("--batch", type=int, default=256)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=RESULTS / "soak.json")
    args = parser.parse_args()
    rows = []
    for env_id in ENV_IDS:
        for view, steps in (("joint", args.steps), ("agents", args.steps // 10)):
            row = soak(env_id, steps, args.batch, args.seed, agent_view=view == "agents")
            rows.append({"env": env_id, "door": f"vector env, {view} view", **row})
        row = soak_parallel(env_id, max(args.steps // 1000, 100), args.seed)
        rows.append({"env": env_id, "door": "PettingZoo", **row})
    header = f"{'env':<30} {'door':<26} {'steps':>9} {'non-finite r':>12} {'non-finite o':>12}"
    print(header + f" {'outside':>8} {'exceptions':>10}")
    print("-" * (len(header) + 20))
    for r in rows:
        print(
            f"{r['env']:<30} {r['door']:<26} {r['steps']:>9,} {r['nonfinite_reward']:>12}"
            f" {r['nonfinite_obs']:>12} {r.get('obs_outside_space', 0):>8} {r['exceptions']:>10}"
        )
        if r["first_error"]:
            print("    first error:", r["first_error"].strip().splitlines()[-1])
    write_results(args.out, rows, steps=args.steps, batch=args.batch, seed=args.seed)


if __name__ == "__main__":
    main()
