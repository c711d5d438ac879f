"""Paper 000: detection and tracking of several objects by 2 or 3 receivers (theory §5.2–5.3).

*Alternative algorithm* (n = 2, the "existing approach", theory §5.2): every pair of direction
vectors ``(a_1(i, j1), a_2(i, j2))`` of a period is conjugated by least squares (000 eq. 7–8);
pairs with ``J = ‖e_2‖² ≤ ε_J`` (eq. 9) become candidate positions ``M(i, j)``. Groups of
candidates across periods start as all pairs of periods 1 and 2, are extended by
extrapolating a straight-line fit over their members and gating ``ΔJ ≤ δ``, and the m̂
least-index groups sharing no vector are output. The motion between fixes (``Δt``) is
ignored in the spatial step, so positions carry the dynamic error ``≈ (a_1·V) Δt``.

*Proposed algorithm* (n = 3, velocity-aware, theory §5.3): every triple is solved by the 6×6
system (000 eq. 10–11) for ranges and velocity, ``r̂_1`` re-solved from the pair with
``B̂_2 = b_2 − V̂ Δt_2``; every triple is a candidate ``(M, V)`` (the square system cannot
reject any), groups are extended by ``ΔJ = ‖M(i, j) − (M̂_s + V̂_s Δt)‖ ≤ δ`` and keep the
latest spatial estimate. False triples die in the temporal stage.

Gating and pruning (theory §13.13): spatial candidates with a non-positive range or a
speed above ``max_speed`` are dropped, and the G_max beam bounds the number of groups. The
least squares are the conjugation core's (:mod:`.conjugation`), called once per period on
all candidates.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sensorgym.trackers.stereo import association as assoc
from sensorgym.trackers.stereo.conjugation import solve_pair, solve_proposed
from sensorgym.trackers.validation import check_fields, finite_array

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


@dataclass(frozen=True)
class AlternativeParams:
    """Thresholds of the alternative algorithm (theory §5.2, §13.6)."""

    position_sigma: float = 0.1
    """σ_x: std of each coordinate of the error of a candidate position M(i, j), m."""
    max_speed: float = 50.0
    """Largest plausible object speed, m/s (bounds the motion-induced conjugation error)."""
    max_delay: float = 0.25
    """Largest delay Δt between the two receivers' fixes of one object, s."""
    gate_probability: float = 0.999
    """Probability that a true candidate passes each noise gate."""
    bias_drift: float = 1.0
    """Fraction of the largest dynamic error ``max_speed · max_delay`` by which that error may
    change between periods (the line of sight turns), added to δ."""
    max_shared: int = 0
    """π: vectors a selected group may share with each other selected group."""
    beam: int | None = 2000
    """G_max: largest number of groups carried between periods (None: unbounded)."""
    eps_J_override: float | None = None
    """ε_J in m² if given, else :attr:`eps_J`."""
    delta_override: float | None = None
    """δ in m if given, else :attr:`delta`."""

    def __post_init__(self) -> None:
        check_fields(self)  # every field of its annotated type: no bool for a count or a number
        if not (self.position_sigma > 0.0 and self.max_speed >= 0.0 and self.max_delay >= 0.0):
            raise ValueError("position_sigma > 0, max_speed >= 0, max_delay >= 0 required")
        if not 0.0 < self.gate_probability < 1.0:
            raise ValueError("gate_probability: must lie in (0, 1)")
        if self.max_shared < 0 or (self.beam is not None and self.beam < 1):
            raise ValueError("max_shared >= 0 and beam >= 1 (or None) required")

    @property
    def eps_J(self) -> float:
        """ε_J, m²: ``(q_{3D}(√2 σ_x) + v_max Δt_max)²`` — noise plus the largest miss distance
        the unmodelled motion can open between the two rays."""
        if self.eps_J_override is not None:
            return self.eps_J_override
        q = assoc.norm_quantile(np.sqrt(2.0) * self.position_sigma, self.gate_probability)
        return (q + self.max_speed * self.max_delay) ** 2

    @property
    def delta(self) -> float:
        """δ, m: ``q_{3D}(√6 σ_x) + bias_drift · v_max Δt_max``. √6 σ_x bounds the error of a
        two-point extrapolation (``2M_2 − M_1``, variance 5σ²) plus the new candidate (σ²)."""
        if self.delta_override is not None:
            return self.delta_override
        q = assoc.norm_quantile(np.sqrt(6.0) * self.position_sigma, self.gate_probability)
        return q + self.bias_drift * self.max_speed * self.max_delay


