"""Paper 003: algebraic accuracy (variants 1, 2) and the algorithmic P(m) table (theory §5.6, §12.4).

Scenario choices where the paper is silent (printed with the tables):

* raster (gap 29): 100 × 100 pixels over a 30° × 30° sector (0.3° steps), 2 ms per pixel,
  τ = 20 s for the algebraic runs; for the algorithmic runs (N = 5–10 periods) the same raster
  swept in τ = 1 s, since 5–10 periods of 20 s at 2.5 m/s would carry the objects past the
  receivers;
* noise: Gaussian 0.03° on azimuth and elevation of every direction vector (variant 2's
  "angular error 0.03°", used everywhere);
* variant 2: receivers on a circle of radius 50 m at 0°, 90°, 180° (n = 3) or 0°, 90°
  (economical n = 2, N = 2), aimed at a point 25 m above the centre; one object starts
  within ±3 m of that point and flies horizontally at 2.5 m/s in a random direction;
* variant 1 ("unfavourable"): receivers at x = 0, 7.5, 15 m with 1–3 m offsets on the other
  axes and boresights turned by tenths of a degree, one object flying toward them from 100 m
  to 50 m in one period of 20 s;
* algorithmic: the variant-1 pair (7.5 m apart) with m objects ≥ 3 m apart in a ±5 m cube
  around a point 100 m out, each flying toward the receivers at 1–5 m/s within 10° of the
  line; or a pair on the 50 m circle (0°, 90°) with objects around its centre, 10 m up,
  flying in random directions at 0.5–2 m/s; an object is detected when one selected group
  holds exactly its vectors in all N periods (gap 35); P(m) = all m detected.
"""

from __future__ import annotations

from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, replace

import numpy as np

from sensorgym.envs.worlds.drones import GroupSpec, Trajectories, random_group
from sensorgym.envs.worlds.scanning import RasterScan
from sensorgym.envs.worlds.stereo import NoiseModel, ReceiverLayout, simulate
from sensorgym.reproduce.experiments.reporting import format_checks, target_check
from sensorgym.trackers.geometry import look_at_rotation
from sensorgym.trackers.stereo.algebraic_detection import algebraic_single, economical
from sensorgym.trackers.stereo.algorithmic_detection import AlgorithmicParams, detect_algorithmic

#: paper's P(m): N -> values for m = 2..5
PAPER_P = {5: (1.0, 1.0, 0.97, 0.93), 10: (1.0, 1.0, 1.0, 1.0)}


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


def _job(job: tuple) -> dict:
    kind, ss, scenario, args = job
    rng = np.random.default_rng(ss)
    if kind == "algebraic":
        return algebraic_accuracy(rng, scenario, *args)
    return algorithmic_cell(rng, scenario, *args)


