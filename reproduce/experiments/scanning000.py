"""Paper 000's Tables 1–2 through ``sensorgym/StereoScanning-v0`` (issue 12, fidelity of the env).

The env's own tracker — paper 000's proposed algorithm (or its alternative) run online inside
the compiled period kernel — is driven with the papers' fixed full sweep over paper 000's
scenario (the choices of :class:`~sensorgym.reproduce.experiments.paper000.Scenario000`,
theory §13.15): receivers on the 120 m arc at 0°, 90°, 270° looking 40 m up, ``m`` objects on
close straight paths drawn by the same generator, ``σ_x = 0.1 m`` shared apparent-position
noise and no angular noise, ``N = 5`` periods of 1 s. The delays come from the scan: receiver
``k``'s raster starts ``Δt_k`` into the period and sweeps its (hemispherical) sector in
``sweep_time`` = 1 ms, so each fix lands ``Δt_k`` plus under a millisecond after receiver 1's.

After period ``N`` the confirmed tracks are the found objects: ``d`` is the distance between
each track's estimate and the true position at that estimate's time (nearest one-to-one),
``Pr_m`` the fraction of runs in which every object has a track within 4 m. The targets and
tolerances are those of the paper 000 reproduction (theory §12.1 RT-2 … RT-4).
"""

from __future__ import annotations

from dataclasses import asdict

import numpy as np

from sensorgym.envs.stereo_scanning import kernels
from sensorgym.envs.stereo_scanning import simulation as sim
from sensorgym.envs.worlds.drones import GroupSpec, random_group
from sensorgym.reproduce.experiments.paper000 import (
    CELLS,
    Scenario000,
    delay_ratio_checks,
    detection_checks,
    format_tables,
    maxwell_checks,
    table_cells,
)
from sensorgym.reproduce.experiments.reporting import format_checks
from sensorgym.trackers.stereo.association import match_tracks

#: the raster sweep of one period, s (short: the delays are the sweeps' start offsets)
SWEEP = 1e-3


def env_params(sc: Scenario000, algorithm: str, m: int, delays: tuple) -> sim.ScanningParams:
    """The env's params for one table cell: paper 000's layout and noise, the fixed sweep's
    hemispherical sector, raster offsets ``(0, Δt_2[, Δt_3])``, no scene limits."""
    offsets = (0.0, *delays) if len(delays) == 2 else (0.0, delays[0], 0.5)
    return sim.ScanningParams(
        receiver_azimuths=(0.0, float(np.pi / 2), float(3 * np.pi / 2)),
        circle_radius=sc.radius,
        aim_height=sc.altitude,
        n_drones=m,
        close_drones=0,
        late_drones=0,
        start_spread=sc.spread,
        scene_half_width=1e5,
        scene_height=1e5,
        scene_floor=-1e5,
        start_altitude=(sc.altitude - sc.spread, sc.altitude + sc.spread),
        period=sc.period,
        sweep_time=SWEEP,
        scan_offsets=offsets,
        field_of_regard=0.1,
        sector_width=(0.1, float(np.pi)),
        noise_per_width=0.0,
        sigma_ang_min=0.0,
        position_sigma=sc.position_sigma,
        tracker=algorithm,
        confirm_hits=2 if algorithm == "proposed" else 3,
        max_misses=sc.periods,
        track_capacity=64,
        truth_gate=sc.gate,
    )


def run_cell(
    rng: np.random.Generator, sc: Scenario000, algorithm: str, m: int, delays: tuple, runs: int
) -> dict:
    """Monte Carlo of one table cell through the env's simulation core (a batch of ``runs``
    scenarios stepped together); returns d_avg, σ_d, Pr_m and the rate of m̂ = m."""
    params = env_params(sc, algorithm, m, delays)
    spec = GroupSpec(
        centre=(0.0, sc.altitude, 0.0),
        spread=sc.spread,
        min_separation=sc.min_separation,
        speed=sc.speed,
        heading_spread_deg=sc.heading_spread_deg,
        speed_jitter=sc.speed_jitter,
    )
    groups = [random_group(rng, m, spec) for _ in range(runs)]
    p = np.stack([g.start for g in groups])
    v = np.stack([g.velocity for g in groups])
    state = sim.start(params, p, v, np.zeros_like(p), np.zeros((runs, m)))
    # the fixed full sweep: every receiver's widest sector about its boresight
    action = np.broadcast_to(np.array([0.0, 0.0, 1.0]), (runs, 3, 3)).copy()
    for _ in range(sc.periods):
        state, _, _ = sim.step(params, state, action, rng)
    dists, found, exact = [], 0, 0
    for i in range(runs):
        rows = np.flatnonzero(state.track_status[i] == kernels.CONFIRMED)
        exact += rows.size == m
        if rows.size == 0:
            continue
        t = state.track_t[i, rows]
        est = state.track_x[i, rows, :3]
        # truth of object j at the time of estimate k: (m, K, 3)
        truth = p[i][:, None] + v[i][:, None] * t[None, :, None]
        d = np.linalg.norm(truth - est[None], axis=-1)
        nearest = match_tracks(d, np.inf)
        ok = nearest >= 0
        dists.extend(d[np.flatnonzero(ok), nearest[ok]])
        found += bool(np.all(match_tracks(d, sc.gate) >= 0))
    dists = np.asarray(dists)
    return {
        "d_avg": float(dists.mean()) if dists.size else float("nan"),
        "d_std": float(dists.std()) if dists.size else float("nan"),
        "pr_m": found / runs,
        "m_hat_exact": exact / runs,
    }


def reproduce(runs: int = 1000, seed: int = 0, scenario: Scenario000 | None = None) -> dict:
    """Every cell of Tables 1–2 through the env, and RT-2 … RT-4 with the reproduction's
    tolerances. Pure; no printing. Each cell draws from its own child of ``SeedSequence(seed)``."""
    scenario = Scenario000() if scenario is None else scenario
    seeds = np.random.SeedSequence(seed).spawn(len(CELLS))
    results = [
        run_cell(np.random.default_rng(ss), scenario, cell[1], cell[2], cell[3], runs)
        for cell, ss in zip(CELLS, seeds, strict=True)
    ]
    cells = table_cells(results)
    checks = maxwell_checks(cells) + delay_ratio_checks(cells) + detection_checks(cells)
    return {
        "runs": runs,
        "seed": seed,
        "scenario": asdict(scenario),
        "sweep_time": SWEEP,
        "cells": cells,
        "checks": checks,
    }


def format_report(result: dict) -> str:
    """Plain aligned text: both tables with paper vs ours (through the env), then the checks."""
    lines = [
        f"Paper 000 through sensorgym/StereoScanning-v0 (fixed full sweep) — {result['runs']} "
        f"runs per cell, seed {result['seed']}",
        f"Raster sweep {result['sweep_time'] * 1e3:g} ms per period; scenario choices:",
    ]
    lines += [f"  {k} = {v}" for k, v in result["scenario"].items()]
    lines += format_tables(
        result["cells"],
        {
            "1": "Table 1 — alternative algorithm (receivers 1–2)",
            "2": "Table 2 — proposed algorithm (n = 3)",
        },
    )
    lines += format_checks(result["checks"])
    return "\n".join(lines)


__all__ = ["env_params", "format_report", "reproduce", "run_cell"]
