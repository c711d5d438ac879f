"""Scoring every policy of an env on the same seeded scenarios (the chart: :mod:`.score_chart`).

A policy is named by a :class:`PolicySpec`: a rule registered in
:mod:`sensorgym.agents.registry`, or a ``sensorgym train`` run folder (given by the user or
shipped, :mod:`.shipped`). :func:`score` builds the env and the policy from the spec and
evaluates it, so one policy is one independent job — what ``sensorgym benchmark`` runs in turn
and ``sensorgym sweep`` fans out as Ray tasks.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

#: namespace of the registered envs the benchmark covers
NAMESPACE = "sensorgym/"


@dataclass(frozen=True)
class PolicySpec:
    """What to score: a registered rule or a run folder."""

    kind: str
    """``"rule"`` or ``"model"``."""
    name: str
    """The rule's registered name, or the run folder (as a string) for a model."""
    shipped: bool = False
    """A model shipped with sensorgym (:mod:`.shipped`) rather than given by the user."""


class NotApplicable(ValueError):
    """A rule that does not apply to the env's params (e.g. one planning for one platform)."""


def registered_envs() -> list[str]:
    """Every env id registered under ``sensorgym/``, in registration order."""
    import gymnasium as gym

    import sensorgym.envs  # noqa: F401  (registers the ids)

    return [env_id for env_id in gym.registry if env_id.startswith(NAMESPACE)]


def policies_for(
    env_id: str,
    models: list[Path] | tuple[Path, ...] = (),
    shipped: bool = True,
    rules: Iterable[str] | None = None,
) -> dict[str, PolicySpec]:
    """Display name → spec of every policy scored on ``env_id``: the rules ``rules`` (default:
    the env's default set, :func:`~sensorgym.agents.registry.default_rules`; ``KeyError``
    naming the registered ones for a name not registered for it), the shipped policies
    (``shipped:<run>``, unless ``shipped`` is false) and those of ``models`` (run folders)
    trained on it (``model:<run>``)."""
    from sensorgym.agents.registry import RULES, default_rules
    from sensorgym.train.models import read_config, run_dir_of
    from sensorgym.train.shipped import shipped_policies

    names = default_rules(env_id) if rules is None else list(rules)
    unknown = [name for name in names if name not in RULES.get(env_id, {})]
    if unknown:
        raise KeyError(
            f"no rule {', '.join(unknown)} registered for {env_id}; "
            f"known: {', '.join(RULES.get(env_id, {})) or 'none'}"
        )
    specs = {name: PolicySpec("rule", name) for name in names}
    if shipped:
        for run, folder in shipped_policies(env_id).items():
            specs[f"shipped:{run}"] = PolicySpec("model", str(folder), shipped=True)
    for path in models:
        run_dir = run_dir_of(path)
        if read_config(run_dir)["env"] == env_id:
            specs[f"model:{run_dir.name}"] = PolicySpec("model", str(path))
    return specs


def build_policy(
    env_id: str,
    spec: PolicySpec,
    n_envs: int,
    seed: int,
    unsafe_pickle: bool = False,
    params: dict[str, Any] | None = None,
) -> tuple[Any, Any]:
    """``(vector env, policy)`` as :func:`score` plays them: ``n_envs`` scenarios seeded
    ``seed``, one random stream per episode; a rule on the env's joint view
    (:class:`NotApplicable` when it does not apply to ``params``), a run folder through its
    wrappers (per agent for a parameter-sharing run). The caller closes the env."""
    from sensorgym.agents.registry import RULES
    from sensorgym.train.evaluation import env_params, make_sb3_env, simulator_state
    from sensorgym.train.models import (
        CONFIG_FILE,
        RunFolderError,
        check_model_params,
        load_model,
        read_config,
        run_dir_of,
        wrappers_of,
    )

    params = params or {}
    if spec.kind == "rule":
        env = make_sb3_env(env_id, n_envs, seed, episode_streams=True, **params)
        try:
            policy: Any = RULES[env_id][spec.name](env_params(env), simulator_state(env))
        except ValueError as exc:
            env.close()
            raise NotApplicable(f"{spec.name}: {exc}") from None
    elif spec.kind == "model":
        config = read_config(run_dir_of(Path(spec.name)))
        check_model_params(config, params)
        agents = bool(config.get("agents", False))
        wrappers = wrappers_of(config)
        try:
            env = make_sb3_env(
                env_id, n_envs, seed, agents=agents, wrappers=wrappers, episode_streams=True,
                **params,
            )  # fmt: skip
        except ValueError as exc:  # a wrapper's values in the run's config.yaml
            raise RunFolderError(f"{spec.name}: {CONFIG_FILE}, hyperparams: {exc}") from None
        try:
            policy = load_model(Path(spec.name), env, unsafe_pickle=unsafe_pickle)
        except BaseException:
            env.close()
            raise
    else:
        raise ValueError(f"spec.kind: expected 'rule' or 'model', got {spec.kind!r}")
    return env, policy


