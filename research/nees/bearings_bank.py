"""Why BearingsManeuver's bank over-claims at the episode end: its member update, re-run offline.

``benchmarks/nees.py`` measures the NEES of ``sensorgym/BearingsManeuver-v0``'s range-
parameterised EKF bank (theory §7.9, §11.2): consistent at reset, 4.3–5.3 (4 expected) at the
episode end. This probe records, per policy, ``--scenarios`` seeded episodes from the vector
env (the bearings, the platform positions, the true target, the bank at reset and the env's own
estimate) and re-runs the bank on the same bearings with other member updates and banks:

* ``EKF`` — the env's update in numpy (Joseph form, theory §7.9):
  ``ν = wrap(z − β(x)), S = max(H P Hᵀ, 0) + σ², K = P Hᵀ/S, P⁺ = (I−KH) P (I−KH)ᵀ + σ² K Kᵀ``;
  checked against the env's estimate on the same bearings (the ``agreement`` rows).
* ``EKF2`` — the Gaussian second-order filter (Bar-Shalom, Li & Kirubarajan 2001, §10.3):
  the bearing's curvature ``B = ∂²β/∂p²`` (``β = atan2(Δx, Δy)``, ``r⁴ B = [[−2ΔxΔy,
  Δx² − Δy²], [Δx² − Δy², 2ΔxΔy]]``) adds ``½ tr(B P_pp)`` to the predicted bearing and
  ``½ tr(B P_pp B P_pp)`` to ``S``; ``P⁺ = P − K S Kᵀ``.
* ``CKF`` — the cubature update (Arasaratnam & Haykin 2009; theory §7.9), ``2n`` points
  ``x ± √n L eᵢ``, in numpy as the package's; checked against the public
  ``range_bank_update(component="ckf")``.

Member weights follow ``log wᵢ += log N(νᵢ; 0, Sᵢ)`` and the output is the moment-matched mixture
in every variant. Banks: the env's 8 range members and 16/32/64 (``range_bank_prior``, the env's
prior, theory §11.2), and a bank split by course too (``R×C``: ``C`` course sectors of width
``2π/C`` about ``z₀``, each a uniform course prior, weight ``1/C``, times ``R`` range members).

Two sources with no env in them isolate what is left: ``prior/straight`` and ``prior/turn``
draw the truth from the filter's own prior (a member by its weight, then its Gaussian), so an
exact Bayesian filter's NEES would average exactly 4 (``E[eᵀP⁻¹e] = tr(P⁻¹P)``); the platform
flies straight, or turns 90° at step 10.

NEES is taken at each scenario's end (step 30, or the step that brought the platform within
``min_range``), as ``benchmarks/nees.py``'s "end" rows. Run:
``.venv/bin/python research/nees/bearings_bank.py [--scenarios 2000] [--seed 0]``; writes
``research/nees/results/bearings_bank.json``.
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

from sensorgym.trackers.bearings.filters import (
    RangeBankState,
    range_bank_prior,
    range_bank_update,
)
from sensorgym.trackers.bearings.models import BearingsGaussian

ENV = "sensorgym/BearingsManeuver-v0"
POLICIES = ("random", "straight-course", "greedy-information")
# (label, update, range members, course sectors)
FILTERS = (
    ("EKF 8", "ekf", 8, 1),
    ("EKF2 8", "ekf2", 8, 1),
    ("CKF 8", "ckf", 8, 1),
    ("EKF 16", "ekf", 16, 1),
    ("EKF 32", "ekf", 32, 1),
    ("EKF 64", "ekf", 64, 1),
    ("CKF 16", "ckf", 16, 1),
    ("CKF 32", "ckf", 32, 1),
    ("CKF 64", "ckf", 64, 1),
    ("EKF 8×4", "ekf", 8, 4),
    ("CKF 8×4", "ckf", 8, 4),
)
PARTS = {"joint": slice(0, 4), "position": slice(0, 2), "velocity": slice(2, 4)}


def wrap(a: FloatArray) -> FloatArray:
    return (a + np.pi) % (2.0 * np.pi) - np.pi


def record(name: str, scenarios: int, seed: int) -> dict[str, Any]:
    """One seeded batch of episodes under a policy: bearings ``z (B, 31)``, platform ``pos
    (B, 31, 2)``, truth ``target (B, 31, 4)``, the bank at reset, each scenario's last step and
    the env's estimate there (``benchmarks/nees.py`` with the same seed sees the same)."""
    env = gym.make_vec(ENV, num_envs=scenarios, vectorization_mode="vector_entry_point")
    obs, _ = env.reset(seed=seed)
    p = env.params
    if p.platforms != 1 or p.world.q_tilde != 0.0:
        raise SystemExit("the probe replays one platform and a constant-velocity target")
    act = policy(ENV, name, env, seed)
    s = env.simulator_state
    bank0 = (s.bank.log_weights.copy(), s.bank.members.x.copy(), s.bank.members.P.copy())
    z, pos, target = [s.bearing[:, 0].copy()], [s.platform_position[:, 0].copy()], [s.target.copy()]
    est_x, est_P = s.estimate.x.copy(), s.estimate.P.copy()
    last = np.zeros(scenarios, dtype=int)
    live = np.ones(scenarios, dtype=bool)
    k = 0
    while live.any():
        obs, _, terminated, truncated, _ = env.step(act(obs, k))
        k += 1
        s = env.simulator_state
        # after its end a scenario's row holds the next episode (autoreset): keep the last values
        z.append(np.where(live, s.bearing[:, 0], z[-1]))
        pos.append(np.where(live[:, None], s.platform_position[:, 0], pos[-1]))
        target.append(np.where(live[:, None], s.target, target[-1]))
        est = s.estimate
        est_x = np.where(live[:, None], est.x, est_x)
        est_P = np.where(live[:, None, None], est.P, est_P)
        last = np.where(live, k, last)
        live &= ~(terminated | truncated)
    env.close()
    return {
        "params": p,
        "z": np.stack(z, 1),
        "pos": np.stack(pos, 1),
        "target": np.stack(target, 1),
        "bank0": bank0,
        "last": last,
        "env_x": est_x,
        "env_P": est_P,
    }


