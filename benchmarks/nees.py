"""Does the trackers' covariance tell the truth? NEES of the env's own estimate, step by step.

For ``sensorgym/BearingsManeuver-v0`` and ``sensorgym/StereoScanning-v0``, ``--scenarios``
(2,000) scenarios run through the native vector env (``gym.make_vec(id, num_envs=N,
vectorization_mode="vector_entry_point")``, seeded) under a stated policy — uniform random
actions (seeded) and registered rules of :mod:`sensorgym.agents` — and at every step the
normalised estimation error squared (NEES) of the tracker's estimate against the truth of the
env's ``simulator_state`` is pooled over the scenarios:

* **BearingsManeuver** — the moment-matched estimate ``state.estimate`` (``x̂``, ``P``) of the
  range-parameterised bank (second-order EKF members; theory §7.9, §11.2, §11.6) against
  ``state.target``:
  ``ε = (x̂ − x)ᵀ P⁻¹ (x̂ − x)`` of the joint state ``(x, y, ẋ, ẏ)`` (``d = 4``), its position
  and its velocity blocks (``d = 2`` each). A scenario counts from its reset to its last step
  (30, or the step that brought a platform within ``min_range``).
* **StereoScanning** — every drone with a confirmed track assigned (``state.assigned``): the
  track's position ``p̂ + v̂ Δ`` and velocity ``v̂`` at the time the reward compares them (the
  track's own time if updated in the period, else the period end, ``Δ`` since its latest
  member; theory §11.5) against the drone's (constant-acceleration motion, exact) and the
  tracker's *scalar* spreads ``σ_pos² + (σ_vel Δ)²`` and ``σ_vel²``, the total (trace)
  variances the tracker claims (theory §3.4, §11.5). With no full covariance to invert, the
  NEES is the one the scalar implies read isotropically, ``ε = d ‖e‖²/σ²`` (``d = 3``; joint
  ``d = 6`` the sum): its mean is ``d`` whenever ``σ²`` is the true total variance, whatever
  the shape of the error; the tail above the ``χ²_d`` 99 % quantile is only ``1 %`` for an
  isotropic error (an elongated one has a heavier tail at the right variance). Each part is
  also reported per class (:data:`CLASSES`): by association — the track's three latest fixes
  all of its drone (``own``, matched by their rays, :func:`track_drones`) or not (``wrong``)
  — and, for ``own``, fixed in the period or coasting.

Per step: the mean NEES over the ``N`` samples and its 95 % band (the mean of ``N`` draws of
``χ²_d``, ``chi2.ppf([0.025, 0.975], N d)/N``), whether the mean is inside, and the fraction
above the ``χ²_d`` 99 % quantile (1 % expected). The table shows reset (BearingsManeuver) or the
first period with confirmed tracks (StereoScanning), the middle and the end of the episodes
(StereoScanning: each scenario's last period with a tracked drone); the JSON holds every step.

Run: ``.venv/bin/python benchmarks/nees.py [--scenarios 2000] [--seed 0] [--env NAME]``;
writes ``benchmarks/results/nees.json``. ``--env BearingsManeuver`` or ``--env StereoScanning``
measures that env only (default: both); the JSON then holds that env alone, so give ``--out``
unless the committed file is to lose the other.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray
from rich.console import Console
from rich.table import Table
from scipy.stats import chi2
from timing import RESULTS, write_results

import sensorgym.envs  # noqa: F401  (registers the envs)
from sensorgym.agents.registry import rules_for

BEARINGS = "sensorgym/BearingsManeuver-v0"
SCANNING = "sensorgym/StereoScanning-v0"
#: the policies measured per env: uniform random actions and registered rules
POLICIES = {
    BEARINGS: ("random", "straight-course", "greedy-information"),
    SCANNING: ("random", "full-sweep", "cue-following"),
}
#: the parts of the state and their dimensions, per env
PARTS = {"joint": None, "position": slice(0, 2), "velocity": slice(2, 4)}
#: StereoScanning's samples also split by association: ``own`` — the track's latest members
#: are all fixes of the drone it is assigned to; ``wrong`` — some is another drone's or false;
#: and the ``own`` ones by whether the track was fixed in the period (``fresh``, compared at
#: its own time) or coasts (compared at the period end, ``σ_pos² + (σ_vel Δ)²``)
CLASSES = ("own", "wrong", "own fresh", "own coasting")
SCANNING_PARTS = (*PARTS, *(f"{c} {p}" for c in CLASSES for p in PARTS))

FloatArray = NDArray[np.float64]
# per step, per part: the NEES samples pooled over the scenarios
Samples = list[dict[str, FloatArray]]


def summary(nees: FloatArray, d: int) -> dict[str, Any]:
    """Mean NEES of ``N`` samples of dimension ``d``, its 95 % band ``χ²_{Nd}`` quantiles
    ``/N``, whether the mean lies inside and the fraction above the ``χ²_d`` 99 % quantile."""
    n = int(nees.size)
    if n == 0:
        return {"n": 0, "d": d}
    lo, hi = chi2.ppf([0.025, 0.975], n * d) / n
    mean = float(nees.mean())
    return {
        "n": n,
        "d": d,
        "mean": mean,
        "band": [float(lo), float(hi)],
        "in_band": bool(lo <= mean <= hi),
        "above_q99": float(np.mean(nees > chi2.ppf(0.99, d))),
    }


def _policy(env_id: str, name: str, env: Any, seed: int) -> Callable[[Any, int], Any]:
    """``act(obs, step) -> actions``: seeded uniform random actions, or a registered rule
    (with its SB3-style state kept here and ``episode_start`` at step 0)."""
    if name == "random":
        rng = np.random.default_rng(seed + 1)
        return lambda obs, k: rng.uniform(-1.0, 1.0, env.action_space.shape).astype(np.float32)
    rule = rules_for(env_id, env.params, lambda: env.simulator_state)[name]
    memory: list[Any] = [None]

    def act(obs: Any, k: int) -> Any:
        start = np.full(env.num_envs, k == 0)
        action, memory[0] = rule.predict(obs, memory[0], episode_start=start)
        return action

    return act


def bearings_nees(state: Any) -> dict[str, FloatArray]:
    """Joint, position and velocity NEES ``(B,)`` of the bank's moment-matched estimate
    (theory §7.9) against the true target state."""
    est = state.estimate
    e = est.x - state.target
    out = {}
    for part, block in PARTS.items():
        b = slice(None) if block is None else block
        eb, Pb = e[:, b], est.P[:, b, b]
        out[part] = np.einsum("bi,bi->b", eb, np.linalg.solve(Pb, eb[..., None])[..., 0])
    return out


def track_drones(state: Any, params: Any, drone: NDArray[np.int64]) -> None:
    """Update ``drone (B, T)``, the drone whose fixes a track row's latest members all are
    (−1: some is another drone's or false), for every row updated in the last period (the
    others keep theirs). A triple's solution passes exactly through its three fixes' rays at
    their times (``n = 3``): each receiver's member is the fix whose ray the track's position
    at that fix's time lies on (to 1e-7 in direction; no match: −1)."""
    updated = state.track_t >= state.t[:, None] - params.period - 1e-9
    fresh = (state.track_int[..., 2] > 0) & updated
    b, q = np.nonzero(fresh)
    if b.size == 0:
        return
    x, t1 = state.track_x[b, q], state.track_t[b, q]
    O = params.receivers[:3]
    fw, ft = state.fix_world[b, :3], state.fix_time[b, :3]  # (S, 3, F, 3), (S, 3, F)
    valid = np.arange(fw.shape[2]) < state.fix_count[b, :3, None]
    d = x[:, None, None, :3] + x[:, None, None, 3:] * (ft - t1[:, None, None])[..., None]
    d = d - O[None, :, None]
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    on_ray = valid & (np.linalg.norm(d - fw, axis=-1) < 1e-7)
    idx = on_ray.argmax(-1)  # (S, 3) the member of each receiver
    of = state.fix_drone[b[:, None], np.arange(3)[None], idx]
    own = on_ray.any(-1).all(-1) & (of >= 0).all(-1) & (of == of[:, :1]).all(-1)
    drone[b, q] = np.where(own, of[:, 0], -1)


