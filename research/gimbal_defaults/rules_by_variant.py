"""How much room GimbalTracking leaves above its rules, setting by setting (issue 40).

At the first defaults the fieldable ``carrier-feedforward`` servo came within a few per cent
of the truth-informed servo: nothing for a learner to win. This scores the rules and the
truth-informed servo on 48 scenarios (seed 700, tuning range) of the first defaults and of
variants with longer occlusions and harder turns, with the episode bound beside them, and
writes ``results.json``: mean return, share of episodes terminated (target lost for good),
mean frames in view.

    python research/gimbal_defaults/rules_by_variant.py [--variants a,b] [--scenarios 48]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import gymnasium as gym
import numpy as np

import sensorgym.envs  # noqa: F401  (registers the ids)
from sensorgym.agents.registry import rules_for
from sensorgym.envs.gimbal_tracking import bound

ENV_ID = "sensorgym/GimbalTracking-v0"
SEED = 700
FIRST_DEFAULTS = {
    "occlusion_length": (5, 40),
    "occlusion_gap": (50, 200),
    "turn_rate": (0.0, 0.1),
    "turn_length": (25, 100),
}
VARIANTS: dict[str, dict] = {
    "first-defaults": FIRST_DEFAULTS,
    "long-occlusions-hard-turns": {
        "occlusion_length": (20, 75), "occlusion_gap": (40, 150), "turn_rate": (0.05, 0.2),
        "turn_length": (25, 100),
    },
    "mid": {
        "occlusion_length": (15, 60), "occlusion_gap": (50, 150), "turn_rate": (0.02, 0.15),
        "turn_length": (25, 100),
    },
    "mid2": {
        "occlusion_length": (10, 50), "occlusion_gap": (50, 200), "turn_rate": (0.0, 0.15),
        "turn_length": (50, 150),
    },
    "new-defaults": {},
}  # fmt: skip
RULES = ("carrier-feedforward", "paper001-servo", "kalman-servo", "hold-last-rate", "truth-servo")


def score(fields: dict, name: str, scenarios: int) -> dict:
    env = gym.make_vec(ENV_ID, num_envs=scenarios, vectorization_mode="vector_entry_point",
                       **fields)  # fmt: skip
    obs, _ = env.reset(seed=SEED)
    bounds = bound.episode_bound(env.params, env.simulator_state)
    rule = rules_for(ENV_ID, env.params, lambda: env.simulator_state)[name]
    ret, in_view = np.zeros(scenarios), np.zeros(scenarios)
    live, lost = np.ones(scenarios, dtype=bool), np.zeros(scenarios, dtype=bool)
    memory = None
    for k in range(500):
        action, memory = rule.predict(obs, memory, episode_start=np.full(scenarios, k == 0))
        obs, reward, terminated, truncated, _ = env.step(action)
        ret[live] += reward[live]
        in_view[live] += env.simulator_state.in_view[live]
        lost |= terminated & live
        live &= ~(terminated | truncated)
    return {
        "mean_return": float(ret.mean()),
        "terminated_share": float(lost.mean()),
        "frames_in_view": float(in_view.mean()),
        "bound": float(bounds.mean()),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--variants", default=",".join(VARIANTS))
    parser.add_argument("--scenarios", type=int, default=48)
    args = parser.parse_args()
    out = {"seed": SEED, "scenarios": args.scenarios, "first_defaults": FIRST_DEFAULTS,
           "variants": {}}  # fmt: skip
    for variant in args.variants.split(","):
        fields = VARIANTS[variant]
        rows = {name: score(fields, name, args.scenarios) for name in RULES}
        out["variants"][variant] = {"fields": fields, "rules": rows}
        print(variant, {n: round(r["mean_return"]) for n, r in rows.items()}, flush=True)
    path = Path(__file__).with_name("results.json")
    path.write_text(json.dumps(out, indent=1) + "\n")


if __name__ == "__main__":
    main()
