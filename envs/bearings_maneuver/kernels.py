"""The BearingsManeuver reset, step and observation as compiled passes over the batch's rows.

:func:`step_kernel` is :func:`.simulation.step` for the scenarios ``lo ≤ b < hi`` (so that
:func:`sensorgym.envs.shells.rows.run_rows` can split a batch over threads);
:func:`reset_kernel` is :func:`.simulation.reset` after its draws. All are built from the primitives written once in
:mod:`sensorgym.trackers.bearings.kernels` (prior, bank, bound, accuracy) and
:mod:`sensorgym.envs.worlds.platform_kernels` (flight, target motion, bearings); the bank's
members take the second-order EKF update (``bank_update``, theory §7.9, §11.6). The random draws
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
from numba.extending import register_jitable

from sensorgym.envs.worlds.platform_kernels import fly_platform, noisy_bearing, propagate_target
from sensorgym.trackers.bearings.kernels import (
    STATE_DIM,
    accuracy,
    bank_estimate,
    bank_predict,
    bank_update,
    bound_predict,
    bound_update,
    late_bearing_information,
    late_update_root,
    position_update,
    psd_square_root,
    range_bank_prior,
)

# copies by explicit loops: a slice assignment from an array compiles numba's shape-error
# message (string formatting, seconds at cold start)
from sensorgym.trackers.stereo.kernels import copy1, copy2

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
                copy2(L2[b], L_pred)
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
            copy2(L[b], L_in)
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


# every entry clipped to [−clip, clip]. _put and _put_spread are called with constant
# indices: register_jitable types them on plain integers (one compile each), where a
# dispatcher compiles one specialisation per literal index (11 + 2, 2 s of cold compile)
@register_jitable(**_JIT)
def _put(out, b, k, i, value, clip):
    out[b, k, i] = min(max(value, -clip), clip)


@register_jitable(**_JIT)
def _put_spread(out, b, k, i, s, c, p00, p01, p11, scale, clip):
    """A 2-D covariance ``[[p00, p01], [p01, p11]]`` (world axes East, North) turned into the
    platform frame, ``R P Rᵀ`` with ``R = [[c, −s], [s, c]]`` (:func:`body_frame`), written as
    ``ln(σ₀/scale)``, ``ln(σ₁/scale)`` and the correlation at ``out[b, k, i : i + 3]``
    (variances floored at 1e-12: a finite log for a collapsed estimate)."""
    rp00 = c * p00 - s * p01
    rp01 = c * p01 - s * p11
    rp10 = s * p00 + c * p01
    rp11 = s * p01 + c * p11
    pb00 = rp00 * c - rp01 * s
    pb01 = rp00 * s + rp01 * c
    pb11 = rp10 * s + rp11 * c
    sd0 = math.sqrt(max(pb00, 1e-12))
    sd1 = math.sqrt(max(pb11, 1e-12))
    _put(out, b, k, i, math.log(sd0 / scale), clip)
    _put(out, b, k, i + 1, math.log(sd1 / scale), clip)
    _put(out, b, k, i + 2, pb01 / (sd0 * sd1), clip)


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
        # the position and the velocity covariance in the platform frame, as spreads
        _put_spread(obs, b, k, 7, s, co, Pe[0, 0], Pe[0, 1], Pe[1, 1], range_scale, clip)
        _put_spread(obs, b, k, 10, s, co, Pe[2, 2], Pe[2, 3], Pe[3, 3], speed_scale, clip)
        # each other platform's position relative to this one, in platform order
        i = 13
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


# one platform flies command (ω, Δv) for len(out) steps: its positions ``out (H, 2)``
@njit(**_JIT)
def _fly_hold(c, px, py, h, v, turn, dv, out):
    for s in range(out.shape[0]):
        px, py, h, v = fly_platform(
            px, py, h, v, turn, dv, c[DT], c[MAX_TURN], c[MAX_DV], c[MIN_SPEED], c[MAX_SPEED]
        )
        out[s, 0], out[s, 1] = px, py


# the target's mean path x' = F x (no noise draw) from x0 (4,): ``path (H, 4)``
@njit(**_JIT)
def _mean_path(c, x0, path, x, x_next, G):
    copy1(x0, x)
    for s in range(path.shape[0]):
        propagate_target(x, x, G, c[DT], 0.0, x_next)
        copy1(x_next, x)
        copy1(x, path[s])


# a bearing's position information n̂ n̂ᵀ / (r σ)² from ``track (H, 2)`` on ``path`` into
# ``info (H, 3)`` as (i00, i01, i11)
@njit(**_JIT)
def _bearing_information(path, track, sigma, info):
    for s in range(path.shape[0]):
        dx, dy = path[s, 0] - track[s, 0], path[s, 1] - track[s, 1]
        r = math.hypot(dx, dy)
        n0, n1 = dy / r, -dx / r
        a = 1.0 / (r * sigma) ** 2
        info[s, 0], info[s, 1], info[s, 2] = a * n0 * n0, a * n0 * n1, a * n1 * n1


# position information [[i00, i01], [i01, i11]] fused into the square root ``L_pred`` as two
# rank-one updates, the columns of its Cholesky factor (``L_pred`` is overwritten)
@njit(**_JIT)
def _fuse_position_information(L_pred, i00, i01, i11, out, A):
    if i00 > 0.0:
        g = math.sqrt(i00)
        position_update(L_pred, 1.0, g, i01 / g, out, A)
        copy2(out, L_pred)
        i11 = i11 - i01 * i01 / i00
    position_update(L_pred, 1.0, 0.0, math.sqrt(max(i11, 0.0)), out, A)


@njit(**_JIT)
def _plan_accuracy(c, L0, path, track, others, use_others, too_close, ox, oy, Lc, L_pred, A_pred,
                   A_update):  # fmt: skip
    """The bound recursion of :func:`step_kernel` along a plan: from the square root ``L0``,
    each step predicts and fuses the bearing from ``track[s]`` on the target ``path[s]``; with
    ``use_others``, together with the other platforms' position information ``others[s]``
    (``(i00, i01, i11)``): the 2×2 sum enters as two rank-one updates, the columns of its
    Cholesky factor (information adds, so this is the env's sequential fusion of every
    bearing). Returns the accuracy the reward measures at the end (relative range from
    ``(ox, oy)``), or ``inf`` when the track comes within ``too_close`` of the path."""
    dt, q_tilde, sigma = c[DT], c[Q_TILDE], c[SIGMA]
    copy2(L0, Lc)
    close = False
    for s in range(path.shape[0]):
        bound_predict(Lc, dt, q_tilde, L_pred, A_pred)
        dx, dy = path[s, 0] - track[s, 0], path[s, 1] - track[s, 1]
        if use_others:
            r = math.hypot(dx, dy)
            n0, n1 = dy / r, -dx / r
            a = 1.0 / (r * sigma) ** 2
            i00 = others[s, 0] + a * n0 * n0
            i01 = others[s, 1] + a * n0 * n1
            i11 = others[s, 2] + a * n1 * n1
            _fuse_position_information(L_pred, i00, i01, i11, Lc, A_update)
        else:
            bound_update(L_pred, path[s, 0], path[s, 1], track[s, 0], track[s, 1], sigma, Lc,
                         A_update)  # fmt: skip
        if math.hypot(dx, dy) < too_close:
            close = True
    if close:
        return np.inf
    H = path.shape[0] - 1
    return accuracy(c[RELATIVE_RANGE] > 0.0, Lc, path[H, 0], path[H, 1], ox, oy, c[FLOOR])


# q̃ = 0: the plan's own bearings fuse last (trackers.bearings.kernels.late_bearing_information),
# so the recursion of the prior and the other platforms' bearings runs once per platform, not
# once per candidate: ``Lo`` is its square root at the end of the horizon
@njit(**_JIT)
def _others_root(c, L0, others, horizon, Lo, L_pred, A_pred, A_update):
    dt, q_tilde = c[DT], c[Q_TILDE]
    copy2(L0, Lo)
    for s in range(horizon):
        bound_predict(Lo, dt, q_tilde, L_pred, A_pred)
        _fuse_position_information(L_pred, others[s, 0], others[s, 1], others[s, 2], Lo, A_update)


@njit(**_JIT)
def _late_plan_accuracy(c, Lo, path, track, too_close, ox, oy, C, u, Lc):
    """:func:`_plan_accuracy` for ``q̃ = 0`` from the others' root ``Lo`` (:func:`_others_root`):
    the plan's bearings enter at the end in one update (equal up to rounding)."""
    dt, sigma = c[DT], c[SIGMA]
    H = path.shape[0]
    for i in range(STATE_DIM):
        for j in range(STATE_DIM):
            C[i, j] = 1.0 if i == j else 0.0
    for s in range(H):
        if math.hypot(path[s, 0] - track[s, 0], path[s, 1] - track[s, 1]) < too_close:
            return np.inf
        late_bearing_information(Lo, path[s, 0], path[s, 1], track[s, 0], track[s, 1], sigma,
                                 (H - 1 - s) * dt, C, u)  # fmt: skip
    late_update_root(Lo, C, Lc)
    return accuracy(c[RELATIVE_RANGE] > 0.0, Lc, path[H - 1, 0], path[H - 1, 1], ox, oy, c[FLOOR])


