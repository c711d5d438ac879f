"""Train one policy shared by every agent of a PettingZoo env, then run it agent by agent.

In ``sensorgym/StereoPlacement-v0`` each of 3 receiver vehicles is an agent; parameter sharing
trains one policy on every agent's own observation (all get the team reward). The same weights
then drive each agent of the PettingZoo ``parallel_env``.

    python examples/train_shared_policy.py [--timesteps 20000] [--out results/examples]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from sensorgym.envs.stereo_placement import parallel_env
from sensorgym.train.models import load_model
from sensorgym.train.trainer import train

ENV_ID = "sensorgym/StereoPlacement-v0"


def main(argv: list[str] | None = None) -> float:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--timesteps", type=int, default=20_000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=Path("results/examples"))
    args = parser.parse_args(argv)

    # agents=True: the SB3 env's slots are scenarios × agents, one batched simulation step
    result = train(ENV_ID, "ppo", seed=args.seed, timesteps=args.timesteps, n_envs=8,
                   out=args.out, eval_episodes=8, progress=False, agents=True)  # fmt: skip
    print(f"trained one shared policy, saved {result.run_dir}")
    print(f"its evaluation (team return): {result.evaluation['trained']['mean']:.2f}")

    # the PettingZoo door: every agent acts with the same weights on its own observation
    model = load_model(result.run_dir)
    env = parallel_env()
    observations, _ = env.reset(seed=10_000 + args.seed)
    team_return = 0.0
    while env.agents:
        actions = {a: model.predict(observations[a], deterministic=True)[0] for a in env.agents}
        observations, rewards, _, _, _ = env.step(actions)
        team_return += float(np.mean(list(rewards.values())))  # one team reward, every agent
    print(f"one PettingZoo episode, agents {env.possible_agents}: team return {team_return:.2f}")
    env.close()
    return team_return


if __name__ == "__main__":
    main()
