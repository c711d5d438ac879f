"""``sensorgym benchmark``: score the rules and trained policies on every env — the main job.

Every env registered under ``sensorgym/`` (or those given with ``--env``) is scored: its default
rule set (:func:`sensorgym.agents.registry.default_rules`: the fieldable rules to compare
against and the truth-informed ones; ``--rule NAME`` scores the named rules instead, ablations
included, ``--all-rules`` every registered one), every policy shipped with sensorgym
(:mod:`sensorgym.train.shipped`) and every model given with ``--model``, each evaluated with one
seed over the same scenarios, in the same order (:func:`sensorgym.train.evaluation.evaluate` on
the native vector env). One table per env shows mean return, the 95 % confidence half-width and
interval, the mean episode length and each policy's paired difference to the best fieldable
rule (truth-informed rules, which see the truth, excluded): the mean and 95 % interval of the per-episode
difference on the same scenarios; beside it the difference's interquartile mean with a bootstrap
95 % interval (what a typical episode gains, robust to a few episodes hundreds apart) and how
many episodes the policy did better and worse than the best rule
(:func:`sensorgym.train.benchmark.paired_difference`). The JSON also holds the standard deviation, every policy's
per-episode ``returns`` and the paired differences (``paired``); the numbers go to
``OUT/<env>.json`` (one per env) and ``OUT/benchmark.json`` (all; rescoring some envs with
``--env`` keeps the others' scores of a file written with the same settings), the chart to
``OUT/benchmark.png``. A second table per env shows the tail in physical units: the return's
p10 and the median, p90 and CVaR₅ % of the env's accuracy measures in metres
(:mod:`sensorgym.train.tail`); the per-env JSON holds every policy's per-episode values
(``results[policy]["tails"]``) and those statistics (``tail``). ``--param NAME=VALUE`` scores the env at another size or setting
(every rule; a trained policy only if it was trained with the same params). The best rule a
policy is paired with is the best of the rules scored; the headroom needs the env's passive rule
among them (:data:`sensorgym.train.bounds.PASSIVE_RULES`, in every default set), and a
platform-manoeuvre env's hindsight bound starts from the actions of the policies scored.

The default seed 10000 is held out: no training run draws its scenarios from it or is chosen
on it (``sensorgym train`` trains on its ``--seed`` and evaluates on the tuning seed 500), so a
shipped policy scores here what ``docs/scores/`` records.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from sensorgym.cli import args as types
from sensorgym.cli.console import Steps, make_console, print_written
from sensorgym.cli.params import add_param_argument, params_from

HELP = "Score the rules and trained policies on every env (seeded, same scenarios), with a chart."

#: the help of ``--unsafe-pickle`` (benchmark and render)
UNSAFE_PICKLE_HELP = (
    "also load a run folder that has only SB3's model.zip (no policy.safetensors): this "
    "unpickles the file, which EXECUTES ANY CODE IN IT; use it only on files you trust"
)

#: the held-out evaluation seed (never a training scenario seed)
DEFAULT_SEED = 10_000

#: scenarios stepped at once unless ``--n-envs`` says (fewer when ``--episodes`` is smaller)
DEFAULT_N_ENVS = 16


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--env",
        action="append",
        default=None,
        help="env id; repeatable (default: every registered sensorgym/ env)",
    )
    parser.add_argument(
        "--episodes", type=types.positive_int, default=64, help="episodes per policy"
    )
    parser.add_argument(
        "--n-envs",
        type=types.positive_int,
        default=None,
        help=f"scenarios stepped at once (default {DEFAULT_N_ENVS}, at most --episodes)",
    )
    parser.add_argument(
        "--seed", type=types.seed, default=DEFAULT_SEED, help=f"default {DEFAULT_SEED} (held out)"
    )
    parser.add_argument(
        "--model",
        type=Path,
        action="append",
        default=[],
        help="a `sensorgym train` run folder (policy.safetensors + config.yaml); repeatable",
    )
    parser.add_argument(
        "--no-shipped", action="store_true", help="leave out the policies shipped with sensorgym"
    )
    rules = parser.add_mutually_exclusive_group()
    rules.add_argument(
        "--rule",
        action="append",
        default=None,
        metavar="NAME",
        help="score this registered rule, an ablation too; repeatable; every name must be "
        "registered for every env scored; shipped policies (unless --no-shipped) and --model "
        "runs are scored beside them (default: each env's default set, its fieldable rules to "
        "compare against and the truth-informed ones: sensorgym.agents.registry.default_rules; "
        "a name not registered lists those that are)",
    )
    rules.add_argument(
        "--all-rules",
        action="store_true",
        help="score every registered rule, the ablations included (what docs/scores holds)",
    )
    parser.add_argument("--unsafe-pickle", action="store_true", help=UNSAFE_PICKLE_HELP)
    parser.add_argument("--no-chart", action="store_true", help="write no PNG chart")
    parser.add_argument(
        "--out",
        type=Path,
        default=Path("results/benchmark"),
        help="folder for the per-env score files, benchmark.json and the chart",
    )
    add_param_argument(parser)


def run(args: argparse.Namespace) -> int:
    from sensorgym.train.benchmark import paired_to_best_rule, registered_envs
    from sensorgym.train.bounds import PASSIVE_RULES, headroom
    from sensorgym.train.score_chart import plot_scores

    if args.n_envs is None:  # the default batch, never more scenarios than episodes
        args.n_envs = min(DEFAULT_N_ENVS, args.episodes)
    elif args.episodes < args.n_envs:
        raise SystemExit(
            f"--episodes ({args.episodes}) must be >= --n-envs ({args.n_envs}): every "
            "scenario slot ends an episode"
        )
    known = registered_envs()
    env_ids = args.env or known
    unknown = [e for e in env_ids if e not in known]
    if unknown:
        raise SystemExit(f"--env: not a registered env: {unknown}; known: {known}")
    if args.param and not args.env:
        raise SystemExit("--param: name the env(s) it sets with --env")
    args.rules = {env_id: _rules_of(env_id, args) for env_id in env_ids}
    args.params = {
        env_id: params_from(env_id, args.param, scenarios=args.n_envs) for env_id in env_ids
    }
    for path in args.model:
        _check_model(path, env_ids, args)
    types.output_dir(args.out)  # before any scoring: a bad --out fails now, not in minutes
    console = make_console()
    settings: dict[str, Any] = {"episodes": args.episodes, "n_envs": args.n_envs, "seed": args.seed}
    scores: dict[str, dict[str, dict[str, float]]] = {}
    written: list[Path] = []
    for env_id in env_ids:
        scored = _benchmark(env_id, args, console)
        if scored is None:
            continue
        results, bound_summary = scored
        scores[env_id] = results
        args.out.mkdir(parents=True, exist_ok=True)
        path = args.out / f"{env_id.replace('/', '__')}.json"
        best, paired = paired_to_best_rule(results)
        params = {k: list(v) if isinstance(v, tuple) else v for k, v in args.params[env_id].items()}
        doc = {
            "settings": {"env": env_id, **settings, **({"params": params} if params else {})},
            "results": results,
            "best_rule": best,
            "paired": paired,
        }
        room = headroom(results, PASSIVE_RULES.get(env_id), best)
        if room:
            doc["passive_rule"] = PASSIVE_RULES[env_id]
            doc["headroom"] = room
        if bound_summary is not None:
            doc["bound"] = bound_summary
        tails = tail_summaries(env_id, results)
        if tails:
            doc["tail"] = tails
        path.write_text(json.dumps(doc, indent=2) + "\n")
        written.append(path)
    if scores:
        summary = args.out / "benchmark.json"
        merged = {**_kept_scores(summary, settings, args), **scores}
        scores = {e: merged[e] for e in known if e in merged}  # the registry's order
        summary.write_text(json.dumps({"settings": settings, "scores": scores}, indent=2) + "\n")
        written.append(summary)
        if not args.no_chart:
            written.append(plot_scores(scores, args.out / "benchmark.png"))
    print_written(console, written)
    return 0


def _kept_scores(summary: Path, settings: dict[str, Any], args: argparse.Namespace) -> dict:
    """The other envs' scores of an ``OUT/benchmark.json`` that rescoring some envs (``--env``,
    default params) keeps: those of a file written with the same episodes, batch and seed, so
    that the summary and the chart still show every env; none otherwise."""
    if not args.env or any(args.params[e] for e in args.env) or not summary.is_file():
        return {}
    try:
        old = json.loads(summary.read_text())
    except (OSError, ValueError):
        return {}
    if not isinstance(old, dict) or old.get("settings") != settings:
        return {}
    kept = old.get("scores")
    return {k: v for k, v in kept.items() if k not in args.env} if isinstance(kept, dict) else {}


def _rules_of(env_id: str, args: argparse.Namespace) -> list[str]:
    """The rules scored on ``env_id``: those of ``--rule`` (``SystemExit`` naming the registered
    ones if one is not registered for it), every registered one with ``--all-rules``, else the
    env's default set."""
    from sensorgym.agents.registry import RULES, default_rules

    known = list(RULES.get(env_id, {}))
    if args.all_rules:
        return known
    if args.rule is None:
        return default_rules(env_id)
    unknown = [name for name in args.rule if name not in known]
    if unknown:
        raise SystemExit(
            f"--rule: {', '.join(unknown)} not registered for {env_id}; "
            f"known: {', '.join(known) or 'none'}"
        )
    return list(dict.fromkeys(args.rule))  # each once, in the order given