@njit(**_JIT)
def plan_kernel(lo, hi, c, pos, heading, speed, target, L, command, horizon, too_close, out):
    """The truth-informed lookahead's plans for one platform (:meth:`sensorgym.agents.bearings_maneuver.
    TruthLookahead.plan_bounds`) for scenarios ``lo ≤ b < hi``: platform 1 of ``pos (B, K, 2)``,
    ``heading``, ``speed`` ``(B, K)`` holds each command ``command (C, 2)`` (rad/s, m/s; clipped
    as the step does) for ``horizon`` steps while the target follows its mean path ``F x`` from
    ``target (B, 4)`` and the bound's square root ``L (B, 4, 4)`` runs the env's recursion
    (:func:`step_kernel`'s predict and bearing update on the true state). Writes the accuracy
    the reward measures at the end, ``out (B, C)``, or ``inf`` for a plan that comes within
    ``too_close`` (m)."""
    x = np.empty(STATE_DIM)
    x_next = np.empty(STATE_DIM)
    G = np.zeros((STATE_DIM, STATE_DIM))
    path = np.empty((horizon, STATE_DIM))
    track = np.empty((horizon, 2))
    none = np.empty((0, 3))
    Lc = np.empty((STATE_DIM, STATE_DIM))
    L_pred = np.empty((STATE_DIM, STATE_DIM))
    A_pred = np.empty((2 * STATE_DIM, STATE_DIM))
    A_update = np.empty((STATE_DIM + 1, STATE_DIM + 1))
    late = c[Q_TILDE] == 0.0
    no_others = np.zeros((horizon, 3))
    Lo = np.empty((STATE_DIM, STATE_DIM))
    u = np.empty(STATE_DIM)
    for b in range(lo, hi):
        _mean_path(c, target[b], path, x, x_next, G)
        if late:
            _others_root(c, L[b], no_others, horizon, Lo, L_pred, A_pred, A_update)
        for j in range(command.shape[0]):
            _fly_hold(c, pos[b, 0, 0], pos[b, 0, 1], heading[b, 0], speed[b, 0], command[j, 0],
                      command[j, 1], track)  # fmt: skip
            if late:
                out[b, j] = _late_plan_accuracy(
                    c, Lo, path, track, too_close, track[-1, 0], track[-1, 1], L_pred, u, Lc
                )
            else:
                out[b, j] = _plan_accuracy(
                    c, L[b], path, track, none, False, too_close, track[-1, 0], track[-1, 1],
                    Lc, L_pred, A_pred, A_update,
                )  # fmt: skip