def score(
    env_id: str,
    spec: PolicySpec,
    episodes: int,
    n_envs: int,
    seed: int,
    unsafe_pickle: bool = False,
    params: dict[str, Any] | None = None,
    record_actions: bool = False,
) -> dict[str, Any]:
    """Episode-return statistics (:class:`~.evaluation.EpisodeStats` as a dict) of one policy
    over ``episodes`` episodes of ``n_envs`` scenarios seeded with ``seed``: every policy scored
    with one seed and batch meets the same scenarios, episode by episode, however it ends them
    (one random stream per episode, :mod:`sensorgym.envs.shells.streams`). Parameter-sharing models act on the per-agent view
    of those scenarios. ``params``: params fields of the env (``--param``); a model trained
    with other ones is refused (:class:`~.models.RunFolderError` saying which differ). For an
    env with a proven bound (:data:`~.bounds.EPISODE_BOUNDS`) each episode's bound comes with
    its return (``bounds``). ``record_actions``: the result also holds every episode's actions
    and key (``actions``, ``keys``: :attr:`~.evaluation.EpisodeStats.actions`), not JSON, for
    a bound computed from what the policies played (:data:`~.bounds.HINDSIGHT_BOUNDS`)."""
    from sensorgym.train.bounds import episode_bound_of
    from sensorgym.train.evaluation import env_params, evaluate

    env, policy = build_policy(env_id, spec, n_envs, seed, unsafe_pickle, params)
    try:
        bound = episode_bound_of(env_id, env_params(env))
        stats = evaluate(policy, env, episodes, seed, bound, record_actions=record_actions)
        out = stats.as_dict()
        if record_actions:
            out["actions"], out["keys"] = list(stats.actions), list(stats.keys)
        return out
    finally:
        env.close()


def pool(parts: list[dict[str, Any]]) -> dict[str, Any]:
    """The statistics of the episodes of several :func:`score` results taken together (exact
    pooled mean and sample standard deviation; normal 95 % half-width of the mean); the
    per-episode ``returns``, and the ``bounds`` and ``tails`` where every part has them,
    concatenated in the parts' order."""
    if not parts:
        raise ValueError("parts: expected at least one result")
    n = np.array([p["episodes"] for p in parts], dtype=np.float64)
    mean = np.array([p["mean"] for p in parts])
    std = np.array([p["std"] for p in parts])
    total = n.sum()
    grand = float((n * mean).sum() / total)
    # Σ (x − x̄)² = Σ_k [(n_k − 1) s_k² + n_k (x̄_k − x̄)²]
    ss = float(((n - 1) * std**2 + n * (mean - grand) ** 2).sum())
    sd = float(np.sqrt(ss / (total - 1))) if total > 1 else 0.0
    length = float((n * np.array([p["mean_length"] for p in parts])).sum() / total)
    pooled: dict[str, Any] = {
        "mean": grand,
        "std": sd,
        "ci95": float(1.96 * sd / np.sqrt(total)),
        "episodes": int(total),
        "mean_length": length,
        "returns": [x for p in parts for x in p.get("returns", [])],
    }
    if all("bounds" in p for p in parts):
        pooled["bounds"] = [x for p in parts for x in p["bounds"]]
    names = set.intersection(*(set(p.get("tails", {})) for p in parts))
    if names:
        pooled["tails"] = {k: [x for p in parts for x in p["tails"][k]] for k in sorted(names)}
    return pooled


