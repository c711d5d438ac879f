"""Paper 003 experiments (scenarios, algebraic accuracy, algorithmic P(m) cells) for
:mod:`sensorgym.reproduce.paper003`, which runs them, checks the targets and prints.

Private module (leading underscore): not a ``sensorgym reproduce`` entry of its own. The
scenario choices are documented in :mod:`sensorgym.reproduce.paper003`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from sensorgym.envs.worlds.drones import GroupSpec, Trajectories, random_group
from sensorgym.envs.worlds.scanning import RasterScan
from sensorgym.envs.worlds.stereo import NoiseModel, ReceiverLayout, simulate
from sensorgym.trackers.geometry import look_at_rotation
from sensorgym.trackers.stereo.algebraic_detection import algebraic_single, economical
from sensorgym.trackers.stereo.algorithmic_detection import AlgorithmicParams, detect_algorithmic


@dataclass(frozen=True)
class Scenario003:
    """Scenario choices where paper 003 is silent (module docstring)."""

    angle_sigma_deg: float = 0.03
    """Angle error on azimuth and elevation, deg (paper)."""
    circle_radius: float = 50.0
    """Variant 2 circle radius, m (paper)."""
    aim_height: float = 25.0
    """Variant 2 objects' height above the receivers, m."""
    algebraic_speed: float = 2.5
    """Object speed in the algebraic runs, m/s (100 → 50 m in 20 s)."""
    economical_speed: float = 0.5
    """Object speed in the economical (N = 2 × 20 s) runs, m/s."""
    baseline: float = 7.5
    """Spacing of the close receivers, m (paper: 5–10 m)."""
    algorithmic_range: float = 100.0
    """Distance of the algorithmic objects' area, m."""
    algorithmic_speed: tuple[float, float] = (1.0, 5.0)
    """Speed range of the algorithmic objects, m/s."""
    arc_speed: tuple[float, float] = (0.5, 2.0)
    """Speed range on the arc (random 3-D direction), m/s: slower, as the objects fly across
    the receivers' 30° sectors at 50 m instead of toward them."""
    spread: float = 5.0
    """Algorithmic objects start in a cube of this half-width, m."""
    min_separation: float = 3.0
    """Minimum starting distance between algorithmic objects, m ("a few metres")."""
    algorithmic_period: float = 1.0
    """Scan period τ of the algorithmic runs, s."""

    @property
    def angle_sigma(self) -> float:
        """Angle error, rad."""
        return float(np.deg2rad(self.angle_sigma_deg))


def _close_layout(sc: Scenario003, n: int, aim: tuple) -> ReceiverLayout:
    """Variant 1: receivers 7.5 m apart along X, 1–3 m offsets, axes turned by tenths of a deg."""
    pos = np.array([[0.0, 0.0, 0.0], [sc.baseline, 1.5, 1.0], [2 * sc.baseline, 2.5, 3.0]])[:n]
    R = look_at_rotation(pos, np.broadcast_to(np.asarray(aim, float), pos.shape))
    turn = np.deg2rad([0.0, 0.3, -0.2])[:n]
    c, s = np.cos(turn), np.sin(turn)
    yaw = np.zeros((n, 3, 3))
    yaw[:, 0, 0], yaw[:, 0, 2], yaw[:, 1, 1], yaw[:, 2, 0], yaw[:, 2, 2] = c, s, 1.0, -s, c
    return ReceiverLayout(R @ yaw, pos)


def algebraic_accuracy(rng: np.random.Generator, sc: Scenario003, variant: int, runs: int) -> dict:
    """Mean and median position error of the 6-parameter (with velocity) and 3-parameter
    solves in one period, and of the economical variant (n = 2, N = 2)."""
    scan = RasterScan.paper003()
    noise = NoiseModel(angle_sigma=sc.angle_sigma)
    if variant == 2:
        aim = (0.0, sc.aim_height, 0.0)
        layout = ReceiverLayout.on_circle(sc.circle_radius, [0.0, 90.0, 180.0], aim=aim)
        pair = ReceiverLayout.on_circle(sc.circle_radius, [0.0, 90.0], aim=aim)
    else:
        aim = (sc.baseline, 2.0, 75.0)
        layout = _close_layout(sc, 3, aim)
        pair = layout.subset([0, 1])
    P, b = layout.relative
    P2, b2 = pair.relative
    err6, err3, err_eco = [], [], []
    for _ in range(runs):
        if variant == 2:
            heading = rng.uniform(0, 2 * np.pi)
            v = sc.algebraic_speed * np.array([np.sin(heading), 0.0, np.cos(heading)])
            # at the aim point at mid-period, so the raster meets it inside the sector
            start = np.asarray(aim) + rng.uniform(-3, 3, 3) - v * 0.5 * scan.period
        else:
            start = np.asarray([sc.baseline, 2.0, 100.0]) + rng.uniform(-1, 1, 3)
            v = np.array([0.0, 0.0, -sc.algebraic_speed])
        traj = Trajectories.linear(start[None], v[None])
        per, _ = simulate(rng, traj, layout, (scan,) * 3, 1, scan.period, noise)
        fixes = per[0]
        if any(f.count != 1 for f in fixes):
            continue
        t1 = fixes[0].times[0]
        truth = layout.to_frame1(traj.position(t1))[0]
        for order, store in ((1, err6), (0, err3)):
            sol = algebraic_single(fixes, P, b, order=order)
            store.append(float(np.linalg.norm(sol.position - truth)))
        # economical variant: 2 periods (40 s), slowed so the object stays in the sector
        slow = Trajectories.linear(
            (
                np.asarray(aim)
                + rng.uniform(-3, 3, 3)
                - v / sc.algebraic_speed * sc.economical_speed * scan.period
            )[None],
            (v / max(np.linalg.norm(v), 1e-12) * sc.economical_speed)[None],
        )
        per2, _ = simulate(rng, slow, pair, (scan,) * 2, 2, scan.period, noise)
        if all(f.count == 1 for p in per2 for f in p):
            det = economical(per2, P2[0], b2[0], 2 * scan.period)
            if det.m_hat:
                t11 = per2[0][0].times[0]
                err_eco.append(
                    float(
                        np.linalg.norm(det.positions[0, 0] - pair.to_frame1(slow.position(t11))[0])
                    )
                )
    return {
        "error_6_params": float(np.mean(err6)),
        "error_3_params": float(np.mean(err3)),
        "error_economical": float(np.mean(err_eco)) if err_eco else float("nan"),
        "median_6_params": float(np.median(err6)),
        "median_3_params": float(np.median(err3)),
        "median_economical": float(np.median(err_eco)) if err_eco else float("nan"),
        "runs_used": len(err6),
    }


