"""PPO frames per second through our SB3 adapter against SB3's own ``DummyVecEnv``, per env.

The same PPO settings (one torch thread, ``n_steps`` 64, one epoch, batch 4096) learn for
``--timesteps`` transitions from 256 scenarios: once on the native vector env through
``train/sb3_vec_env.py`` (one batched simulation call per step) and once on SB3's
``DummyVecEnv`` of 256 single envs (one Python call per scenario per step). Prints the fps of
both and their ratio and writes ``benchmarks/results/training.json``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import torch
from stable_baselines3 import PPO
from stable_baselines3.common.env_util import make_vec_env
from timing import RESULTS, write_results

from sensorgym.envs import ENV_IDS
from sensorgym.train.evaluation import make_sb3_env

N_ENVS = 256


def fps(env, timesteps: int) -> float:
    model = PPO(
        "MlpPolicy", env, n_steps=64, batch_size=4096, n_epochs=1, seed=0, device="cpu", verbose=0
    )
    model.learn(N_ENVS * 64)  # warm-up: the first rollout and update
    t0 = time.perf_counter()
    model.learn(timesteps, reset_num_timesteps=False)
    return timesteps / (time.perf_counter() - t0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--env", action="append", default=None, help="env id (default: all)")
    parser.add_argument("--timesteps", type=int, default=N_ENVS * 64 * 2)
    parser.add_argument("--out", type=Path, default=RESULTS / "training.json")
    args = parser.parse_args()
    torch.set_num_threads(1)
    rows = []
    for env_id in args.env or ENV_IDS:
        ours = fps(make_sb3_env(env_id, N_ENVS, seed=0), args.timesteps)
        dummy = fps(make_vec_env(env_id, n_envs=N_ENVS, seed=0), args.timesteps)
        rows.append({"env": env_id, "adapter_fps": ours, "dummy_fps": dummy, "ratio": ours / dummy})
        print(
            f"{env_id:<32} adapter {ours:>9,.0f} fps   DummyVecEnv {dummy:>8,.0f} fps   ×{ours / dummy:.1f}"
        )
    write_results(args.out, rows, n_envs=N_ENVS, timesteps=args.timesteps)


if __name__ == "__main__":
    main()
