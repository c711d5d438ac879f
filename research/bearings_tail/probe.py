"""BearingsManeuver-v0 PPO recipes tried for issue 37 item 4 (a trained policy that beats the
best rule on the mean return *and* in the tail: p90 and RMS of the tracker's final position
error no worse than the rule's, no stand-off broken). Each run and the rule ``mpc-estimate``
are scored on the tuning seed 600 (256 episodes by default, one random stream per episode, so
the comparison is paired episode by episode); the held-out seeds are never used. Lab record,
not a benchmark.

    python research/bearings_tail/probe.py NAME=RUN_DIR ... --out research/bearings_tail/results.json

The runs were trained with ``sensorgym train --env sensorgym/BearingsManeuver-v0`` and the
``--hyperparam`` overrides recorded in each run's config.yaml (copied into the JSON).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from sensorgym.train.benchmark import PolicySpec, paired_difference, score
from sensorgym.train.models import read_config
from sensorgym.train.tail import cvar, rms

ENV_ID = "sensorgym/BearingsManeuver-v0"
SEED = 600
RULE = "mpc-estimate"
EPISODE_STEPS = 30


def summary(result: dict, rule: dict | None = None) -> dict:
    """Mean return, the final error's median / p90 / RMS / worst-5 % mean (m), the stand-off
    breaks (episodes ended before the time limit) and, given the rule's result, the paired
    difference of the returns."""
    error = np.array(result["tails"]["final_error"], dtype=float)
    out = {
        "mean_return": float(np.mean(result["returns"])),
        "final_error_median_m": float(np.median(error)),
        "final_error_p90_m": float(np.quantile(error, 0.9)),
        "final_error_rms_m": rms(error),
        "final_error_worst5_m": cvar(error),
        "breaks": int(np.sum(np.asarray(result["lengths"]) < EPISODE_STEPS)),
        "mean_length": result["mean_length"],
    }
    if rule is not None:
        out["paired_vs_rule"] = paired_difference(result["returns"], rule["returns"])
    return out


def scored(spec: PolicySpec, episodes: int, n_envs: int) -> dict:
    """:func:`score` on the tuning seed, with every episode's length (steps) from its recorded
    actions instead of the actions themselves."""
    result = score(ENV_ID, spec, episodes, n_envs, SEED, record_actions=True)
    result["lengths"] = [len(a) for a in result.pop("actions")]
    del result["keys"]
    return result


def _shaping(w: dict) -> str:
    """A training wrapper in a few words: ``term 20``, ``err 1/1000 m``, ``bound 1/1000 m (time
    limit)`` (``bound``: the charge is on the final PCRLB, ``position_bound``)."""
    if w["name"] == "termination-penalty":
        return f"term {w['penalty']:g}"
    if w["name"] == "final-error-penalty":
        where = " (time limit)" if w.get("time_limit_only") else ""
        what = "bound" if w.get("key") == "position_bound" else "err"
        return f"{what} {w['weight']:g}/{w.get('scale', 1000):g} m{where}"
    return w["name"]


def table(doc: dict) -> str:
    """The README's table: the rule, then every run, from a results file."""
    lines = [
        "| policy (training seed) | training shaping, n_envs, steps | return | paired − rule "
        "| final error median, m | p90 | RMS | worst 5 % | breaks |",
        "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    r = doc["rule_summary"][RULE]
    lines.append(
        f"| `{RULE}` (rule) | | {r['mean_return']:.3f} | | {r['final_error_median_m']:.0f} "
        f"| {r['final_error_p90_m']:.0f} | {r['final_error_rms_m']:.0f} "
        f"| {r['final_error_worst5_m']:.0f} | {r['breaks']} |"
    )
    for name, entry in doc["trained"].items():
        s, hp = entry["summary"], entry["hyperparams"]
        shaping = ", ".join(_shaping(w) for w in hp.get("training_wrappers") or [])
        expert = (hp.get("pretrain") or {}).get("expert")
        if expert != "rule:lookahead-estimate":  # the recipe's expert: say when another one
            shaping += f", imitates {expert.removeprefix('rule:')}" if expert else ", no imitation"
        p = s["paired_vs_rule"]
        lines.append(
            f"| {name} ({entry['seed']}) | {shaping or 'none'}; {hp['n_envs']}, "
            f"{hp['n_timesteps']:,} | {s['mean_return']:.3f} | {p['mean']:+.3f} ± {p['ci95']:.3f} "
            f"| {s['final_error_median_m']:.0f} | {s['final_error_p90_m']:.0f} "
            f"| {s['final_error_rms_m']:.0f} | {s['final_error_worst5_m']:.0f} | {s['breaks']} |"
        )
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("runs", nargs="*", help="NAME=RUN_DIR")
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--episodes", type=int, default=256)
    parser.add_argument("--n-envs", type=int, default=64)
    parser.add_argument(
        "--table", action="store_true", help="print the README's table, score nothing"
    )
    args = parser.parse_args()
    if args.table:
        print(table(json.loads(args.out.read_text())))
        return
    doc = json.loads(args.out.read_text()) if args.out.exists() else {}
    if doc.get("episodes") != args.episodes or RULE not in doc.get("rule", {}):
        rule = scored(PolicySpec("rule", RULE), args.episodes, args.n_envs)
        doc = {"seed": SEED, "episodes": args.episodes, "rule": {RULE: rule}, "trained": {}}
    rule = doc["rule"][RULE]
    print(RULE, json.dumps(summary(rule)))
    for spec in args.runs:
        name, _, folder = spec.partition("=")
        result = scored(PolicySpec("model", folder), args.episodes, args.n_envs)
        config = read_config(Path(folder))
        entry = {"summary": summary(result, rule), "result": result}
        entry["hyperparams"], entry["seed"] = config["hyperparams"], config["seed"]  # all of it
        doc["trained"][name] = entry
        print(name, json.dumps(entry["summary"]))
    doc["rule_summary"] = {RULE: summary(rule)}
    args.out.write_text(json.dumps(doc) + "\n")


if __name__ == "__main__":
    main()
