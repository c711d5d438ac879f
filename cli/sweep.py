"""``sensorgym sweep``: multi-seed training and hyperparameter search on Ray, with a benchmark.

Every trial is an ordinary ``sensorgym train`` run folder (under ``OUT/trials/<config>/``); the
sweep aggregates them — per configuration the mean evaluation return over the seeds with its
95 % interval, and the best configuration — into one table, ``OUT/sweep.json`` and the chart
``OUT/sweep.png``; ``--benchmark-episodes N`` then scores the best configuration's runs beside
every rule and shipped policy on N episodes each, fanned out as Ray tasks
(``OUT/benchmark.png``). Ray runs on a local instance by default; ``--address`` joins an existing
cluster (``docs/sweeps.md``). Needs the ``ray`` extra: ``pip install 'sensorgym[ray]'``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from sensorgym.cli import args as types
from sensorgym.cli.console import make_console, print_written
from sensorgym.cli.params import add_hyperparam_argument, hyperparams_from

HELP = "Multi-seed training and hyperparameter search on Ray (local or a cluster), aggregated."

DEFAULT_ENV = "sensorgym/BearingsManeuver-v0"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--env", default=DEFAULT_ENV, help=f"env id (default {DEFAULT_ENV})")
    parser.add_argument(
        "--algo", default="ppo", choices=["ppo", "sac", "ars"], help="trainer (default ppo)"
    )
    parser.add_argument(
        "--seeds",
        type=types.seed,
        nargs="+",
        default=[0, 1, 2],
        help="training seeds (default 0 1 2)",
    )
    parser.add_argument(
        "--timesteps", type=types.positive_int, default=None, help="override the YAML's"
    )
    parser.add_argument(
        "--n-envs", type=types.positive_int, default=None, help="override the YAML's"
    )
    parser.add_argument(
        "--space",
        action="append",
        default=[],
        metavar="NAME=KIND:ARGS",
        help="a hyperparameter to search, repeatable: uniform:LO:HI, loguniform:LO:HI, "
        "randint:LO:HI, choice:A,B,… (sampled) or grid:A,B,… (every value); e.g. "
        "--space learning_rate=loguniform:1e-4:1e-3 --space gamma=choice:0.95,0.99",
    )
    parser.add_argument(
        "--samples",
        type=types.positive_int,
        default=1,
        help="configurations drawn at random from --space (each trained with every seed)",
    )
    parser.add_argument(
        "--search-seed", type=types.seed, default=0, help="seed of the random search"
    )
    parser.add_argument(
        "--asha", action="store_true", help="stop lagging trials early (ASHA scheduler)"
    )
    add_hyperparam_argument(parser)
    parser.add_argument("--eval-episodes", type=types.positive_int, default=64, help="per trial")
    parser.add_argument(
        "--benchmark-episodes",
        type=types.non_negative_int,
        default=0,
        help="afterwards score the best configuration's runs beside the rules on N episodes "
        "each, as Ray tasks (default 0: no benchmark)",
    )
    parser.add_argument(
        "--benchmark-chunk", type=types.positive_int, default=64, help="episodes per task"
    )
    parser.add_argument(
        "--address",
        default=None,
        help="an existing Ray cluster ('auto' or HOST:PORT; default: start a local instance)",
    )
    parser.add_argument(
        "--num-cpus",
        type=types.positive_int,
        default=None,
        help="CPUs of the local instance (default: all)",
    )
    parser.add_argument(
        "--cpus-per-trial",
        type=types.positive_float,
        default=1.0,
        help="Ray CPUs per trial and task",
    )
    parser.add_argument("--verbose", type=int, default=0, choices=[0, 1, 2], help="Ray's output")
    parser.add_argument(
        "--out",
        type=Path,
        default=Path("results/sweep"),
        help="folder for the trials, sweep.json and sweep.png",
    )


def run(args: argparse.Namespace) -> int:
    from sensorgym.train.sweep import join_with_token

    join_with_token(args.address)  # before Ray is imported: it reads its auth mode once
    try:
        import ray  # noqa: F401
    except ImportError:
        raise SystemExit(
            "sweep: needs Ray: pip install 'sensorgym[ray]' (or 'ray[tune]')"
        ) from None
    from rich.table import Table

    from sensorgym.train.config import check_overrides, load_hyperparams
    from sensorgym.train.sweep import SweepSettings, parse_space, run_sweep
    from sensorgym.train.trainer import VALIDATION_SEED

    try:
        load_hyperparams(args.algo, args.env)
    except KeyError as exc:
        raise SystemExit(f"--env/--algo: {exc.args[0]}") from None
    space = {}
    for spec in args.space:
        try:
            name, _ = parse_space(spec)
        except ValueError as exc:
            raise SystemExit(f"--space: {exc}") from None
        space[name] = spec.partition("=")[2]
    fixed = hyperparams_from(args.algo, args.env, args.hyperparam)
    try:  # a searched name must be an entry the recipe can take, like a fixed one
        check_overrides(
            args.algo, args.env, {**fixed, **dict.fromkeys(space, 0)}, check_values=False
        )
    except KeyError as exc:
        raise SystemExit(f"--space: {exc.args[0]}") from None
    types.output_dir(args.out)  # before Ray starts: a bad --out fails now
    settings = SweepSettings(
        env_id=args.env,
        algo=args.algo,
        seeds=tuple(dict.fromkeys(args.seeds)),
        timesteps=args.timesteps,
        n_envs=args.n_envs,
        space=space,
        fixed=fixed,
        samples=args.samples,
        search_seed=args.search_seed,
        asha=args.asha,
        eval_episodes=args.eval_episodes,
        benchmark_episodes=args.benchmark_episodes,
        benchmark_chunk=args.benchmark_chunk,
        cpus_per_trial=args.cpus_per_trial,
    )
    console = make_console()
    with console.status(f"sweep on Ray: {args.algo} on {args.env}, seeds {list(settings.seeds)}"):
        doc = run_sweep(
            settings, args.out, address=args.address, num_cpus=args.num_cpus, verbose=args.verbose
        )

    names = sorted({k for c in doc["configs"].values() for k in c["hyperparams"]})
    table = Table(
        title=f"{args.env}: {args.algo} sweep, evaluation return over seeds "
        f"({args.eval_episodes} episodes per run, validation seed {VALIDATION_SEED})"
    )
    for column in ("config", *names, "seeds", "mean", "±95 %", "per seed"):
        table.add_column(column, justify="left" if column == "config" else "right")
    for tag, c in sorted(doc["configs"].items(), key=lambda kv: -kv[1]["mean"]):
        best = " (best)" if tag == doc["best"] else ""
        table.add_row(
            tag + best,
            *(_fmt(c["hyperparams"].get(n)) for n in names),
            str(len(c["seeds"])),
            f"{c['mean']:.3f}",
            "–" if c["ci95"] is None else f"{c['ci95']:.3f}",
            " ".join(f"{r:.2f}" for r in c["returns"]),
        )
    console.print(table)
    if doc["incomplete"]:
        console.print(f"{doc['incomplete']} trial(s) stopped early or failed: left out")
    if doc["benchmark"]:
        bench = Table(title=f"{args.env}: benchmark fan-out ({args.benchmark_episodes} episodes)")
        for column in ("policy", "mean", "±95 %"):
            bench.add_column(column, justify="left" if column == "policy" else "right")
        for name, r in sorted(doc["benchmark"].items(), key=lambda kv: -kv[1]["mean"]):
            bench.add_row(name, f"{r['mean']:.3f}", f"{r['ci95']:.3f}")
        console.print(bench)
    out = args.out.resolve()
    names = ("sweep.json", "sweep.png", "benchmark.png", "trials")
    print_written(console, [out / name for name in names if (out / name).exists()])
    return 0


def _fmt(value: object) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    return "yaml" if value is None else str(value)