def scanning_nees(
    state: Any, period: float, drone: NDArray[np.int64] | None = None
) -> tuple[dict[str, FloatArray], NDArray[np.int64]]:
    """Position, velocity and joint NEES (``d ‖e‖²/σ²``, see the module doc) of every drone
    with an assigned confirmed track, at the time the reward compares them (theory §11.5),
    and the scenario of each sample; with ``drone`` (:func:`track_drones`) also each part per
    association class (:data:`CLASSES`; NaN where a sample is of the other class)."""
    b, j = np.nonzero(state.assigned >= 0)
    q = state.assigned[b, j]
    t_track = state.track_t[b, q]
    t_end = state.t[b]
    # the track's own time if it was updated in the period, else the period end
    fresh = t_track >= t_end - period - 1e-9
    t_cmp = np.where(fresh, t_track, t_end)
    lag = t_cmp - t_track
    x = state.track_x[b, q]
    sigma = state.track_sigma[b, q]
    p_hat = x[:, :3] + x[:, 3:] * lag[:, None]
    # truth at t_cmp from the period end: constant acceleration, exact
    u = (t_cmp - t_end)[:, None]
    acc = state.drone_acceleration[b, j]
    p_true = state.drone_position[b, j] + state.drone_velocity[b, j] * u + 0.5 * acc * u * u
    v_true = state.drone_velocity[b, j] + acc * u
    var_pos = sigma[:, 0] ** 2 + (sigma[:, 1] * lag) ** 2
    pos = 3.0 * np.sum((p_hat - p_true) ** 2, axis=1) / var_pos
    vel = 3.0 * np.sum((x[:, 3:] - v_true) ** 2, axis=1) / sigma[:, 1] ** 2
    out = {"joint": pos + vel, "position": pos, "velocity": vel}
    if drone is not None:
        own = drone[b, q] == j
        classes = (own, ~own, own & fresh, own & ~fresh)
        for c, keep in zip(CLASSES, classes, strict=True):
            # NaN outside the class: every part keeps one entry per sample (and row)
            out |= {f"{c} {p}": np.where(keep, out[p], np.nan) for p in PARTS}
    return out, b


