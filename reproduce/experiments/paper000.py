"""Paper 000, Tables 1–2: alternative (n = 2) vs proposed (n = 3) tracking (theory §5.6–5.7).

Seeded Monte Carlo of the paper's scenario; the paper is silent on much of it (theory §5.6, gap
§13.15), and our choices are the fields of :class:`Scenario000`, printed with the tables:

* receivers on an arc of radius 120 m at azimuths 0°, 90°, 270° (receiver 1 at 0°, so both
  other lines of sight are orthogonal to it), at ground level, aimed at the objects' area
  40 m up (the elevation keeps the three lines of sight non-coplanar, theory §3.5);
* m objects start a few metres apart (uniform in a ±3 m cube, ≥ 2 m apart) around that point
  and fly close straight paths ("close trajectories"): a group direction uniformly random in
  3-D and a group speed uniform in ``speed`` — calibrated so the mean |a₁·V| gives Table 1's
  d_avg(Δt = 0.1) (theory §5.7: ≈ 12.5 m/s) — from which each object deviates by up to
  ``heading_spread_deg`` in direction and ``speed_jitter`` in relative speed;
* receiver k fixes every object ``Δt_k`` after receiver 1 (same delay for all objects);
* the papers' noise, σ_x = 0.1 m on each coordinate of the position vector M(i, j), realised in
  the world as one apparent-position error per object and period seen by every receiver
  (:class:`~sensorgym.envs.worlds.stereo.NoiseModel`);
* N = 5 periods of τ = 1 s; d = distance between each object's estimate in period N and its
  true position at that estimate's time; Pr_m = fraction of runs in which every object is
  identified (one-to-one) with a found track within 4 m (theory §5.7 hypothesis).
"""

from __future__ import annotations

from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass

import numpy as np

from sensorgym.envs.worlds.drones import GroupSpec, random_group
from sensorgym.envs.worlds.stereo import FixedDelay, NoiseModel, ReceiverLayout, simulate
from sensorgym.reproduce.experiments.reporting import format_checks, target_check
from sensorgym.trackers.stereo.association import match_tracks
from sensorgym.trackers.stereo.period_tracking import (
    AlternativeParams,
    ProposedParams,
    track_alternative,
    track_proposed,
)


@dataclass(frozen=True)
class Scenario000:
    """Scenario choices where paper 000 is silent (module docstring)."""

    radius: float = 120.0
    """Arc radius, m (ranges of order 100–200 m)."""
    altitude: float = 40.0
    """Height of the objects' starting area above the receivers, m."""
    speed: tuple[float, float] = (9.0, 36.0)
    """Uniform speed range of the objects, m/s."""
    spread: float = 3.0
    """Objects start in a cube of this half-width, m."""
    min_separation: float = 2.0
    """Minimum starting distance between objects, m."""
    heading_spread_deg: float = 5.0
    """Each object's direction lies within this cone around the group's, deg."""
    speed_jitter: float = 0.1
    """Each object's speed is the group's times 1 + U(−jitter, jitter)."""
    position_sigma: float = 0.1
    """σ_x, m (paper)."""
    periods: int = 5
    """N (paper)."""
    period: float = 1.0
    """τ, s (paper)."""
    gate: float = 4.0
    """Identification gate for Pr_m, m."""


#: (table, algorithm, m, delays Δt_2[, Δt_3], paper d_avg, paper σ_d, paper Pr_m)
CELLS = (
    ("1", "alternative", 1, (0.10,), 1.25, 0.89, 1.00),
    ("1", "alternative", 1, (0.25,), 3.10, 2.30, 0.71),
    ("1", "alternative", 2, (0.10,), 1.28, 1.03, 0.97),
    ("1", "alternative", 2, (0.25,), 3.30, 2.40, 0.60),
    ("2", "proposed", 1, (0.1, 0.2), 0.15, 0.07, 1.00),
    ("2", "proposed", 1, (0.3, 0.4), 0.15, 0.07, 1.00),
    ("2", "proposed", 2, (0.1, 0.2), 0.37, 0.95, 0.96),
    ("2", "proposed", 2, (0.3, 0.4), 0.55, 1.34, 0.95),
)


