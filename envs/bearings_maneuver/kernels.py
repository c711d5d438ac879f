"""The BearingsManeuver reset, step and observation as compiled passes over the batch's rows.

:func:`step_kernel` is :func:`.simulation.step` for the scenarios ``lo ≤ b < hi`` (so that
:func:`sensorgym.envs.shells.rows.run_rows` can split a batch over threads);
:func:`reset_kernel` is :func:`.simulation.reset` after its draws. All are built from the primitives written once in
:mod:`sensorgym.trackers.bearings.kernels` (prior, bank, bound, accuracy) and
:mod:`sensorgym.envs.worlds.platform_kernels` (flight, target motion, bearings). The random draws
are made by the caller with numpy's Generator, in the order and shapes of the numpy form, and
passed in: seeded episodes do not depend on the kernel or on the split of the rows.

The step reads the old state's arrays and writes freshly allocated ones (states are values).
Every kernel that writes a state also writes its derived fields — the observation
(:func:`derive`, the table of :func:`.simulation.observe_agents`), the nearest range and the
estimate's position error — from one moment-matched bank estimate, so that
:func:`.simulation.observe` and :func:`.simulation.info` only read them.

Scalar settings come packed in one float64 array ``c`` (:attr:`.simulation.ManeuverParams.
kernel_constants`), indexed by the constants below.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from sensorgym.envs.worlds.platform_kernels import fly_platform, noisy_bearing, propagate_target
from sensorgym.trackers.bearings.kernels import (
    STATE_DIM,
    accuracy,
    bank_estimate,
    bank_predict,
    bank_update,
    bound_predict,
    bound_update,
    psd_square_root,
    range_bank_prior,
)

_JIT = {"cache": True, "nogil": True, "error_model": "numpy", "boundscheck": False}

# indices into the packed settings ``c``
DT, Q_TILDE, SIGMA, MAX_TURN, MAX_DV, MIN_SPEED, MAX_SPEED = 0, 1, 2, 3, 4, 5, 6
FLOOR, MIN_RANGE, PENALTY, RELATIVE_RANGE = 7, 8, 9, 10
RANGE_SCALE, SPEED_SCALE, CLIP, SPEED_MEAN, SPEED_SIGMA = 11, 12, 13, 14, 15
N_CONSTANTS = 16


@njit(**_JIT)
def step_kernel(
    lo,
    hi,
    c,
    pos,
    heading,
    speed,
    target,
    lw,
    X,
    P,
    L,
    acc,
    action,
    target_noise,
    noise_factor,
    bearing_noise,
    pos2,
    heading2,
    speed2,
    target2,
    lw2,
    X2,
    P2,
    L2,
    acc2,
    z2,
    obs,
    nearest,
    error,
    reward,
    terminated,
):
    """One step of scenarios ``lo ≤ b < hi``: reads the state ``pos (B, K, 2)``, ``heading``,
    ``speed`` ``(B, K)``, ``target (B, 4)``, bank ``lw (B, N)``, ``X (B, N, 4)``,
    ``P (B, N, 4, 4)``, bound ``L (B, 4, 4)``, ``acc (B,)``, and writes the new one into the
    arrays suffixed 2, with the bearings ``z2 (B, K)``, the derived fields ``obs``,
    ``nearest``, ``error`` and ``reward``, ``terminated`` ``(B,)``. ``action (B, K, 2)`` is
    clipped to ``[−1, 1]``; ``target_noise (B, 4)`` standard normals (used when ``q̃ > 0``,
    with ``noise_factor`` ``G``, ``G Gᵀ = Q``), ``bearing_noise (B, K)``. Returns the number of
    non-finite action entries (the caller raises: the kernel trusts everything else)."""
    K = heading.shape[1]
    dt, q_tilde, sigma = c[DT], c[Q_TILDE], c[SIGMA]
    L_pred = np.empty((STATE_DIM, STATE_DIM))
    A_pred = np.empty((2 * STATE_DIM, STATE_DIM))
    A_update = np.empty((STATE_DIM + 1, STATE_DIM + 1))
    x = np.empty(STATE_DIM)
    Pe = np.empty((STATE_DIM, STATE_DIM))
    w = np.empty(lw.shape[1])
    bad = 0
    for b in range(lo, hi):
        # 1. platforms fly the commanded arcs: (a₀ ω_max, a₁ Δv_max), a clipped to [−1, 1]
        for k in range(K):
            a0, a1 = action[b, k, 0], action[b, k, 1]
            if not (np.isfinite(a0) and np.isfinite(a1)):
                bad += 1
            a0 = min(max(a0, -1.0), 1.0)
            a1 = min(max(a1, -1.0), 1.0)
            pos2[b, k, 0], pos2[b, k, 1], heading2[b, k], speed2[b, k] = fly_platform(
                pos[b, k, 0],
                pos[b, k, 1],
                heading[b, k],
                speed[b, k],
                a0 * c[MAX_TURN],
                a1 * c[MAX_DV],
                dt,
                c[MAX_TURN],
                c[MAX_DV],
                c[MIN_SPEED],
                c[MAX_SPEED],
            )
        # the target moves on
        propagate_target(
            target[b],
            target_noise[b] if q_tilde > 0.0 else x,
            noise_factor,
            dt,
            q_tilde,
            target2[b],
        )
        # 2. noisy bearings; the bank predicts, then fuses them in turn
        for k in range(K):
            z2[b, k] = noisy_bearing(
                target2[b, 0],
                target2[b, 1],
                pos2[b, k, 0],
                pos2[b, k, 1],
                sigma,
                bearing_noise[b, k],
            )
        for n in range(lw.shape[1]):
            lw2[b, n] = lw[b, n]
        bank_predict(X[b], P[b], dt, q_tilde, X2[b], P2[b])
        for k in range(K):
            bank_update(lw2[b], X2[b], P2[b], z2[b, k], pos2[b, k, 0], pos2[b, k, 1], sigma)
        # 3. the bound: P̄ = F P Fᵀ + Q, then each platform's bearing information, square root
        bound_predict(L[b], dt, q_tilde, L_pred, A_pred)
        for k in range(K):
            bound_update(
                L_pred,
                target2[b, 0],
                target2[b, 1],
                pos2[b, k, 0],
                pos2[b, k, 1],
                sigma,
                L2[b],
                A_update,
            )
            if k + 1 < K:
                L_pred[:, :] = L2[b]
        m = accuracy(
            c[RELATIVE_RANGE] > 0.0,
            L2[b],
            target2[b, 0],
            target2[b, 1],
            pos2[b, 0, 0],
            pos2[b, 0, 1],
            c[FLOOR],
        )
        # reward_k = ln m_k − ln m_{k+1}; − close_penalty when a platform comes within min_range
        r = math.log(acc[b]) - math.log(m)
        acc2[b] = m
        end = False
        for k in range(K):
            if (
                math.hypot(target2[b, 0] - pos2[b, k, 0], target2[b, 1] - pos2[b, k, 1])
                < c[MIN_RANGE]
            ):
                end = True
        terminated[b] = end
        reward[b] = r - c[PENALTY] * (1.0 if end else 0.0)
        derive(
            b, c, pos2, heading2, speed2, z2, target2, lw2, X2, P2, x, Pe, w, obs, nearest, error
        )
    return bad


@njit(**_JIT)
def reset_kernel(
    c, r, sr, lw0, pos_f, vel_f, heading, speed, target, pos, eps, z, lw, X, P, L, acc, obs,
    nearest, error,
):  # fmt: skip
    """Fresh scenarios from their draws (platforms ``pos (B, K, 2)``, ``heading``, ``speed``
    ``(B, K)``, ``target (B, 4)``, bearing noise ``eps (B, K)``), every row: the first bearings
    ``z``; the prior bank from platform 1's (range cells ``r``, ``sr``, ``lw0`` ``(N,)``, spread
    factors ``pos_f``, ``vel_f`` ``(3,)``, course mean = the bearing) into ``lw``, ``X``,
    ``P``; the bound's square root ``L`` of the bank's moment-matched covariance; the other
    platforms' first bearings fused into both; the accuracy ``acc`` and the derived fields."""
    x = np.empty(STATE_DIM)
    Pe = np.empty((STATE_DIM, STATE_DIM))
    L_in = np.empty((STATE_DIM, STATE_DIM))
    A_update = np.empty((STATE_DIM + 1, STATE_DIM + 1))
    w = np.empty(lw.shape[1])
    sigma = c[SIGMA]
    for b in range(z.shape[0]):
        for k in range(z.shape[1]):
            z[b, k] = noisy_bearing(
                target[b, 0], target[b, 1], pos[b, k, 0], pos[b, k, 1], sigma, eps[b, k]
            )
        range_bank_prior(
            z[b, 0],
            pos[b, 0, 0],
            pos[b, 0, 1],
            r,
            sr,
            lw0,
            pos_f,
            c[SPEED_MEAN],
            c[SPEED_SIGMA],
            z[b, 0],
            vel_f,
            lw[b],
            X[b],
            P[b],
        )
        # P_0 = (P_prior⁻¹ + Σ_{k≥2} I_k(x_0))⁻¹: the prior already holds platform 1's bearing
        bank_estimate(lw[b], X[b], P[b], x, Pe, w)
        psd_square_root(Pe, L[b])
        for k in range(1, z.shape[1]):
            bank_update(lw[b], X[b], P[b], z[b, k], pos[b, k, 0], pos[b, k, 1], sigma)
            L_in[:, :] = L[b]
            bound_update(
                L_in, target[b, 0], target[b, 1], pos[b, k, 0], pos[b, k, 1], sigma, L[b], A_update
            )
        acc[b] = accuracy(
            c[RELATIVE_RANGE] > 0.0,
            L[b],
            target[b, 0],
            target[b, 1],
            pos[b, 0, 0],
            pos[b, 0, 1],
            c[FLOOR],
        )
        derive(b, c, pos, heading, speed, z, target, lw, X, P, x, Pe, w, obs, nearest, error)


