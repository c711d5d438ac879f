"""The docs' speed tables, generated from the committed benchmark results (so they cannot drift).

``python benchmarks/tables.py`` rewrites every block between ``<!-- table:NAME -->`` and
``<!-- /table:NAME -->`` in README.md, docs/environments.md, docs/results.md and
docs/reproduction/bot-control.md from ``benchmarks/results/*.json``, ``docs/scores/*.json`` and
``docs/reproduction/bot_control.json``; ``--check`` only reports (exit 1) blocks that differ — what
``tests/test_docs_tables.py`` runs.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

from sensorgym.train.tail import ERROR_UNITS, rms, rms_ratio

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"
REPRODUCTION = ROOT / "docs" / "reproduction"
DOCS = (
    ROOT / "README.md",
    ROOT / "docs" / "environments.md",
    ROOT / "docs" / "results.md",
    REPRODUCTION / "bot-control.md",
    REPRODUCTION / "paper004.md",
)
ENVS = (
    "bearings_maneuver",
    "stereo_pointing",
    "stereo_placement",
    "stereo_scanning",
    "gimbal_tracking",
)


def _rows(name: str) -> dict[str, dict]:
    doc = json.loads((RESULTS / f"{name}.json").read_text())
    return {row["case"]: row for row in doc["results"]}, doc["settings"]


def env_speed() -> str:
    """Single env and native vector env beside CartPole-v1, per env."""
    lines = [
        "| env | `gym.make`, steps/s | × CartPole-v1 | vector env, 1024 scenarios, scenario-steps/s | × CartPole-v1 | cold start, s |",
        "| --- | ---: | ---: | ---: | ---: | ---: |",
    ]
    for name in ENVS:
        rows, settings = _rows(name)
        single = rows["gym.make, 1 scenario"]
        vector = rows["native vector env, 1024"]
        cold = settings.get("cold_start_s")
        lines.append(
            f"| `{settings['env']}` | {single['per_s']:,.0f} | {single['vs_cartpole']:.2f} "
            f"| {vector['per_s']:,.0f} | {vector['vs_cartpole']:.2f} "
            f"| {'' if cold is None else f'{cold:.1f}'} |"
        )
    return "\n".join(lines)


def training_speed() -> str:
    """PPO fps through our adapter against SB3's DummyVecEnv, per env."""
    doc = json.loads((RESULTS / "training.json").read_text())
    n = doc["settings"]["n_envs"]
    lines = [
        f"| env | PPO fps, our adapter ({n} scenarios) | PPO fps, SB3 `DummyVecEnv` ({n} envs) | ratio |",
        "| --- | ---: | ---: | ---: |",
    ]
    for r in doc["results"]:
        lines.append(
            f"| `{r['env']}` | {r['adapter_fps']:,.0f} | {r['dummy_fps']:,.0f} | {r['ratio']:.0f}× |"
        )
    return "\n".join(lines)


SCORES = ROOT / "docs" / "scores"

#: what each scored policy is, for the score tables (``model:…`` rows are the PPO runs)
POLICY_LABELS = {
    "truth-lookahead": "`TruthLookahead` (truth-informed, not fieldable: best constant action over 5 steps on the true bound, receding horizon)",
    "book-leg-change": "`book_leg_change` (the book's manoeuvre: 140° → 20° at 30°/min in minutes 13–16, open loop)",
    "book-optimised-plan": "`optimised_open_loop` (a fixed turn sequence optimised on the book's nominal target path, 500 m stand-off margin, by `reproduce bot-control`)",
    "lookahead-estimate": "`EstimateLookahead` (`TruthLookahead`'s 8-step planner on the tracker's estimate instead of the truth)",
    "mpc-estimate": "`RecedingPlan` (every remaining step's command optimised on the tracker's estimate each step, range kept ≥ stand-off + κσ_r)",
    "book-plan-tuned": "`tuned_open_loop` (`optimised_open_loop`'s optimiser with its stand-off margin tuned on tuning seeds: 500 m)",
    "paper002": "`Paper002Maneuver` (theory §10.5 OC-5: run along the bearing, then turn abeam at full speed)",
    "straight-course": "`StraightCourse` (no manoeuvre: range unobservable)",
    "orthogonal-pairs": "`OrthogonalPairs` (theory §10.1 OC-1: pair the receivers whose lines of sight are closest to 90°)",
    "track-nearest": "`TrackNearest` (each receiver on its nearest drone)",
    "hold-still": "`HoldStill` (stay on the cue until the drones leave the field of view)",
    "circle-placement": "`CirclePlacement` (theory §10.3 OC-3: circle of radius √2·ĥ around the estimated ground point)",
    "hold-position": "`HoldPosition` (stay in the 15 m start cluster)",
    "truth-sectors": "`TruthSectors` (truth-informed, not fieldable: the greedy sectors on the true drones)",
    "cue-following": "`CueFollowing` (sectors just covering the predicted tracks; a search of two full sweeps every tenth period)",
    "cue-entry-search": '`CueFollowing(search="entry")` (the same, searching the region where drones enter with 53° sectors)',
    "cue-no-search": "`CueFollowing(sweep_every=NEVER)` (the same sectors, no search after the first two sweeps)",
    "orthogonal-sectors": "`OrthogonalSectors` (theory §10.1 OC-1: narrow sectors on the tracks with the most orthogonal lines of sight)",
    "full-sweep": "`FullSweep` (the papers' fixed sweep of the whole field of regard)",
    "plan-horizon": "`PlanHorizon` (the assignment with the best planned return over 100 steps, 0.3 per receiver kept)",
    "plan-acquire": "`PlanHorizon(acquisition=True)` (`plan-horizon`, each drone's planned return weighted by the chance its receivers find it)",
    "plan-acquire-share": "`PlanHorizon(..., sharing=Sharing())` (`plan-acquire`, a receiver aiming between two drones that fit its field of view)",
    "plan-fix-first": "`PlanHorizon(..., cue_steps=1)` (`plan-acquire-share` holding the cue's pairs for the first step)",
}


