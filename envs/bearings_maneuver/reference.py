"""The readable reference of the BearingsManeuver reset and step: the spec of the compiled kernels.

The envs (``sensorgym/BearingsManeuver-v0``, ``sensorgym/BearingsManeuverBook-v0`` and their
vector and PettingZoo doors) run :mod:`.simulation`, whose :func:`~.simulation.reset` and
:func:`~.simulation.step` hand their draws to the compiled kernels of :mod:`.kernels`, which
are written for speed (fused loops over rows, scalars in locals, scratch arrays). This module
is the same reset and step written to be read: numpy over the batch, one stage a function,
in the order of the equations of ``docs/theory.md`` (§2.5, §7.7–§7.9, §11.2), each stage
citing its section. It is never run by the envs.

It follows the simulation contract (:mod:`sensorgym.envs.shells.contract`) with the very
signatures of :mod:`.simulation`: the same params, the same :class:`~.simulation.ManeuverState`
(with the derived fields the kernels write: observation, nearest range, position error), the
same random draws taken from the Generator in the same order and shapes. :func:`spaces`,
:func:`observe`, :func:`observe_agents` and :func:`info` only read a state's fields, so they
are :mod:`.simulation`'s own, re-exported: this module is a complete simulation, and
``Core(reference, params)`` runs.

Each formula lives once: where the package has a readable numpy form (the motion and
measurement models of :mod:`sensorgym.trackers.bearings.models`, the second-order EKF bank
update of :mod:`sensorgym.trackers.bearings.filters`, the bounds read off ``P`` in
:mod:`sensorgym.trackers.bearings.crlb`, the prior's range cells) it is called, not copied.
Three one-line primitives are the package's single compiled copies and are called as such
from numpy: the bearing ``β = atan2(Δx, Δy)`` (:func:`~sensorgym.trackers.bearings.models.
bearing`), the angle wrap (:func:`~sensorgym.trackers.geometry.wrap_angle`) and the rotation
into a platform's frame (:func:`.simulation.body_frame`). Everything else is numpy here.

How it is checked: ``tests/envs/bearings_maneuver/test_reference.py`` steps this module and
:mod:`.simulation` from the same state with the same draws over whole episodes of both envs'
params (autoresets included) and compares states, observations, rewards, terminations and
infos within rounding (numba may fuse and reorder float operations).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sensorgym.envs.bearings_maneuver.simulation import (
    ACCURACY_FLOOR,
    ManeuverParams,
    ManeuverState,
    body_frame,
    draw_scenario,
    info,
    observe,
    observe_agents,
    spaces,
)
from sensorgym.envs.shells.contract import clip_observation
from sensorgym.envs.worlds.platform import cwna_noise_factor
from sensorgym.trackers.bearings.crlb import position_rms_bound, relative_range_bound
from sensorgym.trackers.bearings.filters import RangeBankState, range_bank_update
from sensorgym.trackers.bearings.models import (
    BearingsGaussian,
    bearing,
    bearing_jacobian,
    cv_transition,
    cwna_covariance,
    cwna_covariance_factor,
)
from sensorgym.trackers.geometry import wrap_angle

__all__ = ["info", "observe", "observe_agents", "reset", "spaces", "step"]

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


# --- the contract: reset and step ---------------------------------------------------------------


def reset(
    params: ManeuverParams,
    rng: np.random.Generator,
    batch: int,
    like: ManeuverState | None = None,
) -> ManeuverState:
    """``batch`` fresh scenarios (:func:`.simulation.reset`): the scenario draws, the first
    bearings, the tracker's prior from platform 1's bearing, the bound ``P_0`` and the other
    platforms' first bearings fused into both (theory §11.2)."""
    if batch < 1:
        raise ValueError(f"batch: must be >= 1, got {batch}")
    sigma = params.world.sigma_bearing
    heading, target, positions = draw_scenario(params, rng, batch)
    z = take_bearings(params, target, positions, rng.standard_normal((batch, params.platforms)))
    bank = prior_bank(params, z[:, 0], positions[:, 0], 0.0 if like is None else like.bank.t)
    # P_0 = P_prior, the bank's prior covariance, which already holds platform 1's first bearing
    # (§11.2); its square root by Cholesky (the kernel counts a pivot that rounding takes to
    # ≤ 0 as zero: never at these scales, where np.linalg.cholesky would raise)
    L = np.linalg.cholesky(moment_match(bank).P)
    # P_0 = (P_prior⁻¹ + Σ_{k≥2} Hᵀ H / σ²)⁻¹: the other platforms' first bearings
    for k in range(1, params.platforms):
        bank = update_bank(bank, z[:, k], positions[:, k], sigma)
        L = update_bound(L, target, positions[:, k], sigma)
    state = ManeuverState(
        t=np.zeros(batch),
        platform_position=positions,
        heading=heading,
        speed=np.full((batch, params.platforms), params.initial_platform_speed),
        target=target,
        bank=bank,
        bound_factor=L,
        accuracy=accuracy(params, L, target, positions[:, 0]),
        bearing=z,
        observation=np.empty(0, dtype=np.float32),  # derived below
        nearest_range=np.empty(0),
        position_error=np.empty(0),
    )
    return with_derived_fields(params, state)