# a world vector v in the platform frame (starboard, ahead): (c v₀ − s v₁, s v₀ + c v₁)
@njit(**_JIT)
def body_frame(s, c, v0, v1):
    return c * v0 - s * v1, s * v0 + c * v1


# every entry clipped to [−clip, clip]
@njit(**_JIT)
def _put(out, b, k, i, value, clip):
    out[b, k, i] = min(max(value, -clip), clip)


@njit(**_JIT)
def derive(b, c, pos, heading, speed, bearing, target, lw, X, P, x, Pe, w, obs, nearest, error):
    """Row ``b``'s derived fields from the bank's moment-matched estimate ``x``, ``Pe``
    (scratch, with the weights ``w``): each platform's observation ``obs[b] (K, obs_dim)`` float32 (the table of
    :func:`.simulation.observe_agents`), the nearest platform's range
    ``min_k ‖x_t − p_k‖`` and the estimate's position error ``‖x̂ − x_t‖``."""
    K = heading.shape[1]
    max_speed, range_scale, speed_scale, clip = (
        c[MAX_SPEED],
        c[RANGE_SCALE],
        c[SPEED_SCALE],
        c[CLIP],
    )
    bank_estimate(lw[b], X[b], P[b], x, Pe, w)
    for k in range(K):
        psi = heading[b, k]
        s, co = math.sin(psi), math.cos(psi)
        rel = bearing[b, k] - psi
        _put(obs, b, k, 0, math.sin(rel), clip)
        _put(obs, b, k, 1, math.cos(rel), clip)
        _put(obs, b, k, 2, speed[b, k] / max(max_speed, 1e-12), clip)
        r0, r1 = body_frame(s, co, x[0] - pos[b, k, 0], x[1] - pos[b, k, 1])
        _put(obs, b, k, 3, r0 / range_scale, clip)
        _put(obs, b, k, 4, r1 / range_scale, clip)
        v0, v1 = body_frame(s, co, x[2] - speed[b, k] * s, x[3] - speed[b, k] * co)
        _put(obs, b, k, 5, v0 / speed_scale, clip)
        _put(obs, b, k, 6, v1 / speed_scale, clip)
        # position covariance in the platform frame: R P Rᵀ, R = [[c, −s], [s, c]]
        rp00 = co * Pe[0, 0] + -s * Pe[1, 0]
        rp01 = co * Pe[0, 1] + -s * Pe[1, 1]
        rp10 = s * Pe[0, 0] + co * Pe[1, 0]
        rp11 = s * Pe[0, 1] + co * Pe[1, 1]
        pb00 = rp00 * co + rp01 * -s
        pb01 = rp00 * s + rp01 * co
        pb11 = rp10 * s + rp11 * co
        sd0 = math.sqrt(max(pb00, 1e-12))
        sd1 = math.sqrt(max(pb11, 1e-12))
        _put(obs, b, k, 7, math.log(sd0 / range_scale), clip)
        _put(obs, b, k, 8, math.log(sd1 / range_scale), clip)
        _put(obs, b, k, 9, pb01 / (sd0 * sd1), clip)
        # each other platform's position relative to this one, in platform order
        i = 10
        for j in range(K):
            if j != k:
                o0, o1 = body_frame(s, co, pos[b, j, 0] - pos[b, k, 0], pos[b, j, 1] - pos[b, k, 1])
                _put(obs, b, k, i, o0 / range_scale, clip)
                _put(obs, b, k, i + 1, o1 / range_scale, clip)
                i += 2
    r = np.inf
    for k in range(K):
        r = min(r, math.hypot(target[b, 0] - pos[b, k, 0], target[b, 1] - pos[b, k, 1]))
    nearest[b] = r
    error[b] = math.hypot(x[0] - target[b, 0], x[1] - target[b, 1])