@dataclass(frozen=True)
class ProposedParams:
    """Thresholds of the proposed velocity-aware algorithm (theory §5.3, §13.6)."""

    position_sigma: float = 0.1
    """σ_x: std of each coordinate of the error of a candidate position M(i, j), m."""
    velocity_sigma: float = 0.0
    """Std of each coordinate of the candidate velocity error, m/s (0 under the papers' model,
    where every receiver sees the same displaced point and V̂ is exact)."""
    period: float = 1.0
    """Period τ, s (extrapolation horizon of the velocity error in δ)."""
    max_speed: float = 50.0
    """Candidates faster than this are implausible and dropped, m/s."""
    gate_probability: float = 0.999
    """Probability that a true continuation passes δ."""
    max_shared: int = 0
    """π: vectors a selected group may share with each other selected group."""
    beam: int | None = 2000
    """G_max: largest number of groups carried between periods (None: unbounded)."""
    cond_max: float = 1e7
    """Condition number above which the core takes the pseudo-inverse branch."""
    delta_override: float | None = None
    """δ in m if given, else :attr:`delta`."""

    def __post_init__(self) -> None:
        check_fields(self)  # every field of its annotated type: no bool for a count or a number
        if not (self.position_sigma > 0.0 and self.velocity_sigma >= 0.0 and self.period > 0.0):
            raise ValueError("position_sigma > 0, velocity_sigma >= 0, period > 0 required")
        if not 0.0 < self.gate_probability < 1.0:
            raise ValueError("gate_probability: must lie in (0, 1)")
        if self.max_shared < 0 or (self.beam is not None and self.beam < 1):
            raise ValueError("max_shared >= 0 and beam >= 1 (or None) required")

    @property
    def delta(self) -> float:
        """δ, m: ``q_{3D}(√(2σ_x² + σ_v²τ²))`` — the difference of two independent candidate
        errors plus the velocity error over one period (theory §13.6: 5.7 σ_x at 99.9 %)."""
        if self.delta_override is not None:
            return self.delta_override
        s = np.sqrt(2.0 * self.position_sigma**2 + (self.velocity_sigma * self.period) ** 2)
        return assoc.norm_quantile(s, self.gate_probability)


@dataclass(frozen=True)
class Candidates:
    """Spatial-processing output of one period (theory §5.2 step 3, §5.3 step 2)."""

    members: IntArray
    """(C, n) fix index in each receiver's list."""
    position: FloatArray
    """(C, 3) M(i, j) = r̂_1 a_1 in frame 1 at ``time``, m."""
    velocity: FloatArray
    """(C, 3) velocity estimate in frame 1, m/s (NaN for the alternative algorithm)."""
    time: FloatArray
    """(C,) t(i, j) = t_1 of the receiver-1 fix, s."""
    residual: FloatArray
    """(C,) conjugation residual J = ‖E‖², m²."""


def _check_period(fixes: Sequence[assoc.Fixes], n: int, i: int) -> None:
    if len(fixes) != n:
        raise ValueError(f"periods[{i}]: expected fixes of {n} receivers, got {len(fixes)}")


def alternative_candidates(
    fix1: assoc.Fixes, fix2: assoc.Fixes, P2: ArrayLike, b2: ArrayLike, eps_J: float
) -> Candidates:
    """All pairs ``(j1, j2)`` conjugated at once (000 eq. 7–9); keep ``J ≤ ε_J``, ``r̂ > 0``."""
    C = assoc.combinations([fix1.times.shape[0], fix2.times.shape[0]])
    if C.shape[0] == 0:
        return Candidates(C, np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0), np.zeros(0))
    sol = solve_pair(fix1.directions[C[:, 0]], fix2.directions[C[:, 1]], P2, b2)
    # J ≤ ε_J (000 step 3) and both ranges in front of the receivers
    keep = (sol.residual <= eps_J) & np.all(sol.ranges > 0.0, axis=-1) & ~sol.used_pinv
    vel = np.full((int(keep.sum()), 3), np.nan)
    return Candidates(C[keep], sol.position[keep], vel, fix1.times[C[keep, 0]], sol.residual[keep])