def run_cell(
    rng: np.random.Generator, sc: Scenario000, algorithm: str, m: int, delays: tuple, runs: int
) -> dict:
    """Monte Carlo of one table cell; returns d_avg, σ_d, Pr_m and the rate of m̂ = m."""
    n = 2 if algorithm == "alternative" else 3
    layout = ReceiverLayout.on_circle(
        sc.radius, [0.0, 90.0, 270.0][:n], aim=(0.0, sc.altitude, 0.0)
    )
    P, b = layout.relative
    timings = (FixedDelay(0.0), *(FixedDelay(d) for d in delays))
    spec = GroupSpec(
        centre=(0.0, sc.altitude, 0.0),
        spread=sc.spread,
        min_separation=sc.min_separation,
        speed=sc.speed,
        heading_spread_deg=sc.heading_spread_deg,
        speed_jitter=sc.speed_jitter,
    )
    noise = NoiseModel(position_sigma=sc.position_sigma)
    alt = AlternativeParams(position_sigma=sc.position_sigma, max_delay=max(delays))
    prop = ProposedParams(position_sigma=sc.position_sigma, period=sc.period)
    dists, found, exact = [], 0, 0
    for _ in range(runs):
        traj = random_group(rng, m, spec)
        periods, _ = simulate(rng, traj, layout, timings, sc.periods, sc.period, noise)
        if algorithm == "alternative":
            det = track_alternative(periods, P[0], b[0], alt)
        else:
            det = track_proposed(periods, P, b, prop)
        pos, _, t = det.latest()
        # truth of object i at the time of estimate k, in frame 1: (m, K, 3)
        truth = np.stack([traj.position(np.full(m, tk)) for tk in t], axis=1) if det.m_hat else None
        if truth is None:
            continue
        local = layout.to_frame1(truth)
        d = np.linalg.norm(local - pos[None], axis=-1)
        nearest = match_tracks(d, np.inf)
        ok = nearest >= 0
        dists.extend(d[np.flatnonzero(ok), nearest[ok]])
        found += bool(np.all(match_tracks(d, sc.gate) >= 0))
        exact += det.m_hat == m
    dists = np.asarray(dists)
    return {
        "d_avg": float(dists.mean()) if dists.size else float("nan"),
        "d_std": float(dists.std()) if dists.size else float("nan"),
        "pr_m": found / runs,
        "m_hat_exact": exact / runs,
    }


#: why the alternative's m = 2 cells differ (diagnosed from the runs)
_GHOSTS = (
    ": mis-associations — a ghost pair (receiver 1 on one object, receiver 2 on the other)"
    " of two objects a few metres apart on close paths passes ε_J and moves nearly"
    " consistently through δ, so some selected groups mix the objects (see the m̂ = m column)"
)


def table_cells(results: list[dict]) -> list[dict]:
    """Each cell of :data:`CELLS` with the paper's numbers beside ``results`` (ours, in order)."""
    return [
        {
            "table": table,
            "algorithm": alg,
            "m": m,
            "delays": list(delays),
            "paper": {"d_avg": pd, "d_std": ps, "pr_m": pp},
            "ours": ours,
        }
        for (table, alg, m, delays, pd, ps, pp), ours in zip(CELLS, results, strict=True)
    ]


def _by_key(cells: list[dict]) -> dict:
    return {(x["algorithm"], x["m"], tuple(x["delays"])): x["ours"] for x in cells}


def maxwell_checks(cells: list[dict]) -> list[dict]:
    """RT-2: the proposed algorithm at m = 1 gives the Maxwell band of d (theory §12)."""
    c = _by_key(cells)
    out = []
    for dl in ((0.1, 0.2), (0.3, 0.4)):
        o = c[("proposed", 1, dl)]
        ok = 0.14 <= o["d_avg"] <= 0.18 and 0.055 <= o["d_std"] <= 0.08
        out.append(
            target_check(
                "RT-2",
                f"proposed m=1 Δt={dl}: d_avg/σ_d in [0.14,0.18]/[0.055,0.08]",
                "0.15/0.07",
                f"{o['d_avg']:.3f}/{o['d_std']:.3f}",
                ok,
                "outside the Maxwell band",
            )
        )
    return out


def delay_ratio_checks(cells: list[dict], ghosts: str = "") -> list[dict]:
    """RT-3: the alternative algorithm's d_avg grows 2.5 ± 0.3 times from Δt 0.10 to 0.25;
    ``ghosts`` is added to the reason of a missed m = 2 row."""
    c = _by_key(cells)
    out = []
    for m, paper_ratio in ((1, 2.48), (2, 2.58)):
        r = c[("alternative", m, (0.25,))]["d_avg"] / c[("alternative", m, (0.10,))]["d_avg"]
        out.append(
            target_check(
                "RT-3",
                f"alternative m={m}: d_avg(0.25)/d_avg(0.10) = 2.5 ± 0.3",
                f"{paper_ratio:.2f}",
                f"{r:.2f}",
                abs(r - 2.5) <= 0.3,
                "ratio outside 2.2–2.8" + (ghosts if m == 2 else ""),
            )
        )
    return out


def detection_checks(cells: list[dict]) -> list[dict]:
    """RT-4: the alternative's Pr_m falls with the delay; the proposed one's stays ≥ 0.9."""
    c = _by_key(cells)
    out = []
    for m in (1, 2):
        lo, hi = c[("alternative", m, (0.10,))]["pr_m"], c[("alternative", m, (0.25,))]["pr_m"]
        out.append(
            target_check(
                "RT-4",
                f"alternative m={m}: Pr_m falls with Δt",
                "1.00→0.71" if m == 1 else "0.97→0.60",
                f"{lo:.2f}→{hi:.2f}",
                hi < lo,
                "no fall with delay",
            )
        )
    for key, o in c.items():
        if key[0] == "proposed":
            out.append(
                target_check(
                    "RT-4",
                    f"proposed m={key[1]} Δt={key[2]}: Pr_m ≥ 0.9",
                    "≥ 0.95",
                    f"{o['pr_m']:.3f}",
                    o["pr_m"] >= 0.9,
                    "detection probability below 0.9",
                )
            )
    return out


