"""Play one episode of an env with a heuristic rule, then score the rule on 32 episodes.

python examples/use_a_rule.py [--seed 0] [--episodes 32]
"""

from __future__ import annotations

import argparse

import gymnasium as gym

import sensorgym.envs  # noqa: F401  (registers the sensorgym/ ids)
from sensorgym.agents import GreedyManeuver
from sensorgym.train.evaluation import evaluate, make_sb3_env


def main(argv: list[str] | None = None) -> float:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--episodes", type=int, default=32)
    args = parser.parse_args(argv)

    # one episode, step by step: the rule reads only the observation (the tracker's view)
    env = gym.make("sensorgym/BearingsManeuver-v0")
    rule = GreedyManeuver(env.unwrapped.params)
    obs, info = env.reset(seed=args.seed)
    print(f"start: position bound {info['bound']:9.1f} m, true range {info['range']:8.0f} m")
    episode_return, done = 0.0, False
    while not done:
        action, _ = rule.predict(obs, deterministic=True)
        obs, reward, terminated, truncated, info = env.step(action)
        episode_return += float(reward)
        done = terminated or truncated
    print(
        f"end:   position bound {info['bound']:9.1f} m, return ln(bound0/boundT) = "
        f"{episode_return:.3f}"
    )
    env.close()

    # many episodes at once: the native vector env behind SB3's evaluate_policy
    venv = make_sb3_env("sensorgym/BearingsManeuver-v0", n_envs=min(16, args.episodes),
                        seed=args.seed)  # fmt: skip
    stats = evaluate(GreedyManeuver(env.unwrapped.params), venv, args.episodes, args.seed)
    print(f"{args.episodes} episodes: mean return {stats.mean:.3f} ± {stats.ci95:.3f} (95 %)")
    venv.close()
    return episode_return


if __name__ == "__main__":
    main()
