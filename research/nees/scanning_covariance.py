"""StereoScanning's n = 3 covariance against the exact first-order one, and the NEES under each.

The scanning tracker (theory §5.3, §11.5) gives each track the latest ``n = 3`` velocity-aware
solution ``X = (r_1, r_2, r_3, V)`` of ``A X = B`` (theory §3.3, §3.5; world frame, block
``k = 2, 3``: ``r_1 a_1 − r_k a_k + V Δt_k = O_k − O_1``, ``M = O_1 + r_1 a_1`` at ``t_1``) and
the scalar spreads of ``σ_e² (AᵀA)⁻¹`` (theory §3.4, §13.4): ``σ_e² = (1/3) Σ_k (σ_k r_k)²``,
``σ_pos² = σ_e² (Q_11 + 2)``, ``σ_vel² = σ_e² tr Q_VV``, ``Q = (AᵀA)⁻¹``. That takes the
conjugation errors of the blocks as i.i.d., while both blocks share receiver 1's error and each
error lies across its line of sight.

The exact first-order covariance: a fix's direction error is ``n_k ~ N(0, σ_k² (I − a_k a_kᵀ))``
(the env's ``a + σ (I − a aᵀ) z``, normalised), ``σ_k = max(κ w_k, σ_min)`` of the sector width
``w_k``. It moves block ``k`` by ``δA X = r_1 n_1 − r_k n_k``, so ``δX = −A⁻¹ D n`` and
``δM = a_1 δr_1 + r_1 n_1``: ``C = J Σ_n Jᵀ`` with ``J`` of ``(δM, δV)`` in ``n = (n_1, n_2, n_3)``.

For every drone with a confirmed track assigned (``state.assigned``) and updated in the period,
the probe finds the three fixes the track holds (its state lies exactly on each receiver's ray
at that fix's time), re-solves ``A X = B`` from them (must reproduce the track; the tracker's σ
recomputed must reproduce ``track_sigma``) and classes the sample: ``own`` — all three fixes are
of its drone; ``wrong`` — some fix is of another drone or false (an association error);
``unmatched`` — no fix triple reproduces the track. Per class it reports the ratios of the
exact variances to the tracker's, and the NEES against the truth at the track's time (constant
acceleration, exact): under the tracker's scalars read isotropically (``3‖e‖²/σ²`` per part, as
``benchmarks/nees.py``) and under ``C`` (``eᵀC⁻¹e``, 6-D and per part). ``accel`` is the NEES of
the noise-free solution's error (the true directions at the fix times): the unmodelled
acceleration alone. Samples are pooled over the first period with confirmed tracks, over each
scenario's last period with a sample (``end``; ``benchmarks/nees.py``'s end also counts tracks
not updated in that period, grown by ``σ_vel Δ``) and over all periods (``all``: a scenario
gives many correlated samples, so the band of the mean is narrower than it should be).

Run: ``.venv/bin/python research/nees/scanning_covariance.py [--scenarios 2000] [--seed 0]``;
writes ``research/nees/results/scanning_covariance.json``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from probe import RESULTS, FloatArray, cell, policy, quadratic, summary, write
from rich.console import Console
from rich.table import Table

ENV = "sensorgym/StereoScanning-v0"
POLICIES = ("random", "full-sweep", "cue-following")
CLASSES = ("own", "wrong", "unmatched")


def unit(v: FloatArray) -> FloatArray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def system(a: FloatArray, t: FloatArray, O: FloatArray) -> tuple[FloatArray, FloatArray]:
    """``A (S, 6, 6)`` and ``B (S, 6)`` of the triple with directions ``a (S, 3, 3)`` and fix
    times ``t (S, 3)`` (receivers 1–3 at ``O``)."""
    S = a.shape[0]
    A, B = np.zeros((S, 6, 6)), np.zeros((S, 6))
    for k in (1, 2):
        rows = slice(3 * (k - 1), 3 * k)
        A[:, rows, 0] = a[:, 0]
        A[:, rows, k] = -a[:, k]
        A[:, rows, 3:] = np.eye(3) * (t[:, k] - t[:, 0])[:, None, None]
        B[:, rows] = O[k] - O[0]
    return A, B


def state_of(
    A: FloatArray, B: FloatArray, a1: FloatArray, O1: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """``(M, V)`` as ``(S, 6)`` and ``X = (r_1, r_2, r_3, V)``."""
    X = np.linalg.solve(A, B[..., None])[..., 0]
    return np.concatenate([O1 + X[:, :1] * a1, X[:, 3:]], 1), X


def exact_covariance(A: FloatArray, X: FloatArray, a: FloatArray, sig: FloatArray) -> FloatArray:
    """``C (S, 6, 6)`` of ``(M, V)`` to first order in the direction errors (module doc)."""
    S = A.shape[0]
    I3 = np.broadcast_to(np.eye(3), (S, 3, 3))
    D = np.zeros((S, 6, 9))
    for k in (1, 2):
        rows = slice(3 * (k - 1), 3 * k)
        D[:, rows, 0:3] = X[:, 0, None, None] * I3
        D[:, rows, 3 * k : 3 * k + 3] = -X[:, k, None, None] * I3
    dX = -np.linalg.solve(A, D)  # (S, 6, 9): δX = dX n
    J = np.zeros((S, 6, 9))
    J[:, :3] = a[:, 0, :, None] * dX[:, None, 0]
    J[:, :3, 0:3] += X[:, 0, None, None] * I3
    J[:, 3:] = dX[:, 3:]
    Sn = np.zeros((S, 9, 9))
    for k in range(3):
        Sn[:, 3 * k : 3 * k + 3, 3 * k : 3 * k + 3] = sig[:, k, None, None] ** 2 * (
            I3 - a[:, k, :, None] * a[:, k, None, :]
        )
    return J @ Sn @ J.mT


def difference_check(
    a: FloatArray, t: FloatArray, O: FloatArray, sig: FloatArray, C: FloatArray
) -> float:
    """Largest relative difference of ``C`` from central differences of the solve (step 1e-6 rad
    along two directions across each line of sight)."""
    J = []
    for k in range(3):
        e1 = unit(np.cross(a[:, k], [0.0, 1.0, 0.0]))
        for u in (e1, np.cross(a[:, k], e1)):
            plus, minus = a.copy(), a.copy()
            plus[:, k], minus[:, k] = unit(a[:, k] + 1e-6 * u), unit(a[:, k] - 1e-6 * u)
            xp = state_of(*system(plus, t, O), plus[:, 0], O[0])[0]
            xm = state_of(*system(minus, t, O), minus[:, 0], O[0])[0]
            J.append((xp - xm) / 2e-6 * sig[:, k, None])
    J = np.stack(J, -1)
    Cd = J @ J.mT
    return float(np.max(np.abs(Cd - C) / np.abs(C).max((1, 2), keepdims=True)))


def tracker_sigmas(A: FloatArray, X: FloatArray, sig: FloatArray) -> FloatArray:
    """``(σ_pos, σ_vel)`` of ``σ_e² (AᵀA)⁻¹`` (theory §3.4, §13.4; module doc)."""
    Q = np.linalg.inv(A.mT @ A)
    se2 = np.mean((sig * X[:, :3]) ** 2, axis=1)
    return np.sqrt(
        se2[:, None] * np.stack([Q[:, 0, 0] + 2.0, np.trace(Q[:, 3:, 3:], axis1=1, axis2=2)], 1)
    )


def samples(env: Any, live: FloatArray) -> dict[str, FloatArray] | None:
    """Every fresh assigned confirmed track of a live scenario: its class, the error, the
    tracker's and the exact spreads (module doc)."""
    s, p = env.simulator_state, env.params
    O = p.receivers
    b, j = np.nonzero((s.assigned >= 0) & live[:, None])
    q = s.assigned[b, j]
    fresh = s.track_t[b, q] >= s.t[b] - p.period - 1e-9
    b, j, q = b[fresh], j[fresh], q[fresh]
    if b.size == 0:
        return None
    x, t1 = s.track_x[b, q], s.track_t[b, q]
    fw, ft = s.fix_world[b, :3], s.fix_time[b, :3]  # (S, 3, F, 3), (S, 3, F)
    valid = np.arange(fw.shape[2]) < s.fix_count[b, :3, None]
    # the track's position at each fix's time lies on that fix's ray (exact for n = 3)
    along = unit(
        x[:, None, None, :3]
        + x[:, None, None, 3:] * (ft - t1[:, None, None])[..., None]
        - O[None, :3, None]
    )
    on_ray = valid & (np.linalg.norm(along - fw, axis=-1) < 1e-7)
    matched = on_ray.sum(-1).min(-1) >= 1
    idx = on_ray.argmax(-1)  # (S, 3) the fix of each receiver
    rows = np.arange(b.size)[:, None], np.arange(3)[None]
    a, tf = fw[(*rows, idx)], ft[(*rows, idx)]
    a[~matched], tf[~matched] = np.eye(3), np.array([0.0, 0.25, 0.5])  # placeholders
    A, B = system(a, tf, O)
    x_solved, X = state_of(A, B, a[:, 0], O[0])
    reproduced = matched & (np.abs(x_solved - x).max(1) <= 1e-6 * (1.0 + np.abs(x).max(1)))
    own = (s.fix_drone[b[:, None], np.arange(3)[None], idx] == j[:, None]).all(1)
    klass = np.where(~reproduced, 2, np.where(own, 0, 1))
    sig = np.maximum(p.noise_per_width * s.sectors[b, :3, 2], p.sigma_ang_min)
    C = exact_covariance(A, X, a, sig)
    # truth at the track's time and at the fix times (constant acceleration from the period end)
    pos, vel, acc = s.drone_position[b, j], s.drone_velocity[b, j], s.drone_acceleration[b, j]
    u = (t1 - s.t[b])[:, None]
    truth = np.concatenate([pos + vel * u + 0.5 * acc * u * u, vel + acc * u], 1)
    uk = (tf - s.t[b][:, None])[..., None]
    a_true = unit(pos[:, None] + vel[:, None] * uk + 0.5 * acc[:, None] * uk * uk - O[None, :3])
    A0, B0 = system(a_true, tf, O)
    return {
        "class": klass,
        "scenario": b,
        "e": x - truth,
        "bias": state_of(A0, B0, a_true[:, 0], O[0])[0] - truth,
        "sigma": s.track_sigma[b, q],
        "sigma_recomputed": tracker_sigmas(A, X, sig),
        "C": C,
        "a": a,
        "tf": tf,
        "sig": sig,
    }