def algorithmic_params(
    sc: Scenario003, baseline: float, max_delay: float, r: float
) -> AlgorithmicParams:
    """Noise-derived normalisers: a pair ``baseline`` apart, objects ``algorithmic_range`` out."""
    s = sc.angle_sigma
    return AlgorithmicParams(
        sigma_e=r * s,
        # range error of a stereo pair: r² √2 σ_ang / baseline (disparity of two noisy angles)
        sigma_position=min(r * r * np.sqrt(2.0) * s / baseline, r),
        period=sc.algorithmic_period,
        max_speed=2.0 * sc.algorithmic_speed[1],
        max_delay=max_delay,
        gate=6.0,
    )


def algorithmic_cell(
    rng: np.random.Generator,
    sc: Scenario003,
    m: int,
    N: int,
    runs: int,
    spread_pair: bool,
    whitened: bool = False,
) -> dict:
    """P(m) and position error of the algorithmic detector in one (m, N) cell.

    ``whitened`` uses our extension of the index (``AlgorithmicParams.sigma_transverse``),
    not the paper's isotropic norms.
    """
    centre = (sc.baseline / 2, 10.0, sc.algorithmic_range)
    if spread_pair:
        centre = (0.0, 10.0, 0.0)
        layout = ReceiverLayout.on_circle(sc.circle_radius, [0.0, 90.0], aim=centre)
        baseline = np.sqrt(2.0) * sc.circle_radius
        heading = None
    else:
        layout = _close_layout(sc, 2, centre)
        baseline = sc.baseline
        heading = (0.0, 0.0, -1.0)
    P, b = layout.relative
    # close receivers see an object at nearly the same pixel (delay of a few lines); receivers
    # on an arc see it anywhere in their rasters (delay up to the period)
    if spread_pair:
        params = algorithmic_params(sc, baseline, sc.algorithmic_period, sc.circle_radius)
    else:
        params = algorithmic_params(sc, baseline, 0.02, sc.algorithmic_range)
    if whitened:
        r = sc.circle_radius if spread_pair else sc.algorithmic_range
        params = replace(params, sigma_transverse=r * sc.angle_sigma)
    scan = RasterScan(30.0, 30.0, 100, 100, sc.algorithmic_period)
    noise = NoiseModel(angle_sigma=sc.angle_sigma)
    spec = GroupSpec(
        centre=centre,
        spread=sc.spread,
        min_separation=sc.min_separation,
        speed=sc.arc_speed if spread_pair else sc.algorithmic_speed,
        heading=heading,
        heading_spread_deg=10.0 if heading else 0.0,
    )
    all_found, errors, m_exact = 0, [], 0
    for _ in range(runs):
        traj = random_group(rng, m, spec)
        periods, truth = simulate(rng, traj, layout, (scan, scan), N, sc.algorithmic_period, noise)
        det = detect_algorithmic(periods, P[0], b[0], params)
        m_exact += det.m_hat == m
        found = 0
        for s in range(det.m_hat):
            mem = det.members[s]
            if np.any(mem < 0):
                continue
            lab = np.array([[truth[i].source[k][mem[i, k]] for k in (0, 1)] for i in range(N)])
            if lab[0, 0] >= 0 and np.all(lab == lab[0, 0]):
                found += 1
                j = lab[0, 0]
                t = det.times[s, -1]
                true = layout.to_frame1(traj.position(np.full(m, t))[j])
                errors.append(float(np.linalg.norm(det.positions[s, -1] - true)))
        all_found += found == m
    return {
        "p_m": all_found / runs,
        "m_hat_exact": m_exact / runs,
        "position_error": float(np.mean(errors)) if errors else float("nan"),
    }
