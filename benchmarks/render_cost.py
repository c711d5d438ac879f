"""Milliseconds per ``render()`` frame of every registered env (``render_mode="rgb_array"``).

One seeded episode of the registered length under seeded random actions, ``--frames`` frames
spread evenly over it (a frame draws the episode so far, so late frames cost more), at the
renderer's default size; the first frame (imports, figure creation) is reported apart from the
median and the 90th percentile of the frames after it (wall clock, so machine load shows: the
1-minute load is recorded). Issue 39 asks for a frame within ~50 ms at the defaults,
so that ``RecordVideo`` or ``sensorgym render`` of a whole episode takes seconds. Prints a table
and writes ``benchmarks/results/render_cost.json``.

Run: ``.venv/bin/python benchmarks/render_cost.py [--frames 30] [--env ID]``.
"""

from __future__ import annotations

import argparse
import os
import time

import gymnasium as gym
import numpy as np
from timing import RESULTS, write_results

import sensorgym.envs as envs


def frame_times(env_id: str, frames: int, seed: int = 0) -> tuple[float, np.ndarray, tuple]:
    """Seconds of the first frame, of the ``frames`` frames after it, and the frame's shape."""
    env = gym.make(env_id, render_mode="rgb_array")
    env.reset(seed=seed)
    env.action_space.seed(seed)
    t0 = time.perf_counter()
    shape = env.render().shape
    first = time.perf_counter() - t0
    steps = env.spec.max_episode_steps
    at = set(np.linspace(1, steps, frames).round().astype(int).tolist())
    times = []
    for step in range(1, steps + 1):
        _, _, terminated, truncated, _ = env.step(env.action_space.sample())
        if step in at and not (terminated or truncated):
            t0 = time.perf_counter()
            env.render()
            times.append(time.perf_counter() - t0)
        if terminated or truncated:
            env.reset()
    env.close()
    return first, np.array(times), shape


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=30)
    parser.add_argument("--env", action="append", help="an env id (repeatable; default: all)")
    args = parser.parse_args()
    print(f"{'env':<40} {'frame':>9} {'first, ms':>10} {'median, ms':>11} {'p90, ms':>8}")
    print("-" * 82)
    rows = []
    for env_id in args.env or envs.ENV_IDS:
        first, times, shape = frame_times(env_id, args.frames)
        med, p90 = np.median(times) * 1e3, np.percentile(times, 90) * 1e3
        size = f"{shape[1]}x{shape[0]}"
        print(f"{env_id:<40} {size:>9} {first * 1e3:>10.0f} {med:>11.1f} {p90:>8.1f}")
        rows.append(
            {"env": env_id, "width": shape[1], "height": shape[0], "first_ms": first * 1e3,
             "median_ms": med, "p90_ms": p90}
        )  # fmt: skip
    load = os.getloadavg()[0]
    print(
        f"wall clock, up to {args.frames} frames over an episode after the first; load {load:.1f}"
    )
    write_results(RESULTS / "render_cost.json", rows, frames=args.frames, clock="wall")


if __name__ == "__main__":
    main()
