"""Throughput of one registered env beside CartPole-v1, measured interleaved in one run.

Scenario-steps per second for the Gymnasium env (``gym.make``, one scenario per call), SB3's
``DummyVecEnv`` of 8 single envs, the native vector env at 1, 16, 256 and 1024 scenarios, and the
``predict`` of every rule registered for the env on a batch of 256 observations. Every env case
is timed alternately with CartPole-v1's single env (best of ``--repeat`` each), and the row
records the ratio: machine load slows both alike, so the ratio is what the docs quote. The cold
start (import, first reset and step with an empty numba cache, in a fresh process) is measured
too. Prints a table and writes ``benchmarks/results/<name>.json``; ``benchmarks/tables.py``
turns the results into the docs' tables.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import gymnasium as gym
import numpy as np
from stable_baselines3.common.env_util import make_vec_env
from timing import RESULTS, write_results

import sensorgym.envs  # noqa: F401  (registers the ids)
from sensorgym.agents.registry import rules_for

BATCHES = (1, 16, 256, 1024)
RULE_BATCH = 256


def _time_steps(env: object, actions: np.ndarray) -> float:
    t0 = time.perf_counter()
    for a in actions:
        env.step(a)
    return time.perf_counter() - t0


class CartPole:
    """CartPole-v1's single env, stepped like ours (resets when an episode ends, untimed)."""

    def __init__(self, steps: int):
        self.env = gym.make("CartPole-v1", max_episode_steps=-1)
        self.env.reset(seed=0)
        self.actions = np.random.default_rng(1).integers(0, 2, steps)

    def seconds(self) -> float:
        t0 = time.perf_counter()
        for a in self.actions:
            _, _, terminated, _, _ = self.env.step(int(a))
            if terminated:
                self.env.reset()
        return time.perf_counter() - t0

    @property
    def steps(self) -> int:
        return len(self.actions)


def interleaved(run_env, count: int, cartpole: CartPole, repeat: int) -> dict[str, float]:
    """Best-of-``repeat`` rates of ``run_env()`` (``count`` items) and CartPole, alternated."""
    run_env()  # warm-up (compilation, caches)
    cartpole.seconds()
    best_env = best_cart = np.inf
    for _ in range(repeat):
        best_env = min(best_env, run_env())
        best_cart = min(best_cart, cartpole.seconds())
    per_s, cart = count / best_env, cartpole.steps / best_cart
    return {"per_s": per_s, "cartpole_per_s": cart, "vs_cartpole": per_s / cart}


def cold_start(env_id: str) -> float:
    """Seconds from a fresh interpreter to the first step, with an empty numba cache."""
    code = (
        "import time; t = time.perf_counter(); import gymnasium as gym; import numpy as np; "
        "import sensorgym.envs; "
        f"env = gym.make({env_id!r}); env.reset(seed=0); "
        "env.step(np.zeros(env.action_space.shape, np.float32)); "
        f"v = gym.make_vec({env_id!r}, 4, vectorization_mode='vector_entry_point'); "
        "v.reset(seed=0); v.step(np.zeros(v.action_space.shape, np.float32)); "
        "print(time.perf_counter() - t)"
    )
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache}
        out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    if out.returncode != 0:
        raise RuntimeError(out.stderr)
    return float(out.stdout.strip().splitlines()[-1])


def main(env_id: str, name: str, description: str) -> None:
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--steps", type=int, default=300, help="env steps per timed call")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--out", type=Path, default=RESULTS / f"{name}.json")
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    cartpole = CartPole(args.steps)
    rows = []

    # no TimeLimit wrapper: the timed loop measures steps, never a reset
    env = gym.make(env_id, max_episode_steps=-1)
    env.reset(seed=0)
    n_act = env.action_space.shape[0]
    actions = rng.uniform(-1, 1, (args.steps, n_act)).astype(np.float32)
    row = interleaved(lambda: _time_steps(env, actions), args.steps, cartpole, args.repeat)
    rows.append({"case": "gym.make, 1 scenario", **row})

    sb3 = make_vec_env(env_id, n_envs=8, seed=0)
    sb3.reset()
    tiled = np.repeat(actions[:, None], 8, axis=1)
    row = interleaved(lambda: _time_steps(sb3, tiled), 8 * args.steps, cartpole, args.repeat)
    rows.append({"case": "SB3 DummyVecEnv, 8", **row})

    for B in BATCHES:
        venv = gym.make_vec(env_id, num_envs=B, vectorization_mode="vector_entry_point")
        venv.reset(seed=0)
        batch = rng.uniform(-1, 1, (args.steps, B, n_act)).astype(np.float32)
        row = interleaved(
            lambda venv=venv, batch=batch: _time_steps(venv, batch),
            B * args.steps,
            cartpole,
            args.repeat,
        )
        rows.append({"case": f"native vector env, {B}", **row})

    venv = gym.make_vec(env_id, num_envs=RULE_BATCH, vectorization_mode="vector_entry_point")
    obs, _ = venv.reset(seed=0)
    core_env = venv.unwrapped
    rules = rules_for(env_id, core_env.params, lambda: core_env.simulator_state)
    for rule_name, rule in rules.items():

        def run(rule=rule) -> float:
            t0 = time.perf_counter()
            for _ in range(5):
                rule.predict(obs)
            return time.perf_counter() - t0

        row = interleaved(run, 5 * RULE_BATCH, cartpole, args.repeat)
        rows.append({"case": f"{rule_name}.predict, {RULE_BATCH}", **row})

    cold = cold_start(env_id)
    print(f"{env_id}\n{'case':<40} {'scenario-steps /s':>18} {'× CartPole-v1':>14}")
    print("-" * 74)
    for r in rows:
        print(f"{r['case']:<40} {r['per_s']:>18,.0f} {r['vs_cartpole']:>14.2f}")
    print(f"cold start (import, compile, first single and vector step): {cold:.1f} s")
    write_results(
        args.out, rows, env=env_id, steps=args.steps, repeat=args.repeat, cold_start_s=cold
    )
