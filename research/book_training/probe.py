"""Book PPO recipes tried for issue 37 item 3 (a trained policy at PCRLB <= 40 m, no stand-off
broken): each run's learning curve (tuning seed 500, 64 episodes, from its curve.json) and the
book's per-run PCRLB at 32 min with the stand-off breaks over 256 runs of tuning seed 600
(``reproduce/experiments/bot_control``'s own measure). Lab record, not a benchmark.

    python research/book_training/probe.py NAME=RUN_DIR ... --out research/book_training/results.json

The runs were trained with ``sensorgym train --env sensorgym/BearingsManeuverBook-v0`` and the
``--hyperparam`` overrides recorded in each run's config.yaml (copied into the JSON).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import yaml

from sensorgym.agents.registry import RULES
from sensorgym.reproduce.experiments import bot_control as bc
from sensorgym.train.evaluation import env_params
from sensorgym.train.models import load_model, read_config

SEED = 600
RUNS = 256


def measure(flown: dict) -> dict:
    r = bc._summarise("", "", flown)
    return {
        "pcrlb_per_run_m": r.per_run_32min,
        "env_return": r.env_return,
        "standoff_broken": r.standoff_broken,
        "closest_m": r.min_range,
    }


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("runs", nargs="+", help="NAME=RUN_DIR")
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    env = bc._book_env(RUNS, SEED)
    rule = RULES[bc.BOOK_ENV_ID]["book-plan-tuned"](env_params(env), None)
    doc = {
        "seed": SEED,
        "runs": RUNS,
        "rule": {"book-plan-tuned": measure(bc.fly(rule, env, RUNS, SEED))},
        "trained": {},
    }
    for spec in args.runs:
        name, _, folder = spec.partition("=")
        config = read_config(Path(folder))
        tenv = bc._book_env(RUNS, SEED, config)
        entry = measure(bc.fly(load_model(Path(folder), tenv), tenv, RUNS, SEED))
        curve = json.loads((Path(folder) / "curve.json").read_text())["points"]
        entry["curve_seed500"] = [[p["timesteps"], p["mean"]] for p in curve]
        hp = config["hyperparams"]
        entry["hyperparams"] = {
            k: hp.get(k)
            for k in ("n_envs", "n_timesteps", "learning_rate", "training_wrappers", "pretrain")
        }
        entry["seed"] = config["seed"]
        doc["trained"][name] = entry
        print(name, yaml.safe_dump({k: v for k, v in entry.items() if k != "curve_seed500"}))
        tenv.close()
    args.out.write_text(json.dumps(doc, indent=1) + "\n")


if __name__ == "__main__":
    main()