def bank(p: Any, z0: FloatArray, p0: FloatArray, ranges: int, courses: int) -> tuple:
    """The env's prior from the first bearing (theory §11.2: range uniform over the prior
    ranges, course uniform, speed moments of the generator), as ``ranges × courses`` members."""
    speed_mean, speed_sigma = p.prior_speed_moments
    lo, hi = p.prior_ranges
    parts = []
    for j in range(courses):
        b = range_bank_prior(
            z0, p.world.sigma_bearing, p0, 0.0, range_min=lo, range_max=hi, n_members=ranges,
            speed_mean=speed_mean, speed_sigma=speed_sigma,
            course_mean=z0 + 2.0 * np.pi * (j + 0.5) / courses,
            course_sigma=np.pi / courses / np.sqrt(3.0),  # a uniform sector's σ
            course_distribution="uniform", range_density="uniform",
        )  # fmt: skip
        parts.append((b.log_weights - np.log(courses), b.members.x, b.members.P))
    return tuple(np.concatenate(a, axis=1) for a in zip(*parts, strict=True))


def member_update(
    X: FloatArray, P: FloatArray, z: FloatArray, p: FloatArray, sigma: float, mode: str
):
    """Every member ``(B, N)`` updated with bearing ``z (B,)`` from ``p (B, 2)``; returns the
    updated ``X``, ``P`` and the innovation ``ν``, its variance ``S`` (the weights' likelihood)."""
    p = p[:, None, :]
    if mode == "ckf":
        n = 4
        jitter = 1e-9 * np.abs(P).max()  # as the package's ckf_update
        L = np.linalg.cholesky(P + jitter * np.eye(n))
        pts = X[..., None, :] + np.sqrt(n) * np.concatenate([L.mT, -L.mT], -2)  # (B, N, 2n, 4)
        z0 = np.arctan2(X[..., 0] - p[..., 0], X[..., 1] - p[..., 1])
        dz = wrap(
            np.arctan2(pts[..., 0] - p[..., None, 0], pts[..., 1] - p[..., None, 1]) - z0[..., None]
        )
        zhat = z0 + dz.mean(-1)
        dz = dz - dz.mean(-1, keepdims=True)
        S = (dz**2).mean(-1) + sigma**2
        K = np.einsum("...ki,...k->...i", pts - X[..., None, :], dz) / (2 * n) / S[..., None]
        nu = wrap(z[:, None] - zhat)
        return (
            X + K * nu[..., None],
            P - S[..., None, None] * K[..., :, None] * K[..., None, :],
            nu,
            S,
        )
    dx, dy = X[..., 0] - p[..., 0], X[..., 1] - p[..., 1]
    r2 = dx * dx + dy * dy
    H = np.zeros(X.shape)
    H[..., 0], H[..., 1] = dy / r2, -dx / r2
    PH = np.einsum("...ij,...j->...i", P, H)
    S = np.maximum(np.einsum("...i,...i->...", H, PH), 0.0) + sigma**2
    zhat = np.arctan2(dx, dy)
    if mode == "ekf2":
        B = np.stack(
            [
                np.stack([-2 * dx * dy, dx * dx - dy * dy], -1),
                np.stack([dx * dx - dy * dy, 2 * dx * dy], -1),
            ],
            -2,
        )
        BP = B / (r2 * r2)[..., None, None] @ P[..., :2, :2]
        zhat = zhat + 0.5 * np.trace(BP, axis1=-2, axis2=-1)
        S = S + 0.5 * np.einsum("...ij,...ji->...", BP, BP)
    K = PH / S[..., None]
    nu = wrap(z[:, None] - zhat)
    X = X + K * nu[..., None]
    if mode == "ekf2":
        P = P - S[..., None, None] * K[..., :, None] * K[..., None, :]
    else:  # Joseph form
        A = np.eye(4) - K[..., :, None] * H[..., None, :]
        P = A @ P @ A.mT + sigma**2 * K[..., :, None] * K[..., None, :]
    return X, 0.5 * (P + P.mT), nu, S


