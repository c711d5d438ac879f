"""Where the headroom goes: the gap between each episode's upper bound and the return, split by
phase of the episode and by episode (issue 37, item 5).

Run: ``.venv/bin/python benchmarks/headroom_gap.py [--env sensorgym/StereoPlacement-v0 …]
[--episodes 256] [--bearings-episodes 64]``; prints one table per env and writes (merges, env by
env) ``benchmarks/results/headroom_gap.json``. Evaluation only, on the held-out seed 10000:
nothing is tuned.

For each env it plays the best shipped trained policy (the highest mean in the committed
``docs/scores/sensorgym__<env>.json``; :mod:`sensorgym.train.shipped`) and the best fieldable
rule of that file on the benchmark's own episodes — the vector env of ``sensorgym benchmark``
(:func:`sensorgym.train.evaluation.make_sb3_env` with ``episode_streams=True``, the same seed
and batch), so episode ``e`` here is episode ``e`` of the committed file, and the returns are
checked against it. Per episode and step it records the reward ``r_t`` and the bound's part
``B_t``:

* **StereoPointing, Crowded, StereoPlacement, StereoScanning**: the per-step bounds of
  theory §11.3.1, §11.4.1 and §11.5.1 (``bound_path`` / ``step_bounds`` of ``envs/*/bound.py``)
  from the state the episode starts in; their sum in step order is the committed episode bound
  exactly. Steps after the episode's end keep ``B_t`` (the bound sums to the time limit) and
  ``r_t = 0``.
* **BearingsManeuver, Book** (theory §11.2.1): the hindsight optimum of the episode
  (:func:`~sensorgym.envs.bearings_maneuver.bound.hindsight_optimum`, rebuilt from the episode's
  stream by ``benchmark_episode``), started from the two players' own actions and the
  benchmark's random restarts and polish; ``B_t`` is the reward of its action sequence at step
  ``t``, replayed through the env's own step. It is a lower estimate of the true optimum (the
  benchmark's bound started from every scored policy; both means are recorded), and it costs
  seconds per episode, so these envs use ``--bearings-episodes`` (the benchmark's first ones).

The gap ``B − R = Σ_t (B_t − r_t)`` is then split

* **by phase**: fixed step ranges of the time limit (step 1, to 10 %, 10–20 %, then by fifths),
  and by the state of the step where the env reports it (:func:`state_splits`: every drone
  fixed or not; on StereoScanning every present drone tracked or not, and how many are
  present); the parts sum to the total gap;
* **by episode**: the share of the summed gap carried by the worst 10 % and 25 % of the
  episodes, and per scenario feature read at the reset (ranges, geometry, drones, …) its rank
  correlation with the episode's gap and its mean over the worst 10 % against the rest.

``closes`` is the benchmark's share, ``(R̄ − R̄_best)/(B̄ − R̄_best) = 1 − gap/gap_best``; its
split by phase, ``(gap_best − gap)_phase / gap_best``, sums to it. For an env without a shipped
policy (StereoPointingCrowded until one is added) only the best rule is played, with a message.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results" / "headroom_gap.json"
SCORES = ROOT / "docs" / "scores"
SEED = 10000
EPISODES = 256
BEARINGS_EPISODES = 64
N_ENVS = 16

ENVS = (
    "sensorgym/BearingsManeuver-v0",
    "sensorgym/BearingsManeuverBook-v0",
    "sensorgym/StereoPointing-v0",
    "sensorgym/StereoPointingCrowded-v0",
    "sensorgym/StereoPlacement-v0",
    "sensorgym/StereoScanning-v0",
)
HINDSIGHT = ("sensorgym/BearingsManeuver-v0", "sensorgym/BearingsManeuverBook-v0")

#: env id → ``"module:function"`` of its per-step bound ``(params, state, steps) -> (B, steps)``
STEP_BOUNDS = {
    "sensorgym/StereoPointing-v0": "sensorgym.envs.stereo_pointing.bound:bound_path",
    "sensorgym/StereoPointingCrowded-v0": "sensorgym.envs.stereo_pointing.bound:bound_path",
    "sensorgym/StereoPlacement-v0": "sensorgym.envs.stereo_placement.bound:bound_path",
    "sensorgym/StereoScanning-v0": "sensorgym.envs.stereo_scanning.bound:step_bounds",
}

#: the phases: (name, first step, end step) as fractions of the time limit, steps 1-based
PHASE_EDGES = (0.1, 0.2, 0.4, 0.6, 0.8, 1.0)
#: the per-step diagnostics read from the env's ``info`` for the splits by state
INFO_KEYS = ("unfixed_share", "drones_present", "drones_tracked")
#: the shares of the worst episodes whose part of the summed gap is reported
WORST = (0.10, 0.25)


# ---------------------------------------------------------------- what is played


def score_doc(env_id: str) -> dict[str, Any]:
    """The committed benchmark file of ``env_id`` (``best_rule`` filled in when missing)."""
    from sensorgym.train.benchmark import best_rule

    doc = json.loads((SCORES / f"{env_id.replace('/', '__')}.json").read_text())
    doc.setdefault("best_rule", best_rule(doc["results"]))
    return doc


def players(env_id: str, doc: dict[str, Any]) -> tuple[str | None, str]:
    """``(best shipped policy's row name or None, best rule)``: the shipped run with the
    highest committed mean among those shipped now (:mod:`sensorgym.train.shipped`)."""
    from sensorgym.train.shipped import shipped_policies

    runs = shipped_policies(env_id)
    rows = {f"shipped:{run}": doc["results"].get(f"shipped:{run}") for run in runs}
    scored = {k: r["mean"] for k, r in rows.items() if r is not None}
    if runs and not scored:  # shipped, not yet in the committed file: the first one
        return f"shipped:{sorted(runs)[0]}", doc["best_rule"]
    return (max(scored, key=scored.__getitem__) if scored else None), doc["best_rule"]


def build(env_id: str, name: str, n_envs: int, seed: int) -> tuple[Any, Any]:
    """``(vector env, policy)`` of the benchmark's policy ``name``
    (:func:`sensorgym.train.benchmark.build_policy`, as ``score`` plays it). The split is per
    scenario slot, so a parameter-sharing run (a slot per agent) is refused."""
    from sensorgym.train.benchmark import build_policy, policies_for
    from sensorgym.train.evaluation import agents_per_scenario

    env, policy = build_policy(env_id, policies_for(env_id)[name], n_envs, seed)
    if agents_per_scenario(env) != 1:
        env.close()
        raise ValueError(f"{name}: a parameter-sharing run has a slot per agent, not per scenario")
    return env, policy


def _import(entry: str) -> Callable[..., Any]:
    import importlib

    module, _, fn = entry.partition(":")
    return getattr(importlib.import_module(module), fn)


def play(
    env_id: str, name: str, episodes: int, n_envs: int, seed: int, steps: int
) -> dict[str, Any]:
    """Play ``name`` on the benchmark's episodes (:func:`.evaluation.evaluate`'s loop and
    order: by round, then slot). Per episode: ``rewards (steps,)`` (0 after its end), its
    ``length``, ``key (slot, round)``, ``features`` at the reset, and — for an env with a
    per-step bound — ``bounds (steps,)``; for the bearings envs the ``actions`` it took;
    ``info (keys, steps)`` of the per-step diagnostics of :data:`INFO_KEYS` the env reports."""
    from sensorgym.train.evaluation import env_params, simulator_state

    env, policy = build(env_id, name, n_envs, seed)
    try:
        params = env_params(env)
        state_fn = simulator_state(env)
        step_bound = _import(STEP_BOUNDS[env_id]) if env_id in STEP_BOUNDS else None
        record = env_id in HINDSIGHT
        target = np.array([(episodes + s) // n_envs for s in range(n_envs)])
        env.seed(seed)
        obs = env.reset()

        def starts(rows: np.ndarray) -> tuple[dict[str, np.ndarray], np.ndarray | None]:
            state = state_fn()
            feats = features(env_id, params, state)
            b = None
            if step_bound is not None:
                b = np.asarray(step_bound(params, state, steps), dtype=np.float64)
            return {k: v[rows] for k, v in feats.items()}, None if b is None else b[rows]

        all_rows = np.arange(n_envs)
        feat, bnd = starts(all_rows)
        cur = {
            "features": [{k: float(v[i]) for k, v in feat.items()} for i in all_rows],
            "bounds": [None if bnd is None else bnd[i] for i in all_rows],
        }
        rewards = [[] for _ in range(n_envs)]
        logged: list[list[list[float]]] = [[] for _ in range(n_envs)]
        acts = [[] for _ in range(n_envs)]
        done_eps: list[list[dict[str, Any]]] = [[] for _ in range(n_envs)]
        rounds = np.zeros(n_envs, dtype=np.int64)
        start = np.ones(n_envs, dtype=bool)
        state = None
        while any(len(done_eps[i]) < target[i] for i in range(n_envs)):
            action, state = policy.predict(
                obs, state=state, episode_start=start, deterministic=True
            )
            obs, reward, done, infos = env.step(action)
            if record:
                taken = np.asarray(env.get_attr("last_action")[0])
            for i in range(n_envs):
                info = infos[i].get("final_info", infos[i]) if done[i] else infos[i]
                rewards[i].append(float(reward[i]))
                logged[i].append([float(info.get(k, np.nan)) for k in INFO_KEYS])
                if record:
                    acts[i].append(taken[i].copy())
            idx = np.flatnonzero(done)
            if idx.size:
                for i in idx:
                    if len(done_eps[i]) < target[i]:
                        r = np.zeros(steps)
                        n = len(rewards[i])
                        r[:n] = rewards[i]
                        ep: dict[str, Any] = {
                            "key": (int(i), int(rounds[i])),
                            "rewards": r,
                            "length": n,
                            "features": cur["features"][i],
                        }
                        if cur["bounds"][i] is not None:
                            ep["bounds"] = cur["bounds"][i]
                        info_steps = np.full((len(INFO_KEYS), steps), np.nan)
                        info_steps[:, :n] = np.array(logged[i]).T
                        ep["info"] = info_steps
                        if record:
                            ep["actions"] = np.stack(acts[i])
                        done_eps[i].append(ep)
                    rewards[i], logged[i], acts[i] = [], [], []
                    rounds[i] += 1
                if any(len(done_eps[i]) < target[i] for i in idx):
                    feat, bnd = starts(idx)
                    for j, i in enumerate(idx):
                        cur["features"][i] = {k: float(v[j]) for k, v in feat.items()}
                        cur["bounds"][i] = None if bnd is None else bnd[j]
            start = np.asarray(done, dtype=bool)
        order = [
            done_eps[s][k] for k in range(int(target.max())) for s in range(n_envs)
            if k < len(done_eps[s])
        ]  # fmt: skip
        return {"params": params, "episodes": order}
    finally:
        env.close()


# ---------------------------------------------------------------- scenario features at reset


def _angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The angle between vectors along the last axis, degrees."""
    na, nb = np.linalg.norm(a, axis=-1), np.linalg.norm(b, axis=-1)
    cos = np.einsum("...i,...i->...", a, b) / np.maximum(na * nb, 1e-300)
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def features(env_id: str, params: Any, state: Any) -> dict[str, np.ndarray]:
    """Per scenario of the batched reset ``state``: what the scenario is, read from the truth
    at its start (evaluation only; names with their unit)."""
    if env_id in HINDSIGHT:
        pos = state.platform_position[:, 0]
        tgt = state.target
        los = tgt[:, :2] - pos  # platform → target
        heading = np.stack([np.sin(state.heading[:, 0]), np.cos(state.heading[:, 0])], axis=1)
        return {
            "range_km": np.hypot(los[:, 0], los[:, 1]) / 1e3,
            "target_speed_mps": np.hypot(tgt[:, 2], tgt[:, 3]),
            "target_aspect_deg": _angle(tgt[:, 2:4], -los),
            "platform_off_bearing_deg": _angle(heading, los),
            "ln_initial_bound": np.log(state.accuracy),
        }
    if env_id == "sensorgym/StereoPlacement-v0":
        rc = state.receivers.mean(axis=1)  # (B, 3), y = 0 on the ground
        d = state.drone_position - rc
        horiz = np.hypot(d[:, 0], d[:, 2])
        v = state.drone_velocity
        radial = -(d[:, 0] * v[:, 0] + d[:, 2] * v[:, 2]) / np.maximum(horiz, 1e-9)
        return {
            "ground_range_m": horiz,
            "height_m": state.drone_position[:, 1],
            "speed_mps": np.linalg.norm(v, axis=1),
            "closing_speed_mps": radial,
        }
    if env_id == "sensorgym/StereoScanning-v0":
        p, v = state.drone_position, state.drone_velocity
        m = p.shape[1]
        iu, ju = np.triu_indices(m, 1)
        gaps = np.linalg.norm(p[:, iu] - p[:, ju], axis=-1)
        return {
            "late_drones": (state.enter > 0.0).sum(axis=1).astype(np.float64),
            "last_entry_s": state.enter.max(axis=1),
            "speed_mps": np.linalg.norm(v, axis=-1).mean(axis=1),
            "closest_pair_m": gaps.min(axis=1) if gaps.shape[1] else np.zeros(len(p)),
            "altitude_m": p[..., 1].mean(axis=1),
        }
    # StereoPointing, Crowded: receivers (n, 3), drones (B, m, 3)
    rec = np.asarray(params._receivers, dtype=np.float64)
    p, v = state.drone_position, state.drone_velocity
    w = p[:, None, :, :] - rec[None, :, None, :]  # (B, n, m, 3) receiver → drone
    rng = np.linalg.norm(w, axis=-1)
    m = p.shape[1]
    iu, ju = np.triu_indices(m, 1)
    sep = _angle(w[:, :, iu], w[:, :, ju])  # (B, n, pairs)
    u = w / rng[..., None]
    cross = v[:, None] - np.einsum("bnmi,bmi->bnm", u, v)[..., None] * u
    rate = np.degrees(np.linalg.norm(cross, axis=-1) / rng)  # angular rate seen, deg/s
    return {
        "range_mean_m": rng.mean(axis=(1, 2)),
        "range_min_m": rng.min(axis=(1, 2)),
        "closest_pair_deg": sep.min(axis=(1, 2)) if sep.shape[2] else np.zeros(len(p)),
        "angular_rate_dps": rate.mean(axis=(1, 2)),
        "speed_mps": np.linalg.norm(v, axis=-1).mean(axis=1),
    }


