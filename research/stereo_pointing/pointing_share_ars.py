"""The learned sharing of ``sensorgym/StereoPointing-v0`` on the tuning seeds (issue 13).

``python research/stereo_pointing/pointing_share_ars.py RUN [RUN ...] [--seeds 500 600] [--episodes 256]``
scores each ``sensorgym train --algo ars`` run folder of the learned sharing (share bits over
``plan-acquire``'s assignment; the hyperparameters each run recorded, the ``ars.yml`` entry it
was trained with, are written beside its scores) on the tuning
seeds, paired episode by episode to ``plan-acquire-share`` as registered when the runs were
trained (fraction 0.97 of the field of view; the rule their zero weights were) and
to the best static sharing setting of the probe, (0.5, 1.0, 3)
(``research/stereo_pointing/pointing_sharing_state.py``), on the same scenarios. Writes
``research/stereo_pointing/results/pointing_share_ars.json``: per run its share weights by feature name,
scenario seeds, and per seed the paired differences with 95 % intervals. Tuning seeds only
(never 10000 or 31337): the held-out check is ``sensorgym benchmark``'s.

The share bits (``pointing-plan`` with ``share_bits``, ``plan-features`` with ``sharing``,
``CandidatePolicy`` with ``share``) were removed from the product by issue 38: scoring these
runs needs the product at commit ``be69734``, the last that has them. :func:`ars_run_record`
still serves ``pointing_ars_plan_search.py``.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import yaml
from pointing_sharing import tuning_args
from pointing_sharing_state import SHARE_FEATURES

from sensorgym.agents.stereo_pointing_horizon import PlanHorizon
from sensorgym.agents.stereo_pointing_sharing import Sharing
from sensorgym.envs.stereo_pointing.simulation import PointingParams
from sensorgym.train.benchmark import paired_difference
from sensorgym.train.evaluation import evaluate, make_sb3_env
from sensorgym.train.models import load_model

RESULTS = Path(__file__).resolve().parent / "results" / "pointing_share_ars.json"
ENV_ID = "sensorgym/StereoPointing-v0"
N_ENVS = 16
#: the probe's best static setting (q, f, max_rms)
STATIC = Sharing(0.5, 1.0, 3.0)

#: ``Sharing.fraction`` of ``plan-acquire-share`` when the runs were trained (now 1.0)
REGISTERED_THEN = 0.97


def ars_run_record(run: Path, config: dict, names: list[str], weights: list[float]) -> dict:
    """What a results file keeps of an ARS run folder: its training seed, the hyperparameters
    it recorded (its ``ars.yml`` entry), its vector by feature name, and the number and
    scenario seeds of its iterations (``search.json``)."""
    history = json.loads((run / "search.json").read_text())
    return {
        "seed": config["seed"],
        "hyperparams": config["hyperparams"],
        "theta": dict(zip(names, weights, strict=True)),
        "iterations": len(history),
        "scenario_seeds": [h["scenario_seed"] for h in history],
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", type=Path, nargs="+")
    args = tuning_args(__doc__, RESULTS, [500, 600], ap)
    start = time.perf_counter()
    params = PointingParams()
    rules = {
        "plan-acquire-share": PlanHorizon(
            params, acquisition=True, sharing=Sharing(fraction=REGISTERED_THEN)
        ),
        "static (0.5, 1.0, 3)": PlanHorizon(params, acquisition=True, sharing=STATIC),
    }
    plain = make_sb3_env(ENV_ID, N_ENVS, 0)
    base = {
        (name, seed): np.array(evaluate(rule, plain, args.episodes, seed).returns)
        for name, rule in rules.items()
        for seed in args.seeds
    }
    out: dict = {
        "settings": {
            "env": ENV_ID,
            "episodes": args.episodes,
            "seeds": args.seeds,
            "n_envs": N_ENVS,
            "rules": {k: float(v.mean()) for k, v in ((f"{n} seed {s}", b) for (n, s), b in base.items())},
        },
        "runs": {},
    }  # fmt: skip
    for run in args.runs:
        config = yaml.safe_load((run / "config.yaml").read_text())
        wrappers = config["hyperparams"]["wrappers"]
        env = make_sb3_env(ENV_ID, N_ENVS, 0, wrappers=wrappers)
        model = load_model(run, env)
        row = ars_run_record(run, config, SHARE_FEATURES, model.theta.tolist())
        for seed in args.seeds:
            ours = np.array(evaluate(model, env, args.episodes, seed).returns)
            row[f"seed_{seed}"] = {
                "mean": float(ours.mean()),
                **{
                    f"paired_minus_{name}": paired_difference(ours, base[name, seed])
                    for name in rules
                },
            }
            print(run.name, seed, json.dumps(row[f"seed_{seed}"]), flush=True)
        out["runs"][run.name] = row
    out["settings"]["seconds"] = round(time.perf_counter() - start, 1)
    args.out.write_text(json.dumps(out, indent=1) + "\n")


if __name__ == "__main__":
    main()