def run(name: str, scenarios: int, seed: int) -> tuple[dict[str, FloatArray], int, Any]:
    """Pooled samples of one policy over every period, how many periods ran, the params."""
    env = gym.make_vec(ENV, num_envs=scenarios, vectorization_mode="vector_entry_point")
    p = env.params
    if p.n_receivers != 3 or p.tracker != "proposed" or p.position_sigma != 0.0:
        raise SystemExit("the probe covers the default: 3 receivers, proposed tracker, σ_x = 0")
    obs, _ = env.reset(seed=seed)
    act = policy(ENV, name, env, seed)
    live = np.ones(scenarios, dtype=bool)
    pooled: list[dict[str, FloatArray]] = []
    k = 0
    while live.any():
        obs, _, terminated, truncated, _ = env.step(act(obs, k))
        k += 1
        got = samples(env, live)
        if got is not None:
            got["period"] = np.full(got["class"].shape, k)
            pooled.append(got)
        live &= ~(terminated | truncated)
    env.close()
    return {key: np.concatenate([g[key] for g in pooled]) for key in pooled[0]}, k, p


def report(d: dict[str, FloatArray], sel: FloatArray) -> dict[str, Any]:
    """Ratios and NEES of the selected samples."""
    out: dict[str, Any] = {"n": int(sel.sum())}
    if not out["n"]:
        return out
    e, sg = d["e"][sel], d["sigma"][sel]
    ep2, ev2 = np.sum(e[:, :3] ** 2, 1), np.sum(e[:, 3:] ** 2, 1)
    tp, tv = 3 * ep2 / sg[:, 0] ** 2, 3 * ev2 / sg[:, 1] ** 2
    out["tracker"] = {
        "joint": summary(tp + tv, 6),
        "position": summary(tp, 3),
        "velocity": summary(tv, 3),
    }
    # C only where the track's triple was found (classes own, wrong)
    sel = sel & (d["class"] < 2)
    out["n_exact"] = int(sel.sum())
    if not out["n_exact"]:
        return out
    e, C, sg = d["e"][sel], d["C"][sel], d["sigma"][sel]
    tr_p, tr_v = np.trace(C[:, :3, :3], axis1=1, axis2=2), np.trace(C[:, 3:, 3:], axis1=1, axis2=2)
    out["exact_over_tracker_var_pos"] = float(np.mean(tr_p / sg[:, 0] ** 2))
    out["exact_over_tracker_var_vel"] = float(np.mean(tr_v / sg[:, 1] ** 2))
    ep2, ev2 = np.sum(e[:, :3] ** 2, 1), np.sum(e[:, 3:] ** 2, 1)
    out["exact_trace"] = {"joint": summary(3 * ep2 / tr_p + 3 * ev2 / tr_v, 6)}
    out["exact"] = {
        "joint": summary(quadratic(e, C), 6),
        "position": summary(quadratic(e[:, :3], C[:, :3, :3]), 3),
        "velocity": summary(quadratic(e[:, 3:], C[:, 3:, 3:]), 3),
    }
    out["accel_bias_nees_mean"] = float(np.mean(quadratic(d["bias"][sel], C)))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenarios", type=int, default=2_000, help="scenarios per policy")
    parser.add_argument("--seed", type=int, default=0, help="env reset seed (random actions: +1)")
    parser.add_argument("--out", type=Path, default=RESULTS / "scanning_covariance.json")
    args = parser.parse_args()
    t0 = time.perf_counter()
    results = []
    for name in POLICIES:
        d, periods, params = run(name, args.scenarios, args.seed)
        ok = d["class"] < 2
        agree = float(np.max(np.abs(d["sigma_recomputed"][ok] / d["sigma"][ok] - 1.0), initial=0.0))
        first = d["period"] == d["period"].min()
        # each scenario's last period with a sample (benchmarks/nees.py's "end", fresh tracks)
        latest = np.zeros(args.scenarios, dtype=int)
        np.maximum.at(latest, d["scenario"], d["period"])
        end = d["period"] == latest[d["scenario"]]
        i = np.flatnonzero(ok)[:500]
        fd = (
            difference_check(d["a"][i], d["tf"][i], params.receivers, d["sig"][i], d["C"][i])
            if i.size
            else float("nan")
        )
        rec: dict[str, Any] = {
            "policy": name,
            "periods": periods,
            "sigma_recomputed_max_rel_diff": agree,
            "exact_C_vs_differences_max_rel_diff": fd,
        }
        for when, w in (
            ("all periods", np.ones_like(first)),
            ("first period", first),
            ("end", end),
        ):
            rec[when] = {
                "all": report(d, w),
                **{c: report(d, w & (d["class"] == i)) for i, c in enumerate(CLASSES)},
            }
        rec["first_period"] = int(d["period"].min())
        results.append(rec)
        print(f"{name}: {time.perf_counter() - t0:.0f} s", flush=True)
    console = Console(width=175)
    t = Table(
        title=f"StereoScanning n = 3 tracks: the tracker's σ against the exact first-order C ({args.scenarios:,} scenarios per policy; NEES mean (share > χ² 99 %), red: mean outside its 95 % band)"
    )
    for col in (
        "policy",
        "when",
        "class",
        "N",
        "C/σ² pos",
        "C/σ² vel",
        "σ: 6-D",
        "σ: pos 3",
        "σ: vel 3",
        "C: 6-D",
        "C: pos 3",
        "C: vel 3",
        "accel",
    ):
        t.add_column(col, justify="left" if col in ("policy", "when", "class") else "right")
    for r in results:
        for when in ("first period", "end", "all periods"):
            label = {"first period": f"period {r['first_period']}", "all periods": "all"}.get(
                when, when
            )
            for c in ("all", *CLASSES):
                x = r[when][c]
                if not x["n"]:
                    continue
                if not x["n_exact"]:
                    t.add_row(
                        r["policy"],
                        label,
                        c,
                        f"{x['n']:,}",
                        "–",
                        "–",
                        cell(x["tracker"]["joint"]),
                        cell(x["tracker"]["position"]),
                        cell(x["tracker"]["velocity"]),
                    )
                    continue
                t.add_row(
                    r["policy"], label, c, f"{x['n']:,}",
                    f"{x['exact_over_tracker_var_pos']:.2f}", f"{x['exact_over_tracker_var_vel']:.2f}",
                    cell(x["tracker"]["joint"]), cell(x["tracker"]["position"]), cell(x["tracker"]["velocity"]),
                    cell(x["exact"]["joint"]), cell(x["exact"]["position"]), cell(x["exact"]["velocity"]),
                    f"{x['accel_bias_nees_mean']:.3f}",
                )  # fmt: skip
        t.add_section()
    console.print(t)
    for r in results:
        console.print(
            f"{r['policy']}: tracker σ recomputed from σ_e² (AᵀA)⁻¹ vs track_sigma, max rel diff "
            f"{r['sigma_recomputed_max_rel_diff']:.1e}; exact C vs central differences (500 samples) "
            f"{r['exact_C_vs_differences_max_rel_diff']:.1e}"
        )
    write(
        args.out,
        results,
        scenarios=args.scenarios,
        seed=args.seed,
        env=ENV,
        seconds=round(time.perf_counter() - t0),
    )


if __name__ == "__main__":
    main()
