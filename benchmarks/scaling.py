"""Scaling: one env step and one decision of every rule against the number of sensors and targets.

Run: ``.venv/bin/python benchmarks/scaling.py [--batch 256] [--steps N] [--repeat 3] [--warm N]``;
writes ``benchmarks/results/scaling.json`` and ``benchmarks/results/scaling.png`` (log-log).

For every env, sizes are set through the env's own params (what ``--param`` sets on the
command line): receivers × drones for StereoPointing and StereoScanning (its default layout of
``n`` receivers: evenly spread azimuths, staggered scan offsets), receiver vehicles for
StereoPlacement, platforms for BearingsManeuver. At each size the native vector env of
``--batch`` scenarios first runs one episode length under a tracking rule (:data:`WARM_RULE`;
``--warm`` steps, autoresets included), so that the timed states hold tracks as in use (a
fresh reset under random actions holds almost none). The step is then timed under that rule
over ``--steps`` consecutive steps (default: one episode length; µs per scenario-step, the
rule's own time left out), best of ``--repeat`` rounds. A whole episode, because the batch's
episodes end together at the time limit and so run in step, and a step's cost depends on the
phase: StereoScanning's periods of full sweeps, every drone in every receiver's sector, cost
4-6x its tracking periods, and a few steps' window measures one phase only. Half an episode
later every registered rule decides on the observations reached (µs per scenario-decision;
its own state chained from :data:`RULE_WARM` untimed decisions, so a stateful rule is timed
past its first periods), best of ``--repeat``. Wall time and this process's CPU time
(``*_cpu_us``: all its threads, less sensitive to other work on the machine; each row also
records the 1-min load average). A rule or env that refuses a size, or fails on it, is
recorded with its error message — that is a result too. The growth exponent is the
least-squares slope of log time against log(receivers × drones) (or platforms) over the sizes
that ran, and over the three largest (``exponents_largest``). Target (issue 15): at 16
receivers × 10 drones every decision ≤ 1 ms per scenario at 256 scenarios and the step
≤ 50 µs per scenario. With ``--env`` the rows of the other envs already in ``scaling.json``
are kept.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from typing import Any

import gymnasium as gym
import numpy as np
from timing import RESULTS, write_results

import sensorgym.envs  # noqa: F401  (registers the ids)
from sensorgym.agents.registry import RULES
from sensorgym.train.evaluation import env_params, make_sb3_env, simulator_state

#: env id → [(size label, receivers·drones (or platforms), params fields)]
SIZES: dict[str, list[tuple[str, int, dict[str, Any]]]] = {
    "sensorgym/StereoPointing-v0": [
        (f"{n} receivers × {m} drones", n * m, {"n_receivers": n, "n_drones": m})
        # exhaustive assignment search up to 4096 = 4^6 candidates, polynomial beyond
        for n, m in ((4, 2), (4, 4), (6, 3), (8, 4), (12, 6), (16, 10))
    ],
    "sensorgym/StereoScanning-v0": [
        # the default layout of n receivers (evenly spread, staggered scan offsets)
        (f"{n} receivers × {m} drones", n * m, {"n_receivers": n, "n_drones": m})
        for n, m in ((3, 4), (4, 4), (8, 6), (16, 10))
    ],
    "sensorgym/StereoPlacement-v0": [
        (f"{n} receivers", n, {"n_receivers": n}) for n in (3, 4, 6, 8, 16)
    ],
    "sensorgym/BearingsManeuver-v0": [
        (f"{k} platforms", k, {"platforms": k}) for k in (1, 2, 4, 8, 16)
    ],
}


#: the rule each env runs under before and while its step is timed (one that holds tracks)
WARM_RULE = {
    "sensorgym/StereoPointing-v0": "greedy-information",
    "sensorgym/StereoScanning-v0": "cue-following",
    "sensorgym/StereoPlacement-v0": "greedy-information",
    "sensorgym/BearingsManeuver-v0": "greedy-information",
}


#: untimed decisions of each rule (its state chained) before its decisions are timed
RULE_WARM = 3


def _error(exc: BaseException) -> str:
    text = " ".join(f"{type(exc).__name__}: {exc}".split())
    return text if len(text) <= 160 else text[:159] + "…"


def measure(
    env_id: str,
    fields: dict[str, Any],
    batch: int,
    steps: int | None,
    repeat: int,
    warm: int | None,
) -> dict:
    """µs per scenario of a step and of every rule's decision at one size, after ``warm``
    steps (default: one episode length) under :data:`WARM_RULE`: the step's mean over
    ``steps`` consecutive steps (default: one episode length, every phase of an episode:
    the batch's episodes end together at the time limit, so they run in step), best of
    ``repeat`` rounds; then half an episode more, and every rule decides there."""
    row: dict[str, Any] = {"step_us": None, "rules": {}, "load_average_1min": os.getloadavg()[0]}
    try:
        env = make_sb3_env(env_id, batch, seed=0, **fields)
    except Exception as exc:
        row["error"] = _error(exc)
        return row
    obs = env.reset()
    episode = int(gym.spec(env_id).max_episode_steps)
    warm = episode if warm is None else warm
    steps = episode if steps is None else steps
    row["warm_rule"], row["warm_steps"], row["timed_steps"] = WARM_RULE[env_id], warm, steps
    try:
        driver = RULES[env_id][WARM_RULE[env_id]](env_params(env), simulator_state(env))
        state, start = None, np.ones(batch, dtype=bool)

        def advance(n: int) -> tuple[float, float]:
            """``n`` steps under the warm rule; their wall and CPU seconds (the rule's left
            out)."""
            nonlocal obs, state, start
            wall = used = 0.0
            for _ in range(n):
                action, state = driver.predict(obs, state, start, deterministic=True)
                t0, c0 = time.perf_counter(), time.process_time()
                obs, _, start, _ = env.step(action)
                wall += time.perf_counter() - t0
                used += time.process_time() - c0
            return wall, used

        advance(warm)
        best, cpu = np.inf, np.inf
        for _ in range(repeat):
            wall, used = advance(steps)
            best, cpu = min(best, wall), min(cpu, used)
        row["step_us"] = best / (steps * batch) * 1e6
        row["step_cpu_us"] = cpu / (steps * batch) * 1e6
        advance(episode // 2)  # the rules decide mid-episode, where tracks are held
    except Exception as exc:
        row["error"] = _error(exc)
        return row
    for name, make in RULES.get(env_id, {}).items():
        try:
            rule = make(env_params(env), simulator_state(env))
            # the rule's own state past its first periods (a rule with a search phase, such as
            # StereoScanning's periodic sweeps, decides cheaply then), its episodes running on
            rule_state, rule_start = None, start
            for _ in range(RULE_WARM):
                _, rule_state = rule.predict(obs, rule_state, rule_start, deterministic=True)
                rule_start = np.zeros(batch, dtype=bool)
            best, cpu = np.inf, np.inf
            for _ in range(repeat):
                t0, c0 = time.perf_counter(), time.process_time()
                _, rule_state = rule.predict(obs, rule_state, rule_start, deterministic=True)
                best = min(best, time.perf_counter() - t0)
                cpu = min(cpu, time.process_time() - c0)
            row["rules"][name] = {
                "decision_us": best / batch * 1e6,
                "decision_cpu_us": cpu / batch * 1e6,
            }
        except Exception as exc:
            row["rules"][name] = {"error": _error(exc)}
    env.close()
    return row


def exponent(xs: list[float], ys: list[float]) -> float | None:
    """Least-squares slope of log y on log x (None with fewer than two distinct sizes)."""
    if len(set(xs)) < 2:
        return None
    return float(np.polyfit(np.log(xs), np.log(ys), 1)[0])


def growth(results: list[dict], env_id: str, largest: int | None = None) -> dict:
    """Growth exponent of the env step and of every rule's decision for ``env_id`` over the
    sizes that ran (only the ``largest`` sizes, if given)."""
    rows = [r for r in results if r["env"] == env_id and r.get("step_us") is not None]
    rows = sorted(rows, key=lambda r: r["size"])[-largest if largest else 0 :]
    out = {"env step": exponent([r["size"] for r in rows], [r["step_us"] for r in rows])}
    for name in RULES.get(env_id, {}):
        pts = [(r["size"], r["rules"][name]["decision_us"]) for r in rows
               if "decision_us" in r["rules"].get(name, {})]  # fmt: skip
        out[name] = exponent(*map(list, zip(*pts, strict=True))) if pts else None
    return out


def plot(results: list[dict], path: Any) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    envs = list(SIZES)
    fig, axes = plt.subplots(1, len(envs), figsize=(4.2 * len(envs), 3.8), squeeze=False)
    for ax, env_id in zip(axes[0], envs, strict=True):
        rows = [r for r in results if r["env"] == env_id]
        series: dict[str, list[tuple[int, float]]] = {}
        for r in rows:
            if r.get("step_us") is not None:
                series.setdefault("env step", []).append((r["size"], r["step_us"]))
            for name, t in r.get("rules", {}).items():
                if "decision_us" in t:
                    series.setdefault(name, []).append((r["size"], t["decision_us"]))
        for name, pts in series.items():
            x, y = zip(*pts, strict=True)
            style = "k-o" if name == "env step" else "-o"
            ax.loglog(x, y, style, markersize=3, label=name, linewidth=1.2)
        ax.set_title(env_id.split("/")[1], fontsize=9)
        ax.set_xlabel("receivers × drones" if "Stereo" in env_id else "platforms", fontsize=8)
        ax.grid(alpha=0.3, which="both")
        if series:
            ax.legend(fontsize=6)
    axes[0, 0].set_ylabel("µs per scenario (batch of 256)")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--batch", type=int, default=256)
    parser.add_argument(
        "--steps", type=int, default=None, help="timed steps per round (default: one episode)"
    )
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument(
        "--warm", type=int, default=None, help="steps before timing (default: one episode)"
    )
    parser.add_argument("--env", action="append", default=None, help="env id; repeatable")
    args = parser.parse_args()
    results = []
    for env_id in args.env or list(SIZES):
        for label, size, fields in SIZES[env_id]:
            row = measure(env_id, fields, args.batch, args.steps, args.repeat, args.warm)
            results.append({"env": env_id, "case": label, "size": size, **row})
            step = "—" if row.get("step_us") is None else f"{row['step_us']:.1f}"
            cpu = f" (CPU {row['step_cpu_us']:.1f})" if "step_cpu_us" in row else ""
            print(f"{env_id:32s} {label:24s} step {step:>8s} µs{cpu}", row.get("error", ""))
            for name, t in row.get("rules", {}).items():
                value = (
                    f"{t['decision_us']:.1f} µs (CPU {t['decision_cpu_us']:.1f})"
                    if "decision_us" in t
                    else t["error"]
                )
                print(f"{'':58s} {name:24s} {value}")
    envs = args.env or list(SIZES)
    slopes = {env_id: growth(results, env_id) for env_id in envs}
    # the growth at the largest sizes: where a rule's search switches method with the size
    # (exhaustive at small sizes), the slope over all sizes says little about larger ones
    tail = {env_id: growth(results, env_id, largest=3) for env_id in envs}
    print("\ngrowth exponent (slope of log time on log size; all sizes, three largest):")
    for env_id, s in slopes.items():
        for name, k in s.items():
            k3 = tail[env_id][name]
            print(
                f"  {env_id:32s} {name:24s} {'—' if k is None else f'{k:.2f}':>6s}"
                f" {'—' if k3 is None else f'{k3:.2f}':>6s}"
            )
    path = RESULTS / "scaling.json"
    if args.env and path.exists():  # keep the rows of the envs not run now
        kept = json.loads(path.read_text())["results"]
        results = [r for r in kept["rows"] if r["env"] not in args.env] + results
        results.sort(key=lambda r: list(SIZES).index(r["env"]))  # stable: the sizes' order
        slopes = {e: s for e, s in kept["exponents"].items() if e not in args.env} | slopes
        old_tail = kept.get("exponents_largest", {})
        tail = {e: s for e, s in old_tail.items() if e not in args.env} | tail
    write_results(
        path,
        {"rows": results, "exponents": slopes, "exponents_largest": tail},
        batch=args.batch,
        steps="one episode" if args.steps is None else args.steps,
        repeat=args.repeat,
        warm="one episode" if args.warm is None else args.warm,
    )
    plot(results, RESULTS / "scaling.png")
    print(f"wrote {RESULTS / 'scaling.json'} and {RESULTS / 'scaling.png'}")


if __name__ == "__main__":
    main()
