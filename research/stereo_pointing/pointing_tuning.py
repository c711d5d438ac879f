"""Tuning-seed comparison of StereoPointing's planners and trained runs, paired (issue 13).

``python research/stereo_pointing/pointing_tuning.py [--seed 500 --seed 600] [--episodes 256]
[--model RUN_DIR ...]`` scores ``plan-horizon``, ``plan-acquire`` and each ``sensorgym train``
run folder on the same seeded scenarios (:func:`sensorgym.train.evaluation.evaluate`, 16
scenarios at a time) and writes ``research/stereo_pointing/results/pointing_tuning.json``: every policy's
mean return and its paired per-episode difference to both rules, with each run's recipe (its
wrappers, steps and policy settings from ``config.yaml``), runs named by their folder's name. Seeds below 10000 only: these are the
numbers recipes are chosen on, never the held-out benchmark seeds.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np
import torch

from sensorgym.agents.registry import rules_for
from sensorgym.envs.stereo_pointing.simulation import PointingParams
from sensorgym.train.evaluation import evaluate, make_sb3_env
from sensorgym.train.models import load_model, read_config, wrappers_of

ENV_ID = "sensorgym/StereoPointing-v0"
RESULTS = Path(__file__).resolve().parent / "results" / "pointing_tuning.json"
RULES = ("plan-horizon", "plan-acquire")
HELD_OUT = 10000


def paired(a: np.ndarray, b: np.ndarray) -> dict[str, float]:
    """Mean of ``a − b`` per episode and its 95 % half-width."""
    d = a - b
    return {"mean": float(d.mean()), "ci95": float(1.96 * d.std(ddof=1) / np.sqrt(d.size))}


def recipe(config: dict[str, Any]) -> dict[str, Any]:
    """What a run was trained with: its wrappers, steps, training seed and policy settings."""
    hp = config["hyperparams"]
    return {
        "seed": config["seed"],
        "wrappers": hp.get("wrappers"),
        "n_timesteps": hp.get("n_timesteps"),
        "policy_kwargs": hp.get("policy_kwargs"),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, action="append")
    ap.add_argument("--episodes", type=int, default=256)
    ap.add_argument("--model", type=Path, action="append", default=[])
    ap.add_argument("--out", type=Path, default=RESULTS)
    args = ap.parse_args()
    seeds = args.seed or [500, 600]
    if any(s >= HELD_OUT for s in seeds):
        raise SystemExit(f"--seed: tuning seeds are below {HELD_OUT} (held out: 10000, 31337)")
    torch.set_num_threads(1)
    rules = rules_for(ENV_ID, PointingParams(), lambda: None)
    out: dict[str, Any] = {
        "settings": {"env": ENV_ID, "episodes": args.episodes, "seeds": seeds, "n_envs": 16},
        "runs": {m.name: recipe(read_config(m)) for m in args.model},
        "results": [],
    }
    for seed in seeds:
        returns = {
            name: np.array(
                evaluate(rules[name], make_sb3_env(ENV_ID, 16, 0), args.episodes, seed).returns
            )
            for name in RULES
        }
        for m in args.model:
            env = make_sb3_env(ENV_ID, 16, 0, wrappers=wrappers_of(read_config(m)))
            returns[m.name] = np.array(
                evaluate(load_model(m, env), env, args.episodes, seed).returns
            )
        for name, r in returns.items():
            row = {"seed": seed, "policy": name, "mean": float(r.mean())}
            row.update(
                {f"minus_{rule}": paired(r, returns[rule]) for rule in RULES if rule != name}
            )
            out["results"].append(row)
            print(json.dumps(row), flush=True)
    args.out.write_text(json.dumps(out, indent=1) + "\n")


if __name__ == "__main__":
    main()