def public_update(lw, X, P, z, p, sigma, component):
    """The package's own bank update (``range_bank_update``) in the replay's terms."""
    b = range_bank_update(RangeBankState(lw, BearingsGaussian(X, P, 0.0)), z, p, sigma, component)
    return b.log_weights, b.members.x, b.members.P


def replay(rec: dict[str, Any], start: tuple, mode: str, public: bool = False) -> tuple:
    """The bank from ``start`` over the recorded bearings, each scenario frozen after its last
    step; returns the moment-matched ``(x, P)`` at each scenario's end."""
    p = rec["params"]
    dt, sigma = p.world.dt, p.world.sigma_bearing
    F = np.eye(4)
    F[0, 2] = F[1, 3] = dt
    lw, X, P = (a.copy() for a in start)
    for k in range(1, rec["z"].shape[1]):
        Xp, Pp = X @ F.T, F @ P @ F.T  # constant velocity, q̃ = 0
        z, pk = rec["z"][:, k], rec["pos"][:, k]
        if public:
            lw2, X2, P2 = public_update(lw, Xp, Pp, z, pk, sigma, mode)
        else:
            X2, P2, nu, S = member_update(Xp, Pp, z, pk, sigma, mode)
            lw2 = lw - 0.5 * (nu**2 / S + np.log(2 * np.pi * S))
            lw2 = lw2 - lw2.max(-1, keepdims=True)
            lw2 = lw2 - np.log(np.exp(lw2).sum(-1, keepdims=True))
        on = k <= rec["last"]
        lw = np.where(on[:, None], lw2, lw)
        X = np.where(on[:, None, None], X2, X)
        P = np.where(on[:, None, None, None], P2, P)
    w = np.exp(lw)
    x = np.einsum("bn,bni->bi", w, X)
    d = X - x[:, None]
    return x, np.einsum("bn,bnij->bij", w, P + d[..., :, None] * d[..., None, :])


def end_nees(rec: dict[str, Any], x: FloatArray, P: FloatArray) -> dict[str, Any]:
    truth = rec["target"][np.arange(len(x)), rec["last"]]
    return {
        part: summary(quadratic((x - truth)[:, b], P[:, b, b]), b.stop - b.start)
        for part, b in PARTS.items()
    }


def prior_scenarios(p: Any, scenarios: int, rng: np.random.Generator, turn: bool) -> dict[str, Any]:
    """Truth drawn from the filter's own 8-member prior given ``z₀``; the platform (5 m/s, random
    heading) flies straight, or turns 90° to starboard at step 10; 30 steps of ``dt``."""
    K, dt = 30, p.world.dt
    z0 = rng.uniform(-np.pi, np.pi, scenarios)
    start = bank(p, z0, np.zeros((scenarios, 2)), p.bank_members, 1)
    lw, X0, P0 = start
    i = (rng.random(scenarios)[:, None] > np.cumsum(np.exp(lw), 1)).sum(1)
    b = np.arange(scenarios)
    L = np.linalg.cholesky(
        P0[b, i] + 1e-9 * np.eye(4) * np.abs(P0[b, i]).max((1, 2), keepdims=True)
    )
    x0 = X0[b, i] + np.einsum("bij,bj->bi", L, rng.standard_normal((scenarios, 4)))
    steps = np.arange(K + 1)[None, :, None]
    target = x0[:, None, :] + steps * dt * np.concatenate([x0[:, 2:], 0 * x0[:, 2:]], 1)[:, None, :]
    h = rng.uniform(-np.pi, np.pi, scenarios)
    v = 5.0 * np.stack([np.sin(h), np.cos(h)], -1)[:, None, :]
    pos = steps * dt * v
    if turn:
        v2 = np.stack([v[..., 1], -v[..., 0]], -1)
        pos = np.where(steps > 10, pos[:, 10:11] + (steps - 10) * dt * v2, pos)
    d = target[..., :2] - pos
    z = np.arctan2(d[..., 0], d[..., 1]) + p.world.sigma_bearing * rng.standard_normal(
        (scenarios, K + 1)
    )
    z[:, 0] = z0
    close = np.hypot(d[..., 0], d[..., 1]) < p.min_range
    last = np.where(close.any(1), close.argmax(1), K)
    return {"params": p, "z": z, "pos": pos, "target": target, "bank0": start, "last": last}