GREEDY_LABELS = {
    "BearingsManeuver-v0": "`GreedyManeuver` (one-step D-optimal, from the tracker's estimate)",
    "BearingsManeuverBook-v0": "`GreedyManeuver` (one-step D-optimal, from the tracker's estimate)",
    "StereoPointing-v0": "`GreedyPointing` (assignment maximising Σ ln det of the predicted position information)",
    "StereoPointingCrowded-v0": "`GreedyPointing` (assignment maximising Σ ln det of the predicted position information)",
    "StereoPlacement-v0": "`GreedyPlacement` (one-step move of every receiver maximising the env's reward predicted one period ahead)",
    "StereoScanning-v0": "`GreedyInformation` (the common width and centres maximising the expected covariance reward of the tracks)",
}


#: rules renamed since a record of ``benchmarks/results`` was written (the records are kept as
#: written; the tables show today's names)
RENAMED = {
    "oracle-lookahead": "truth-lookahead",
    "oracle-plan": "truth-plan",
    "oracle-sectors": "truth-sectors",
    "oracle-open-loop": "book-optimised-plan",
}


#: labels of rules whose registered name another env uses for a different rule
ENV_LABELS = {
    (
        "StereoPlacement-v0",
        "truth-lookahead",
    ): "`TruthGreedyPlacement` (truth-informed, not fieldable: `GreedyPlacement`'s search over 3 periods on the true drone)",
    (
        "StereoPlacement-v0",
        "lookahead-information",
    ): "`GreedyPlacement(horizon=3)` (the greedy search summed over 3 periods of straight drives)",
    (
        "GimbalTracking-v0",
        "hold-still",
    ): "`HoldStill` (the drives at rest: the carrier's motion alone moves the axis)",
}


def _label(env: str, name: str) -> str:
    """What the policy ``name`` of ``env``'s score file is, for the score tables."""
    if ":" in name:
        return f"trained (`{name}`; `train/hyperparams/`)"
    label = GREEDY_LABELS[env] if name == "greedy-information" else POLICY_LABELS.get(name, name)
    return ENV_LABELS.get((env, name), label)


def _named(env: str, name: str) -> str:
    """A rule's registered name, and what it is where the tables have a label for it."""
    label = _label(env, name)
    return f"`{name}`" if label == name else f"`{name}`: {label}"


def _ablations(env: str) -> frozenset[str]:
    """The rules of ``env`` left out of the benchmark's default set
    (:data:`sensorgym.agents.registry.ABLATIONS`): shown once, in :func:`ablations`."""
    from sensorgym.agents.registry import ABLATIONS

    return ABLATIONS.get(f"sensorgym/{env}", frozenset())


def _shown(env: str, results: dict) -> list[str]:
    """The rows of ``env``'s score tables, best first: every policy but the ablations."""
    left_out = _ablations(env)
    ranked = sorted(results, key=lambda name: -results[name]["mean"])
    return [name for name in ranked if name not in left_out]


def scores(env: str) -> str:
    """Mean return ± 95 % of every policy of ``docs/scores/<env>.json`` but the ablations, best
    first."""
    doc = json.loads((SCORES / f"sensorgym__{env}.json").read_text())
    settings = doc["settings"]
    lines = [
        f"Seed {settings['seed']}, {settings['episodes']} episodes "
        f"(`docs/scores/sensorgym__{env}.json`):",
        "",
        "| policy | mean return | ± 95 % |",
        "| --- | ---: | ---: |",
    ]
    for name in _shown(env, doc["results"]):
        r = doc["results"][name]
        lines.append(f"| {_label(env, name)} | {r['mean']:.3f} | {r['ci95']:.3f} |")
    return "\n".join(lines)


def ablations(env: str) -> str:
    """The rules of ``env`` outside the benchmark's default set, from ``docs/scores/<env>.json``:
    each one's mean return ± 95 % and its paired difference to the best rule (mean and 95 %
    interval, the episodes better and worse), best first."""
    doc = _score_doc(env)
    settings, best, paired = doc["settings"], doc.get("best_rule"), doc.get("paired", {})
    ranked = sorted(doc["results"], key=lambda name: -doc["results"][name]["mean"])
    names = [name for name in ranked if name in _ablations(env)]
    lines = [
        f"Seed {settings['seed']}, {settings['episodes']} episodes "
        f"(`docs/scores/sensorgym__{env}.json`); `sensorgym benchmark --rule NAME` scores one, "
        f"the paired difference is per episode, on the same scenarios, to the best rule "
        f"`{best}`:",
        "",
        "| rule | mean return | ± 95 % | paired − best rule | paired 95 % interval "
        "| better / worse |",
        "| --- | ---: | ---: | ---: | ---: | ---: |",
    ]
    for name in names:
        r, d = doc["results"][name], paired.get(name)
        cells = (
            ["", "", ""]
            if d is None
            else [
                f"{d['mean']:+.3f}",
                f"[{d['mean'] - d['ci95']:+.3f}, {d['mean'] + d['ci95']:+.3f}]",
                f"{d['better']} / {d['worse']}" if "better" in d else "",
            ]
        )
        lines.append(
            f"| {_named(env, name)} | {r['mean']:.3f} | {r['ci95']:.3f} | "
            + " | ".join(cells)
            + " |"
        )
    if not names:
        lines.append("| (none in the committed scores) | | | | | |")
    return "\n".join(lines)