def step(
    params: ManeuverParams, state: ManeuverState, action: ArrayLike, rng: np.random.Generator
) -> tuple[ManeuverState, FloatArray, BoolArray]:
    """One step of ``params.world.dt`` under the joint action ``(B, K, 2)`` in ``[−1, 1]``
    (:func:`.simulation.step`): ``(state, reward (B,), terminated (B,))``."""
    w = params.world
    B, K = state.heading.shape
    a = np.asarray(action, dtype=np.float64).reshape(B, K, 2)
    # the draws, in this order: the target's process noise (only when q̃ > 0), the bearings' noise
    target_noise = rng.standard_normal((B, 4)) if w.q_tilde > 0.0 else None
    bearing_noise = rng.standard_normal((B, K))
    if not np.all(np.isfinite(a)):
        raise ValueError("action: contains NaN or infinite values")
    # 1. the platforms fly, the target moves on
    positions, heading, speed = fly(params, state.platform_position, state.heading, state.speed, a)
    target = move_target(params, state.target, target_noise)
    # 2. every platform takes a bearing; the bank predicts, then fuses them in platform order
    z = take_bearings(params, target, positions, bearing_noise)
    bank = predict_bank(state.bank, w.dt, w.q_tilde)
    for k in range(K):
        bank = update_bank(bank, z[:, k], positions[:, k], w.sigma_bearing)
    # 3. the bound on the true state: predict, then each platform's bearing information
    L = predict_bound(state.bound_factor, w.dt, w.q_tilde)
    for k in range(K):
        L = update_bound(L, target, positions[:, k], w.sigma_bearing)
    m = accuracy(params, L, target, positions[:, 0])
    # 4. what the agents see (and info reads), from the bank's estimate
    new = ManeuverState(
        t=state.t + w.dt,
        platform_position=positions,
        heading=heading,
        speed=speed,
        target=target,
        bank=bank,
        bound_factor=L,
        accuracy=m,
        bearing=z,
        observation=np.empty(0, dtype=np.float32),  # derived below
        nearest_range=np.empty(0),
        position_error=np.empty(0),
    )
    new = with_derived_fields(params, new)
    # 5. reward and episode end: a platform within the stand-off min_range
    terminated = new.nearest_range < params.min_range
    return new, reward(params, state.accuracy, m, terminated), terminated


# --- the world: scenario, flight, target motion, bearings (theory §2.5, §7.7, §11.2) ------------


