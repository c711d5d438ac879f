"""One scan period of moving ground receivers and its velocity-aware conjugation fix (theory §3).

Within a period of length ``τ`` receiver ``k`` fixes the drone at its own delay ``d_k`` after
the period start (theory §6.4, §10.4 OC-4: scanning receivers fix at different times). Receivers
are vehicles: they move in a straight line during the period, so receiver ``k`` is at
``O_k(d_k)`` when it fixes the drone at ``M(d_k)``. The drone flies a straight line, so
``M(d_k) = M(d_1) + V (d_k − d_1)`` and the conjugation equations of theory §3.2 hold exactly
with the base vectors taken *at the fix times*::

    r_1 a_1 − r_k P_k a_k + V Δt_k − b_k = e_k ,   Δt_k = d_k − d_1 ,
    P_k = R_1ᵀ R_k ,   b_k = R_1ᵀ (O_k(d_k) − O_1(d_1))                        (theory §2.1)

solved for ``(r_1, …, r_n, V)`` by :func:`~sensorgym.trackers.stereo.conjugation.solve_conjugation`
(``order=1``; compiled: the closed form for n = 3, the normal equations for more). Each receiver's frame looks at the aim point
(the tracker's predicted drone position), so ``P_k ≠ I`` in general.

Covariance mapping. The solver's ``Q = σ_e² (AᵀA)⁻¹`` assumes i.i.d. errors of ``σ_e`` (m) on
every component of ``e_k`` (the papers' model). A direction error of ``σ_ang`` (rad) displaces
a point at range ``r`` by about ``r σ_ang`` across the line of sight, so we use
``σ_e = σ_ang · mean_k |r̂_k|`` with the *estimated* ranges (the tracker knows no truth). This is
the papers' model, not the angle-noise bound: it is what the tracker reports; the reward uses
the Cramér–Rao bound instead (:mod:`.simulation`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sensorgym.envs.stereo_placement import kernels
from sensorgym.trackers.kernel_args import kernel_array
from sensorgym.trackers.stereo.conjugation import DEFAULT_COND_MAX, solve_conjugation

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


@dataclass(frozen=True)
class ScanFix:
    """The conjugation tracker's output for one scan period, batched over scenarios ``B``."""

    position: FloatArray = field(repr=False)
    """(B, 3) estimated drone position at the period end, world frame, m."""
    velocity: FloatArray = field(repr=False)
    """(B, 3) estimated drone velocity, world frame, m/s."""
    range_sigma: FloatArray = field(repr=False)
    """(B, n) standard deviations of the ranges ``√diag(Q)[:n]``, m."""
    velocity_sigma: FloatArray = field(repr=False)
    """(B,) RMS velocity error ``√tr Q_VV``, m/s."""
    condition: FloatArray = field(repr=False)
    """(B,) Frobenius condition number ``κ_F`` of the conjugation matrix ``A`` (inf: singular)."""
    degenerate: BoolArray = field(repr=False)
    """(B,) True where the solver fell back to the pseudo-inverse (``used_pinv``)."""

    @classmethod
    def trusted(cls, **fields: Any) -> ScanFix:
        """One from arrays the kernels have just written, without the dataclass constructor
        (hot paths only: every field must be given, consistent)."""
        obj = object.__new__(cls)
        obj.__dict__.update(fields)
        return obj


@dataclass(frozen=True)
class ScanGeometry:
    """The true geometry of one scan period (ground truth: reward and rendering only)."""

    origins: FloatArray = field(repr=False)
    """(B, n, 3) receiver positions at their fix times, world frame, m."""
    los: FloatArray = field(repr=False)
    """(B, n, 3) true unit lines of sight at the fix times, world frame."""
    ranges: FloatArray = field(repr=False)
    """(B, n) true ranges at the fix times, m."""
    degenerate: BoolArray = field(repr=False)
    """(B,) True where the noise-free conjugation of this geometry needs the pseudo-inverse
    (coplanar or parallel lines of sight, equal delays): no noise draw can be trusted there."""

    @classmethod
    def trusted(cls, **fields: Any) -> ScanGeometry:
        """One from arrays the kernels have just written, without the dataclass constructor
        (hot paths only: every field must be given, consistent)."""
        obj = object.__new__(cls)
        obj.__dict__.update(fields)
        return obj