def run(
    env_id: str, policy: str, scenarios: int, seed: int
) -> tuple[Samples, dict[str, FloatArray]]:
    """Every step's NEES samples of one env under one policy, and those of each scenario's
    end (StereoScanning: its last period with a tracked drone)."""
    env = gym.make_vec(env_id, num_envs=scenarios, vectorization_mode="vector_entry_point")
    obs, _ = env.reset(seed=seed)
    act = _policy(env_id, policy, env, seed)
    live = np.ones(scenarios, dtype=bool)
    bearings = env_id == BEARINGS
    # step 0 is the reset (StereoScanning has no track yet)
    empty = {p: np.empty(0) for p in (PARTS if bearings else SCANNING_PARTS)}
    steps: Samples = [bearings_nees(env.simulator_state) if bearings else empty]
    last_bearings = steps[0] if bearings else {}
    last_scanning: dict[int, dict[str, FloatArray]] = {}  # scenario → its latest samples
    drone = np.full(env.simulator_state.track_int.shape[:2], -1) if not bearings else None
    k = 0
    while live.any():
        obs, _, terminated, truncated, _ = env.step(act(obs, k))
        k += 1
        state = env.simulator_state
        if bearings:
            nees = bearings_nees(state)
            steps.append({p: v[live] for p, v in nees.items()})
            last_bearings = {p: np.where(live, nees[p], last_bearings[p]) for p in PARTS}
        else:
            track_drones(state, env.params, drone)
            nees, rows = scanning_nees(state, env.params.period, drone)
            keep = live[rows]
            nees, rows = {p: v[keep] for p, v in nees.items()}, rows[keep]
            steps.append({p: v[~np.isnan(v)] for p, v in nees.items()})
            for s in np.unique(rows):
                last_scanning[int(s)] = {p: v[rows == s] for p, v in nees.items()}
        # NEXT_STEP autoreset: a scenario's episode is over once it terminates or truncates
        live &= ~(terminated | truncated)
    env.close()
    if bearings:
        return steps, last_bearings
    end = {p: np.concatenate([v[p] for v in last_scanning.values()]) for p in SCANNING_PARTS}
    return steps, {p: v[~np.isnan(v)] for p, v in end.items()}