def _check_model(path: Path, env_ids: list[str], args: argparse.Namespace) -> None:
    """``SystemExit`` with one line unless the run folder ``path`` loads for one of
    ``env_ids`` at the ``--param`` settings: its config, its weights and the model they build
    (:func:`~sensorgym.train.models.load_model`) are checked before any scoring."""
    from sensorgym.train.models import (
        RunFolderError,
        check_model_params,
        check_run_folder,
        load_model,
    )

    try:
        config = check_run_folder(path, args.unsafe_pickle)
    except RunFolderError as exc:
        raise SystemExit(f"--model: {exc}") from None
    trained_on = config["env"]
    if trained_on not in env_ids:
        raise SystemExit(f"--model {path}: trained on {trained_on}, not on {env_ids}")
    try:
        check_model_params(config, args.params[trained_on])
        load_model(path, unsafe_pickle=args.unsafe_pickle)
    except RunFolderError as exc:
        raise SystemExit(f"--model {path}: {exc}") from None


def _benchmark(
    env_id: str, args: argparse.Namespace, console: Any
) -> tuple[dict[str, dict[str, Any]], dict[str, Any] | None] | None:
    """Score the policies of ``env_id`` and print its table: the results and, for an env whose
    bound is computed from what the policies played, its summary; ``None`` when it has no
    policy."""
    from rich.table import Table

    from sensorgym.train.benchmark import NotApplicable, paired_to_best_rule, policies_for, score
    from sensorgym.train.bounds import (
        HINDSIGHT_BOUNDS,
        PASSIVE_RULES,
        add_hindsight_bounds,
        bound_violations,
        headroom,
    )
    from sensorgym.train.env_params import resolve
    from sensorgym.train.models import RunFolderError, check_model_params, read_config, run_dir_of

    params = args.params[env_id]
    specs = policies_for(env_id, args.model, shipped=not args.no_shipped, rules=args.rules[env_id])
    for name, spec in list(specs.items()):
        if spec.kind != "model":
            continue
        try:
            check_model_params(read_config(run_dir_of(Path(spec.name))), params)
        except RunFolderError as exc:
            if not spec.shipped:
                raise SystemExit(f"--model {spec.name}: {exc}") from None
            console.print(f"{env_id}: {name} left out: {exc}")
            del specs[name]
    if not specs:
        console.print(f"{env_id}: no rule registered and no trained policy: skipped")
        return None
    results = {}
    with Steps(console, env_id, len(specs)) as steps:
        for name, spec in specs.items():
            steps.start(name)
            try:
                results[name] = score(
                    env_id,
                    spec,
                    args.episodes,
                    args.n_envs,
                    args.seed,
                    args.unsafe_pickle,
                    params,
                    record_actions=env_id in HINDSIGHT_BOUNDS,
                )
            except RunFolderError as exc:
                raise SystemExit(f"--model: {exc}") from None
            except NotApplicable as exc:  # a rule that does not apply to these params
                console.print(f"{env_id}: rule left out: {exc}")

    bound_summary = None
    if env_id in HINDSIGHT_BOUNDS:
        with console.status(f"{env_id}: the hindsight optimum of every episode"):
            bound_summary = add_hindsight_bounds(
                env_id, resolve(env_id, params), args.seed, results
            )
    best, paired = paired_to_best_rule(results)
    room = headroom(results, PASSIVE_RULES.get(env_id), best)
    for name, r in results.items():
        over = bound_violations(r)
        if over:  # a bound no policy can exceed was exceeded: the bound or the env is wrong
            raise RuntimeError(f"{env_id}: {name} exceeds the episode bound on episodes {over}")
    table = Table(title=f"{env_id}: episode return ({args.episodes} episodes, seed {args.seed})")
    columns = (
        "policy",
        "mean",
        "±95 %",
        "95 % interval",
        "length",
        f"paired − {best}",
        "paired IQM",
        "better/worse",
    )
    for column in columns:
        table.add_column(column, justify="left" if column == "policy" else "right", no_wrap=True)
    for name, r in sorted(results.items(), key=lambda kv: -kv[1]["mean"]):
        d = paired.get(name)
        diff = "best rule" if name == best else "" if d is None else paired_cell(d)
        robust = iqm_cell(d) if d is not None and "iqm" in d else ""
        counts = f"{d['better']}/{d['worse']}" if d is not None and "better" in d else ""
        table.add_row(
            name,
            f"{r['mean']:.3f}",
            f"{r['ci95']:.3f}",
            f"[{r['mean'] - r['ci95']:.2f}, {r['mean'] + r['ci95']:.2f}]",
            f"{r['mean_length']:.1f}",
            diff,
            robust,
            counts,
        )
    console.print(table)
    order = sorted(results, key=lambda name: -results[name]["mean"])
    if room:
        console.print(headroom_table(env_id, room, PASSIVE_RULES[env_id], best, order))
    tails = tail_summaries(env_id, results)
    if tails:
        console.print(tail_table(env_id, tails, args.episodes, order))
    return results, bound_summary