def agreement(rec: dict[str, Any]) -> dict[str, float]:
    """How closely the numpy replay reproduces the env (EKF) and the package (CKF)."""
    p = rec["params"]
    z0, p0 = rec["z"][:, 0], rec["pos"][:, 0]
    rebuilt = bank(p, z0, p0, p.bank_members, 1)
    rel = lambda a, b: float(np.max(np.abs(a - b)) / np.max(np.abs(b)))  # noqa: E731
    x, P = replay(rec, rec["bank0"], "ekf")
    xc, Pc = replay(rec, rec["bank0"], "ckf")
    xp, Pp = replay(rec, rec["bank0"], "ckf", public=True)
    env = end_nees(rec, rec["env_x"], rec["env_P"])["joint"]["mean"]
    return {
        "prior_rebuilt_vs_env_rel": max(
            rel(a, b) for a, b in zip(rebuilt, rec["bank0"], strict=True)
        ),
        "ekf_vs_env_x_rel": rel(x, rec["env_x"]),
        "ekf_vs_env_P_rel": rel(P, rec["env_P"]),
        "ekf_vs_env_mean_nees_diff": abs(end_nees(rec, x, P)["joint"]["mean"] - env),
        "ckf_vs_public_x_rel": rel(xc, xp),
        "ckf_vs_public_P_rel": rel(Pc, Pp),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenarios", type=int, default=2_000, help="scenarios per source")
    parser.add_argument("--seed", type=int, default=0, help="env reset seed (random actions: +1)")
    parser.add_argument("--out", type=Path, default=RESULTS / "bearings_bank.json")
    args = parser.parse_args()
    t0 = time.perf_counter()
    results: list[dict[str, Any]] = []
    rng = np.random.default_rng(args.seed)
    sources: list[tuple[str, Any]] = [(name, None) for name in POLICIES]
    sources += [("prior/straight", False), ("prior/turn", True)]
    for name, turn in sources:
        if turn is None:
            rec = record(name, args.scenarios, args.seed)
            params = rec["params"]
            out = {"env EKF 8": end_nees(rec, rec["env_x"], rec["env_P"])}
            agree = agreement(rec)
        else:
            rec, agree = prior_scenarios(params, args.scenarios, rng, turn), None
            out = {}
        z0, p0 = rec["z"][:, 0], rec["pos"][:, 0]
        for label, mode, ranges, courses in FILTERS:
            start = (
                rec["bank0"]
                if (ranges, courses) == (8, 1)
                else bank(params, z0, p0, ranges, courses)
            )
            out[label] = end_nees(rec, *replay(rec, start, mode))
        results.append({"source": name, "agreement": agree, "end": out})
        print(f"{name}: {time.perf_counter() - t0:.0f} s", flush=True)
    console = Console(width=130)
    title = f"BearingsManeuver end-of-episode NEES, joint d = 4: mean (share > χ²₄ 99 %), {args.scenarios:,} scenarios each"
    t = Table(title=title)
    t.add_column("filter")
    for r in results:
        t.add_column(r["source"], justify="right")
    for label in ("env EKF 8", *(f[0] for f in FILTERS)):
        t.add_row(
            label, *(cell(r["end"][label]["joint"]) if label in r["end"] else "–" for r in results)
        )
    console.print(t)
    band = results[0]["end"]["CKF 8"]["joint"]["band"]
    console.print(
        f"95 % band of the mean at N = {args.scenarios:,}: {band[0]:.2f}–{band[1]:.2f} (red: outside)"
    )
    for r in results:
        if r["agreement"]:
            text = ", ".join(f"{k} {v:.1e}" for k, v in r["agreement"].items())
            console.print(f"agreement ({r['source']}): {text}")
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