#: Student's t quantiles, two-sided 95 %, by degrees of freedom (across training seeds)
T95 = {1: 12.706, 2: 4.303, 3: 3.182, 4: 2.776, 5: 2.571, 6: 2.447, 7: 2.365, 8: 2.306, 9: 2.262}


def _score_doc(env: str) -> dict:
    """A committed benchmark file; ``best_rule`` filled in for files written before it was."""
    from sensorgym.train.benchmark import best_rule

    doc = json.loads((SCORES / f"sensorgym__{env}.json").read_text())
    doc.setdefault("best_rule", best_rule(doc["results"]))
    return doc


def _trained(results: dict) -> list[str]:
    return sorted(name for name in results if ":" in name)


def results_summary() -> str:
    """Per env: the best fieldable rule, the trained policies' paired difference to it (mean
    over training seeds with a t interval across seeds), the best truth-informed rule's mean
    where there is one (what knowing the truth buys a planner; not a bound)."""
    lines = [
        "| env | episodes, seed | best rule | its mean | trained policies | their mean | "
        "paired − best rule, mean over runs (95 % t interval across runs) | runs above the rule "
        "(paired 95 % interval > 0) | runs above by the paired IQM (bootstrap 95 % > 0) | "
        "best truth-informed rule |",
        "| --- | --- | --- | ---: | --- | ---: | ---: | ---: | ---: | ---: |",
    ]
    from sensorgym.train.benchmark import TRUTH_PREFIX

    for env in SCORE_ENVS:
        doc = _score_doc(env)
        res, best, paired = doc["results"], doc.get("best_rule"), doc.get("paired", {})
        settings = doc["settings"]
        runs = [name for name in _trained(res) if name in paired]
        truth = [r["mean"] for k, r in res.items() if k.startswith(TRUTH_PREFIX)]
        truth_best = f"{max(truth):.3f}" if truth else "—"
        if not runs or best is None:
            lines.append(
                f"| `{env}` | {settings['episodes']}, {settings['seed']} | `{best}` | "
                f"{res[best]['mean']:.3f} | none | | | | | {truth_best} |"
                if best
                else f"| `{env}` | | | | none | | | | | {truth_best} |"
            )
            continue
        diffs = [paired[name]["mean"] for name in runs]
        mean = sum(diffs) / len(diffs)
        if len(diffs) > 1:
            sd = (sum((d - mean) ** 2 for d in diffs) / (len(diffs) - 1)) ** 0.5
            half = T95[len(diffs) - 1] * sd / len(diffs) ** 0.5
            across = f"{mean:+.3f} ({mean - half:+.3f}, {mean + half:+.3f})"
        else:
            across = f"{mean:+.3f} (one run)"
        above = sum(paired[n]["mean"] - paired[n]["ci95"] > 0 for n in runs)
        robust = sum(paired[n]["iqm_ci95"][0] > 0 for n in runs)
        trained_mean = sum(res[n]["mean"] for n in runs) / len(runs)
        names = ", ".join(f"`{n.split(':', 1)[1]}`" for n in runs)
        lines.append(
            f"| `{env}` | {settings['episodes']}, {settings['seed']} | `{best}` | "
            f"{res[best]['mean']:.3f} | {names} | {trained_mean:.3f} | {across} | "
            f"{above} of {len(runs)} | {robust} of {len(runs)} | {truth_best} |"
        )
    return "\n".join(lines)