def _cell_job(job: tuple) -> dict:
    ss, scenario, alg, m, delays, runs = job
    return run_cell(np.random.default_rng(ss), scenario, alg, m, delays, runs)


def reproduce(
    runs: int = 1000, seed: int = 0, scenario: Scenario000 = Scenario000(), jobs: int = 1
) -> dict:
    """Run every cell of Tables 1–2 and evaluate RT-2..RT-5 (theory §12). Pure; no printing.

    Each cell draws from its own child of ``SeedSequence(seed)``, so results do not depend on
    ``jobs`` (worker processes).
    """
    seeds = np.random.SeedSequence(seed).spawn(len(CELLS))
    work = [(ss, scenario, c[1], c[2], c[3], runs) for c, ss in zip(CELLS, seeds, strict=True)]
    if jobs > 1:
        with ProcessPoolExecutor(jobs) as pool:
            results = list(pool.map(_cell_job, work))
    else:
        results = [_cell_job(w) for w in work]
    cells = table_cells(results)
    checks = maxwell_checks(cells) + delay_ratio_checks(cells, _GHOSTS)
    for x in cells:
        if x["algorithm"] != "alternative":
            continue
        o, p = x["ours"], x["paper"]
        ok = abs(o["d_avg"] / p["d_avg"] - 1) <= 0.2
        checks.append(
            target_check(
                "RT-3",
                f"alternative m={x['m']} Δt={x['delays'][0]}: d_avg within ±20 %",
                f"{p['d_avg']:.2f}",
                f"{o['d_avg']:.2f}",
                ok,
                "outside ±20 %" + (_GHOSTS if x["m"] == 2 else ": speed calibration"),
            )
        )
    checks += detection_checks(cells)
    c = _by_key(cells)
    for dl in ((0.1, 0.2), (0.3, 0.4)):
        o = c[("proposed", 2, dl)]
        checks.append(
            target_check(
                "RT-5",
                f"proposed m=2 Δt={dl}: heavy tail σ_d > d_avg",
                "0.37/0.95" if dl[0] == 0.1 else "0.55/1.34",
                f"{o['d_avg']:.3f}/{o['d_std']:.3f}",
                o["d_std"] > o["d_avg"],
                "no mis-associations in our scenario: the velocity-aware gate δ"
                " separates the objects, so d is pure Maxwell noise",
            )
        )
    return {
        "runs": runs,
        "seed": seed,
        "scenario": asdict(scenario),
        "cells": cells,
        "checks": checks,
    }


def format_tables(cells: list[dict], titles: dict[str, str]) -> list[str]:
    """Lines of Tables 1 and 2, paper beside ours per cell (``titles``: table id → title);
    the reproduction and the one through StereoScanning-v0 print the same layout."""
    lines: list[str] = []
    for table, title in titles.items():
        lines += [
            "",
            title,
            f"  {'m':>2} {'Δt, s':>9} | {'d_avg/σ_d paper':>16} {'ours':>13}"
            f" | {'Pr_m paper':>10} {'ours':>6} {'m̂=m':>6}",
        ]
        for x in cells:
            if x["table"] != table:
                continue
            p, o = x["paper"], x["ours"]
            dl = "/".join(f"{d:g}" for d in x["delays"])
            lines.append(
                f"  {x['m']:>2} {dl:>9} | {p['d_avg']:>7.2f}/{p['d_std']:<8.2f}"
                f" {o['d_avg']:>6.3f}/{o['d_std']:<6.3f} | {p['pr_m']:>10.2f}"
                f" {o['pr_m']:>6.3f} {o['m_hat_exact']:>6.3f}"
            )
    return lines


def format_report(result: dict) -> str:
    """Plain aligned text: both tables with paper vs ours, then the target checks."""
    lines = [
        f"Paper 000 — {result['runs']} runs per cell, seed {result['seed']}",
        "Scenario choices:",
    ]
    lines += [f"  {k} = {v}" for k, v in result["scenario"].items()]
    lines += format_tables(
        result["cells"],
        {
            "1": "Table 1 — alternative algorithm (n = 2)",
            "2": "Table 2 — proposed algorithm (n = 3)",
        },
    )
    lines += format_checks(result["checks"])
    return "\n".join(lines)


__all__ = [
    "CELLS",
    "Scenario000",
    "delay_ratio_checks",
    "detection_checks",
    "format_report",
    "format_tables",
    "maxwell_checks",
    "reproduce",
    "run_cell",
    "table_cells",
]