def boresight_rotations(origins: FloatArray, aim: FloatArray, max_elevation: float) -> FloatArray:
    """Local→world rotations ``(B, n, 3, 3)`` of receivers at ``origins (B, n, 3)`` looking at
    ``aim (B, 3)``, the boresight elevation held within ``±max_elevation`` (rad) so that the
    frame's roll (``Y`` towards world up) stays defined even right under the aim point."""
    o = np.ascontiguousarray(origins, dtype=np.float64)
    out = np.empty((*o.shape, 3))
    kernels.boresight_batch(o, np.ascontiguousarray(aim, dtype=np.float64), max_elevation, out)
    return out


def _resolve(sol_x, sol_q, kappa, a1, ak, P, b, dt, cond_max: float) -> BoolArray:
    """Re-solve on the generic SVD path where the closed form left ``κ_F > cond_max`` (exactly
    what :func:`solve_conjugation` does after its kernel); returns ``used_pinv``."""
    used = ~(kappa <= cond_max)
    if kernels.any_true(used):
        sol = solve_conjugation(a1[used], ak[used], P[used], b[used], dt[used], order=1)
        sol_x[used] = np.concatenate([sol.ranges, sol.velocity], -1)
        sol_q[used] = sol.covariance
        kappa[used] = sol.condition
        used[used] = sol.used_pinv
    return used


def draw_normals(rng: np.random.Generator, batch: int, n: int, sigma_ang: float) -> FloatArray:
    """The period's noise draws ``(B, n, 3)``: those of ``perturb_directions``, in its order and
    shape (zeros, and no draw, when ``sigma_ang = 0``)."""
    return rng.standard_normal((batch, n, 3)) if sigma_ang > 0.0 else np.zeros((batch, n, 3))


def scan_period(
    delays: FloatArray,
    period: float,
    sigma_ang: float,
    max_elevation: float,
    start: FloatArray,
    end: FloatArray,
    drone_end: FloatArray,
    drone_velocity: FloatArray,
    previous: FloatArray,
    rng: np.random.Generator,
    sigma_ref: float = 1.0,
    reward_clip: float = 5.0,
) -> tuple[ScanFix, ScanGeometry, FloatArray, FloatArray, FloatArray]:
    """One period of every scenario through the compiled kernels (:mod:`.kernels`).

    As :func:`scan`, with the receivers' frames looking at ``previous (B, 6)`` (the tracker's
    last estimate) coasted to mid-period. Returns ``(fix, geometry, estimate (B, 6), bound (B,),
    reward (B,))``: the estimate is the fix, or ``previous`` coasted by ``τ`` where the fix is
    degenerate; ``bound`` the CRLB ``σ_pos`` of the true geometry and ``reward``
    ``clip(ln(σ_ref/σ_pos), −R, R)``, ``−R`` where degenerate (:mod:`.simulation`).
    """
    normals = draw_normals(rng, start.shape[0], len(delays), sigma_ang)
    return solve_period(
        delays, period, sigma_ang, max_elevation, start, end, drone_end, drone_velocity,
        previous, normals, sigma_ref, reward_clip,
    )  # fmt: skip