@njit(**_JIT)
def plan_kernel(lo, hi, c, pos, heading, speed, target, L, command, horizon, too_close, out):
    """The oracle's plans (:class:`sensorgym.agents.bearings_maneuver.OracleLookahead`) for
    scenarios ``lo ≤ b < hi``: platform 1 of ``pos (B, K, 2)``, ``heading``, ``speed``
    ``(B, K)`` holds each command ``command (C, 2)`` (rad/s, m/s; clipped as the step does) for
    ``horizon`` steps while the target follows its mean path ``F x`` from ``target (B, 4)`` and
    the bound's square root ``L (B, 4, 4)`` runs the env's recursion (:func:`step_kernel`'s
    predict and bearing update on the true state). Writes the accuracy the reward measures at
    the end, ``out (B, C)``, or ``inf`` for a plan that comes within ``too_close`` (m)."""
    dt, q_tilde, sigma = c[DT], c[Q_TILDE], c[SIGMA]
    x = np.empty(STATE_DIM)
    x_next = np.empty(STATE_DIM)
    G = np.zeros((STATE_DIM, STATE_DIM))
    Lc = np.empty((STATE_DIM, STATE_DIM))
    L_pred = np.empty((STATE_DIM, STATE_DIM))
    A_pred = np.empty((2 * STATE_DIM, STATE_DIM))
    A_update = np.empty((STATE_DIM + 1, STATE_DIM + 1))
    for b in range(lo, hi):
        for j in range(command.shape[0]):
            px, py, h, v = pos[b, 0, 0], pos[b, 0, 1], heading[b, 0], speed[b, 0]
            x[:] = target[b]
            Lc[:, :] = L[b]
            close = False
            for _ in range(horizon):
                px, py, h, v = fly_platform(
                    px,
                    py,
                    h,
                    v,
                    command[j, 0],
                    command[j, 1],
                    dt,
                    c[MAX_TURN],
                    c[MAX_DV],
                    c[MIN_SPEED],
                    c[MAX_SPEED],
                )
                # the target's mean path: x' = F x (no noise draw)
                propagate_target(x, x, G, dt, 0.0, x_next)
                x[:] = x_next
                bound_predict(Lc, dt, q_tilde, L_pred, A_pred)
                bound_update(L_pred, x[0], x[1], px, py, sigma, Lc, A_update)
                if math.hypot(x[0] - px, x[1] - py) < too_close:
                    close = True
            if close:
                out[b, j] = np.inf
            else:
                out[b, j] = accuracy(c[RELATIVE_RANGE] > 0.0, Lc, x[0], x[1], px, py, c[FLOOR])