def reproduce(
    runs: int = 1000,
    seed: int = 0,
    scenario: Scenario003 | None = None,
    algorithmic_runs: int | None = None,
    jobs: int = 1,
) -> dict:
    """All 003 experiments and the RT-10..RT-13 checks. Pure; no printing.

    Every experiment draws from its own child of ``SeedSequence(seed)``, so results do not
    depend on ``jobs`` (worker processes).
    """
    scenario = Scenario003() if scenario is None else scenario
    ar = runs if algorithmic_runs is None else algorithmic_runs
    ss = np.random.SeedSequence(seed).spawn(19)
    er = max(ar // 4, 1)
    work = [("algebraic", ss[0], scenario, (2, runs)), ("algebraic", ss[1], scenario, (1, runs))]
    cells = [(m, N) for N in (5, 10) for m in (2, 3, 4, 5)]
    work += [
        ("algorithmic", s, scenario, (m, N, ar, False))
        for (m, N), s in zip(cells, ss[2:10], strict=True)
    ]
    work.append(("algorithmic", ss[10], scenario, (3, 5, max(ar // 2, 1), True)))
    # extension: the same cells with the whitened index, a quarter of the runs
    work += [
        ("algorithmic", s, scenario, (m, N, er, False, True))
        for (m, N), s in zip(cells, ss[11:19], strict=True)
    ]
    # longest jobs first keeps both workers busy
    order = sorted(
        range(len(work)),
        key=lambda k: -(work[k][3][1] * work[k][3][0]) if work[k][0] == "algorithmic" else 0,
    )
    if jobs > 1:
        with ProcessPoolExecutor(jobs) as pool:
            done = dict(zip(order, pool.map(_job, [work[k] for k in order]), strict=True))
    else:
        done = {k: _job(work[k]) for k in order}
    out = [done[k] for k in range(len(work))]
    v2, v1 = out[0], out[1]
    table = {N: [out[2 + cells.index((m, N))] for m in (2, 3, 4, 5)] for N in (5, 10)}
    arc = out[10]
    whitened = {N: [out[11 + cells.index((m, N))] for m in (2, 3, 4, 5)] for N in (5, 10)}
    checks = []

    def check(id_, what, paper, ours, ok, why):
        checks.append(target_check(id_, what, paper, ours, ok, why))

    ratio = v2["error_3_params"] / v2["error_6_params"]
    check(
        "RT-10",
        "variant 2: error ratio 3-param / 6-param ≈ 10 (within ×2)",
        "≈ 10",
        f"{ratio:.1f}",
        5.0 <= ratio <= 20.0,
        "the mean 6-parameter error carries a tail of runs whose three fix times are nearly"
        " equal (same raster lines), where the velocity is poorly determined",
    )
    check(
        "RT-10",
        "variant 2: 6-param error within ×2 of 0.3 m",
        "0.3",
        f"{v2['error_6_params']:.2f}",
        0.15 <= v2["error_6_params"] <= 0.6,
        "absolute accuracy differs (raster timing / geometry choices)",
    )
    check(
        "RT-10",
        "variant 2: 3-param error within ×2 of 3 m",
        "3",
        f"{v2['error_3_params']:.2f}",
        1.5 <= v2["error_3_params"] <= 6.0,
        "dynamic error depends on the chosen delays and speed",
    )
    eco = v2["error_economical"]
    check(
        "RT-10",
        "variant 2, economical n=2, N=2: error within ×2 of 0.3 m",
        "≈ 0.3",
        f"{eco:.2f}",
        0.15 <= eco <= 0.6,
        "ours is several times more accurate: with 0.03° Gaussian angle errors at ≈ 55 m the"
        " conjugation error is ≈ 0.03 m and each subgroup's r̂_1 is well determined (its"
        " velocity, from one receiver's two nearly parallel vectors, is not, but the"
        " position does not need it); the paper's ≈ 0.3 m implies an error source it does"
        " not state",
    )
    check(
        "RT-11",
        "variant 1 (close receivers): 6-param error ≫ variant 2",
        "unsatisfactory",
        f"{v1['error_6_params']:.2f} vs {v2['error_6_params']:.2f}",
        v1["error_6_params"] > 5 * v2["error_6_params"],
        "close layout not clearly worse",
    )
    for N in (5, 10):
        for m, paper, cell in zip((2, 3, 4, 5), PAPER_P[N], table[N], strict=True):
            check(
                "RT-12",
                f"P(m) N={N} m={m} within ±0.05",
                f"{paper:.2f}",
                f"{cell['p_m']:.3f}",
                abs(cell["p_m"] - paper) <= 0.05,
                "a group switching objects in one period fails the exact-vector criterion",
            )
    pm5 = [c["p_m"] for c in table[5]]
    check(
        "RT-12",
        "trend: P(m) falls with m (N=5)",
        "1→0.93",
        "→".join(f"{p:.2f}" for p in pm5),
        pm5[0] >= pm5[-1],
        "no fall with m",
    )
    rises = all(a["p_m"] >= b["p_m"] - 0.02 for a, b in zip(table[10], table[5], strict=True))
    check(
        "RT-12",
        "trend: P(m) rises with N",
        "N=10 ≥ N=5",
        " ".join(
            f"{b['p_m']:.2f}/{a['p_m']:.2f}" for a, b in zip(table[10], table[5], strict=True)
        ),
        rises,
        "swaps: with a 7.5 m baseline the range error (≈1 m) is 20× the transverse one, and"
        " the isotropic indices J_2, J_3 make a switch between objects a few metres apart"
        " cheap; more periods give more chances to switch",
    )
    w5, w10 = ([c["p_m"] for c in whitened[N]] for N in (5, 10))
    check(
        "ext",
        "whitened index (our extension): P(m) within ±0.05 of the paper, all cells",
        "table",
        " ".join(f"{a:.2f}/{b:.2f}" for a, b in zip(w5, w10, strict=True)),
        all(abs(p - q) <= 0.05 for p, q in zip(w5 + w10, PAPER_P[5] + PAPER_P[10], strict=True)),
        "see the extension table",
    )
    close_err = np.nanmean([c["position_error"] for c in table[5]])
    check(
        "RT-13",
        "close pair position error 1–3 m (order)",
        "1–3",
        f"{close_err:.2f}",
        0.3 <= close_err <= 10.0,
        "order of magnitude differs",
    )
    check(
        "RT-13",
        "arc pair position error ≈ 0.3 m (order)",
        "0.3",
        f"{arc['position_error']:.2f}",
        0.03 <= arc["position_error"] <= 1.0,
        "order of magnitude differs",
    )
    return {
        "runs": runs,
        "algorithmic_runs": ar,
        "seed": seed,
        "scenario": asdict(scenario),
        "variant2": v2,
        "variant1": v1,
        "table": {str(k): v for k, v in table.items()},
        "arc_pair_m3_N5": arc,
        "extension_runs": er,
        "extension_whitened": {str(k): v for k, v in whitened.items()},
        "checks": checks,
    }


def format_report(res: dict) -> str:
    """Plain aligned text: the algebraic results, the P(m) table with the paper's values, checks."""
    lines = [
        f"Paper 003 — {res['runs']} algebraic runs, {res['algorithmic_runs']} algorithmic runs"
        f" per cell, seed {res['seed']}",
        "Scenario choices:",
    ] + [f"  {k} = {v}" for k, v in res["scenario"].items()]
    lines += [
        "",
        "Algebraic approach, mean position error, m",
        "  (paper: ≈0.3 with velocity, ≈3 without; variant 1 unsatisfactory)",
    ]
    for name in ("variant2", "variant1"):
        v = res[name]
        lines.append(
            f"  {name} (mean / median): 6 params {v['error_6_params']:.3f} /"
            f" {v['median_6_params']:.3f}   3 params {v['error_3_params']:.3f} /"
            f" {v['median_3_params']:.3f}   economical n=2,N=2 {v['error_economical']:.3f} /"
            f" {v['median_economical']:.3f}   ({v['runs_used']} runs)"
        )
    lines += [
        "",
        "Algorithmic approach, P(m) (paper / ours), close pair",
        f"  {'N':>3} | " + "  ".join(f"m={m:<11}" for m in (2, 3, 4, 5)),
    ]
    for N in ("5", "10"):
        row = "  ".join(
            f"{p:.2f}/{c['p_m']:.3f}    "
            for p, c in zip(PAPER_P[int(N)], res["table"][N], strict=True)
        )
        lines.append(f"  {N:>3} | {row}")
    lines += [
        "  position error (close pair): "
        + ", ".join(f"{c['position_error']:.2f}" for c in res["table"]["5"])
        + " m  (paper 1–3 m)",
        f"  arc pair, m=3, N=5: P = {res['arc_pair_m3_N5']['p_m']:.3f}, position error"
        f" {res['arc_pair_m3_N5']['position_error']:.3f} m (paper ≈0.3 m)",
        "",
        f"Extension (not in the paper): whitened J_2, J_3 (sigma_transverse), close pair,"
        f" {res['extension_runs']} runs per cell, P(m) (paper / ours)",
    ]
    for N in ("5", "10"):
        row = "  ".join(
            f"{p:.2f}/{c['p_m']:.3f}    "
            for p, c in zip(PAPER_P[int(N)], res["extension_whitened"][N], strict=True)
        )
        lines.append(f"  {N:>3} | {row}")
    lines += format_checks(res["checks"])
    return "\n".join(lines)
