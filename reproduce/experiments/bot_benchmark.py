"""Bearings-only tracking (BOT) benchmark: the textbook scenario, estimators vs CRLB.

Scenario (Ristic, Arulampalam & Gordon, *Beyond the Kalman Filter*, 2004, ch. 6): bearings
every minute, 33 of them (t = 0…32 min), σ = 1.5°; observer at 5 kn on course 140° turning
to 20° at 30°/min during the 13th–16th minute (t = 12…16 min); target initially at
(4.92, 0.85) km East/North of the observer, 4 kn, course −140°; q̃ = 9·10⁻¹² km²/s³.

Prior (from the first bearing, Ristic §6.3.1): range ``r̄ ~ N(r, (2 km)²)`` and speed
``s̄ ~ N(s, (2 kn)²)`` drawn per run around the truth (so the prior is statistically honest
and the posterior CRLB's ``J₀ = P₀⁻¹`` applies), course ``c̄ = z₁ + π`` with σ_c = π/√12.

Estimators: Cartesian EKF and CKF (one wide prior), the range-parameterised EKF bank, and
batch ML and the weighted pseudo-linear estimator (no prior, every bearing so far) at
checkpoints after the manoeuvre. Bounds: the posterior CRLB (Tichavský et al.) with
the prior and q̃, averaged over the simulated trajectories; and for ML the deterministic CRLB
without prior, evaluated on a separate q̃ = 0 run set (ML assumes a deterministic target).

A run has *diverged* when its final position error exceeds ``DIVERGENCE_FACTOR`` times the
final PCRLB position RMS (documented choice; the book uses a similar final-error test).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from scipy.stats import chi2

from sensorgym.envs.worlds.platform import (
    PlatformTrajectory,
    PlatformWorldParams,
    PlatformWorldState,
    rollout,
    true_bearings,
)
from sensorgym.trackers.bearings.crlb import (
    batch_information,
    bearing_information,
    crlb,
    position_rms_bound,
    posterior_information,
)
from sensorgym.trackers.bearings.filters import bearing_prior, range_bank_prior, run_filter
from sensorgym.trackers.bearings.maximum_likelihood import ml_estimate
from sensorgym.trackers.bearings.models import KNOT
from sensorgym.trackers.bearings.pseudolinear import pseudolinear_estimate
from sensorgym.trackers.geometry import wrap_angle

DIVERGENCE_FACTOR = 5.0
#: Bearing indices (minutes) at which the batch estimators are evaluated.
BATCH_CHECKPOINTS = (16, 20, 24, 28, 32)


@dataclass(frozen=True)
class BotScenario:
    """The textbook bearings-only scenario (SI units)."""

    n_bearings: int = 33
    """Number of bearings ``K`` (one per ``dt``, first at t = 0)."""
    dt: float = 60.0
    """Sampling interval (s)."""
    sigma: float = np.deg2rad(1.5)
    """Bearing noise σ (rad)."""
    observer_speed: float = 5.0 * KNOT
    """Observer speed (m/s)."""
    observer_course: float = np.deg2rad(140.0)
    """Initial observer course from North clockwise (rad)."""
    turn_rate: float = np.deg2rad(-30.0) / 60.0
    """Observer turn rate during the manoeuvre (rad/s); −30°/min takes 140° to 20°."""
    turn_steps: tuple[int, ...] = (12, 13, 14, 15)
    """Steps (intervals [k, k+1] min) during which the observer turns."""
    target_offset: tuple[float, float] = (4920.0, 850.0)
    """Initial target position relative to the observer, East/North (m)."""
    target_speed: float = 4.0 * KNOT
    """Target speed (m/s)."""
    target_course: float = np.deg2rad(-140.0)
    """Target course from North clockwise (rad)."""
    q_tilde: float = 9e-6
    """Target acceleration noise intensity (m²/s³) = 9·10⁻¹² km²/s³."""
    range_sigma: float = 2000.0
    """Prior range σ (m)."""
    speed_sigma: float = 2.0 * KNOT
    """Prior speed σ (m/s)."""
    course_sigma: float = np.pi / np.sqrt(12.0)
    """Prior course σ (rad)."""

    @property
    def times(self) -> np.ndarray:
        """Bearing times (s)."""
        return self.dt * np.arange(self.n_bearings)

    def actions(self) -> np.ndarray:
        """Observer commands ``(K−1, 2)``: heading rate (rad/s), speed change (m/s)."""
        a = np.zeros((self.n_bearings - 1, 2))
        a[list(self.turn_steps), 0] = self.turn_rate
        return a

    def world_params(self, q_tilde: float | None = None) -> PlatformWorldParams:
        """World parameters able to fly this scenario."""
        return PlatformWorldParams(
            dt=self.dt,
            max_turn_rate=abs(self.turn_rate),
            min_speed=0.0,
            max_speed=self.observer_speed,
            max_speed_change=0.0,
            q_tilde=self.q_tilde if q_tilde is None else q_tilde,
            sigma_bearing=self.sigma,
        )

    def initial_state(self, n_runs: int) -> PlatformWorldState:
        """World state at t = 0 for ``n_runs`` identical scenarios."""
        v = self.target_speed * np.array([np.sin(self.target_course), np.cos(self.target_course)])
        target = np.concatenate([np.asarray(self.target_offset), v])
        return PlatformWorldState(
            t=0.0,
            platform_position=np.zeros((n_runs, 2)),
            heading=np.full(n_runs, self.observer_course),
            speed=np.full(n_runs, self.observer_speed),
            target=np.tile(target, (n_runs, 1)),
        )


@dataclass(frozen=True)
class Simulation:
    """Seeded Monte Carlo runs of the scenario."""

    trajectory: PlatformTrajectory
    """True platform and target trajectories ``(B, K, ·)``."""
    z: np.ndarray
    """Noisy bearings ``(B, K)`` (rad)."""
    range_mean: np.ndarray
    """Prior range mean per run ``(B,)`` (m)."""
    speed_mean: np.ndarray
    """Prior speed mean per run ``(B,)`` (m/s)."""


def simulate(
    scn: BotScenario, n_runs: int, rng: np.random.Generator, q_tilde: float | None = None
) -> Simulation:
    """Truth, bearings and per-run prior means for ``n_runs`` runs."""
    params = scn.world_params(q_tilde)
    traj = rollout(params, scn.initial_state(n_runs), scn.actions(), rng)
    beta = true_bearings_along(traj)
    z = wrap_angle(beta + scn.sigma * rng.standard_normal(beta.shape))
    r0 = np.hypot(*scn.target_offset)
    range_mean = np.maximum(r0 + scn.range_sigma * rng.standard_normal(n_runs), 500.0)
    speed_mean = np.abs(scn.target_speed + scn.speed_sigma * rng.standard_normal(n_runs))
    return Simulation(traj, z, range_mean, speed_mean)


def true_bearings_along(traj: PlatformTrajectory) -> np.ndarray:
    """Noise-free bearings ``(B, K)`` of a recorded trajectory."""
    B, K = traj.target.shape[:2]
    flat = PlatformWorldState(
        t=0.0,
        platform_position=traj.platform_position.reshape(B * K, 2),
        heading=np.zeros(B * K),
        speed=np.zeros(B * K),
        target=traj.target.reshape(B * K, 4),
    )
    return true_bearings(flat).reshape(B, K)


def prior_for(scn: BotScenario, sim: Simulation):
    """Wide single-Gaussian prior from the first bearing (Ristic §6.3.1)."""
    z1 = sim.z[:, 0]
    return bearing_prior(
        z1,
        scn.sigma,
        sim.trajectory.platform_position[:, 0],
        0.0,
        range_mean=sim.range_mean,
        range_sigma=scn.range_sigma,
        speed_mean=sim.speed_mean,
        speed_sigma=scn.speed_sigma,
        course_mean=wrap_angle(z1 + np.pi),
        course_sigma=scn.course_sigma,
        course_distribution="uniform",
    )


def bank_prior_for(scn: BotScenario, sim: Simulation, n_members: int):
    """Range-parameterised bank over ``r̄ ± 3σ_r`` (floored at 0.5 km), Gaussian weights."""
    z1 = sim.z[:, 0]
    return range_bank_prior(
        z1,
        scn.sigma,
        sim.trajectory.platform_position[:, 0],
        0.0,
        range_min=np.maximum(sim.range_mean - 3.0 * scn.range_sigma, 500.0),
        range_max=sim.range_mean + 3.0 * scn.range_sigma,
        n_members=n_members,
        speed_mean=sim.speed_mean,
        speed_sigma=scn.speed_sigma,
        course_mean=wrap_angle(z1 + np.pi),
        course_sigma=scn.course_sigma,
        course_distribution="uniform",
        range_mean=sim.range_mean,
        range_sigma=scn.range_sigma,
    )


def prior_information(scn: BotScenario, x0: np.ndarray, p0: np.ndarray) -> np.ndarray:
    """The bound's prior information ``J₀ = P₀⁻¹`` ``(4, 4)`` for the true initial target state
    ``x0`` seen from ``p0``: the book's prior (range σ, speed σ, course z + π with σ_c) around the
    truth, as the filters' priors are drawn."""
    r0 = np.hypot(*scn.target_offset)
    beta0 = np.arctan2(*scn.target_offset)
    P0 = bearing_prior(
        beta0,
        scn.sigma,
        p0,
        0.0,
        range_mean=r0,
        range_sigma=scn.range_sigma,
        speed_mean=np.hypot(*x0[2:]),
        speed_sigma=scn.speed_sigma,
        course_mean=beta0 + np.pi,
        course_sigma=scn.course_sigma,
        course_distribution="uniform",
    ).P
    return np.linalg.inv(P0)