#: a rule whose name starts so plans on the simulator's truth (agents.registry): it shows what
#: knowing the truth buys a planner; not fieldable, so never the best rule, and no bound either
TRUTH_PREFIX = "truth-"


def is_rule(name: str) -> bool:
    """Whether a benchmark row is a registered rule (models are ``model:…``/``shipped:…``)."""
    return ":" not in name


def best_rule(results: dict[str, dict[str, Any]]) -> str | None:
    """The rule with the highest mean return among ``results``' rows that are fieldable rules
    (no truth-informed rule, ``truth-…``: those see the simulator's truth); ``None`` when
    there is none."""
    rules = {
        k: r["mean"] for k, r in results.items() if is_rule(k) and not k.startswith(TRUTH_PREFIX)
    }
    return max(rules, key=rules.__getitem__) if rules else None


#: resamples of the paired bootstrap; its generator is seeded, so committed numbers reproduce
BOOTSTRAP_RESAMPLES = 9999
#: a per-episode difference smaller than this counts as a tie (identical play gives exactly 0)
TIE_TOLERANCE = 1e-9


def paired_difference(a: list[float], b: list[float]) -> dict[str, Any]:
    """The per-episode difference ``d = a − b`` of two policies' returns on the same scenarios
    (:func:`score` with one seed and batch gives them in the same episode order): pairing
    removes the scenario-to-scenario spread both share, so its interval is far tighter than the
    two separate ones.

    * ``mean``, ``std``, ``ci95``: the mean of ``d`` and its normal 95 % half-width — the
      issue-13 criterion.
    * ``iqm``, ``iqm_ci95``: the interquartile mean of ``d`` (25 % trimmed each side) and its
      95 % percentile-bootstrap interval ``[lo, hi]`` over episodes (Agarwal et al. 2021, "Deep
      RL at the edge of the statistical precipice"): what a typical episode gains, which a few
      episodes with a drone lost or found (hundreds each) cannot carry.
    * ``better``, ``worse``: how many episodes ``a`` beat ``b``, and lost to it (the rest tie).
    """
    from scipy.stats import bootstrap, trim_mean

    x, y = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    if x.shape != y.shape or x.ndim != 1 or x.size < 2:
        raise ValueError(
            f"paired_difference: need two equally long lists of >= 2 returns, got "
            f"{x.shape} and {y.shape}"
        )
    d = x - y
    if not np.all(np.isfinite(d)):
        raise ValueError("paired_difference: the returns must be finite")
    sd = float(d.std(ddof=1))

    def iqm(sample: np.ndarray, axis: int = -1) -> np.ndarray:
        return trim_mean(sample, 0.25, axis=axis)

    if np.ptp(d) > 0:
        boot = bootstrap(
            (d,),
            iqm,
            n_resamples=BOOTSTRAP_RESAMPLES,
            method="percentile",
            rng=np.random.default_rng(0),
        ).confidence_interval
        iqm_ci = [float(boot.low), float(boot.high)]
    else:  # every episode the same difference: nothing to resample
        iqm_ci = [float(d[0]), float(d[0])]
    return {
        "mean": float(d.mean()),
        "std": sd,
        "ci95": float(1.96 * sd / np.sqrt(d.size)),
        "episodes": int(d.size),
        "iqm": float(iqm(d)),
        "iqm_ci95": iqm_ci,
        "better": int(np.sum(d > TIE_TOLERANCE)),
        "worse": int(np.sum(d < -TIE_TOLERANCE)),
    }


def paired_to_best_rule(results: dict[str, dict[str, Any]]) -> tuple[str | None, dict[str, Any]]:
    """``(best rule, {policy: paired difference to it})`` for every other row of ``results``
    that has per-episode ``returns`` (rows without them are left out)."""
    best = best_rule(results)
    if best is None or not results[best].get("returns"):
        return best, {}
    ref = results[best]["returns"]
    return best, {
        name: paired_difference(r["returns"], ref)
        for name, r in results.items()
        if name != best and len(r.get("returns", ())) == len(ref)
    }