def proposed_candidates(
    fixes: Sequence[assoc.Fixes], P: ArrayLike, b: ArrayLike, params: ProposedParams
) -> Candidates:
    """All triples ``(j1, j2, j3)`` solved at once by the velocity-aware system (000 eq. 10–11)."""
    C = assoc.combinations([f.times.shape[0] for f in fixes])
    if C.shape[0] == 0:
        return Candidates(C, np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0), np.zeros(0))
    a1 = fixes[0].directions[C[:, 0]]
    ak = np.stack([fixes[k].directions[C[:, k]] for k in (1, 2)], axis=1)
    t1 = fixes[0].times[C[:, 0]]
    # Δt_k = t_k(i, j_k) − t_1(i, j_1)
    dt = np.stack([fixes[k].times[C[:, k]] for k in (1, 2)], axis=1) - t1[:, None]
    sol = solve_proposed(a1, ak, P, b, dt, cond_max=params.cond_max)
    speed = np.linalg.norm(sol.velocity, axis=-1)
    keep = np.all(sol.ranges > 0.0, axis=-1) & (speed <= params.max_speed)
    return Candidates(C[keep], sol.position[keep], sol.velocity[keep], t1[keep], sol.residual[keep])


def _line_fit(S: FloatArray, t_ref: FloatArray) -> tuple[FloatArray, FloatArray]:
    """LS straight line ``M(t) = M̂ + V̂ (t − t_ref)`` from sums ``(S0, St, Stt, SM(3), StM(3))``.

    theory §13.11: the alternative's "re-estimate from all vectors of the group, taking
    their formation times into account" as a least-squares line fit over the members.
    """
    S0, St, Stt = S[:, 0:1], S[:, 1:2], S[:, 2:3]
    SM, StM = S[:, 3:6], S[:, 6:9]
    # V̂ = (S0 ΣtM − Σt ΣM) / (S0 Σt² − (Σt)²)
    V = (S0 * StM - St * SM) / (S0 * Stt - St**2)
    # M̂(t_ref) = (ΣM − V̂ Σt)/S0 + V̂ t_ref
    M = (SM - V * St) / S0 + V * t_ref[:, None]
    return M, V


def _sums(position: FloatArray, time: FloatArray) -> FloatArray:
    t = time[:, None]
    return np.concatenate([np.ones_like(t), t, t**2, position, t * position], axis=1)


def track_alternative(
    periods: Sequence[Sequence[assoc.Fixes]],
    P2: ArrayLike,
    b2: ArrayLike,
    params: AlternativeParams = AlternativeParams(),
) -> assoc.Detection:
    """Paper 000's alternative algorithm (theory §5.2) over ``N ≥ 2`` periods of two receivers.

    ``P2 (3, 3)``, ``b2 (3,)`` relative pose of receiver 2 (or per period: ``(N, 3, 3)``,
    ``(N, 3)``). Positions are fitted lines evaluated at each group's latest member time.
    """
    N = len(periods)
    if N < 2:
        raise ValueError("periods: the alternative algorithm needs at least 2 periods")
    P2 = finite_array(P2, "P2", tail=(3, 3))
    b2 = finite_array(b2, "b2", tail=(3,))
    eps_J, delta = params.eps_J, params.delta
    cands = []
    for i, fixes in enumerate(periods):
        _check_period(fixes, 2, i)
        Pi, bi = assoc.per_period(P2, i, 2), assoc.per_period(b2, i, 1)
        cands.append(alternative_candidates(fixes[0], fixes[1], Pi, bi, eps_J))
    c1, c2 = cands[0], cands[1]
    # periods 1 and 2: every pair of candidates opens a group, J_s = 0 (000 temporal step 1)
    pair = assoc.combinations([c1.time.shape[0], c2.time.shape[0]])
    G = pair.shape[0]
    members = np.full((G, N, 2), -1, dtype=np.int64)
    members[:, 0], members[:, 1] = c1.members[pair[:, 0]], c2.members[pair[:, 1]]
    sums = _sums(c1.position[pair[:, 0]], c1.time[pair[:, 0]]) + _sums(
        c2.position[pair[:, 1]], c2.time[pair[:, 1]]
    )
    pos_hist = np.full((G, N, 3), np.nan)
    vel_hist = np.full((G, N, 3), np.nan)
    t_hist = np.full((G, N), np.nan)
    t_latest = c2.time[pair[:, 1]]
    with np.errstate(divide="ignore", invalid="ignore"):
        M, V = _line_fit(sums, t_latest)
    ok = np.all(np.isfinite(V), axis=1) & (np.linalg.norm(V, axis=1) <= 2.0 * params.max_speed)
    pos_hist[:, 0], t_hist[:, 0] = c1.position[pair[:, 0]], c1.time[pair[:, 0]]
    pos_hist[:, 1], vel_hist[:, 1], t_hist[:, 1] = M, V, t_latest
    keep = np.flatnonzero(ok)
    members, sums, pos_hist, vel_hist, t_hist = (
        x[keep] for x in (members, sums, pos_hist, vel_hist, t_hist)
    )
    score = np.zeros(keep.shape[0])
    M, V, t_latest = M[keep], V[keep], t_latest[keep]
    for i in range(2, N):
        c = cands[i]
        # ΔJ = ‖M(i, j) − (M̂_s + V̂_s (t(i, j) − t_latest))‖  (000 steps 3–4)
        dJ = assoc.extrapolation_residual(M, V, t_latest, c.position, c.time)
        g, j, score = assoc.extend(score, dJ, delta, params.beam)
        members = members[g]
        members[:, i] = c.members[j]
        sums = sums[g] + _sums(c.position[j], c.time[j])
        t_latest = c.time[j]
        M, V = _line_fit(sums, t_latest)
        pos_hist, vel_hist, t_hist = pos_hist[g], vel_hist[g], t_hist[g]
        pos_hist[:, i], vel_hist[:, i], t_hist[:, i] = M, V, t_latest
    return assoc.Detection.select_from(
        members, score, pos_hist, vel_hist, t_hist, params.max_shared
    )