def pcrlb_of(
    scn: BotScenario, J0: np.ndarray, Im: np.ndarray, final_only: bool = False
) -> np.ndarray:
    """Posterior CRLB position RMS ``(..., K)`` (m) from the prior information ``J0`` and the
    bearings' information ``Im`` ``(..., K, 4, 4)`` (one trajectory each, or averaged over
    runs); the first bearing's is left out (it is already inside the prior). ``final_only``:
    only the last time, ``(..., 1)``."""
    Im = np.array(Im, dtype=np.float64)
    Im[..., 0, :, :] = 0.0
    J = posterior_information(J0, scn.times, Im, scn.q_tilde)
    return position_rms_bound(crlb(J[..., -1:, :, :] if final_only else J))


def pcrlb_position(scn: BotScenario, sim: Simulation) -> np.ndarray:
    """Posterior CRLB position RMS ``(K,)`` (m), with the prior and q̃, averaged info over runs."""
    traj = sim.trajectory
    J0 = prior_information(scn, traj.target[0, 0], traj.platform_position[0, 0])
    Im = bearing_information(traj.target, traj.platform_position, scn.sigma).mean(axis=0)
    return pcrlb_of(scn, J0, Im)


def _errors(x_hat: np.ndarray, P: np.ndarray, truth: np.ndarray):
    e = x_hat - truth
    pos_err = np.hypot(e[..., 0], e[..., 1])
    nees = np.einsum("...i,...i->...", e, np.linalg.solve(P, e[..., None])[..., 0])
    return pos_err, nees


