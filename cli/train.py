"""``sensorgym train``: SB3 training on a registered env's native vector env.

Hyperparameters come from ``train/hyperparams/<algo>.yml`` for the env id; ``--timesteps``,
``--n-envs`` and ``--hyperparam KEY=VALUE`` (any entry, the value read as YAML; a dotted KEY
such as ``pretrain.steps`` reaches inside a mapping, ``pretrain=null`` leaves the imitation
out) override them. The run folder gets the policy weights ``policy.safetensors`` (data
only: loading them runs no code), the resolved ``config.yaml``, ``evaluation.json`` (the
trained policy beside the heuristic rules, same seed and scenarios; the printed table pairs
every policy to the best rule as ``sensorgym benchmark`` does, on the tuning seed) and the learning curve
``curve.json``/``curve.png`` (evaluation return against samples, the rules as lines); ``sensorgym benchmark
--model RUN_FOLDER`` scores it again later. ``--param NAME=VALUE`` trains at another size or
setting of the env (recorded in ``config.yaml``; the policy then refuses other settings). ``--tensorboard DIR`` logs the run for TensorBoard.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from sensorgym.cli import args as types
from sensorgym.cli.console import make_console, print_path
from sensorgym.cli.params import (
    add_hyperparam_argument,
    add_param_argument,
    hyperparams_from,
    params_from,
)

HELP = "Train a policy (PPO, SAC or ARS) on an environment and score it beside the rules."

DEFAULT_ENV = "sensorgym/BearingsManeuver-v0"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--env", default=DEFAULT_ENV, help=f"env id (default {DEFAULT_ENV})")
    parser.add_argument("--algo", default="ppo", choices=["ppo", "sac", "ars"], help="trainer")
    parser.add_argument(
        "--timesteps", type=types.positive_int, default=None, help="override the YAML's"
    )
    parser.add_argument(
        "--n-envs", type=types.positive_int, default=None, help="override the YAML's"
    )
    parser.add_argument(
        "--agents",
        action="store_true",
        help="parameter sharing: one policy drives every agent of the env's PettingZoo version",
    )
    parser.add_argument(
        "--torch-threads",
        type=types.positive_int,
        default=1,
        help="torch intra-op threads (default 1: never slower for these small policies)",
    )
    parser.add_argument("--seed", type=types.seed, default=0)
    parser.add_argument(
        "--eval-episodes",
        type=types.positive_int,
        default=64,
        help="episodes of each evaluation (curve points and the final one)",
    )
    parser.add_argument(
        "--out",
        type=Path,
        default=Path("results/train"),
        help="runs go to OUT/<env id, / as __>/<algo>_seed<S>/",
    )
    parser.add_argument(
        "--tensorboard",
        type=Path,
        default=None,
        metavar="DIR",
        help="write TensorBoard event files to DIR: SB3's scalars and the env's accuracy "
        "metrics per episode (episode/bound, episode/position_error, …); view them with "
        "`tensorboard --logdir DIR`",
    )
    parser.add_argument(
        "--curve-points",
        type=types.non_negative_int,
        default=10,
        help="evaluations during learning for curve.json/curve.png (default 10; 0: none)",
    )
    parser.add_argument(
        "--checkpoint-every",
        type=types.positive_int,
        default=None,
        metavar="N",
        help="write RUN/checkpoint/ every N samples (SB3's model.zip with the optimizer, and "
        "the run's state) so that --resume can continue the run (default: no checkpoints)",
    )
    parser.add_argument(
        "--resume",
        type=Path,
        default=None,
        metavar="RUN",
        help="continue the run in the run folder RUN from its checkpoint (every other "
        "setting is the checkpoint's, except --no-progress, --torch-threads, --tensorboard)",
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_hyperparam_argument(parser)
    add_param_argument(parser)


def run(args: argparse.Namespace) -> int:
    from sensorgym.train.config import load_hyperparams
    from sensorgym.train.trainer import train

    if args.resume is not None:
        from sensorgym.train.trainer import resume_arguments

        try:
            resumed = resume_arguments(args.resume)
        except ValueError as exc:
            raise SystemExit(f"--resume: {exc}") from None
        args.env, args.algo, args.eval_episodes = (
            resumed["env_id"],
            resumed["algo"],
            resumed["eval_episodes"],
        )
        result = train(
            **resumed,
            progress=not args.no_progress,
            torch_threads=args.torch_threads,
            tensorboard=args.tensorboard,
        )
        return _report(args, result)
    try:
        recipe = load_hyperparams(args.algo, args.env)
    except KeyError as exc:
        raise SystemExit(f"--env/--algo: {exc.args[0]}") from None
    overrides = hyperparams_from(args.algo, args.env, args.hyperparam)
    n_envs = args.n_envs or overrides.get("n_envs") or recipe["n_envs"]
    params = params_from(args.env, args.param, scenarios=n_envs)
    # before any training: a bad --out or --tensorboard fails now, not when the run is saved
    types.output_dir(args.out)
    if args.tensorboard is not None:
        types.output_dir(args.tensorboard, "--tensorboard")
    result = train(
        args.env,
        args.algo,
        seed=args.seed,
        timesteps=args.timesteps,
        n_envs=args.n_envs,
        out=args.out,
        eval_episodes=args.eval_episodes,
        progress=not args.no_progress,
        agents=args.agents,
        torch_threads=args.torch_threads,
        tensorboard=args.tensorboard,
        curve_points=args.curve_points,
        params=params,
        hyperparams=overrides,
        checkpoint_every=args.checkpoint_every,
    )
    return _report(args, result)


def _report(args: argparse.Namespace, result: Any) -> int:
    """Print the run's evaluation beside the rules and where it was saved."""
    from rich.table import Table

    from sensorgym.cli.benchmark import iqm_cell, paired_cell
    from sensorgym.train.benchmark import best_rule, paired_difference
    from sensorgym.train.trainer import VALIDATION_SEED

    # the trained policy and the rules on the same scenarios, paired to the best fieldable rule
    # (as `sensorgym benchmark` does on the held-out seed; this is the tuning seed)
    scores = result.evaluation
    best = best_rule({k: v for k, v in scores.items() if k != "trained"})
    ref = scores[best].get("returns") if best is not None else None
    paired = {
        name: paired_difference(r["returns"], ref)
        for name, r in scores.items()
        if ref and name != best and len(r.get("returns", ())) == len(ref)
    }
    table = Table(
        title=f"{args.env}: episode return ({args.eval_episodes} evaluation episodes, "
        f"tuning seed {VALIDATION_SEED})"
    )
    columns = ("policy", "mean", "±95 %", f"paired − {best}", "paired IQM", "better/worse")
    for column in columns if paired else columns[:3]:
        table.add_column(column, justify="left" if column == "policy" else "right")
    for name, r in sorted(scores.items(), key=lambda kv: -kv[1]["mean"]):
        row = [name, f"{r['mean']:.3f}", f"{r['ci95']:.3f}"]
        d = paired.get(name)
        if d is not None:
            row += [paired_cell(d), iqm_cell(d), f"{d['better']}/{d['worse']}"]
        elif paired:
            row += ["best rule" if name == best else "", "", ""]
        table.add_row(*row)
    console = make_console()
    console.print(table)
    print_path(console, "saved ", result.run_dir)
    if args.tensorboard is not None:
        print_path(console, "TensorBoard event files in ", args.tensorboard)
    return 0