def results_env(env: str) -> str:
    """Every policy of ``docs/scores/<env>.json`` but the ablations (:func:`ablations`) with its
    paired difference to the best rule, its headroom and its tail."""
    doc = _score_doc(env)
    settings, best, paired = doc["settings"], doc.get("best_rule"), doc.get("paired", {})
    lines = [
        f"Seed {settings['seed']}, {settings['episodes']} episodes, {settings['n_envs']} "
        f"scenarios at a time (`docs/scores/sensorgym__{env}.json`); the paired difference is "
        f"per episode, on the same scenarios, to the best rule `{best}`; its interquartile mean "
        f"(IQM) has a bootstrap interval, and better / worse count the episodes:",
        "",
        "| policy | mean return | ± 95 % | paired − best rule | paired 95 % interval | "
        "paired IQM | IQM 95 % interval | better / worse |",
        "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    order = _shown(env, doc["results"])
    for name in order:
        r, d = doc["results"][name], paired.get(name)
        if name == best:
            cells = ["(best rule)", "", "", "", ""]
        elif d is None:
            cells = [""] * 5
        else:
            lo, hi = d["iqm_ci95"]
            cells = [
                f"{d['mean']:+.3f}",
                f"[{d['mean'] - d['ci95']:+.3f}, {d['mean'] + d['ci95']:+.3f}]",
                f"{d['iqm']:+.3f}",
                f"[{lo:+.3f}, {hi:+.3f}]",
                f"{d['better']} / {d['worse']}",
            ]
        lines.append(
            f"| `{name}` | {r['mean']:.3f} | {r['ci95']:.3f} | " + " | ".join(cells) + " |"
        )
    return "\n".join(lines + _headroom_lines(doc, order) + _tail_lines(doc, order))


def _headroom_lines(doc: dict, order: list[str]) -> list[str]:
    """The headroom table of a score file that has one (:mod:`sensorgym.train.bounds`)."""
    room = doc.get("headroom")
    if not room:
        return []
    passive, best = doc["passive_rule"], doc.get("best_rule")
    lines = [
        "",
        f"Headroom: each episode's true upper bound on the return (a number of the scenario no "
        f"policy can exceed); normalised is, per episode, (R − R₀)/(bound − R₀) averaged, R₀ "
        f"the return of `{passive}` (0) on the same episode, the bound 1; closes is the share "
        f"of the headroom above `{best}` that a policy's mean closes:",
        "",
        "| policy | mean bound | normalised | ± 95 % | closes |",
        "| --- | ---: | ---: | ---: | ---: |",
    ]
    for name in order:
        h = room.get(name)
        if h is None:
            continue
        norm = "" if h["normalised"] is None else f"{h['normalised']:.3f}"
        ci = "" if h["normalised_ci95"] is None else f"{h['normalised_ci95']:.3f}"
        closes = "" if h["closes"] is None else f"{100 * h['closes']:+.1f} %"
        lines.append(f"| `{name}` | {h['bound']:.3f} | {norm} | {ci} | {closes} |")
    bound = doc.get("bound")
    if bound:  # a bound computed from what the policies played (theory §11.2.1)
        lines += [
            "",
            f"The bound is each episode's {bound['method']}, started from every policy's own "
            f"actions on it (so at least each one's return) and from random sequences; the "
            f"optimiser added {bound['gain_mean']:.3f} on average to the best start "
            f"({bound['gain_max']:.3f} at most).",
        ]
    return lines


def _tail_lines(doc: dict, order: list[str]) -> list[str]:
    """The tail table of a score file that has one (:mod:`sensorgym.train.tail`): the return's
    10th percentile and each measure's median, 90th percentile (the bad side), worst-5 % mean
    and, for an error in metres, its RMS over the episodes (from the per-episode values when
    the summary predates it)."""
    tail = doc.get("tail")
    if not tail:
        return []
    first = next(iter(tail.values()))["measures"]
    measures = list(first)
    label = {
        m: f"{m} ({first[m]['unit']})" if first[m]["unit"] in ERROR_UNITS else m for m in measures
    }
    metres = [
        m for m in measures if first[m]["unit"] in ERROR_UNITS and first[m]["lower_is_better"]
    ]
    best = doc.get("best_rule")
    reference = doc["results"].get(best, {}).get("tails", {}) if best else {}
    main = metres[0] if metres and metres[0] in reference else None
    header = "| policy | return p10 | " + " | ".join(
        f"{label[m]} median | {label[m]} p90 | {label[m]} worst 5 %"
        + (f" | {label[m]} RMS" if m in metres else "")
        + (f" | {m} RMS ÷ `{best}`'s [95 %]" if m == main else "")
        for m in measures
    )
    ratio_text = (
        f"; {main}'s RMS divided by the best rule's, with a 95 % interval that resamples the "
        "episodes in pairs (`train.tail.rms_ratio`): above 1 means a larger RMS than the rule, "
        "an interval across 1 a difference within what the draw of episodes moves"
        if main
        else ""
    )
    lines = [
        "",
        "The tail, in the units a user of the sensor quotes (theory §11.7): the return's 10th "
        "percentile and, per accuracy measure, its median, 90th percentile and the mean of "
        f"the worst 5 % of episodes (and an error's RMS over the episodes{ratio_text}):",
        "",
        header + " |",
        "| --- |" + " ---: |" * (1 + 3 * len(measures) + len(metres) + (main is not None)),
    ]

    def cell(x: float | None) -> str:
        return "" if x is None else f"{x:.3g}"

    for name in order:
        t = tail.get(name)
        if t is None:
            continue
        cells = [cell(t["return_p10"])]
        for m in measures:
            q = t["measures"].get(m, {})
            cells += [cell(q.get("median")), cell(q.get("p90")), cell(q.get("cvar5"))]
            if m in metres:
                per_episode = doc["results"].get(name, {}).get("tails", {}).get(m)
                value = q.get("rms")
                if value is None and per_episode is not None:
                    value = rms(per_episode)
                cells.append(cell(value))
            if m == main:
                per_episode = doc["results"].get(name, {}).get("tails", {}).get(m)
                if name == best or per_episode is None:
                    cells.append("")
                else:
                    r, lo, hi = rms_ratio(per_episode, reference[m])
                    cells.append(f"{r:.2f} [{lo:.2f}, {hi:.2f}]")
        lines.append(f"| `{name}` | " + " | ".join(cells) + " |")
    return lines


SCORE_ENVS = (
    "BearingsManeuver-v0",
    "BearingsManeuverBook-v0",
    "StereoPointing-v0",
    "StereoPointingCrowded-v0",
    "StereoPlacement-v0",
    "StereoScanning-v0",
    "GimbalTracking-v0",
)


def results_curves() -> str:
    """Every shipped run's learning curve (``curve.png`` in its run folder), per env."""
    policies = ROOT / "train" / "policies"
    lines = []
    for env in SCORE_ENVS:
        runs = sorted((policies / f"sensorgym__{env}").glob("*/curve.png"))
        if not runs:
            continue
        lines.append(f"**{env}**: " + ", ".join(f"`{p.parent.name}`" for p in runs))
        lines.append("")
        lines += [f"![{env} {p.parent.name}](../{p.relative_to(ROOT).as_posix()})" for p in runs]
        lines.append("")
    return "\n".join(lines).rstrip()


NOT_RECORDED = "not recorded"


def _thousands(n: int) -> str:
    return f"{n:,}".replace(",", " ")


def _seconds(s: float) -> str:
    return f"{s:.0f} s" if s < 600 else f"{s / 60:.1f} min"


def training_cost(policies: Path | None = None) -> str:
    """Per env and shipped run: the samples it trained on, the wall-clock and CPUs it took
    (its ``cost.json``, :mod:`sensorgym.train.cost`; "not recorded" for runs trained before
    it, "not reproducible" where ``benchmarks/training_cost.py`` found that retraining gives
    other weights), and when its learning curve first beat the env's best rule (``best_rule`` of
    ``docs/scores/<env>.json``) on the curve's own evaluation scenarios: the first
    ``curve.json`` point whose mean exceeds that rule's mean in the curve's ``rules``, its
    samples and its wall-clock."""
    import yaml

    from sensorgym.train.cost import first_beat, pretrain_samples

    policies = ROOT / "train" / "policies" if policies is None else Path(policies)
    unreproducible_path = RESULTS / "training_cost_unreproducible.json"
    unreproducible = (
        json.loads(unreproducible_path.read_text()) if unreproducible_path.is_file() else {}
    )
    lines = [
        "| env | run | algorithm | samples: RL + imitation | wall-clock, training (whole run) "
        "| CPUs usable of machine, torch threads | load, 1 min, start → end "
        "| curve seed | best rule, its mean there | first beats it at: samples | wall-clock |",
        "| --- | --- | --- | ---: | ---: | ---: | ---: | ---: | --- | ---: | ---: |",
    ]
    for env in SCORE_ENVS:
        runs = sorted(p.parent for p in (policies / f"sensorgym__{env}").glob("*/config.yaml"))
        best = _score_doc(env).get("best_rule")
        if not runs:
            lines.append(f"| `{env}` | none shipped | | | | | | | `{best}` | | |")
            continue
        for run in runs:
            config = yaml.safe_load((run / "config.yaml").read_text())
            hp = config["hyperparams"]
            cost_path = run / "cost.json"
            cost = json.loads(cost_path.read_text()) if cost_path.is_file() else None
            curve_path = run / "curve.json"
            curve = json.loads(curve_path.read_text()) if curve_path.is_file() else None
            if cost is not None:
                steps, imitated = cost["samples"]["timesteps"], cost["samples"]["pretrain"]
                wall = cost["wall_s"]
                m = cost["machine"]
                load = cost["load_average_1min"]
                clock = f"{_seconds(wall['training'])} ({_seconds(wall['total'])})"
                cpus = f"{m['usable_cpus']} of {m['cpu_count']}, {m['torch_threads']}"
                loads = f"{load['start']:.1f} → {load['end']:.1f}"
            else:  # the samples are on record in curve.json and config.yaml; the time is not
                pre = hp.get("pretrain")
                imitated = (
                    pretrain_samples(pre["steps"], pre.get("rounds", 1), hp["n_envs"]) if pre else 0
                )
                steps = curve["points"][-1]["timesteps"] if curve else hp["n_timesteps"]
                clock = cpus = loads = NOT_RECORDED
                if str(run.relative_to(policies.parent.parent)) in unreproducible:
                    clock = "not reproducible: retrained weights differ"
            samples = f"{_thousands(steps)} + {_thousands(imitated)}"
            seed = json.loads((run / "evaluation.json").read_text())["seed"]
            head = f"| `{env}` | `{run.name}` | {config['algo'].upper()} | {samples} | {clock} "
            head += f"| {cpus} | {loads} | {seed} "
            if curve is None:
                lines.append(head + f"| `{best}` | no curve | |")
                continue
            if best not in curve["rules"]:
                lines.append(head + f"| `{best}`: not in curve.json | | |")
                continue
            rule = curve["rules"][best]
            point = first_beat(curve["points"], rule)
            if point is None:
                top = max(p["mean"] for p in curve["points"])
                lines.append(head + f"| `{best}`, {rule:.3f} | never (best point {top:.3f}) | |")
                continue
            when = _seconds(point["wall_s"]) if "wall_s" in point else NOT_RECORDED
            lines.append(
                head + f"| `{best}`, {rule:.3f} | {_thousands(point['timesteps'])} "
                f"+ {_thousands(imitated)} ({point['mean']:.3f}) | {when} |"
            )
    return "\n".join(lines)


def cold_start() -> str:
    """Seconds from a fresh interpreter to every env's first steps, with an empty and a warm
    numba cache (``benchmarks/cold_start.py``)."""
    doc = json.loads((RESULTS / "cold_start.json").read_text())
    lines = [
        "| | cold (empty cache), s | warm (cached kernels), s | functions compiled (cold)"
        " | compiles beyond one per function |",
        "| --- | ---: | ---: | ---: | ---: |",
    ]
    for r in doc["results"]:
        plain = r["case"] in ("import", "total") or "`" in r["case"]
        case = r["case"] if plain else f"`{r['case']}`"
        counts = [r.get("functions_compiled"), r.get("second_specialisations")]
        cells = " | ".join("" if c is None else str(c) for c in counts)
        lines.append(f"| {case} | {r['cold_s']:.1f} | {r['warm_s']:.2f} | {cells} |")
    return "\n".join(lines)


def scaling() -> str:
    """At each env's largest size of ``benchmarks/scaling.py``: µs per scenario of the env step
    (its mean over one episode) and of every rule's decision (batch of 256, states holding
    tracks), against the issue-15 targets,
    with the growth exponent over the three largest sizes."""
    doc = json.loads((RESULTS / "scaling.json").read_text())["results"]
    rows, slopes = doc["rows"], doc["exponents_largest"]
    lines = [
        "| env, largest size | what | µs per scenario (wall) | CPU µs | target µs | growth exponent |",
        "| --- | --- | ---: | ---: | ---: | ---: |",
    ]
    for env in dict.fromkeys(r["env"] for r in rows):
        row = max((r for r in rows if r["env"] == env), key=lambda r: r["size"])
        head = f"`{env.split('/')[1]}`, {row['case']}"
        k = slopes.get(env, {})

        def fmt(x: float | None) -> str:
            return "—" if x is None else f"{x:.2f}"

        if row.get("step_us") is None:
            lines.append(f"| {head} | env step | {row.get('error', '—')} | | 50 | |")
            continue
        lines.append(
            f"| {head} | env step | {row['step_us']:.1f} | {row['step_cpu_us']:.1f} | 50 "
            f"| {fmt(k.get('env step'))} |"
        )
        for recorded, t in row["rules"].items():
            name = RENAMED.get(recorded, recorded)
            if "decision_us" not in t:
                lines.append(f"| | `{name}` | {t['error']} | | 1000 | |")
                continue
            lines.append(
                f"| | `{name}` | {t['decision_us']:.1f} | {t['decision_cpu_us']:.1f} | 1000 "
                f"| {fmt(k.get(recorded))} |"
            )
    return "\n".join(lines)


def bot_control() -> str:
    """PCRLB at 16 and 32 min of every policy of ``sensorgym reproduce bot-control``, its gap
    to the ceiling (each run's hindsight optimum) in metres and as a ratio
    (``docs/reproduction/bot_control.json``)."""
    doc = json.loads((REPRODUCTION / "bot_control.json").read_text())
    lines = [
        f"`{doc['env_id']}`, {doc['runs']} runs, seed {doc['seed']} "
        "(`docs/reproduction/bot_control.json`):",
        "",
        "| policy | PCRLB at 16 min (m) | PCRLB at 32 min (m) | gap to the ceiling (m) "
        "| ratio to the ceiling | per-run PCRLB at 32 min, RMS (m) | env return | ± 95 % "
        "| broke the 1 km stand-off | closest (m) |",
        "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    for p in doc["policies"]:
        lines.append(
            f"| {p['name']} ({p['kind']}) | {p['pcrlb'][16]:.0f} | {p['pcrlb_32min']:.1f} "
            f"| {p['gap_m']:.1f} | {p['ratio']:.2f} | {p['per_run_32min']:.1f} "
            f"| {p['env_return']:.3f} | {p['env_return_ci95']:.3f} | {p['standoff_broken']} "
            f"| {p['min_range']:.0f} |"
        )
    if doc["missing_trained"]:
        lines.append("| trained policy: missing (none shipped) | | | | | | | | | |")
    opt = doc["optimised"]
    finals = ", ".join("infeasible" if v != v else f"{v:.0f}" for v in opt["restarts"])
    lines += [
        "",
        f"Fixed plan on the nominal (noise-free) target path, 500 m margin: PCRLB at 32 min "
        f"{opt['pcrlb_noise_free']:.0f} m there, closest approach {opt['min_range']:.0f} m; "
        f"the {len(opt['restarts'])} starts (the leg change first) ended at {finals} m. "
        "Turn rate per minute (°/min, + = to starboard): "
        + " ".join(f"{30.0 * u:+.0f}" for u in opt["turns"])
        + ".",
    ]
    c = doc.get("ceiling")
    if c:
        per_run = sorted(c["pcrlb_32min_per_run"])
        best = ", ".join(f"{n} {k}" for n, k in c["best_start_counts"].items() if k)
        lines += [
            "",
            f"Ceiling: each run's hindsight optimum of its book PCRLB at 32 min, 1 km stand-off "
            f"exactly; per run {per_run[len(per_run) // 2]:.1f} m median "
            f"({per_run[0]:.1f}–{per_run[-1]:.1f} m); the nominal optimum on the noise-free path "
            f"{c['nominal_pcrlb']:.1f} m. Gain over each run's best start: ln ratio "
            f"{c['gain_mean']:.3f} mean, {c['gain_max']:.3f} max. Best start per run: {best}.",
        ]
    return "\n".join(lines)


HELD_OUT = ROOT / "docs" / "scores" / "seed31337"


GAP = RESULTS / "headroom_gap.json"


def gimbal_channels() -> str:
    """Paper 004's claim 4 through GimbalTracking-v0: the tracker's accuracy and lock against
    the number of channels and each one's detection probability
    (``benchmarks/results/gimbal_channels.json``)."""
    doc = json.loads((RESULTS / "gimbal_channels.json").read_text())
    st = doc["settings"]
    lines = [
        f"`{st['env']}` at its defaults, `{st['rule']}`, {st['scenarios']} episodes a cell, "
        f"seed {st['seed']}; `P` at F = {st['false_alarm']} (`benchmarks/results/"
        "gimbal_channels.json`):",
        "",
        "| channels | contrast | q | P | frames detected | median error, mrad "
        "| p90 error, mrad | median σ_LOS, mrad | target lost | mean return |",
        "| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    for r in doc["results"]:
        lines.append(
            f"| {r['channels']} | {r['contrast']:.1f} | {r['q']:.2f} "
            f"| {r['detection_probability']:.2f} | {r['detected_share']:.2f} "
            f"| {r['median_error_mrad']:.2f} | {r['p90_error_mrad']:.1f} "
            f"| {r['median_sigma_los_mrad']:.2f} | {r['lost_share']:.2f} "
            f"| {r['mean_return']:.0f} |"
        )
    return "\n".join(lines)


def _pct(x: float | None) -> str:
    return "" if x is None else f"{100 * x:+.1f} %"


def headroom_share() -> str:
    """Per env of ``docs/scores/``: the best rule's share of the headroom above the passive
    rule, ``(R̄_best − R̄₀)/(B̄ − R̄₀)``, and each shipped run's ``closes``, the share of the
    headroom above the best rule its mean closes (:func:`sensorgym.train.bounds.headroom`)."""
    lines = [
        "| env | mean bound | passive rule, its mean | best rule, its mean | best rule closes "
        "of the headroom above the passive rule | shipped runs: closes of the headroom above "
        "the best rule |",
        "| --- | ---: | --- | --- | ---: | --- |",
    ]
    for env in SCORE_ENVS:
        doc = _score_doc(env)
        res, best, passive = doc["results"], doc.get("best_rule"), doc.get("passive_rule")
        room = doc.get("headroom") or {}
        if best not in room or passive not in res:
            lines.append(f"| `{env}` | no bound | | | | |")
            continue
        bound = room[best]["bound"]
        r0, rb = res[passive]["mean"], res[best]["mean"]
        runs = ", ".join(
            f"`{name.split(':', 1)[1]}` {_pct(room[name]['closes'])}"
            for name in _trained(res)
            if name in room
        )
        lines.append(
            f"| `{env}` | {bound:.3f} | `{passive}`, {r0:.3f} | `{best}`, {rb:.3f} | "
            f"{_pct((rb - r0) / (bound - r0))} | {runs or 'none shipped'} |"
        )
    return "\n".join(lines)


def headroom_gap(env: str) -> str:
    """Where the gap ``bound − return`` of the best shipped run and the best rule goes on
    ``env``, by phase and by episode (``benchmarks/headroom_gap.py``,
    ``benchmarks/results/headroom_gap.json``)."""
    r = json.loads(GAP.read_text())["results"][f"sensorgym/{env}"]
    pol, rule, b = r["policy"], r["best_rule"], r["bound"]
    P = r["players"]
    names = [rule] + ([pol] if pol else [])
    hindsight = "hindsight" in b["method"]
    what = (
        "the hindsight optimum of each episode started from both players' actions, its "
        "reward per step replayed in the env"
        if hindsight
        else "the per-step bound B_t of the episode, whose sum is the benchmark's bound"
    )
    head = (
        f"`benchmarks/headroom_gap.py` (`benchmarks/results/headroom_gap.json`): seed "
        f"{r['seed']}, the benchmark's episodes ({r['episodes']}"
        + (f" of {_score_doc(env)['settings']['episodes']}" if hindsight else "")
        + f"), the best rule `{rule}`"
        + (f" and the best shipped run `{pol.split(':', 1)[1]}`" if pol else "")
        + f"; the bound per step is {what} (mean {b['mean']:.3f}; the benchmark's on the same "
        f"episodes {b['benchmark_mean']:.3f}). Gap = bound − return per episode, by phase of "
        f"the episode"
    )
    if pol:
        head += (
            "; the run's gain over the rule in each phase, and the share of the rule's gap it "
            "closes there (the shares sum to the run's closes on these episodes)"
        )
    cols = [f"`{n.split(':', 1)[-1]}` gap" for n in names]
    lines = [head + ":", "", "| phase | " + " | ".join(cols)]
    lines[-1] += " | gain | closes |" if pol else " |"
    lines.append("| --- |" + " ---: |" * (len(cols) + (2 if pol else 0)))
    for i, ph in enumerate(P[rule]["phases"]):
        cells = [f"{P[n]['phases'][i]['gap']:.3f}" for n in names]
        if pol:
            g = r["gain"]["phases"][i]
            cells += [f"{g['gain']:+.3f}", _pct(g["closes"])]
        lines.append(f"| {ph['phase']} | " + " | ".join(cells) + " |")
    cells = [f"**{P[n]['mean_gap']:.3f}**" for n in names]
    if pol:
        cells += [f"**{r['gain']['gain']:+.3f}**", f"**{_pct(r['gain']['closes'])}**"]
    lines.append("| all steps | " + " | ".join(cells) + " |")
    lines.append("")
    notes = []
    for n in names:
        d = P[n]
        notes.append(
            f"`{n.split(':', 1)[-1]}`: the worst 10 % of the episodes carry "
            f"{100 * d['worst']['10 %']:.1f} % of its summed gap, the worst 25 % "
            f"{100 * d['worst']['25 %']:.1f} %"
            + (
                f"; the steps after its episode ended (the bound goes on) "
                f"{100 * d['after_end']['share']:.1f} %."
                if d["after_end"]["gap"]
                else "."
            )
        )
    if pol:
        g = r["gain"]
        top = (
            ""
            if g["gain_worst_10_share"] is None
            else (
                f"; the 10 % of the episodes where it gains most carry "
                f"{100 * g['gain_worst_10_share']:.1f} % of its summed gain"
            )
        )
        notes.append(
            f"The run beats the rule on {g['episodes_better']} of the {r['episodes']} episodes "
            f"and trails it on {g['episodes_worse']}{top}."
        )
    lines.append(" ".join(notes))
    for name in P[rule].get("splits", {}):
        labels = sorted({k for n in names for k in P[n]["splits"][name]})
        if len([k for k in labels if k != "after the end"]) < 2:
            continue  # one state throughout: nothing to split
        cols = [f"`{n.split(':', 1)[-1]}` {c}" for n in names for c in ("gap", "share", "steps")]
        lines += [
            "",
            f"By the state of the step ({name}; steps per episode of {r['steps']}):",
            "",
            f"| {name} | " + " | ".join(cols) + " |",
            "| --- |" + " ---: |" * len(cols),
        ]
        for k in labels:
            cells = []
            for n in names:
                v = P[n]["splits"][name].get(k, {"gap": 0.0, "share": 0.0, "steps": 0.0})
                cells += [f"{v['gap']:.3f}", f"{100 * v['share']:.1f} %", f"{v['steps']:.1f}"]
            lines.append(f"| {k} | " + " | ".join(cells) + " |")
    lines += [
        "",
        "Scenario features at the reset (truth, evaluation only) against the episode's gap: "
        "Spearman's rank correlation, and the feature's mean over the 10 % of the episodes with "
        "the largest gap against the rest (features the same in every episode left out)"
        + (", for the run; and the correlation with the run's gain over the rule:" if pol else ":"),
        "",
    ]
    d = P[pol or rule]
    cols = ["feature", "ρ with the gap", "worst 10 % mean", "rest mean"]
    if pol:
        cols += [f"ρ with `{rule}`'s gap", "ρ with the gain"]
    lines.append("| " + " | ".join(cols) + " |")
    lines.append("| --- |" + " ---: |" * (len(cols) - 1))

    def rho(x: float | None) -> str:
        return "—" if x is None else f"{x:+.2f}"

    for k, v in d["features"].items():
        if v["spearman"] is None and v["worst_10_mean"] == v["rest_mean"]:
            continue  # the same in every episode
        cells = [rho(v["spearman"]), f"{v['worst_10_mean']:.4g}", f"{v['rest_mean']:.4g}"]
        if pol:
            cells += [rho(P[rule]["features"][k]["spearman"]), rho(r["gain"]["features"][k])]
        lines.append(f"| {k} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def held_out(env: str) -> str:
    """Every shipped policy of ``env`` on both held-out seeds (``docs/scores/``: 10000,
    ``docs/scores/seed31337/``): its mean, the best fieldable rule's, and the paired difference
    with its 95 % interval; for an env without one, the best fieldable rule on each seed."""
    docs = [_score_doc(env), json.loads((HELD_OUT / f"sensorgym__{env}.json").read_text())]
    seeds = [d["settings"]["seed"] for d in docs]
    head = " | ".join(f"seed {s}: trained | best rule | paired difference [95 %]" for s in seeds)
    lines = [
        "Source: `docs/scores/` (seed 10000) and `docs/scores/seed31337/` (`sensorgym benchmark "
        f"--env sensorgym/{env} --episodes {docs[1]['settings']['episodes']} "
        + (
            ""
            if docs[1]["settings"]["n_envs"] == 16
            else f"--n-envs {docs[1]['settings']['n_envs']} "
        )
        + "--all-rules "
        "--seed 31337 --out docs/scores/seed31337`).",
        "",
        f"| run | {head} |",
        "| --- |" + " ---: |" * (3 * len(docs)),
    ]
    for run in _trained(docs[0]["results"]):
        cells = []
        for d in docs:
            best, p = d["best_rule"], d["paired"][run]
            cells += [
                f"{d['results'][run]['mean']:.3f}",
                f"{d['results'][best]['mean']:.3f} (`{best}`)",
                f"{p['mean']:+.3f} [{p['mean'] - p['ci95']:+.3f}, {p['mean'] + p['ci95']:+.3f}]",
            ]
        lines.append(f"| `{run.split(':', 1)[1]}` | " + " | ".join(cells) + " |")
    if not _trained(docs[0]["results"]):  # no shipped policy yet: the best rule on each seed
        cells = []
        for d in docs:
            best = d["best_rule"]
            cells += ["—", f"{d['results'][best]['mean']:.3f} (`{best}`)", "—"]
        lines.append("| none shipped | " + " | ".join(cells) + " |")
    return "\n".join(lines)


TABLES = {
    **{f"held-out-{env.split('-')[0]}": (lambda e=env: held_out(e)) for env in SCORE_ENVS},
    "bot-control": bot_control,
    "paper004-env": gimbal_channels,
    "scores-book": lambda: scores("BearingsManeuverBook-v0"),
    "env-speed": env_speed,
    "cold-start": cold_start,
    "scaling": scaling,
    "training-speed": training_speed,
    "scores-bearings": lambda: scores("BearingsManeuver-v0"),
    "scores-pointing": lambda: scores("StereoPointing-v0"),
    "scores-crowded": lambda: scores("StereoPointingCrowded-v0"),
    "scores-placement": lambda: scores("StereoPlacement-v0"),
    "scores-scanning": lambda: scores("StereoScanning-v0"),
    "scores-gimbal": lambda: scores("GimbalTracking-v0"),
    "ablations-book": lambda: ablations("BearingsManeuverBook-v0"),
    "ablations-pointing": lambda: ablations("StereoPointing-v0"),
    "ablations-crowded": lambda: ablations("StereoPointingCrowded-v0"),
    "headroom-share": headroom_share,
    **{f"headroom-gap-{env.split('-')[0]}": (lambda e=env: headroom_gap(e)) for env in SCORE_ENVS},
    "results-summary": results_summary,
    "results-curves": results_curves,
    "training-cost": training_cost,
    **{f"results-{env.split('-')[0]}": (lambda e=env: results_env(e)) for env in SCORE_ENVS},
}


def render(text: str) -> str:
    """``text`` with every generated block replaced by its current table."""

    def block(match: re.Match) -> str:
        name = match.group(1)
        return f"<!-- table:{name} -->\n{TABLES[name]()}\n<!-- /table:{name} -->"

    pattern = r"<!-- table:([\w-]+) -->\n(?:.*?\n)?<!-- /table:\1 -->"
    return re.sub(pattern, block, text, flags=re.S)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--check", action="store_true", help="report stale tables, write none")
    args = parser.parse_args()
    stale = []
    for path in DOCS:
        text = path.read_text()
        new = render(text)
        if new != text:
            stale.append(path)
            if not args.check:
                path.write_text(new)
                print(f"wrote {path.relative_to(ROOT)}")
    if args.check and stale:
        print("stale tables in: " + ", ".join(str(p.relative_to(ROOT)) for p in stale))
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
