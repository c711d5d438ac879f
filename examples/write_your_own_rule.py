"""Write your own rule and score it beside the registered ones on the same scenarios.

A rule is anything with SB3's ``predict(observation, state, episode_start, deterministic)``;
``MemorylessRule`` writes ``predict`` for you from ``act(obs (N, obs_dim)) -> actions``.

    python examples/write_your_own_rule.py [--episodes 32] [--seed 10000]
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass

import numpy as np

from sensorgym.agents.protocol import MemorylessRule
from sensorgym.agents.registry import rules_for
from sensorgym.envs.bearings_maneuver.simulation import OBS_DIM
from sensorgym.train.evaluation import env_params, evaluate, make_sb3_env, simulator_state

ENV_ID = "sensorgym/BearingsManeuver-v0"


@dataclass(frozen=True)
class TurnAcrossTheBearing(MemorylessRule):
    """Steer so that the bearing to the target stays abeam (90° off the heading): the
    bearing then changes fastest, which is what makes range observable."""

    gain: float = 2.0
    """Turn command per radian of bearing away from abeam."""
    obs_dim = OBS_DIM

    def act(self, obs: np.ndarray) -> np.ndarray:
        # observation 0, 1: sin and cos of the last bearing relative to the heading
        # (starboard > 0); a positive turn command turns to port, which moves the bearing aft
        bearing = np.arctan2(obs[:, 0], obs[:, 1])
        abeam = np.where(bearing >= 0.0, np.pi / 2, -np.pi / 2)  # the nearer side
        turn = np.clip(self.gain * (abeam - bearing), -1.0, 1.0)
        return np.stack([turn, np.zeros_like(turn)], axis=1)  # full turn rate, same speed


def main(argv: list[str] | None = None) -> dict[str, float]:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--episodes", type=int, default=32)
    parser.add_argument("--seed", type=int, default=10_000)
    args = parser.parse_args(argv)

    env = make_sb3_env(ENV_ID, n_envs=min(16, args.episodes), seed=args.seed)
    policies = {"turn-across-the-bearing (ours)": TurnAcrossTheBearing()}
    policies |= rules_for(ENV_ID, env_params(env), simulator_state(env))
    scores = {}
    for name, policy in policies.items():  # one seed: every policy meets the same scenarios
        stats = evaluate(policy, env, args.episodes, args.seed)
        scores[name] = stats.mean
        print(f"{name:32s} {stats.mean:7.3f} ± {stats.ci95:.3f}")
    env.close()
    return scores


if __name__ == "__main__":
    main()
