"""Probe: does the learned search order lose by re-searching ground it has covered?

``gimbal-search-order`` hops to the best *unvisited* position, but positions lie one
half-gate apart, so the gate at one covers its neighbours' centres: after a miss the scores
of the positions around it should fall too (a search-theory update: the chance that the
target is at ``x`` after a miss at ``g`` scales by ``1 − c·exp(−|x − g|²/2)``, ``|x − g|`` in
half-gates, ``c`` the chance the gate would have found it there). Here the policy's scores
``s`` are read as ``s + 1`` (the teacher's kernel, a smoothed probability) and updated for
every position visited in the current search before the wrapper's choice.

Tuning seed 502, 1024 episodes of 64 scenarios, paired to the zero scores with ``c = 0``.

    python research/gimbal_learning/search_coverage.py c [c ...]   # → search_coverage.json
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


class Covered:
    """Scores of ``policy`` (``None``: zeros) after the miss update of every visited
    position with detection chance ``c``."""

    def __init__(self, env, policy, c):
        self.w = find_wrapper(env, SearchOrderAction)
        self.policy, self.c = policy, c
        d = self.w.positions[:, None] - self.w.positions[None]
        self.kernel = np.exp(-0.5 * (np.linalg.norm(d, axis=-1) / self.w.half_gate) ** 2)

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        if self.policy is None:
            s = np.zeros((len(obs), len(self.w.positions)))
        else:
            s = np.asarray(self.policy.predict(obs, deterministic=True)[0], np.float64)
        p = np.clip(s, -1.0, 1.0) + 1.0
        # log of prod over visited g of (1 - c k(x, g)), per slot and position
        miss = np.log1p(-self.c * self.kernel)  # (P, P)
        p = p * np.exp(self.w.visited.astype(np.float64) @ miss)
        return (p - 1.0).astype(np.float32), None


def play(policy_of, c):
    env = make_sb3_env(ENV, N_ENVS, SEED, wrappers=WRAPPERS, episode_streams=True)
    stats = evaluate(Covered(env, policy_of(env), c), env, EPISODES, SEED, tails=())
    env.close()
    return np.asarray(stats.returns)


def main():
    out_file = HERE / "search_coverage.json"  # a second process: another file, merged by hand
    if len(sys.argv) > 2 and sys.argv[1] == "--out":
        out_file, sys.argv[1:] = Path(sys.argv[2]), sys.argv[3:]
    out = json.loads(out_file.read_text()) if out_file.exists() else {}
    if "zero c=0" not in out:
        out["zero c=0"] = play(lambda env: None, 0.0).tolist()
    for c in map(float, sys.argv[1:]):
        for name, fn in (
            ("zero", lambda env: None),
            ("ppo_seed2", lambda e: load_model(SHIPPED, e)),
        ):
            key = f"{name} c={c:g}"
            if key not in out:
                out[key] = play(fn, c).tolist()
            r = paired(out[key], out["zero c=0"])
            print(f"{key}: {r['paired']:+.1f} ± {r['ci95']:.1f}", flush=True)
        out_file.write_text(json.dumps(out) + "\n")


if __name__ == "__main__":
    main()
