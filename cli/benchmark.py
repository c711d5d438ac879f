"""``sensorgym benchmark``: score the heuristic rules (and trained models) on an environment.

Every rule registered for the env in :mod:`sensorgym.agents.registry`, and every model given
with ``--model``, is evaluated with one seed over the same scenarios (SB3's
``evaluate_policy`` on the native vector env); the table shows mean return, standard
deviation and the 95 % confidence half-width, and the numbers go to
``OUT/<env>.json``.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

HELP = "Score the heuristic rules (and trained models) on an environment, seeded."

DEFAULT_ENV = "sensorgym/BearingsManeuver-v0"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--env", default=DEFAULT_ENV, help=f"env id (default {DEFAULT_ENV})")
    parser.add_argument("--episodes", type=int, default=64, help="episodes per policy")
    parser.add_argument("--n-envs", type=int, default=16, help="scenarios stepped at once")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--model",
        type=Path,
        action="append",
        default=[],
        help="a model saved by `sensorgym train` (its folder or .zip); repeatable",
    )
    parser.add_argument("--out", type=Path, default=Path("results/benchmark"))


def run(args: argparse.Namespace) -> int:
    from rich.console import Console
    from rich.table import Table

    from sensorgym.agents.registry import rules_for
    from sensorgym.train.evaluation import env_params, evaluate, make_sb3_env
    from sensorgym.train.models import load_model

    if args.n_envs < 1 or args.episodes < args.n_envs:
        raise SystemExit(
            "--episodes must be >= --n-envs >= 1 (every scenario slot ends an episode)"
        )
    env = make_sb3_env(args.env, args.n_envs, args.seed)
    policies = dict(rules_for(args.env, env_params(env)))
    for path in args.model:
        policies[f"model:{path}"] = load_model(path, env)
    console = Console()
    results = {}
    with console.status(f"evaluating {len(policies)} policies on {args.env}"):
        for name, policy in policies.items():
            results[name] = evaluate(policy, env, args.episodes, args.seed).as_dict()
    env.close()

    table = Table(title=f"{args.env}: episode return ({args.episodes} episodes, seed {args.seed})")
    for column in ("policy", "mean", "std", "±95 %", "mean length"):
        table.add_column(column, justify="left" if column == "policy" else "right")
    for name, r in sorted(results.items(), key=lambda kv: -kv[1]["mean"]):
        table.add_row(
            name,
            f"{r['mean']:.3f}",
            f"{r['std']:.3f}",
            f"{r['ci95']:.3f}",
            f"{r['mean_length']:.1f}",
        )
    console.print(table)
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / f"{args.env.replace('/', '__')}.json"
    settings = {
        "env": args.env,
        "episodes": args.episodes,
        "n_envs": args.n_envs,
        "seed": args.seed,
    }
    path.write_text(json.dumps({"settings": settings, "results": results}, indent=2) + "\n")
    console.print(f"wrote {path}")
    return 0