def headroom_table(
    env_id: str, room: dict[str, Any], passive: str, best: str | None, order: list[str]
) -> Any:
    """Per policy, in ``order``: the mean of its episodes' true bounds, the normalised score
    and the share of the headroom above ``best`` it closes (:func:`headroom_cells`)."""
    from rich.table import Table

    table = Table(title=f"{env_id}: headroom against each episode's true upper bound")
    for column in ("policy", "mean bound", "normalised", "closes"):
        table.add_column(column, justify="left" if column == "policy" else "right", no_wrap=True)
    table.caption = (
        f"normalised: per episode (R − R_{passive})/(bound − R_{passive}), mean ± 95 % "
        f"(0: {passive}, 1: the bound); closes: the share of the headroom above {best} that "
        "the policy's mean closes"
    )
    for name in order:
        if name in room:
            table.add_row(name, *headroom_cells(room[name]))
    return table


def tail_summaries(env_id: str, results: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """Per policy of ``results`` with per-episode ``tails``: the return's p10 and each tail
    measure's median, p90 and CVaR₅ % (:func:`~sensorgym.train.tail.tail_summary`); empty for
    an env without tail measures."""
    from sensorgym.train.tail import measures_for, tail_summary

    measures = measures_for(env_id)
    return {name: tail_summary(r, measures) for name, r in results.items() if r.get("tails")}


def tail_table(env_id: str, tails: dict[str, Any], episodes: int, order: list[str]) -> Any:
    """The second table of an env: per policy (in ``order``, the main table's) the return's
    p10 and each tail measure's median, p90 and CVaR₅ % (metres; a share in %)."""
    from rich.table import Table

    from sensorgym.train.tail import measures_for

    measures = measures_for(env_id)
    table = Table(title=f"{env_id}: the tail in physical units ({episodes} episodes)")
    table.add_column("policy", justify="left", no_wrap=True)
    table.add_column("return\np10", justify="right", no_wrap=True)
    for m in measures:
        unit = "%" if m.unit == "share" else m.unit
        for head in (f"{m.name} ({unit})\nmedian", "\np90", "\nCVaR5"):
            table.add_column(head, justify="right", no_wrap=True)
    table.caption = "; ".join(f"{m.name}: {m.description}" for m in measures) + (
        "; p90 and CVaR5 (the mean of the worst 5 % of the episodes) on the bad side"
    )
    for name in order:
        t = tails.get(name)
        if t is None:
            continue
        p10 = t["return_p10"]
        cells = [name, "" if p10 is None else f"{p10:.3f}"]
        for m in measures:
            s = t["measures"].get(m.name, {})
            cells += [_tail_cell(s.get(k), m.unit) for k in ("median", "p90", "cvar5")]
        table.add_row(*cells)
    return table


def _tail_cell(value: float | None, unit: str) -> str:
    """A tail statistic: a share in %, metres with three significant digits."""
    if value is None:
        return "–"
    if unit == "share":
        return f"{100 * value:.1f}"
    return f"{value:.3g}" if abs(value) < 1000 else f"{value:.0f}"


def headroom_cells(h: dict[str, Any] | None) -> list[str]:
    """The bound's mean, the normalised score ``mean ± 95 %`` and the share of the headroom
    above the best rule closed, of one policy's :func:`~sensorgym.train.bounds.headroom`."""
    if h is None:
        return ["", "", ""]
    norm = "" if h["normalised"] is None else f"{h['normalised']:.3f} ± {h['normalised_ci95']:.3f}"
    closes = "" if h["closes"] is None else f"{100 * h['closes']:+.1f} %"
    return [f"{h['bound']:.3f}", norm, closes]


def iqm_cell(d: dict[str, Any]) -> str:
    """``iqm [lo, hi]`` of a paired difference (bootstrap interval), marked like
    :func:`paired_cell`."""
    lo, hi = d["iqm_ci95"]
    mark = " +" if lo > 0 else " −" if hi < 0 else ""
    return f"{d['iqm']:+.3f} [{lo:+.2f}, {hi:+.2f}]{mark}"


def paired_cell(d: dict[str, float]) -> str:
    """``mean [lo, hi]`` of a paired difference, marked ``+``/``−`` when the 95 % interval
    lies above/below zero."""
    lo, hi = d["mean"] - d["ci95"], d["mean"] + d["ci95"]
    mark = " +" if lo > 0 else " −" if hi < 0 else ""
    return f"{d['mean']:+.3f} [{lo:+.2f}, {hi:+.2f}]{mark}"
