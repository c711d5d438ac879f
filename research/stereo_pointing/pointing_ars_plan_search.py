"""Direct policy search from the best rule of ``sensorgym/StereoPointing-v0``, on the tuning seeds
(issue 13).

``python research/stereo_pointing/pointing_ars_plan_search.py [RUN ...] [--seeds 500 600] [--episodes 256]``
scores ``sensorgym train --algo ars`` run folders (default: the shipped StereoPointing runs,
``train/policies/sensorgym__StereoPointing-v0/ars_seed*``) on the tuning seeds, paired episode by
episode to ``plan-search``, the best rule, on the same scenarios and noise. Their ``ars.yml`` entry
aims through ``pointing-plan`` with ``sharing``, ``cue_steps: 1`` and ``search``, so the untrained
policy *is* ``plan-search`` (tested in ``tests/train/test_ars.py``) and the search moves only
the linear correction of its planner's values. Writes
``research/stereo_pointing/results/pointing_ars_plan_search.json``: per run its weights by feature name, the
scenario seeds of its iterations, and per seed the mean and the paired difference with its 95 %
interval and the shares of episodes above and below the rule. Tuning seeds only (never 10000 or
31337): the held-out check is ``sensorgym benchmark``'s.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
from pointing_share_ars import ars_run_record
from pointing_sharing import paired_fields, tuning_args

from sensorgym.agents.registry import RULES
from sensorgym.train.evaluation import env_params, evaluate, make_sb3_env, simulator_state
from sensorgym.train.models import load_model, read_config, wrappers_of
from sensorgym.train.shipped import shipped_policies

RESULTS = Path(__file__).resolve().parent / "results" / "pointing_ars_plan_search.json"
ENV_ID = "sensorgym/StereoPointing-v0"
RULE = "plan-search"
N_ENVS = 16


def weight_names(horizons: list[int]) -> list[str]:
    """The linear residual's feature names, in its order (``CandidatePolicy.linear_features``):
    the planned-return gap per block, the best-plan flag per block, the receivers kept."""
    blocks = [*(str(h) for h in horizons), "left"]
    return [*(f"gap_{b}" for b in blocks), *(f"best_{b}" for b in blocks), "kept"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", type=Path, nargs="*")
    args = tuning_args(__doc__, RESULTS, [500, 600], ap)
    runs = args.runs or [Path(p) for p in shipped_policies(ENV_ID).values()]
    start = time.perf_counter()
    plain = make_sb3_env(ENV_ID, N_ENVS, 0)
    rule = RULES[ENV_ID][RULE](env_params(plain), simulator_state(plain))
    base = {s: np.array(evaluate(rule, plain, args.episodes, s).returns) for s in args.seeds}
    settings = {"env": ENV_ID, "rule": RULE, "n_envs": N_ENVS, "seeds": args.seeds}
    settings["episodes"] = args.episodes
    settings["rule_mean"] = {str(s): float(b.mean()) for s, b in base.items()}
    out: dict = {"settings": settings, "runs": {}}
    for run in runs:
        config = read_config(run)
        env = make_sb3_env(ENV_ID, N_ENVS, 0, wrappers=wrappers_of(config))
        model = load_model(run, env)
        weights = model.policy.search_parameter().detach().numpy().ravel()
        names = weight_names(config["hyperparams"]["policy_kwargs"]["horizons"])
        row = ars_run_record(run, config, names, weights.tolist())
        for seed in args.seeds:
            ours = np.array(evaluate(model, env, args.episodes, seed).returns)
            row[f"seed_{seed}"] = {
                "mean": float(ours.mean()),
                **paired_fields(ours, base[seed], RULE),
            }
            print(run.name, seed, json.dumps(row[f"seed_{seed}"]), flush=True)
        env.close()
        out["runs"][run.name] = row
    plain.close()
    out["settings"]["seconds"] = round(time.perf_counter() - start, 1)
    args.out.write_text(json.dumps(out, indent=1) + "\n")


if __name__ == "__main__":
    main()