def dimension(env_id: str, part: str) -> int:
    """``d`` of a part: 4/2/2 (BearingsManeuver), 6/3/3 (StereoScanning)."""
    if env_id == BEARINGS:
        return 4 if part == "joint" else 2
    return 6 if part.endswith("joint") else 3


#: ``--env`` names
ENVS = {"BearingsManeuver": BEARINGS, "StereoScanning": SCANNING}


def measure(
    scenarios: int, seed: int, envs: tuple[str, ...] = tuple(POLICIES)
) -> list[dict[str, Any]]:
    """One record per env (of ``envs``, ids) and policy: the per-step and the end summaries of
    every part."""
    records = []
    for env_id in envs:
        for policy in POLICIES[env_id]:
            steps, end = run(env_id, policy, scenarios, seed)
            first = (
                0 if env_id == BEARINGS else next(i for i, s in enumerate(steps) if s["joint"].size)
            )
            mid = (first + len(steps) - 1) // 2 if env_id == SCANNING else (len(steps) - 1) // 2
            parts = PARTS if env_id == BEARINGS else SCANNING_PARTS
            per_step = [{p: summary(s[p], dimension(env_id, p)) for p in parts} for s in steps]
            records.append(
                {
                    "env": env_id,
                    "policy": policy,
                    "scenarios": scenarios,
                    "seed": seed,
                    "first_step": first,
                    "mid_step": mid,
                    "steps": per_step,
                    "end": {p: summary(end[p], dimension(env_id, p)) for p in parts},
                }
            )
    return records


def table(records: list[dict[str, Any]], title: str) -> Table:
    """Reset/first, middle and end rows of every env, policy and part."""
    t = Table(title=title)
    for col in ("env", "policy", "part, d", "when", "N", "mean NEES", "95 % band", "in", "> q99"):
        t.add_column(
            col, justify="left" if col in ("env", "policy", "part, d", "when") else "right"
        )
    for r in records:
        short = (
            r["env"].split("/")[1].removesuffix("-v0").replace("Maneuver", "").replace("Stereo", "")
        )
        first = "reset" if r["env"] == BEARINGS else f"step {r['first_step']}"
        when = (
            (first, r["steps"][r["first_step"]]),
            (f"step {r['mid_step']}", r["steps"][r["mid_step"]]),
            ("end", r["end"]),
        )
        shown = (*PARTS, *(f"{c} joint" for c in CLASSES)) if r["env"] == SCANNING else PARTS
        for part in shown:
            for label, row in when:
                s = row[part]
                if not s["n"]:
                    continue
                t.add_row(
                    short,
                    r["policy"],
                    f"{part} {s['d']}",
                    label,
                    f"{s['n']:,}",
                    f"{s['mean']:.2f}",
                    f"{s['band'][0]:.2f}–{s['band'][1]:.2f}",
                    "yes" if s["in_band"] else "[bold red]no[/]",
                    f"{100 * s['above_q99']:.1f} %",
                )
        t.add_section()
    return t


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenarios", type=int, default=2_000, help="scenarios per env/policy")
    parser.add_argument("--seed", type=int, default=0, help="env reset seed (and random actions)")
    parser.add_argument(
        "--env", choices=sorted(ENVS), default=None, help="measure this env only (default: both)"
    )
    parser.add_argument("--out", type=Path, default=RESULTS / "nees.json")
    args = parser.parse_args()
    envs = tuple(POLICIES) if args.env is None else (ENVS[args.env],)
    records = measure(args.scenarios, args.seed, envs)
    Console(width=120).print(table(records, __doc__.splitlines()[0]))
    write_results(args.out, records, scenarios=args.scenarios, seed=args.seed)


if __name__ == "__main__":
    main()