def track_proposed(
    periods: Sequence[Sequence[assoc.Fixes]],
    P: ArrayLike,
    b: ArrayLike,
    params: ProposedParams = ProposedParams(),
) -> assoc.Detection:
    """Paper 000's proposed algorithm (theory §5.3) over ``N ≥ 1`` periods of three receivers.

    ``P (2, 3, 3)``, ``b (2, 3)`` relative poses of receivers 2, 3 (or per period with a leading
    ``N`` axis). Each group keeps its latest spatial estimate ``(M, V)`` (000 step 3).
    """
    N = len(periods)
    if N < 1:
        raise ValueError("periods: need at least one period")
    P = finite_array(P, "P", tail=(2, 3, 3))
    b = finite_array(b, "b", tail=(2, 3))
    cands = []
    for i, fixes in enumerate(periods):
        _check_period(fixes, 3, i)
        Pi, bi = assoc.per_period(P, i, 3), assoc.per_period(b, i, 2)
        cands.append(proposed_candidates(fixes, Pi, bi, params))
    c = cands[0]
    G = c.time.shape[0]
    # period 1: each candidate opens a group, J_s = 0 (000 proposed temporal step 1)
    members = np.full((G, N, 3), -1, dtype=np.int64)
    members[:, 0] = c.members
    score = np.zeros(G)
    pos_hist = np.full((G, N, 3), np.nan)
    vel_hist = np.full((G, N, 3), np.nan)
    t_hist = np.full((G, N), np.nan)
    pos_hist[:, 0], vel_hist[:, 0], t_hist[:, 0] = c.position, c.velocity, c.time
    keep = assoc.prune(score, params.beam)
    members, score, pos_hist, vel_hist, t_hist = (
        x[keep] for x in (members, score, pos_hist, vel_hist, t_hist)
    )
    M, V, t_s = pos_hist[:, 0], vel_hist[:, 0], t_hist[:, 0]
    delta = params.delta
    for i in range(1, N):
        c = cands[i]
        # ΔJ = ‖M(i, j) − (M̂_s + V̂_s (t(i, j) − t_s))‖ ≤ δ  (000 proposed steps 2–3)
        dJ = assoc.extrapolation_residual(M, V, t_s, c.position, c.time)
        g, j, score = assoc.extend(score, dJ, delta, params.beam)
        members = members[g]
        members[:, i] = c.members[j]
        # the group keeps the latest spatial estimates, not a fit
        M, V, t_s = c.position[j], c.velocity[j], c.time[j]
        pos_hist, vel_hist, t_hist = pos_hist[g], vel_hist[g], t_hist[g]
        pos_hist[:, i], vel_hist[:, i], t_hist[:, i] = M, V, t_s
    return assoc.Detection.select_from(
        members, score, pos_hist, vel_hist, t_hist, params.max_shared
    )
