"""Sweeps on Ray: multi-seed training, hyperparameter search and benchmark fan-out.

A sweep is a Ray Tune experiment whose every trial is one ordinary ``sensorgym train`` run
(:func:`.trainer.train`, its run folder under ``OUT/trials/<config>/``). The search space is the
training seeds as a grid plus any sampled hyperparameters (:func:`parse_space`); Tune's
``BasicVariantGenerator`` draws ``samples`` configurations at random (seeded) and holds each
constant over the seeds, so every configuration is trained with every seed. With ``asha=True``
the ASHA scheduler stops trials whose training return lags behind at each rung (their run
folders are incomplete and left out of the aggregate).

The sweep then aggregates the trials — per configuration, the mean over seeds of the trained
policy's evaluation return with its 95 % interval across seeds (Student t), and the best
configuration — and, with ``benchmark_episodes > 0``, fans the benchmark out as Ray tasks:
the env's default rules, every shipped policy and every seed's run of the best configuration,
the episodes split into chunks (chunk ``k`` seeded ``eval_seed + k``, the same scenarios for
every policy).
Ray runs on an instance of its own by default (``address=None`` starts one with
``address="local"``, so a stale cluster file another Ray head left in Ray's temp folder or a
``RAY_ADDRESS`` in the environment is never joined by accident) or on an existing cluster
(``address="auto"`` or ``"HOST:6379"``; with Ray's token auth, ``RAY_AUTH_MODE=token`` and the
cluster's token in the environment, see ``docs/sweeps.md``).
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

#: search-space kinds of ``NAME=KIND:ARGS`` (:func:`parse_space`)
SPACE_KINDS = ("uniform", "loguniform", "randint", "choice", "grid")
#: the metric ASHA compares trials on: mean training episode return of the last rollouts
TRAIN_METRIC = "train_return"


@dataclass(frozen=True)
class SweepSettings:
    """What a sweep trains and how it is run."""

    env_id: str
    """The registered env id."""
    algo: str = "ppo"
    """A trainer of :data:`~sensorgym.train.config.ALGORITHMS` (``"ppo"``, ``"sac"``, ``"ars"``)
    with an entry for ``env_id`` in its ``hyperparams/<algo>.yml``."""
    seeds: tuple[int, ...] = (0, 1)
    """Training seeds: every configuration is trained once with each."""
    timesteps: int | None = None
    """Training steps per trial (``None``: the YAML's)."""
    n_envs: int | None = None
    """Scenarios per training step (``None``: the YAML's)."""
    space: dict[str, str] = field(default_factory=dict)
    """Hyperparameter name → ``KIND:ARGS`` (:func:`parse_space`); empty: the YAML's values."""
    fixed: dict[str, Any] = field(default_factory=dict)
    """Hyperparameters set for every trial (``--hyperparam``; dotted keys reach inside a
    mapping, :func:`~sensorgym.train.config.apply_overrides`); the searched ones go on top."""
    samples: int = 1
    """Configurations drawn from ``space`` (each trained with every seed)."""
    search_seed: int = 0
    """Seed of the random search."""
    asha: bool = False
    """Stop lagging trials early with the ASHA scheduler."""
    eval_episodes: int = 64
    """Evaluation episodes of each trial (``sensorgym train --eval-episodes``)."""
    benchmark_episodes: int = 0
    """Episodes per policy of the benchmark fan-out (0: none)."""
    benchmark_chunk: int = 64
    """Episodes per benchmark task."""
    eval_seed: int = 10_000
    """First seed of the benchmark fan-out (held out: never a training seed)."""
    n_envs_eval: int = 16
    """Scenarios stepped at once in the benchmark tasks."""
    cpus_per_trial: float = 1.0
    """Ray CPUs reserved by each trial and benchmark task."""


def parse_space(spec: str) -> tuple[str, Any]:
    """``NAME=KIND:ARGS`` → ``(NAME, Tune search domain)``.

    Kinds: ``uniform:LO:HI``, ``loguniform:LO:HI``, ``randint:LO:HI`` (HI excluded),
    ``choice:A,B,…`` (sampled) and ``grid:A,B,…`` (every value); values are read as YAML
    scalars (``0.99``, ``1e-4``, ``true``). ``ValueError`` names the malformed part.
    """
    from ray import tune

    name, sep, rest = spec.partition("=")
    kind, _, args = rest.partition(":")
    if not sep or not name or not args:
        raise ValueError(f"space {spec!r}: expected NAME=KIND:ARGS, e.g. gamma=choice:0.95,0.99")
    if kind not in SPACE_KINDS:
        raise ValueError(f"space {spec!r}: kind {kind!r} is not one of {SPACE_KINDS}")
    if kind in ("choice", "grid"):
        values = [yaml.safe_load(v) for v in args.split(",")]
        return name, tune.choice(values) if kind == "choice" else tune.grid_search(values)
    parts = args.split(":")
    try:
        lo, hi = (float(p) for p in parts) if len(parts) == 2 else (None, None)
    except ValueError:
        lo = hi = None
    if lo is None or hi is None or not lo < hi:
        raise ValueError(f"space {spec!r}: expected {kind}:LO:HI with LO < HI")
    if kind == "uniform":
        return name, tune.uniform(lo, hi)
    if kind == "loguniform":
        if lo <= 0:
            raise ValueError(f"space {spec!r}: loguniform needs LO > 0")
        return name, tune.loguniform(lo, hi)
    return name, tune.randint(int(lo), int(hi))


def _plain(value: Any) -> Any:
    """numpy scalars (Tune's samples) → Python values, so YAML and JSON write them."""
    return value.item() if isinstance(value, np.generic) else value


def config_tag(overrides: dict[str, Any]) -> str:
    """A short stable name for a hyperparameter configuration: ``yaml`` for none, else
    ``cfg-<8 hex digits>`` of its sorted JSON."""
    if not overrides:
        return "yaml"
    text = json.dumps({k: _plain(v) for k, v in sorted(overrides.items())}, sort_keys=True)
    return "cfg-" + hashlib.sha1(text.encode()).hexdigest()[:8]


def _trial(config: dict[str, Any], settings: SweepSettings, out: str) -> None:
    """One Tune trial: an ordinary ``sensorgym train`` run, reporting its training return after
    every rollout (PPO, SAC) or iteration (ARS: the mean return of its perturbed policies) for
    ASHA, and at the end its evaluation and run folder."""
    from ray import tune
    from stable_baselines3.common.callbacks import BaseCallback

    from sensorgym.train.ars import ARS
    from sensorgym.train.trainer import train

    class ReportRollouts(BaseCallback):
        def _on_step(self) -> bool:
            if isinstance(self.model, ARS) and self.model.history:  # one call per iteration
                tune.report(
                    {
                        TRAIN_METRIC: float(self.model.history[-1]["mean_return"]),
                        "timesteps": self.num_timesteps,
                    }
                )
            return True

        def _on_rollout_end(self) -> None:
            buffer = self.model.ep_info_buffer
            if buffer:
                tune.report(
                    {
                        TRAIN_METRIC: float(np.mean([e["r"] for e in buffer])),
                        "timesteps": self.num_timesteps,
                    }
                )

    seed = int(config["seed"])
    overrides = {k: _plain(v) for k, v in config.items() if k != "seed"}
    tag = config_tag(overrides)
    reporter = ReportRollouts()
    result = train(
        settings.env_id,
        settings.algo,
        seed=seed,
        timesteps=settings.timesteps,
        n_envs=settings.n_envs,
        out=Path(out) / "trials" / tag,
        eval_episodes=settings.eval_episodes,
        progress=False,
        hyperparams={**settings.fixed, **overrides},
        callbacks=[reporter],
    )
    trained = result.evaluation["trained"]
    buffer = result.model.ep_info_buffer if result.model is not None else []
    final_return = float(np.mean([e["r"] for e in buffer])) if buffer else trained["mean"]
    if isinstance(result.model, ARS) and result.model.history:
        final_return = float(result.model.history[-1]["mean_return"])
    tune.report(
        {
            TRAIN_METRIC: final_return,
            "timesteps": int(result.model.num_timesteps) if result.model is not None else 0,
            "eval_return": trained["mean"],
            "eval_ci95": trained["ci95"],
            "run_dir": str(result.run_dir),
            "tag": tag,
        }
    )


def t_half_width(values: list[float]) -> float | None:
    """Half-width of the 95 % Student-t interval of the mean of ``values`` (``None`` for one)."""
    from scipy import stats

    n = len(values)
    if n < 2:
        return None
    sd = float(np.std(values, ddof=1))
    return float(stats.t.ppf(0.975, n - 1) * sd / math.sqrt(n))


def aggregate(trials: list[dict[str, Any]]) -> dict[str, Any]:
    """Group finished trials by configuration: per configuration its hyperparameters, seeds,
    per-seed evaluation returns and run folders, their mean and 95 % interval across seeds;
    ``best`` is the configuration with the highest mean. Trials without an evaluation (failed
    or stopped early) are counted in ``incomplete``."""
    configs: dict[str, dict[str, Any]] = {}
    incomplete = 0
    for t in trials:
        if t.get("eval_return") is None:
            incomplete += 1
            continue
        c = configs.setdefault(
            t["tag"],
            {"hyperparams": t["hyperparams"], "seeds": [], "returns": [], "run_dirs": []},
        )
        c["seeds"].append(t["seed"])
        c["returns"].append(t["eval_return"])
        c["run_dirs"].append(t["run_dir"])
    for c in configs.values():
        order = np.argsort(c["seeds"])
        for key in ("seeds", "returns", "run_dirs"):
            c[key] = [c[key][i] for i in order]
        c["mean"] = float(np.mean(c["returns"]))
        c["ci95"] = t_half_width(c["returns"])
    best = max(configs, key=lambda tag: configs[tag]["mean"]) if configs else None
    return {"configs": configs, "best": best, "incomplete": incomplete}


#: where ``ray start`` (Ray >= 2.59, token auth on by default) writes the token it generates
RAY_TOKEN_FILE = Path("~/.ray/auth_token")


def join_with_token(address: str | None) -> bool:
    """Before joining the cluster at ``address``, turn Ray's token auth on for this process
    when a token is at hand and the environment does not choose: ``RAY_AUTH_MODE`` unset,
    and ``RAY_AUTH_TOKEN``, ``RAY_AUTH_TOKEN_PATH`` or :data:`RAY_TOKEN_FILE` present.

    A head started by ``ray start --head`` on Ray >= 2.59 refuses clients without the token
    (``InvalidAuthToken``), and a client sends it only in token mode; a cluster without auth
    accepts a client in token mode too. Ray reads the mode once per process, when it is first
    imported and used: call this before. Returns whether the mode was set here."""
    if address is None or "RAY_AUTH_MODE" in os.environ:
        return False
    has_token = bool(os.environ.get("RAY_AUTH_TOKEN") or os.environ.get("RAY_AUTH_TOKEN_PATH"))
    if not (has_token or RAY_TOKEN_FILE.expanduser().is_file()):
        return False
    os.environ["RAY_AUTH_MODE"] = "token"
    return True


def run_sweep(
    settings: SweepSettings,
    out: Path,
    *,
    address: str | None = None,
    num_cpus: int | None = None,
    verbose: int = 0,
) -> dict[str, Any]:
    """Run the sweep on Ray (an instance of its own started here with ``num_cpus`` when
    ``address`` is ``None``, or the cluster at ``address``), write ``OUT/sweep.json`` and the charts, and return the document written.

    An instance already initialised in this process is used as it is (and left running);
    one started here is shut down at the end."""
    join_with_token(address)  # before Ray is imported: it reads its auth mode once
    import ray
    from ray import tune
    from ray.tune.schedulers import ASHAScheduler, FIFOScheduler
    from ray.tune.search.basic_variant import BasicVariantGenerator

    from sensorgym.train.config import load_hyperparams

    load_hyperparams(settings.algo, settings.env_id)  # KeyError names a bad env/algo early
    if not settings.seeds:
        raise ValueError("seeds: expected at least one training seed")
    out = Path(out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    space = dict(parse_space(f"{k}={v}") for k, v in settings.space.items())
    started = not ray.is_initialized()
    if started:
        ray.init(
            address="local" if address is None else address,
            num_cpus=num_cpus if address is None else None,
            include_dashboard=False,
            log_to_driver=verbose > 0,
            configure_logging=verbose > 0,
        )
    try:
        param_space = {"seed": tune.grid_search(list(settings.seeds)), **space}
        scheduler: Any = FIFOScheduler()
        if settings.asha:
            scheduler = ASHAScheduler(
                time_attr="training_iteration", grace_period=1, reduction_factor=2
            )
        tuner = tune.Tuner(
            tune.with_resources(
                tune.with_parameters(_trial, settings=settings, out=str(out)),
                {"cpu": settings.cpus_per_trial},
            ),
            param_space=param_space,
            tune_config=tune.TuneConfig(
                metric=TRAIN_METRIC,
                mode="max",
                num_samples=settings.samples,
                search_alg=BasicVariantGenerator(
                    constant_grid_search=True, random_state=settings.search_seed
                ),
                scheduler=scheduler,
            ),
            run_config=tune.RunConfig(name="tune", storage_path=str(out / "ray"), verbose=verbose),
        )
        grid = tuner.fit()
        trials = []
        for result in grid:
            config = dict(result.config or {})
            metrics = result.metrics or {}
            trials.append(
                {
                    "seed": int(config.get("seed", -1)),
                    "hyperparams": {k: _plain(v) for k, v in config.items() if k != "seed"},
                    "tag": metrics.get("tag"),
                    "eval_return": metrics.get("eval_return"),
                    "run_dir": metrics.get("run_dir"),
                    "error": None if result.error is None else str(result.error)[:300],
                }
            )
        summary = aggregate(trials)
        benchmark = None
        if settings.benchmark_episodes > 0 and summary["best"] is not None:
            runs = summary["configs"][summary["best"]]["run_dirs"]
            benchmark = fan_out_benchmark(settings, [Path(r) for r in runs])
    finally:
        if started:
            ray.shutdown()
    doc = {
        "settings": asdict(settings),
        "trials": trials,
        **summary,
        "rules": rule_lines(summary["configs"]),
        "benchmark": benchmark,
    }
    (out / "sweep.json").write_text(json.dumps(doc, indent=2) + "\n")
    plot_sweep(doc, out / "sweep.png")
    if benchmark:
        from sensorgym.train.score_chart import plot_scores

        plot_scores({settings.env_id: benchmark}, out / "benchmark.png")
    return doc


def fan_out_benchmark(settings: SweepSettings, runs: list[Path]) -> dict[str, dict[str, float]]:
    """Score the env's default rules (as ``sensorgym benchmark`` does), every shipped policy and
    every run of ``runs`` on ``benchmark_episodes`` episodes, as Ray tasks of
    ``benchmark_chunk`` episodes each (chunk ``k`` on seed ``eval_seed + k``: the same
    scenarios for every policy), pooled per policy."""
    import ray

    from sensorgym.train.benchmark import policies_for, pool, score

    specs = policies_for(settings.env_id, runs)
    chunk = max(1, settings.benchmark_chunk)
    sizes = [chunk] * (settings.benchmark_episodes // chunk)
    if settings.benchmark_episodes % chunk:
        sizes.append(settings.benchmark_episodes % chunk)
    task = ray.remote(num_cpus=settings.cpus_per_trial)(score)
    futures = {
        name: [
            task.remote(
                settings.env_id, spec, size, min(settings.n_envs_eval, size), settings.eval_seed + k
            )
            for k, size in enumerate(sizes)
        ]
        for name, spec in specs.items()
    }
    return {name: pool(ray.get(refs)) for name, refs in futures.items()}


def rule_lines(configs: dict[str, dict[str, Any]]) -> dict[str, float]:
    """Every rule's mean return on the trials' evaluation episodes (each trial scores the rules
    beside its policy on the same episodes of the tuning seed: read from the first run folder
    that has its ``evaluation.json``)."""
    for config in configs.values():
        for run_dir in config["run_dirs"]:
            path = Path(run_dir) / "evaluation.json"
            if path.is_file():
                results = json.loads(path.read_text())["results"]
                return {k: float(v["mean"]) for k, v in results.items() if k != "trained"}
    return {}


def plot_sweep(doc: dict[str, Any], path: Path) -> Path | None:
    """A PNG at ``path``: per configuration its mean evaluation return over seeds with the 95 %
    interval, and each seed's return as a dot; the best configuration in orange; every rule's
    return on the same episodes (``doc["rules"]``) as a grey vertical line, named at the top."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    configs = doc["configs"]
    if not configs:
        return None
    tags = sorted(configs, key=lambda tag: configs[tag]["mean"])
    fig, ax = plt.subplots(figsize=(7.5, 2.4 + 0.4 * len(tags)))
    for y, tag in enumerate(tags):
        c = configs[tag]
        color = "#e8833a" if tag == doc["best"] else "#4878a8"
        ax.barh(y, c["mean"], xerr=c["ci95"] or 0.0, color=color, height=0.6, capsize=3)
        ax.plot(c["returns"], [y] * len(c["returns"]), "k.", markersize=5)
    ax.set_yticks(range(len(tags)), tags, fontsize=8)
    ax.axvline(0.0, color="black", linewidth=0.6)
    top = len(tags) - 0.4
    for name, mean in sorted(doc.get("rules", {}).items(), key=lambda kv: kv[1]):
        ax.axvline(mean, color="0.45", linewidth=0.9, linestyle="--", zorder=0)
        ax.text(
            mean, top, name, rotation=90, va="bottom", ha="center", fontsize=7,
            bbox={"facecolor": "white", "edgecolor": "none", "pad": 0.5},
        )  # fmt: skip
    if doc.get("rules"):
        ax.set_ylim(-0.6, top + 0.2 + 0.25 * max(len(n) for n in doc["rules"]) / 4)
    ax.set_xlabel(
        "evaluation return per seed (dots), mean ± 95 % across seeds; rules dashed", fontsize=9
    )
    ax.set_title(f"{doc['settings']['env_id']}: {doc['settings']['algo']} sweep", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return Path(path)
