"""Probe: does the learned search order burn its best positions while the target is hidden?

A search starts 25 frames after the last detection, and occlusions last longer: the first hops
often look where the target will be but cannot be seen yet. ``gimbal-search-order`` never
returns to a visited position until the whole pattern (60 positions) is done, so the positions
the policy scores best may be spent during the occlusion. Here the wrapper forgets its visits
after ``K`` outward hops (its visited set cleared when ``K`` are held): the shipped policy's
scores then choose again among all positions.

Tuning seed 502, 1024 episodes of 64 scenarios, paired to the zero scores (the four-ring
pattern in its fixed order; ``search_coverage.json``'s ``zero c=0``).

    python research/gimbal_learning/search_memory.py K [K ...]   # → search_memory.json
"""

import json
import sys
from pathlib import Path

import numpy as np
from order_fit import ENV, N_ENVS, SHIPPED, WRAPPERS  # the same env, student and batch
from paired import paired

from sensorgym.train.env_wrappers.gimbal_search import SearchOrderAction
from sensorgym.train.evaluation import evaluate, make_sb3_env
from sensorgym.train.models import load_model
from sensorgym.train.wrappers import find_wrapper

SEED, EPISODES = 502, 1024
HERE = Path(__file__).parent


class Forgetting:
    """The shipped policy's scores; the wrapper's visits forgotten once ``k`` are held."""

    def __init__(self, env, k):
        self.w = find_wrapper(env, SearchOrderAction)
        self.policy, self.k = load_model(SHIPPED, env), k

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        self.w.visited[self.w.visited.sum(axis=1) >= self.k] = False
        return self.policy.predict(obs, deterministic=True)


def main():
    out_file = HERE / "search_memory.json"
    if len(sys.argv) > 2 and sys.argv[1] == "--out":  # a second process: merged by hand
        out_file, sys.argv[1:] = Path(sys.argv[2]), sys.argv[3:]
    out = json.loads(out_file.read_text()) if out_file.exists() else {}
    base = np.asarray(json.loads((HERE / "search_coverage.json").read_text())["zero c=0"])
    for k in map(int, sys.argv[1:]):
        key = f"ppo_seed2 K={k}"
        if key not in out:
            env = make_sb3_env(ENV, N_ENVS, SEED, wrappers=WRAPPERS, episode_streams=True)
            out[key] = evaluate(Forgetting(env, k), env, EPISODES, SEED, tails=()).returns
            out[key] = np.asarray(out[key]).tolist()
            env.close()
        r = paired(out[key], base)
        print(f"{key}: {r['paired']:+.1f} ± {r['ci95']:.1f}", flush=True)
        out_file.write_text(json.dumps(out) + "\n")


if __name__ == "__main__":
    main()