@njit(**_JIT)
def greedy_kernel(c, obs, sd, command, too_close, choice):
    """The greedy rule (:class:`sensorgym.agents.bearings_maneuver.GreedyManeuver`) on
    observations ``obs (n, obs_dim)`` with the position standard deviations ``sd (n, 2)`` (m)
    read off them: each command ``command (C, 2)`` (rad/s, m/s) flown from the platform's frame
    (:func:`fly_platform` from the origin, heading 0 = ahead); the estimated target moves on by
    its estimated velocity; the information gain ``n̂ᵀ P n̂ / r²`` of the next bearing at the new
    relative position (``-inf`` within ``too_close``, m). Writes the first best command's index
    into ``choice (n,)``."""
    dt, max_speed = c[DT], c[MAX_SPEED]
    range_scale, speed_scale = c[RANGE_SCALE], c[SPEED_SCALE]
    for b in range(obs.shape[0]):
        v = obs[b, 2] * max_speed
        d0, d1 = obs[b, 3] * range_scale, obs[b, 4] * range_scale
        # estimated target velocity in the platform frame: relative velocity + own (0, v)
        vt0, vt1 = obs[b, 5] * speed_scale, obs[b, 6] * speed_scale + v
        # estimated position covariance from the log standard deviations and the correlation
        p00, p11 = sd[b, 0] * sd[b, 0], sd[b, 1] * sd[b, 1]
        p01 = sd[b, 0] * sd[b, 1] * obs[b, 9]
        best, best_gain = 0, -np.inf
        for j in range(command.shape[0]):
            e0, e1, _, _ = fly_platform(
                0.0,
                0.0,
                0.0,
                v,
                command[j, 0],
                command[j, 1],
                dt,
                c[MAX_TURN],
                c[MAX_DV],
                c[MIN_SPEED],
                max_speed,
            )
            # relative position after the step, the bearing's normal n̂ and its gain
            n0 = d0 + vt0 * dt - e0
            n1 = d1 + vt1 * dt - e1
            dist = math.hypot(n0, n1)
            r = max(dist, 1e-9)
            u0, u1 = n1 / r, -n0 / r
            gain = (u0 * (p00 * u0 + p01 * u1) + u1 * (p01 * u0 + p11 * u1)) / (r * r)
            if dist < too_close:
                gain = -np.inf
            if gain > best_gain:
                best, best_gain = j, gain
        choice[b] = best