@njit(**_JIT)
def joint_plan_kernel(lo, hi, c, pos, heading, speed, target, L, command, horizon, too_close,
                      choice):  # fmt: skip
    """Receding-horizon plans of ``K`` platforms by sequential (coordinate-wise) choice, for
    scenarios ``lo ≤ b < hi`` (:class:`sensorgym.agents.bearings_maneuver.TruthLookahead` on
    the truth, :class:`~sensorgym.agents.bearings_maneuver.EstimateLookahead` on the estimate):
    every platform of ``pos (B, K, 2)``, ``heading``, ``speed`` ``(B, K)`` starts on the plan
    "hold course and speed"; then platforms 1, 2, …, K in turn take the command of
    ``command (C, 2)`` whose ``horizon``-step plan ends with the smallest bound, the others
    flying their current plans (platforms before it their chosen ones, after it straight on),
    their bearings' information fused at every step. Cost ``O(K·C·horizon + K²·horizon)`` per
    scenario (the others' information is summed once per platform, a 2×2 per step; with
    ``q̃ = 0`` the prior and the others' bearings run their square-root recursion once per
    platform and each candidate's own bearings enter at the end, :func:`_late_plan_accuracy`,
    so a candidate costs ``horizon`` rank-one sums instead of ``horizon`` triangularisations). For
    ``K = 1`` this is :func:`plan_kernel`'s argmin. Writes each platform's command index into
    ``choice (B, K)``; a plan within ``too_close`` (m) of the target's mean path is ruled out."""
    K = heading.shape[1]
    sigma = c[SIGMA]
    x = np.empty(STATE_DIM)
    x_next = np.empty(STATE_DIM)
    G = np.zeros((STATE_DIM, STATE_DIM))
    path = np.empty((horizon, STATE_DIM))
    tracks = np.empty((K, horizon, 2))
    track = np.empty((horizon, 2))
    info = np.empty((K, horizon, 3))
    others = np.zeros((horizon, 3))
    Lc = np.empty((STATE_DIM, STATE_DIM))
    L_pred = np.empty((STATE_DIM, STATE_DIM))
    A_pred = np.empty((2 * STATE_DIM, STATE_DIM))
    A_update = np.empty((STATE_DIM + 1, STATE_DIM + 1))
    late = c[Q_TILDE] == 0.0
    Lo = np.empty((STATE_DIM, STATE_DIM))
    u = np.empty(STATE_DIM)
    for b in range(lo, hi):
        _mean_path(c, target[b], path, x, x_next, G)
        for k in range(K):
            _fly_hold(c, pos[b, k, 0], pos[b, k, 1], heading[b, k], speed[b, k], 0.0, 0.0,
                      tracks[k])  # fmt: skip
            _bearing_information(path, tracks[k], sigma, info[k])
        for k in range(K):
            others[:, :] = 0.0
            for i in range(K):
                if i != k:
                    for s in range(horizon):
                        for e in range(3):
                            others[s, e] += info[i, s, e]
            if late:
                _others_root(c, L[b], others, horizon, Lo, L_pred, A_pred, A_update)
            best, best_value = 0, np.inf
            for j in range(command.shape[0]):
                _fly_hold(c, pos[b, k, 0], pos[b, k, 1], heading[b, k], speed[b, k],
                          command[j, 0], command[j, 1], track)  # fmt: skip
                origin = track if k == 0 else tracks[0]
                if late:
                    value = _late_plan_accuracy(
                        c,
                        Lo,
                        path,
                        track,
                        too_close,
                        origin[-1, 0],
                        origin[-1, 1],
                        L_pred,
                        u,
                        Lc,
                    )
                else:
                    value = _plan_accuracy(
                        c, L[b], path, track, others, K > 1, too_close, origin[-1, 0],
                        origin[-1, 1], Lc, L_pred, A_pred, A_update,
                    )  # fmt: skip
                if value < best_value:
                    best, best_value = j, value
            choice[b, k] = best
            _fly_hold(c, pos[b, k, 0], pos[b, k, 1], heading[b, k], speed[b, k],
                      command[best, 0], command[best, 1], tracks[k])  # fmt: skip
            _bearing_information(path, tracks[k], sigma, info[k])