@dataclass
class EstimatorSummary:
    """Per-estimator Monte Carlo statistics."""

    name: str
    rms_position: list[float]
    """RMS position error over time (m), non-diverged runs."""
    rms_position_all: list[float]
    """RMS position error over time (m), all runs."""
    mean_nees: list[float]
    """Average 4-dof NEES over time, non-diverged runs."""
    divergence_rate: float
    """Fraction of runs whose final position error exceeds the divergence threshold."""
    seconds: float
    """Wall-clock time of the estimator over all runs (s)."""


@dataclass
class BotBenchmarkResult:
    """Everything ``bot-benchmark`` reports."""

    n_runs: int
    seed: int
    times_min: list[float]
    pcrlb_position: list[float]
    """Posterior CRLB position RMS over time (m)."""
    divergence_threshold: float
    """Final position error above which a run counts as diverged (m)."""
    nees_band: tuple[float, float]
    """95 % two-sided band of the average NEES (4 dof) over the non-diverged runs."""
    filters: list[EstimatorSummary] = field(default_factory=list)
    batch_minutes: list[float] = field(default_factory=list)
    """Checkpoints (min) at which the batch estimators use all bearings so far."""
    batch_crlb: list[float] = field(default_factory=list)
    """Deterministic CRLB (no prior, q̃ = 0) position RMS at the checkpoints (m)."""
    ml_rms: list[float] = field(default_factory=list)
    """Batch ML position RMS at the checkpoints, q̃ = 0 runs (m)."""
    ml_nees: list[float] = field(default_factory=list)
    """Batch ML average NEES with its inverse-Fisher covariance (q̃ = 0 runs)."""
    ml_coverage95: list[float] = field(default_factory=list)
    """Fraction of ML runs inside the 95 % χ²₄ ellipsoid of its covariance."""
    ple_rms: list[float] = field(default_factory=list)
    """Weighted pseudo-linear position RMS at the checkpoints, q̃ = 0 runs (m)."""
    ml_rms_final_random: float = float("nan")
    """ML final position RMS on the q̃ > 0 runs (model mismatch) (m)."""
    ple_rms_final_random: float = float("nan")
    """PLE final position RMS on the q̃ > 0 runs (m)."""
    batch_seconds: float = float("nan")
    """Wall-clock time of all PLE + ML solves (s)."""