def solve_period(
    delays: FloatArray,
    period: float,
    sigma_ang: float,
    max_elevation: float,
    start: FloatArray,
    end: FloatArray,
    drone_end: FloatArray,
    drone_velocity: FloatArray,
    previous: FloatArray,
    normals: FloatArray,
    sigma_ref: float = 1.0,
    reward_clip: float = 5.0,
) -> tuple[ScanFix, ScanGeometry, FloatArray, FloatArray, FloatArray]:
    """:func:`scan_period` with its noise draws ``normals (B, n, 3)`` given: the generic path
    (any ``n``; systems the closed form leaves re-solved on the SVD path)."""
    # one form whatever the caller's layout (no copy of the env's arrays): numba compiles the
    # kernels once more for each other layout or read-only input
    d, start, end, drone_end, drone_velocity, previous, normals = (
        kernel_array(x, np.shape(x))
        for x in (delays, start, end, drone_end, drone_velocity, previous, normals)
    )
    B, n = start.shape[0], d.shape[0]
    m, p = n - 1, n + 3
    noisy = sigma_ang > 0.0
    origins, los, R = np.empty((B, n, 3)), np.empty((B, n, 3)), np.empty((B, n, 3, 3))
    ranges = np.empty((B, n))
    a1, e1, ak, ek = np.empty((B, 3)), np.empty((B, 3)), np.empty((B, m, 3)), np.empty((B, m, 3))
    P, b, dt = np.empty((B, m, 3, 3)), np.empty((B, m, 3)), np.empty((B, m))
    X, Q, kappa = np.empty((B, p)), np.empty((B, p, p)), np.empty(B)
    Xe, Qe, kappa_e = np.empty((B, p)), np.empty((B, p, p)), np.empty(B)
    J, M1 = np.empty(B), np.empty((B, 3))
    code = kernels.period_systems(
        (float(period), float(sigma_ang), float(max_elevation)), d,
        (start, end, drone_end, drone_velocity, previous), normals, (origins, los, ranges),
        (R, a1, ak, P, b, dt, e1, ek), (X, J, Q, kappa, M1, Xe, Qe, kappa_e),
    )  # fmt: skip
    if code:  # a zero line of sight: the checked solver raises naming the argument
        solve_conjugation(a1, ak, P, b, dt, order=1)
        raise ValueError("scan: a receiver sits on the drone (no line of sight)")
    # σ_e = 1 here; the finish rescales Q by σ_e² = (σ_ang · mean |r̂|)² (module docstring)
    used = _resolve(X, Q, kappa, a1, ak, P, b, dt, DEFAULT_COND_MAX)
    if noisy:  # the same system without noise: is the geometry itself degenerate?
        used_true = _resolve(Xe, Qe, kappa_e, e1, ek, P, b, dt, DEFAULT_COND_MAX)
    else:
        used_true = used
    position, velocity = np.empty((B, 3)), np.empty((B, 3))
    range_sigma, velocity_sigma = np.empty((B, n)), np.empty(B)
    estimate, bound, reward = np.empty((B, 6)), np.empty(B), np.empty(B)
    kernels.period_finish(
        (float(period), float(sigma_ang), float(sigma_ref), float(reward_clip)), d,
        (origins, los, ranges), (R, a1, X, Q), (used, used_true), previous,
        (position, velocity, range_sigma, velocity_sigma), (estimate, bound, reward),
    )  # fmt: skip
    fix = ScanFix(position, velocity, range_sigma, velocity_sigma, kappa, used)
    return fix, ScanGeometry(origins, los, ranges, used_true), estimate, bound, reward


def scan(
    delays: FloatArray,
    period: float,
    sigma_ang: float,
    max_elevation: float,
    start: FloatArray,
    end: FloatArray,
    drone_end: FloatArray,
    drone_velocity: FloatArray,
    aim: FloatArray,
    rng: np.random.Generator,
) -> tuple[ScanFix, ScanGeometry]:
    """Simulate one period and solve its conjugation system.

    ``delays (n,)`` fix times after the period start, s; ``period`` ``τ``, s; ``sigma_ang`` rad;
    receivers move linearly from ``start`` to ``end`` ``(B, n, 3)`` over the period; the drone
    is at ``drone_end (B, 3)`` at the period end with ``drone_velocity (B, 3)``; ``aim (B, 3)``
    is where the receivers' frames look. Draws ``B·n·3`` normals from ``rng`` when
    ``sigma_ang > 0`` (none otherwise).
    """
    arrays = (start, end, drone_end, drone_velocity)
    start, end, drone_end, drone_velocity = (np.ascontiguousarray(x, np.float64) for x in arrays)
    aim = np.ascontiguousarray(aim, dtype=np.float64)
    previous = np.concatenate([aim, np.zeros_like(aim)], -1)  # aim + ½τ·0 = aim
    fix, geometry, *_ = scan_period(
        delays, period, sigma_ang, max_elevation, start, end, drone_end, drone_velocity,
        previous, rng,
    )  # fmt: skip
    return fix, geometry