def fly(
    params: ManeuverParams,
    position: FloatArray,
    heading: FloatArray,
    speed: FloatArray,
    action: FloatArray,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Every platform one step on (theory §11.2): the action ``a`` clipped to ``[−1, 1]``,
    heading rate ``ω = a₀ ω_max``, speed ``v' = clip(v + a₁ Δv_max, v_min, v_max)`` from the
    start of the step, then the exact circular arc::

        p' = p + v' T sinc(ωT/2) (sin ψ_m, cos ψ_m),   ψ_m = ψ + ωT/2,   ψ' = wrap(ψ + ωT)

    with ``sinc x = sin x / x`` (the chord of the arc; velocity ``v (sin ψ, cos ψ)``, §2.5)."""
    w = params.world
    T = w.dt
    a = np.clip(action, -1.0, 1.0)
    omega = a[..., 0] * w.max_turn_rate
    v = np.clip(speed + a[..., 1] * w.max_speed_change, w.min_speed, w.max_speed)
    half_turn = 0.5 * omega * T
    chord = v * T * np.sinc(half_turn / np.pi)  # numpy's sinc is sin(πx)/(πx)
    psi_mid = heading + half_turn
    arc = chord[..., None] * np.stack([np.sin(psi_mid), np.cos(psi_mid)], -1)
    return position + arc, wrap_angle(heading + omega * T), v


def move_target(params: ManeuverParams, target: FloatArray, noise: FloatArray | None) -> FloatArray:
    """The target one step on (theory §7.7): ``x' = F(T) x + w``, ``w = G ε ~ N(0, Q(T))`` with
    ``G`` the Cholesky factor of ``Q`` and ``ε`` the standard normals drawn for it (none when
    ``q̃ = 0``: constant velocity)."""
    w = params.world
    x = target @ cv_transition(w.dt).T
    if noise is not None:
        x = x + noise @ cwna_noise_factor(w.dt, w.q_tilde).T
    return x


def take_bearings(
    params: ManeuverParams, target: FloatArray, positions: FloatArray, noise: FloatArray
) -> FloatArray:
    """Every platform's noisy bearing ``(B, K)`` of the target (theory §2.5, §7.7):
    ``z = wrap(β + σ ε)``, ``β = atan2(x_t − x_p, y_t − y_p)``, ``ε`` the standard normals."""
    beta = bearing(target[:, None, :2], positions)
    return wrap_angle(beta + params.world.sigma_bearing * noise)


# --- the tracker: range-parameterised bank of second-order EKFs (theory §7.9, §11.2) -----------


def prior_bank(
    params: ManeuverParams, z: FloatArray, position: FloatArray, t: float
) -> RangeBankState:
    """The bank's prior from platform 1's first bearing ``z (B,)`` taken at ``position (B, 2)``
    (theory §7.9, Ristic §6.3.1; §11.2): member ``n`` at position ``p + r (sin β, cos β)`` with
    range ``r ~ N(r_n, σ_{r,n}²)`` and bearing ``β ~ N(z, σ²)``, velocity ``s (sin c, cos c)``
    with speed ``s ~ N(s̄, σ_s²)`` and course ``c`` uniform over the full circle (mean ``z``),
    each summarised by its exact moments; ``P = diag(Cov_pos, Cov_vel)``, weights ``w_n``."""
    # the range cells r_n, σ_{r,n} and log weights (a uniform range density over
    # params.prior_ranges), the bearing's spread (Gaussian σ) and the course's (uniform, π/√3)
    r, sigma_r, log_w, bearing_spread, course_spread = params.prior_cells
    s_mean, s_sigma = params.prior_speed_moments
    angle = z[:, None]  # (B, 1): one bearing for every member
    pos_mean, pos_cov = polar_moments(r, sigma_r, angle, bearing_spread)
    vel_mean, vel_cov = polar_moments(s_mean, s_sigma, angle, course_spread)
    B, N = z.shape[0], r.shape[0]
    x = np.concatenate([position[:, None, :] + pos_mean, np.broadcast_to(vel_mean, (B, N, 2))], -1)
    P = np.zeros((B, N, 4, 4))
    P[..., :2, :2] = pos_cov
    P[..., 2:, 2:] = vel_cov
    return RangeBankState(np.tile(log_w, (B, 1)), BearingsGaussian(x, P, t))


def polar_moments(
    m: ArrayLike, sigma_m: ArrayLike, a: ArrayLike, spread: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Exact mean ``(..., 2)`` and covariance ``(..., 2, 2)`` of ``m (sin a, cos a)``, the
    magnitude ``m ~ N(m̄, σ_m²)`` independent of the angle about ``ā`` (theory §7.9), from the
    angle spread's ``spread = (c₁, s₂, Var[cos δ])``, ``c₁ = E[cos δ]``, ``s₂ = E[sin²δ]``
    (:func:`~sensorgym.trackers.bearings.filters.angle_spread_moments`)::

        E = m̄ c₁ u,   Cov = var_u u uᵀ + var_t t tᵀ,   u = (sin ā, cos ā),  t = (cos ā, −sin ā)
        var_u = m̄² Var[cos δ] + σ_m² (1 − s₂),   var_t = (m̄² + σ_m²) s₂
    """
    c1, s2, var_cos = spread
    u = np.stack(np.broadcast_arrays(np.sin(a), np.cos(a)), -1)
    t = np.stack(np.broadcast_arrays(np.cos(a), -np.sin(a)), -1)
    m, sigma_m = np.asarray(m), np.asarray(sigma_m)
    mean = (m * c1)[..., None] * u
    var_u = m**2 * var_cos + sigma_m**2 * (1.0 - s2)
    var_t = (m**2 + sigma_m**2) * s2
    cov = var_u[..., None, None] * _outer(u, u) + var_t[..., None, None] * _outer(t, t)
    return mean, cov


def predict_bank(bank: RangeBankState, T: float, q_tilde: float) -> RangeBankState:
    """Every member ``T`` seconds on (theory §7.7): ``x⁻ = F x``, ``P⁻ = F P Fᵀ + Q``
    (symmetrised); the weights are unchanged."""
    F, Q = cv_transition(T), cwna_covariance(T, q_tilde)
    members = bank.members
    x = members.x @ F.T
    P = _symmetric(F @ members.P @ F.T + Q)
    return RangeBankState(bank.log_weights, BearingsGaussian(x, P, members.t + T))


def update_bank(
    bank: RangeBankState, z: FloatArray, position: FloatArray, sigma: float
) -> RangeBankState:
    """Every member takes the bearing ``z (B,)`` from ``position (B, 2)`` by the second-order
    EKF (theory §7.9, §11.6)::

        ẑ = β(x⁻) + ½ tr(B P_pp),   R = σ² + ½ tr(B P_pp B P_pp),   ν = wrap(z − ẑ),
        S = H P Hᵀ + R,   K = P Hᵀ/S,   x⁺ = x⁻ + K ν,   P⁺ = (I − K H) P (I − K H)ᵀ + K R Kᵀ

    and its weight the bearing's likelihood, ``log wᵢ += log N(νᵢ; 0, Sᵢ)``, renormalised: the
    numpy form :func:`~sensorgym.trackers.bearings.filters.range_bank_update` (``"ekf2"``)."""
    return range_bank_update(bank, z, position, sigma, component="ekf2")


def moment_match(bank: RangeBankState) -> BearingsGaussian:
    """The bank's output, the moment-matched mixture (theory §7.9)::

    x = Σ wᵢ xᵢ,   P = Σ wᵢ (Pᵢ + (xᵢ − x)(xᵢ − x)ᵀ)   (symmetrised)
    """
    w = np.exp(bank.log_weights)[..., None]
    X, P = bank.members.x, bank.members.P
    x = np.sum(w * X, axis=-2)
    d = X - x[..., None, :]
    P = np.sum(w[..., None] * (P + _outer(d, d)), axis=-3)
    return BearingsGaussian(x, _symmetric(P), bank.t)


# --- the bound: posterior CRLB on the true state, square-root form (theory §7.8, §11.2) --------


def predict_bound(L: FloatArray, T: float, q_tilde: float) -> FloatArray:
    """Square root of ``P̄ = F P Fᵀ + Q`` from ``P = L Lᵀ`` (theory §7.8): ``F L`` when ``q̃ = 0``,
    else the triangular factor of ``[F L, G]`` (``G Gᵀ = Q`` in closed form)."""
    FL = cv_transition(T) @ L
    if q_tilde == 0.0:
        return FL
    G = np.broadcast_to(cwna_covariance_factor(T, q_tilde), FL.shape)
    return _triangular_root(np.concatenate([FL, G], axis=-1))


def update_bound(
    L: FloatArray, target: FloatArray, position: FloatArray, sigma: float
) -> FloatArray:
    """Square root of ``P⁺ = (P̄⁻¹ + Hᵀ H / σ²)⁻¹ = P̄ − P̄ Hᵀ (H P̄ Hᵀ + σ²)⁻¹ H P̄`` after one
    bearing at the true ``target (B, 4)`` from ``position (B, 2)`` (theory §7.8): with
    ``H = n̂ᵀ/r`` (``n̂`` the unit normal to the line of sight), triangularise the pre-array
    ``M = [[r σ, n̂ᵀ L_pos], [0, L]]`` (``L`` the root of ``P̄``); its lower-right block is
    the root of ``P⁺``."""
    H = bearing_jacobian(target, position)  # (Δy, −Δx, 0, 0)/r²
    d = target[:, :2] - position
    r = np.hypot(d[:, 0], d[:, 1])
    n_hat = r[:, None] * H[:, :2]
    M = np.zeros((L.shape[0], 5, 5))
    M[:, 0, 0] = r * sigma
    M[:, 0, 1:] = np.einsum("bi,bij->bj", n_hat, L[:, :2, :])
    M[:, 1:, 1:] = L
    return _triangular_root(M)[:, 1:, 1:]


def accuracy(
    params: ManeuverParams, L: FloatArray, target: FloatArray, origin: FloatArray
) -> FloatArray:
    """The accuracy ``m(P)`` the reward measures (theory §11.2) of ``P = L Lᵀ``: the position
    RMS bound ``√(P_xx + P_yy)``, or the relative range bound ``σ_r/r`` from ``origin``
    (platform 1); kept inside ``[ACCURACY_FLOOR, 1/ACCURACY_FLOOR]``."""
    P = L @ np.swapaxes(L, -1, -2)
    if params.metric == "relative_range":
        m = relative_range_bound(P, target[:, :2], origin)
    else:
        m = position_rms_bound(P)
    return np.clip(m, ACCURACY_FLOOR, 1.0 / ACCURACY_FLOOR)


# --- reward, observation -----------------------------------------------------------------------


def reward(
    params: ManeuverParams, m_before: FloatArray, m_after: FloatArray, terminated: BoolArray
) -> FloatArray:
    """``reward_k = ln m(P_k) − ln m(P_{k+1})``, less ``close_penalty`` when a platform came
    within ``min_range`` of the target (the termination; theory §11.2)."""
    return np.log(m_before) - np.log(m_after) - params.close_penalty * terminated


def with_derived_fields(params: ManeuverParams, state: ManeuverState) -> ManeuverState:
    """``state`` with the fields :func:`observe` and :func:`info` read, from the bank's
    moment-matched estimate ``x̂``, ``P̂`` (theory §7.9): every platform's observation (the
    table of :func:`.simulation.observe_agents`, clipped to ``±OBS_CLIP``, float32), the
    nearest platform's range and the estimate's position error ``‖x̂ − x_t‖``."""
    est = moment_match(state.bank)
    psi, p = state.heading, state.platform_position  # (B, K), (B, K, 2)
    K = psi.shape[1]
    rel = state.bearing - psi
    own_speed = state.speed / max(params.world.max_speed, 1e-12)
    # the estimated target relative to each platform, in its frame (starboard, ahead)
    position = body_frame(psi, est.x[:, None, :2] - p)
    velocity = body_frame(psi, est.x[:, None, 2:] - state.platform_velocity)
    columns = [
        np.sin(rel)[..., None],
        np.cos(rel)[..., None],
        own_speed[..., None],
        position / params.range_scale,
        velocity / params.speed_scale,
        _spread(est.P[:, :2, :2], psi, params.range_scale),
        _spread(est.P[:, 2:, 2:], psi, params.speed_scale),
    ]
    if K > 1:  # each other platform's position relative to this one, its frame, in order
        offsets = [
            np.concatenate(
                [body_frame(psi[:, k], p[:, j] - p[:, k]) for j in range(K) if j != k], -1
            )
            for k in range(K)
        ]
        columns.append(np.stack(offsets, axis=1) / params.range_scale)
    error = est.x[:, :2] - state.target[:, :2]
    return replace(
        state,
        observation=clip_observation(np.concatenate(columns, axis=-1)),
        nearest_range=state.range.min(axis=1),
        position_error=np.hypot(error[:, 0], error[:, 1]),
    )


def _spread(P: FloatArray, heading: FloatArray, scale: float) -> FloatArray:
    """A world covariance ``P (B, 2, 2)`` seen in each platform's frame, ``R P Rᵀ`` with ``R``
    the rotation of :func:`.simulation.body_frame`, as ``(ln(σ₀/scale), ln(σ₁/scale), ρ)``
    ``(B, K, 3)`` (variances floored at 1e-12: a finite log for a collapsed estimate)."""
    s, c = np.sin(heading), np.cos(heading)
    R = np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)  # (B, K, 2, 2)
    Pb = R @ P[:, None] @ np.swapaxes(R, -1, -2)
    sd = np.sqrt(np.maximum(np.diagonal(Pb, axis1=-2, axis2=-1), 1e-12))
    rho = Pb[..., 0, 1] / (sd[..., 0] * sd[..., 1])
    return np.concatenate([np.log(sd / scale), rho[..., None]], -1)


# --- linear algebra -----------------------------------------------------------------------------


def _triangular_root(M: FloatArray) -> FloatArray:
    """The lower-triangular ``L`` with ``L Lᵀ = M Mᵀ`` by orthogonal triangularisation:
    ``Mᵀ = Q R`` (Householder, LAPACK's sign convention: the kernels' too), ``L = Rᵀ``."""
    return np.swapaxes(np.linalg.qr(np.swapaxes(M, -1, -2), mode="r"), -1, -2)


def _outer(u: FloatArray, v: FloatArray) -> FloatArray:
    return u[..., :, None] * v[..., None, :]


def _symmetric(P: FloatArray) -> FloatArray:
    return 0.5 * (P + np.swapaxes(P, -1, -2))