def run_benchmark(
    n_runs: int = 1000, seed: int = 0, n_members: int = 8, ml_runs: int | None = None
) -> BotBenchmarkResult:
    """Run all estimators on ``n_runs`` seeded runs; ML on ``ml_runs`` (default ``n_runs``)."""
    scn = BotScenario()
    rng = np.random.default_rng(seed)
    sim = simulate(scn, n_runs, rng)
    traj = sim.trajectory
    bound = pcrlb_position(scn, sim)
    threshold = DIVERGENCE_FACTOR * float(bound[-1])
    lo, hi = chi2.ppf([0.025, 0.975], 4 * n_runs) / n_runs
    res = BotBenchmarkResult(
        n_runs=n_runs,
        seed=seed,
        times_min=list(scn.times / 60.0),
        pcrlb_position=bound.tolist(),
        divergence_threshold=threshold,
        nees_band=(float(lo), float(hi)),
    )
    runs = {
        "EKF (Cartesian)": (lambda: prior_for(scn, sim), "ekf"),
        "CKF (Cartesian)": (lambda: prior_for(scn, sim), "ckf"),
        f"RP-EKF ({n_members})": (lambda: bank_prior_for(scn, sim, n_members), "ekf"),
        f"RP-CKF ({n_members})": (lambda: bank_prior_for(scn, sim, n_members), "ckf"),
    }
    for name, (make_prior, comp) in runs.items():
        t0 = time.perf_counter()
        x, P = run_filter(
            make_prior(), sim.z, scn.times, traj.platform_position, scn.sigma, scn.q_tilde, comp
        )
        secs = time.perf_counter() - t0
        pos_err, nees = _errors(x, P, traj.target)
        good = pos_err[:, -1] <= threshold
        res.filters.append(
            EstimatorSummary(
                name=name,
                rms_position=np.sqrt(np.mean(pos_err[good] ** 2, axis=0)).tolist(),
                rms_position_all=np.sqrt(np.mean(pos_err**2, axis=0)).tolist(),
                mean_nees=np.mean(nees[good], axis=0).tolist(),
                divergence_rate=float(np.mean(~good)),
                seconds=secs,
            )
        )
    # Batch estimators (no prior) at checkpoints, using every bearing so far:
    # (a) deterministic target (q̃ = 0) vs the deterministic CRLB without prior;
    # (b) final time on the q̃ > 0 runs (model mismatch), for reference.
    m = n_runs if ml_runs is None else ml_runs
    t0 = time.perf_counter()
    sim0 = simulate(scn, m, np.random.default_rng([seed, 1]), q_tilde=0.0)
    p0 = sim0.trajectory.platform_position
    q95 = chi2.ppf(0.95, 4)
    for k in BATCH_CHECKPOINTS:
        n, t_ref = k + 1, float(scn.times[k])
        truth = sim0.trajectory.target[:, k]
        ple = pseudolinear_estimate(sim0.z[:, :n], scn.times[:n], p0[:, :n], scn.sigma, t_ref)
        ml = ml_estimate(sim0.z[:, :n], scn.times[:n], p0[:, :n], scn.sigma, t_ref, x_init=ple.x)
        pos, nees = _errors(ml.estimate.x, ml.estimate.P, truth)
        J = batch_information(truth[0], t_ref, scn.times[:n], p0[0, :n], scn.sigma)
        res.batch_minutes.append(t_ref / 60.0)
        res.batch_crlb.append(float(position_rms_bound(crlb(J))))
        res.ml_rms.append(float(np.sqrt(np.mean(pos**2))))
        res.ml_nees.append(float(np.mean(nees)))
        res.ml_coverage95.append(float(np.mean(nees < q95)))
        res.ple_rms.append(float(np.sqrt(np.mean(np.sum((ple.x[:, :2] - truth[:, :2]) ** 2, -1)))))
    t_end = float(scn.times[-1])
    ple1 = pseudolinear_estimate(sim.z[:m], scn.times, traj.platform_position[:m], scn.sigma, t_end)
    ml1 = ml_estimate(
        sim.z[:m], scn.times, traj.platform_position[:m], scn.sigma, t_end, x_init=ple1.x
    )
    truth1 = traj.target[:m, -1, :2]
    res.ml_rms_final_random = float(
        np.sqrt(np.mean(np.sum((ml1.estimate.x[:, :2] - truth1) ** 2, -1)))
    )
    res.ple_rms_final_random = float(np.sqrt(np.mean(np.sum((ple1.x[:, :2] - truth1) ** 2, -1))))
    res.batch_seconds = time.perf_counter() - t0
    return res