# ---------------------------------------------------------------- the bearings envs' bound


def hindsight_steps(
    params: Any, seed: int, eps: list[list[dict[str, Any]]], steps: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per episode ``e`` (played by every player of ``eps``, ``eps[p][e]``): the hindsight
    optimum started from their actions (the benchmark's restarts and polish, restart seed
    ``seed + e`` as the benchmark's), its rewards step by step replayed through the env's own
    step, ``(per-step (E, steps), value (E,), gain (E,), drift (E,))``: ``drift`` the largest
    distance of the target's path from its initial straight line (m; what its process noise
    did, the scenario's only variation in the Book env)."""
    from sensorgym.envs.bearings_maneuver import simulation
    from sensorgym.envs.bearings_maneuver.bound import (
        BENCHMARK_POLISH,
        BENCHMARK_RESTARTS,
        benchmark_episode,
        hindsight_optimum,
    )
    from sensorgym.envs.shells.streams import RowGenerator, episode_generator

    E = len(eps[0])
    per_step, value, gain = np.zeros((E, steps)), np.zeros(E), np.zeros(E)
    drift = np.zeros(E)
    dt = params.world.dt
    for e in range(E):
        slot, number = eps[0][e]["key"]
        state, path = benchmark_episode(params, seed, slot, number, steps)
        # how far the target's path strays from its initial straight line (its process noise)
        x = path[0]
        t = dt * np.arange(steps + 1)[:, None]
        # to the millimetre: a noise-free path (BearingsManeuver) strays by rounding only
        drift[e] = round(float(np.hypot(*(x[:, :2] - (x[0, :2] + t * x[0, 2:4])).T).max()), 3)
        K = state.heading.shape[1]
        starts = [np.asarray(p[e]["actions"], dtype=np.float64).reshape(1, -1, K, 2) for p in eps]
        res = hindsight_optimum(
            params, state, starts, restarts=BENCHMARK_RESTARTS, seed=seed + e, paths=path,
            polish=BENCHMARK_POLISH,
        )  # fmt: skip
        value[e], gain[e] = res.value[0], res.gain[0]
        # replay its actions through the env's step on the episode's own stream
        rng = RowGenerator([episode_generator(seed, slot, number)])
        s = simulation.reset(params, rng, 1)
        for t in range(steps):
            s, r, term = simulation.step(params, s, res.actions[0, t][None], rng)
            per_step[e, t] = float(r[0])
            if term[0]:
                break
    return per_step, value, gain, drift


# ---------------------------------------------------------------- the decomposition


def phases(steps: int) -> list[tuple[str, int, int]]:
    """``(name, lo, hi)``: steps ``lo ≤ t < hi`` (0-based) of a time limit of ``steps``."""
    edges = [0, 1] + [max(2, math.ceil(f * steps - 1e-9)) for f in PHASE_EDGES]
    names = ["step 1", "to 10 %", "10-20 %", "20-40 %", "40-60 %", "60-80 %", "80-100 %"]
    out = []
    for name, lo, hi in zip(names, edges[:-1], edges[1:], strict=True):
        if hi > lo:
            out.append((f"{name} (steps {lo + 1}-{hi})" if hi - lo > 1 else name, lo, hi))
    return out


def decompose(
    bounds: np.ndarray,
    rewards: np.ndarray,
    lengths: np.ndarray,
    feats: dict[str, np.ndarray],
    splits: dict[str, np.ndarray] | None = None,
) -> dict[str, Any]:
    """The gap ``B − R`` of ``E`` episodes from per-step ``bounds`` and ``rewards`` ``(E, T)``
    (rewards 0 after an episode's ``lengths``): its mean; by phase (:func:`phases`; and per
    ``splits[name]``, a label ``(E, T)`` per step, by label — the steps after an episode's end
    labelled ``after the end`` —: each part's mean per episode, its share of the total and its
    steps per episode); by episode (the share of the summed gap carried by the
    worst 10 % and 25 %; per feature its Spearman correlation with the gap and its mean over
    the worst 10 % and the rest)."""
    from scipy.stats import spearmanr

    E, T = rewards.shape
    step_gap = bounds - rewards
    gap = np.zeros(E)
    for t in range(T):  # step order, as a return is summed
        gap += step_gap[:, t]
    total = float(gap.sum())
    ret = rewards.sum(axis=1)

    def part(steps: slice) -> dict[str, float]:
        g = float(step_gap[:, steps].sum())
        return {"gap": g / E, "share": g / total if total else 0.0}

    by_phase = [
        {"phase": name, "steps": [lo + 1, hi], **part(slice(lo, hi))} for name, lo, hi in phases(T)
    ]
    after = np.arange(T)[None, :] >= lengths[:, None]
    after_gap = float(step_gap[after].sum())
    out: dict[str, Any] = {
        "episodes": int(E),
        "mean_return": float(ret.mean()),
        "mean_bound": float(bounds.sum(axis=1).mean()),
        "mean_gap": float(gap.mean()),
        "phases": by_phase,
        "after_end": {"gap": after_gap / E, "share": after_gap / total if total else 0.0},
    }
    out["splits"] = {}
    for name, labels in (splits or {}).items():
        lab = np.where(after, "after the end", np.asarray(labels).astype(str))
        parts = {}
        for value in sorted(set(lab.ravel().tolist())):
            mask = lab == value
            g = float(step_gap[mask].sum())
            parts[value] = {
                "gap": g / E,
                "share": g / total if total else 0.0,
                "steps": float(mask.sum() / E),
            }
        out["splits"][name] = parts
    order = np.argsort(-gap, kind="stable")
    out["worst"] = {
        f"{round(100 * q)} %": float(gap[order[: max(1, math.ceil(q * E))]].sum() / total)
        if total
        else 0.0
        for q in WORST
    }
    out["worst_episodes"] = [int(i) for i in order[: max(1, math.ceil(WORST[0] * E))]]
    worst = np.zeros(E, dtype=bool)
    worst[order[: max(1, math.ceil(WORST[0] * E))]] = True
    fs = {}
    for k, x in feats.items():
        rho = spearmanr(x, gap).statistic if np.ptp(x) > 0 and np.ptp(gap) > 0 else float("nan")
        fs[k] = {
            "spearman": None if not np.isfinite(rho) else float(rho),
            "worst_10_mean": float(x[worst].mean()),
            "rest_mean": float(x[~worst].mean()) if (~worst).any() else None,
        }
    out["features"] = fs
    out["_gap"] = gap  # per episode, for the gain's split (not written)
    out["_step_gap"] = step_gap
    return out


def state_splits(eps: list[dict[str, Any]]) -> dict[str, np.ndarray]:
    """Per-step labels ``(E, T)`` from the episodes' logged diagnostics, where the env reports
    them: ``fix`` (every drone fixed, or some drone without a fix: ``unfixed_share``) for the
    pointing and placement envs; ``tracks`` (every present drone with an assigned confirmed
    track or not) and ``drones present`` for StereoScanning."""
    if "info" not in eps[0]:
        return {}
    info = {k: np.stack([e["info"][i] for e in eps]) for i, k in enumerate(INFO_KEYS)}
    out = {}
    u = info["unfixed_share"]
    if np.isfinite(u).any():
        out["fix"] = np.where(u > 0.0, "a drone unfixed", "every drone fixed")
    present, tracked = info["drones_present"], info["drones_tracked"]
    if np.isfinite(present).any():
        out["tracks"] = np.where(
            present == 0.0,
            "no drone present",
            np.where(tracked < present, "a drone untracked", "every drone tracked"),
        )
        n = np.nan_to_num(present).astype(int)
        out["drones present"] = np.char.add(n.astype(str), " present")
    return out


def gain_split(policy: dict[str, Any], rule: dict[str, Any]) -> dict[str, Any]:
    """What the policy gained over the rule, by phase: ``(gap_rule − gap_policy)`` per phase,
    per episode, and as a share of the rule's gap (the phases' shares sum to ``closes``)."""
    g_rule = rule["mean_gap"]
    rows = []
    for a, b in zip(policy["phases"], rule["phases"], strict=True):
        d = b["gap"] - a["gap"]
        rows.append({"phase": a["phase"], "gain": d, "closes": d / g_rule if g_rule else None})
    d_total = g_rule - policy["mean_gap"]
    per_ep = rule["_gap"] - policy["_gap"]
    return {
        "gain": d_total,
        "closes": d_total / g_rule if g_rule else None,
        "phases": rows,
        "episodes_better": int(np.sum(per_ep > 1e-9)),
        "episodes_worse": int(np.sum(per_ep < -1e-9)),
        "gain_worst_10_share": _top_share(per_ep, WORST[0]),
    }


def _top_share(x: np.ndarray, q: float) -> float | None:
    """The share of ``Σ x`` carried by the ``⌈q n⌉`` largest ``x`` (``None`` if ``Σ x ≤ 0``)."""
    s = float(x.sum())
    if s <= 0:
        return None
    k = max(1, math.ceil(q * x.size))
    return float(np.sort(x)[::-1][:k].sum() / s)


# ---------------------------------------------------------------- one env


def run_env(
    env_id: str,
    episodes: int,
    seed: int = SEED,
    n_envs: int = N_ENVS,
    only_rule: bool = False,
) -> dict[str, Any]:
    """The decomposition of ``env_id`` (module docstring) as a JSON-ready dict."""
    import gymnasium

    import sensorgym.envs  # noqa: F401  (registers the ids)

    t0 = time.perf_counter()
    steps = int(gymnasium.spec(env_id).max_episode_steps)
    doc = score_doc(env_id)
    policy, rule = players(env_id, doc)
    if only_rule:
        policy = None
    names = [n for n in (policy, rule) if n is not None]
    played = {n: play(env_id, n, episodes, n_envs, seed, steps) for n in names}
    params = played[rule]["params"]
    eps = {n: played[n]["episodes"] for n in names}
    E = len(eps[rule])
    keys = [e["key"] for e in eps[rule]]
    for n in names:
        if [e["key"] for e in eps[n]] != keys:
            raise RuntimeError(f"{env_id}: {n} played other episodes than {rule}")
    feats = {k: np.array([e["features"][k] for e in eps[rule]]) for k in eps[rule][0]["features"]}
    out: dict[str, Any] = {
        "seed": seed, "episodes": E, "n_envs": n_envs, "steps": steps,
        "policy": policy, "best_rule": rule, "passive_rule": doc.get("passive_rule"),
    }  # fmt: skip
    # the committed file's episode of each key: index round · n_envs + slot there
    n_doc = int(doc["settings"]["n_envs"])
    at = np.array([k * n_doc + s for s, k in keys])
    committed_bound = np.array(doc["results"][rule]["bounds"])[at]
    if env_id in HINDSIGHT:
        per_step, value, gain, drift = hindsight_steps(params, seed, [eps[n] for n in names], steps)
        feats["target_drift_m"] = drift
        out["bound"] = {
            "method": "hindsight optimum from the players' actions (+ the benchmark's restarts)",
            "mean": float(value.mean()),
            "benchmark_mean": float(committed_bound.mean()),
            "replay_max_abs_diff": float(np.abs(per_step.sum(axis=1) - value).max()),
            "optimiser_gain_mean": float(gain.mean()),
        }
        bounds = {n: per_step for n in names}
    else:
        bounds = {n: np.stack([e["bounds"] for e in eps[n]]) for n in names}
        b_sum = bounds[rule].sum(axis=1)
        out["bound"] = {
            "method": "per-step bound (envs/*/bound.py), summed: the benchmark's episode bound",
            "mean": float(b_sum.mean()),
            "benchmark_mean": float(committed_bound.mean()),
            "max_abs_diff_to_benchmark": float(np.abs(b_sum - committed_bound).max()),
        }
    if env_id == "sensorgym/StereoScanning-v0":  # B_k ≠ 0 exactly while a drone is present
        feats["periods_with_drones"] = (bounds[rule] != 0.0).sum(axis=1).astype(np.float64)
    res: dict[str, Any] = {}
    for n in names:
        rewards = np.stack([e["rewards"] for e in eps[n]])
        lengths = np.array([e["length"] for e in eps[n]])
        d = decompose(bounds[n], rewards, lengths, feats, state_splits(eps[n]))
        committed = np.array(doc["results"][n]["returns"])[at] if n in doc["results"] else None
        if committed is not None:
            d["max_abs_diff_to_benchmark_returns"] = float(
                np.abs(rewards.sum(axis=1) - committed).max()
            )
        res[n] = d
    out["players"] = res
    if policy is not None:
        out["gain"] = gain_split(res[policy], res[rule])
        out["gain"]["features"] = _gain_features(res[rule]["_gap"] - res[policy]["_gap"], feats)
    else:
        out["note"] = "no shipped trained policy for this env yet: the best rule only"
    for d in res.values():
        d.pop("_gap"), d.pop("_step_gap")
    out["runtime_s"] = round(time.perf_counter() - t0, 1)
    return out


def _gain_features(gain: np.ndarray, feats: dict[str, np.ndarray]) -> dict[str, Any]:
    from scipy.stats import spearmanr

    out = {}
    for k, x in feats.items():
        ok = np.ptp(x) > 0 and np.ptp(gain) > 0
        rho = spearmanr(x, gain).statistic if ok else float("nan")
        out[k] = None if not np.isfinite(rho) else float(rho)
    return out


# ---------------------------------------------------------------- report


def report(env_id: str, r: dict[str, Any]) -> None:
    from rich.console import Console
    from rich.table import Table

    con = Console(width=150)
    b = r["bound"]
    con.print(
        f"\n[bold]{env_id}[/bold]: {r['episodes']} episodes, seed {r['seed']}; bound mean "
        f"{b['mean']:.3f} (benchmark's on these episodes {b['benchmark_mean']:.3f}); "
        f"{r['runtime_s']:.0f} s"
    )
    if r.get("note"):
        con.print(r["note"])
    names = list(r["players"])
    t = Table(title="gap = bound − return, per episode, by phase")
    t.add_column("phase")
    for n in names:
        t.add_column(f"{n} gap", justify="right")
        t.add_column("share", justify="right")
    if "gain" in r:
        t.add_column("gain over rule", justify="right")
        t.add_column("closes", justify="right")
    ph = [p["phase"] for p in r["players"][names[0]]["phases"]]
    for i, name in enumerate(ph):
        row = [name]
        for n in names:
            p = r["players"][n]["phases"][i]
            row += [f"{p['gap']:.3f}", f"{100 * p['share']:.1f} %"]
        if "gain" in r:
            g = r["gain"]["phases"][i]
            row += [f"{g['gain']:+.3f}", f"{100 * (g['closes'] or 0):+.1f} %"]
        t.add_row(*row)
    total = ["total"]
    for n in names:
        total += [f"{r['players'][n]['mean_gap']:.3f}", "100 %"]
    if "gain" in r:
        total += [f"{r['gain']['gain']:+.3f}", f"{100 * (r['gain']['closes'] or 0):+.1f} %"]
    t.add_row(*total)
    con.print(t)
    for n in names:
        d = r["players"][n]
        extra = "".join(
            f"; by {name}: "
            + ", ".join(
                f"{k} {100 * v['share']:.1f} % over {v['steps']:.1f} steps"
                for k, v in parts.items()
            )
            for name, parts in d["splits"].items()
        )
        con.print(
            f"{n}: worst 10 % of episodes carry {100 * d['worst']['10 %']:.1f} %, worst 25 % "
            f"{100 * d['worst']['25 %']:.1f} % of the gap; after the episode's end "
            f"{100 * d['after_end']['share']:.1f} %{extra}"
        )
        f = Table(title=f"{n}: scenario features at reset against the episode's gap")
        for c in ("feature", "Spearman ρ", "worst 10 % mean", "rest mean"):
            f.add_column(c, justify="right")
        for k, v in d["features"].items():
            rho = "" if v["spearman"] is None else f"{v['spearman']:+.2f}"
            f.add_row(k, rho, f"{v['worst_10_mean']:.3g}", f"{v['rest_mean']:.3g}")
        con.print(f)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", nargs="+", default=list(ENVS), help="env ids (default: all)")
    parser.add_argument("--episodes", type=int, default=EPISODES)
    parser.add_argument("--bearings-episodes", type=int, default=BEARINGS_EPISODES,
                        help="episodes of the bearings envs (the hindsight optimum's cost)")  # fmt: skip
    parser.add_argument("--seed", type=int, default=SEED)
    parser.add_argument("--n-envs", type=int, default=N_ENVS)
    parser.add_argument("--out", type=Path, default=RESULTS)
    args = parser.parse_args()
    doc = json.loads(args.out.read_text()) if args.out.is_file() else {"results": {}}
    for env_id in args.env:
        n = args.bearings_episodes if env_id in HINDSIGHT else args.episodes
        r = run_env(env_id, n, args.seed, args.n_envs)
        report(env_id, r)
        doc["results"][env_id] = r
        doc["settings"] = {
            "script": "benchmarks/headroom_gap.py", "seed": args.seed, "n_envs": args.n_envs,
            "episodes": args.episodes, "bearings_episodes": args.bearings_episodes,
        }  # fmt: skip
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps(doc, indent=1) + "\n")


if __name__ == "__main__":
    main()
