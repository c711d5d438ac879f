"""The BearingsManeuver step and observation fused into one compiled pass over the batch.

:func:`step_kernel` is :func:`.simulation.step` for every scenario in turn, built from the
primitives written once in :mod:`sensorgym.trackers.bearings.kernels` (bank, bound, accuracy)
and :mod:`sensorgym.envs.worlds.platform_kernels` (flight); :func:`observe_kernel` is
:func:`.simulation.observe_agents`. The random draws are made by the caller with numpy's
Generator, in the order and shapes of the numpy form, and passed in: seeded episodes do not
depend on the kernel. Arrays of the new state are written in place (the caller passes copies).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from sensorgym.envs.worlds.platform_kernels import fly_platform
from sensorgym.trackers.bearings.kernels import (
    STATE_DIM,
    accuracy,
    bank_estimate,
    bank_predict,
    bank_update,
    bound_predict,
    bound_update,
)
from sensorgym.trackers.geometry import wrap_angle_scalar as wrap

_JIT = {"cache": True, "nogil": True, "error_model": "numpy", "boundscheck": False}


@njit(**_JIT)
def step_kernel(
    pos,
    heading,
    speed,
    target,
    lw,
    X,
    P,
    L,
    acc,
    bearing,
    action,
    target_noise,
    target_noise_factor,
    bearing_noise,
    dt,
    bank_dt,
    q_tilde,
    sigma,
    max_turn,
    max_dv,
    min_speed,
    max_speed,
    relative_range,
    floor,
    min_range,
    close_penalty,
    reward,
    terminated,
):
    """One step of every scenario, in place on the state arrays (``pos (B, K, 2)``, ``heading``,
    ``speed``, ``bearing`` ``(B, K)``, ``target (B, 4)``, bank ``lw (B, N)``, ``X (B, N, 4)``,
    ``P (B, N, 4, 4)``, bound ``L (B, 4, 4)``, ``acc (B,)``); ``action (B, K, 2)`` in
    ``[−1, 1]``-clipped units; ``target_noise (B, 4)`` standard normals (used when
    ``q̃ > 0``) and ``bearing_noise (B, K)``. Writes ``reward`` and ``terminated`` ``(B,)``."""
    B, K = heading.shape
    L_pred = np.empty((STATE_DIM, STATE_DIM))
    x_new = np.empty(STATE_DIM)
    for b in range(B):
        # 1. platforms fly the commanded arcs: (a₀ ω_max, a₁ Δv_max), a clipped to [−1, 1]
        for k in range(K):
            a0 = min(max(action[b, k, 0], -1.0), 1.0)
            a1 = min(max(action[b, k, 1], -1.0), 1.0)
            pos[b, k, 0], pos[b, k, 1], heading[b, k], speed[b, k] = fly_platform(
                pos[b, k, 0],
                pos[b, k, 1],
                heading[b, k],
                speed[b, k],
                a0 * max_turn,
                a1 * max_dv,
                dt,
                max_turn,
                max_dv,
                min_speed,
                max_speed,
            )
        # the target moves on: x' = F x + w, w = G_chol ε ~ N(0, Q)
        for i in range(2):
            x_new[i] = target[b, i] + dt * target[b, i + 2]
            x_new[i + 2] = target[b, i + 2]
        if q_tilde > 0.0:
            for i in range(STATE_DIM):
                w = 0.0
                for j in range(STATE_DIM):
                    w += target_noise[b, j] * target_noise_factor[i, j]
                x_new[i] += w
        for i in range(STATE_DIM):
            target[b, i] = x_new[i]
        # 2. noisy bearings z = wrap(β + σ ε); the bank predicts, then fuses them in turn
        for k in range(K):
            beta = math.atan2(target[b, 0] - pos[b, k, 0], target[b, 1] - pos[b, k, 1])
            bearing[b, k] = wrap(beta + sigma * bearing_noise[b, k])
        bank_predict(X[b], P[b], bank_dt, q_tilde)
        for k in range(K):
            bank_update(lw[b], X[b], P[b], bearing[b, k], pos[b, k, 0], pos[b, k, 1], sigma)
        # 3. the bound: P̄ = F P Fᵀ + Q, then each platform's bearing information, square root
        bound_predict(L[b], dt, q_tilde, L_pred)
        for k in range(K):
            bound_update(
                L_pred, target[b, 0], target[b, 1], pos[b, k, 0], pos[b, k, 1], sigma, L[b]
            )
            if k + 1 < K:
                L_pred[:, :] = L[b]
        m = accuracy(
            relative_range, L[b], target[b, 0], target[b, 1], pos[b, 0, 0], pos[b, 0, 1], floor
        )
        # reward_k = ln m_k − ln m_{k+1}; − close_penalty when a platform comes within min_range
        r = math.log(acc[b]) - math.log(m)
        acc[b] = m
        end = False
        for k in range(K):
            if math.hypot(target[b, 0] - pos[b, k, 0], target[b, 1] - pos[b, k, 1]) < min_range:
                end = True
        terminated[b] = end
        reward[b] = r - close_penalty * (1.0 if end else 0.0)


# a world vector v in the platform frame (starboard, ahead): (c v₀ − s v₁, s v₀ + c v₁)
@njit(**_JIT)
def body_frame(s, c, v0, v1):
    return c * v0 - s * v1, s * v0 + c * v1


# every entry clipped to [−clip, clip]
@njit(**_JIT)
def _put(out, b, k, i, value, clip):
    out[b, k, i] = min(max(value, -clip), clip)


@njit(**_JIT)
def observe_kernel(
    pos, heading, speed, bearing, lw, X, P, max_speed, range_scale, speed_scale, clip, out
):
    """Each platform's observation ``out (B, K, obs_dim)`` float32 (the table of
    :func:`.simulation.observe_agents`), from the bank's moment-matched estimate."""
    B, K = heading.shape
    x = np.empty(STATE_DIM)
    Pe = np.empty((STATE_DIM, STATE_DIM))
    for b in range(B):
        bank_estimate(lw[b], X[b], P[b], x, Pe)
        for k in range(K):
            psi = heading[b, k]
            s, c = math.sin(psi), math.cos(psi)
            rel = bearing[b, k] - psi
            _put(out, b, k, 0, math.sin(rel), clip)
            _put(out, b, k, 1, math.cos(rel), clip)
            _put(out, b, k, 2, speed[b, k] / max(max_speed, 1e-12), clip)
            r0, r1 = body_frame(s, c, x[0] - pos[b, k, 0], x[1] - pos[b, k, 1])
            _put(out, b, k, 3, r0 / range_scale, clip)
            _put(out, b, k, 4, r1 / range_scale, clip)
            v0, v1 = body_frame(s, c, x[2] - speed[b, k] * s, x[3] - speed[b, k] * c)
            _put(out, b, k, 5, v0 / speed_scale, clip)
            _put(out, b, k, 6, v1 / speed_scale, clip)
            # position covariance in the platform frame: R P Rᵀ, R = [[c, −s], [s, c]]
            rp00 = c * Pe[0, 0] + -s * Pe[1, 0]
            rp01 = c * Pe[0, 1] + -s * Pe[1, 1]
            rp10 = s * Pe[0, 0] + c * Pe[1, 0]
            rp11 = s * Pe[0, 1] + c * Pe[1, 1]
            pb00 = rp00 * c + rp01 * -s
            pb01 = rp00 * s + rp01 * c
            pb11 = rp10 * s + rp11 * c
            sd0 = math.sqrt(max(pb00, 1e-12))
            sd1 = math.sqrt(max(pb11, 1e-12))
            _put(out, b, k, 7, math.log(sd0 / range_scale), clip)
            _put(out, b, k, 8, math.log(sd1 / range_scale), clip)
            _put(out, b, k, 9, pb01 / (sd0 * sd1), clip)
            # each other platform's position relative to this one, in platform order
            i = 10
            for j in range(K):
                if j != k:
                    o0, o1 = body_frame(
                        s, c, pos[b, j, 0] - pos[b, k, 0], pos[b, j, 1] - pos[b, k, 1]
                    )
                    _put(out, b, k, i, o0 / range_scale, clip)
                    _put(out, b, k, i + 1, o1 / range_scale, clip)
                    i += 2


# nearest platform's range min_k ‖x_t − p_k‖ and the estimate's position error ‖x̂ − x_t‖
@njit(**_JIT)
def info_kernel(pos, target, lw, X, P, nearest, error):
    x = np.empty(STATE_DIM)
    Pe = np.empty((STATE_DIM, STATE_DIM))
    for b in range(pos.shape[0]):
        r = np.inf
        for k in range(pos.shape[1]):
            r = min(r, math.hypot(target[b, 0] - pos[b, k, 0], target[b, 1] - pos[b, k, 1]))
        nearest[b] = r
        bank_estimate(lw[b], X[b], P[b], x, Pe)
        error[b] = math.hypot(x[0] - target[b, 0], x[1] - target[b, 1])