@njit(**_JIT)
def greedy_kernel(c, obs, sd, delta, command, too_close, choice):
    """The greedy rule (:class:`sensorgym.agents.bearings_maneuver.GreedyManeuver`) on every
    platform's view ``obs (n, K, obs_dim)``, platform by platform (sequential greedy): platform
    ``k`` flies each command ``command (C, 2)`` (rad/s, m/s) from its own frame
    (:func:`fly_platform` from the origin, heading 0 = ahead); the estimated target moves on by
    its estimated velocity; the command with the largest information gain ``hᵀ P h`` of the next
    bearing, ``h = n̂/r`` at the new relative position (``-inf`` within ``too_close``, m), is
    taken, and its information updates ``P ← P − P h hᵀ P / (hᵀ P h + σ²)`` before the next
    platform chooses. ``P`` is the estimate's position covariance in platform 1's frame, from
    its standard deviations ``sd (n, 2)`` (m) and correlation (obs 9); ``delta (n, K)`` turns
    platform ``k``'s frame into platform 1's (its heading relative to platform 1's, rad).
    Writes each platform's first best command index into ``choice (n, K)``."""
    K = obs.shape[1]
    dt, max_speed, sigma = c[DT], c[MAX_SPEED], c[SIGMA]
    range_scale, speed_scale = c[RANGE_SCALE], c[SPEED_SCALE]
    for b in range(obs.shape[0]):
        # estimated position covariance from the log standard deviations and the correlation
        p00, p11 = sd[b, 0] * sd[b, 0], sd[b, 1] * sd[b, 1]
        p01 = sd[b, 0] * sd[b, 1] * obs[b, 0, 9]
        for k in range(K):
            v = obs[b, k, 2] * max_speed
            d0, d1 = obs[b, k, 3] * range_scale, obs[b, k, 4] * range_scale
            # estimated target velocity in the platform frame: relative velocity + own (0, v)
            vt0, vt1 = obs[b, k, 5] * speed_scale, obs[b, k, 6] * speed_scale + v
            cd, sdl = math.cos(delta[b, k]), math.sin(delta[b, k])
            best, best_gain, h0, h1 = 0, -np.inf, 0.0, 0.0
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
                # n̂ in platform 1's frame (k's frame turned back by delta)
                u0, u1 = cd * (n1 / r) + sdl * (-n0 / r), -sdl * (n1 / r) + cd * (-n0 / r)
                gain = (u0 * (p00 * u0 + p01 * u1) + u1 * (p01 * u0 + p11 * u1)) / (r * r)
                if dist < too_close:
                    gain = -np.inf
                if gain > best_gain:
                    best, best_gain, h0, h1 = j, gain, u0 / r, u1 / r
            choice[b, k] = best
            # the chosen bearing's information, for the platforms after this one
            if K > 1 and best_gain > -np.inf:
                q0, q1 = p00 * h0 + p01 * h1, p01 * h0 + p11 * h1
                s = best_gain + sigma * sigma
                p00, p01, p11 = p00 - q0 * q0 / s, p01 - q0 * q1 / s, p11 - q1 * q1 / s