def format_report(res: BotBenchmarkResult) -> str:
    """Plain aligned-text report."""
    lines = [
        f"Bearings-only benchmark (Ristic et al. 2004, ch. 6): {res.n_runs} runs, seed {res.seed}",
        f"divergence: final position error > {DIVERGENCE_FACTOR:g} x final PCRLB "
        f"= {res.divergence_threshold:.0f} m;  NEES 95% band (4 dof, avg over runs) "
        f"[{res.nees_band[0]:.2f}, {res.nees_band[1]:.2f}] (band is for the non-diverged count)",
        "",
    ]
    ks = [k for k in (0, 8, 12, 16, 20, 24, 28, 32) if k < len(res.times_min)]
    head = f"{'RMS position error (m)':<24}" + "".join(f"{res.times_min[k]:>8.0f}" for k in ks)
    lines += [
        head + "   (minute)",
        f"{'PCRLB':<24}" + "".join(f"{res.pcrlb_position[k]:>8.0f}" for k in ks),
    ]
    for f in res.filters:
        lines.append(f"{f.name:<24}" + "".join(f"{f.rms_position[k]:>8.0f}" for k in ks))
    lines += [
        "",
        f"{'estimator':<24}{'diverged':>10}{'NEES@end':>10}{'NEES avg':>10}{'time (s)':>10}",
    ]
    for f in res.filters:
        lines.append(
            f"{f.name:<24}{100 * f.divergence_rate:>9.1f}%{f.mean_nees[-1]:>10.2f}"
            f"{np.mean(f.mean_nees[1:]):>10.2f}{f.seconds:>10.2f}"
        )
    lines += [
        "",
        "Batch estimators, no prior, all bearings so far, deterministic target (q~ = 0 runs):",
        f"{'minute':<24}" + "".join(f"{m:>8.0f}" for m in res.batch_minutes),
        f"{'CRLB (deterministic)':<24}" + "".join(f"{v:>8.0f}" for v in res.batch_crlb),
        f"{'ML RMS':<24}" + "".join(f"{v:>8.0f}" for v in res.ml_rms),
        f"{'ML RMS / CRLB':<24}"
        + "".join(f"{a / b:>8.3f}" for a, b in zip(res.ml_rms, res.batch_crlb, strict=True)),
        f"{'ML NEES (4 expected)':<24}" + "".join(f"{v:>8.2f}" for v in res.ml_nees),
        f"{'ML 95% coverage':<24}" + "".join(f"{v:>8.3f}" for v in res.ml_coverage95),
        f"{'PLE RMS (weighted)':<24}" + "".join(f"{v:>8.0f}" for v in res.ple_rms),
    ]
    ratio = res.ml_rms[-1] / res.batch_crlb[-1]
    status = "matched" if abs(ratio - 1.0) <= 0.10 else "missed (ML not efficient here)"
    lines += [
        f"ML RMS within 10 % of the CRLB at {res.batch_minutes[-1]:.0f} min: ratio {ratio:.3f} "
        f"-> {status}",
        f"q~ > 0 runs at {res.times_min[-1]:.0f} min (model mismatch): ML RMS "
        f"{res.ml_rms_final_random:.0f} m, PLE RMS {res.ple_rms_final_random:.0f} m, "
        f"PCRLB {res.pcrlb_position[-1]:.0f} m;  batch solves took {res.batch_seconds:.1f} s",
    ]
    return "\n".join(lines)
