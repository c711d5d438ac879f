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
from typing import Any

HELP = "Score the heuristic rules (and trained models) on an environment, seeded."

#: the help of ``--unsafe-pickle`` (benchmark and render)
UNSAFE_PICKLE_HELP = (
    "also load a run folder that has only SB3's model.zip (no policy.safetensors): this "
    "unpickles the file, which EXECUTES ANY CODE IN IT; use it only on files you trust"
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--env",
        action="append",
        default=None,
        help="env id; repeatable (default: every env with registered rules)",
    )
    parser.add_argument("--episodes", type=int, default=64, help="episodes per policy")
    parser.add_argument("--n-envs", type=int, default=16, help="scenarios stepped at once")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--model",
        type=Path,
        action="append",
        default=[],
        help="a `sensorgym train` run folder (policy.safetensors + config.yaml); repeatable",
    )
    parser.add_argument("--unsafe-pickle", action="store_true", help=UNSAFE_PICKLE_HELP)
    parser.add_argument("--out", type=Path, default=Path("results/benchmark"))


def run(args: argparse.Namespace) -> int:
    from rich.console import Console

    from sensorgym.agents.registry import RULES

    if args.n_envs < 1 or args.episodes < args.n_envs:
        raise SystemExit(
            "--episodes must be >= --n-envs >= 1 (every scenario slot ends an episode)"
        )
    from sensorgym.train.models import RunFolderError, check_run_folder

    env_ids = args.env or list(RULES)
    unknown = [e for e in env_ids if e not in RULES]
    if unknown:
        raise SystemExit(f"--env: no rules registered for {unknown}; known: {sorted(RULES)}")
    for path in args.model:
        try:
            trained_on = check_run_folder(path, args.unsafe_pickle)["env"]
        except RunFolderError as exc:
            raise SystemExit(f"--model: {exc}") from None
        if trained_on not in env_ids:
            raise SystemExit(f"--model {path}: trained on {trained_on}, not on {env_ids}")
    console = Console()
    for env_id in env_ids:
        _benchmark(env_id, args, console)
    return 0


def _benchmark(env_id: str, args: argparse.Namespace, console: Any) -> None:
    from rich.table import Table

    from sensorgym.agents.registry import rules_for
    from sensorgym.train.evaluation import env_params, evaluate, make_sb3_env, simulator_state
    from sensorgym.train.models import RunFolderError, load_model, read_config, run_dir_of

    env = make_sb3_env(env_id, args.n_envs, args.seed)
    # name -> (policy, the SB3 env it acts on): rules and single-agent models on the joint
    # view, parameter-sharing models on the per-agent view of the same scenarios
    policies = {
        name: (rule, env)
        for name, rule in rules_for(env_id, env_params(env), simulator_state(env)).items()
    }
    for path in args.model:
        run_dir = run_dir_of(path)
        config = read_config(run_dir)
        if config["env"] == env_id:
            agents = bool(config.get("agents", False))
            view = make_sb3_env(env_id, args.n_envs, args.seed, agents=True) if agents else env
            try:
                model = load_model(path, view, unsafe_pickle=args.unsafe_pickle)
            except RunFolderError as exc:
                raise SystemExit(f"--model: {exc}") from None
            policies[f"model:{run_dir.name}"] = (model, view)
    results = {}
    with console.status(f"evaluating {len(policies)} policies on {env_id}"):
        for name, (policy, view) in policies.items():
            results[name] = evaluate(policy, view, args.episodes, args.seed).as_dict()
    for _, view in policies.values():
        view.close()

    table = Table(title=f"{env_id}: episode return ({args.episodes} episodes, seed {args.seed})")
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
    path = args.out / f"{env_id.replace('/', '__')}.json"
    settings = {"env": env_id, "episodes": args.episodes, "n_envs": args.n_envs, "seed": args.seed}
    path.write_text(json.dumps({"settings": settings, "results": results}, indent=2) + "\n")
    console.print(f"wrote {path}")
