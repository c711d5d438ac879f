"""The BearingsManeuver reset, step and observation as compiled passes over the batch's rows.

:func:`step_kernel` is :func:`.simulation.step` for the scenarios ``lo ≤ b < hi`` (so that
:func:`sensorgym.envs.shells.rows.run_rows` can split a batch over threads), and
:func:`reset_kernel` is :func:`.simulation.reset` after its draws. Both follow the stages of
the readable numpy form, :mod:`.reference` (theory §2.5, §7.7–§7.9, §11.2), one compiled
function per stage under the reference's name: :func:`fly`, :func:`move_target`,
:func:`take_bearings`, :func:`prior_bank`, :func:`track` (the bank's predict and updates),
:func:`bound` (the bearings' information after the predict, and the accuracy),
:func:`derive` (the observation) and
:func:`reward_and_end`. The stages are built from the primitives written once in
:mod:`sensorgym.trackers.bearings.kernels` (prior, bank, bound, accuracy) and
:mod:`sensorgym.envs.worlds.platform_kernels` (flight, target motion, bearings); the bank's
members take the second-order EKF update (``bank_update``, theory §7.9, §11.6). The random
draws are made by the caller with numpy's Generator, in the order and shapes of the numpy
form, and passed in: seeded episodes do not depend on the kernel or on the split of the rows.

The step reads the old state's arrays and writes freshly allocated ones (states are values).
Every kernel that writes a state also writes its derived fields — the observation (the table
of :func:`.simulation.observe_agents`), the nearest range and the estimate's position error —
from one moment-matched bank estimate, so that :func:`.simulation.observe` and
:func:`.simulation.info` only read them.

What the kernels take:

- the **settings**: one record of dtype :data:`SETTINGS`, read by field name (``p.dt``,
  ``p.sigma``); :attr:`.simulation.ManeuverParams.kernel_constants` builds it once per params;
- a **state** as the tuple of its arrays in the order of :data:`StateArrays` (what
  :func:`.simulation.state_arrays` returns); each kernel takes it apart once per call and
  hands every stage the arrays it reads and writes;
- **scratch** from :func:`workspace` (the step and reset) and :func:`plan_workspace` (the
  planners), allocated once per call and reused over the rows.
"""

from __future__ import annotations

import math
from collections import namedtuple

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
#: the stages are inlined into the kernels: each separately compiled function adds to the
#: cold compile
_INLINE = {**_JIT, "inline": "always"}

#: The scalar settings the kernels read, one record per params
#: (:attr:`.simulation.ManeuverParams.kernel_constants`).
SETTINGS = np.dtype(
    [
        ("dt", np.float64),  # step length T, s
        ("q_tilde", np.float64),  # the target's process noise intensity q̃, m²/s³
        ("sigma", np.float64),  # bearing noise σ, rad
        ("max_turn", np.float64),  # ω_max, rad/s
        ("max_dv", np.float64),  # Δv_max per step, m/s
        ("min_speed", np.float64),  # platform speed limits, m/s
        ("max_speed", np.float64),
        ("floor", np.float64),  # the accuracy is kept inside [floor, 1/floor]
        ("min_range", np.float64),  # stand-off: closer ends the episode, m
        ("penalty", np.float64),  # close_penalty
        ("range_scale", np.float64),  # observation scales: m, m/s
        ("speed_scale", np.float64),
        ("clip", np.float64),  # observations clipped to ±clip
        ("speed_mean", np.float64),  # the tracker's speed prior, m/s
        ("speed_sigma", np.float64),
        ("relative_range", np.bool_),  # the reward measures σ_r/r (else the position RMS)
    ],
    align=True,
)

#: The arrays of a :class:`.simulation.ManeuverState`, in the order the kernels take them:
#: platforms ``pos (B, K, 2)``, ``heading``, ``speed`` ``(B, K)``, ``target (B, 4)``, the bank's
#: log weights ``lw (B, N)``, means ``X (B, N, 4)``, covariances ``P (B, N, 4, 4)``, the bound's
#: square root ``L (B, 4, 4)``, its accuracy ``acc (B,)``, the bearings ``z (B, K)``, the
#: observation ``obs (B, K, obs_dim)`` float32, the nearest range and the position error ``(B,)``.
StateArrays = namedtuple("StateArrays", "pos heading speed target lw X P L acc z obs nearest error")

#: Scratch of the step and the reset (:func:`workspace`): the bank's estimate ``x``, ``Pe`` and
#: weights ``w``, and the bound recursion's ``L_pred`` and pre-arrays ``A_pred``, ``A_update``.
Workspace = namedtuple("Workspace", "x Pe w L_pred A_pred A_update")

#: Scratch of the planners (:func:`plan_workspace`): the target's mean ``path (H, 4)`` (with
#: ``x``, ``x_next`` and the unused noise factor ``G``), a platform's ``track (H, 2)``, every
#: platform's ``tracks (K, H, 2)`` and their bearings' information ``info (K, H, 3)``, the
#: others' summed information ``others (H, 3)`` (``none``: no others), the bound's root ``Lc``
#: with ``L_pred``, ``A_pred``, ``A_update``, and for ``q̃ = 0`` the others' root ``Lo``, the
#: late information ``C`` and its vector ``u``.
PlanWorkspace = namedtuple(
    "PlanWorkspace",
    "x x_next G path track tracks info others none Lc L_pred A_pred A_update Lo C u",
)


@njit(**_INLINE)
def workspace(members):
    """Scratch for the rows of one step or reset call, with a bank of ``members``."""
    return Workspace(
        np.empty(STATE_DIM),
        np.empty((STATE_DIM, STATE_DIM)),
        np.empty(members),
        np.empty((STATE_DIM, STATE_DIM)),
        np.empty((2 * STATE_DIM, STATE_DIM)),
        np.empty((STATE_DIM + 1, STATE_DIM + 1)),
    )


@njit(**_INLINE)
def plan_workspace(horizon, platforms):
    """Scratch for the rows of one planner call: plans of ``horizon`` steps, ``platforms``
    planned jointly (0 for a single platform's plans)."""
    D = STATE_DIM
    return PlanWorkspace(
        np.empty(D),
        np.empty(D),
        np.zeros((D, D)),
        np.empty((horizon, D)),
        np.empty((horizon, 2)),
        np.empty((platforms, horizon, 2)),
        np.empty((platforms, horizon, 3)),
        np.zeros((horizon, 3)),
        np.empty((0, 3)),
        np.empty((D, D)),
        np.empty((D, D)),
        np.empty((2 * D, D)),
        np.empty((D + 1, D + 1)),
        np.empty((D, D)),
        np.empty((D, D)),
        np.empty(D),
    )


# --- the contract: reset and step ---------------------------------------------------------------
#
# The kernels take the state's arrays out of their tuples once and hand each stage the arrays
# it reads and writes: a tuple handed to a stage, or a field read from one, counts a reference
# to each of its arrays every time, which the loops over rows would pay.


@njit(**_JIT)
def reset_kernel(settings, prior, state, eps):
    """Fresh scenarios from their draws (:func:`.reference.reset`), every row of ``state`` (a
    tuple in the order of :data:`StateArrays`): it reads the drawn platforms ``pos``,
    ``heading``, ``speed`` and ``target`` and writes the rest — the first bearings ``z`` (noise
    ``eps (B, K)``); the prior bank from platform 1's bearing (``prior``: the range cells
    ``r``, ``σ_r`` and log weights ``(N,)`` and the spread factors of the bearing and the course
    ``(3,)``, :attr:`.simulation.ManeuverParams.prior_cells`); the bound's square root ``L`` of
    the bank's moment-matched covariance; the other platforms' first bearings fused into both;
    the accuracy ``acc`` and the derived fields. ``settings`` is the params' record."""
    p = settings[0]
    s = StateArrays(*state)
    pos, _, _, target, lw, X, P, L, acc, z = state[:10]
    ws = workspace(lw.shape[1])
    x, Pe, w, L_in, A_update = ws.x, ws.Pe, ws.w, ws.L_pred, ws.A_update
    for b in range(z.shape[0]):
        take_bearings(p, target, pos, eps, b, z)
        prior_bank(p, prior, z, pos, b, lw, X, P)
        # P_0 = P_prior, the bank's covariance, which already holds platform 1's first bearing;
        # then P_0 = (P_prior⁻¹ + Σ_{k≥2} I_k(x_0))⁻¹: the other platforms' first bearings
        bank_estimate(lw[b], X[b], P[b], x, Pe, w)
        psd_square_root(Pe, L[b])
        for k in range(1, z.shape[1]):
            update_bank(p, lw[b], X[b], P[b], z[b, k], pos, b, k)
            copy2(L[b], L_in)
            update_bound(p, L_in, target, pos, b, k, L[b], A_update)
        acc[b] = row_accuracy(p, L[b], target, pos, b)
        derive(p, s, b, ws)


@njit(**_JIT)
def step_kernel(lo, hi, settings, old, action, draws, new, out):
    """One step of the scenarios ``lo ≤ b < hi`` (:func:`.reference.step`): reads the state
    ``old`` and writes the next into ``new`` (tuples of arrays in the order of
    :data:`StateArrays`, derived fields included) and ``out = (reward, terminated)`` ``(B,)``.
    ``action (B, K, 2)`` is clipped to ``[−1, 1]``; ``draws = (target_noise, noise_factor,
    bearing_noise)``: ``(B, 4)`` standard normals (read when ``q̃ > 0``), ``G (4, 4)`` with
    ``G Gᵀ = Q``, ``(B, K)`` standard normals. ``settings`` is the params' record. Returns the
    number of non-finite action entries (the caller raises: the kernel trusts everything else)."""
    p = settings[0]
    pos, heading, speed, target, lw, X, P, L, acc = old[:9]
    pos2, heading2, speed2, target2, lw2, X2, P2, L2, acc2, z2 = new[:10]
    s2 = StateArrays(*new)
    target_noise, noise_factor, bearing_noise = draws
    reward, terminated = out
    ws = workspace(lw.shape[1])
    spare, L_pred, A_pred, A_update = ws.x, ws.L_pred, ws.A_pred, ws.A_update
    bad = 0
    for b in range(lo, hi):
        # 1. the platforms fly the commanded arcs, the target moves on
        bad += fly(p, pos, heading, speed, action, b, pos2, heading2, speed2)
        move_target(p, target[b], target_noise, noise_factor, b, target2[b], spare)
        # 2. every platform takes a bearing; the bank predicts, then fuses them in turn
        take_bearings(p, target2, pos2, bearing_noise, b, z2)
        track(p, lw[b], X[b], P[b], z2, pos2, b, lw2[b], X2[b], P2[b])
        # 3. the bound on the true state: P̄ = F P Fᵀ + Q, then each platform's bearing
        bound_predict(L[b], p.dt, p.q_tilde, L_pred, A_pred)
        acc2[b] = bound(p, L_pred, target2, pos2, b, L2[b], A_update)
        # 4. what the agents see (and info reads), from the bank's estimate
        derive(p, s2, b, ws)
        # 5. reward and episode end: a platform within the stand-off min_range
        reward[b], terminated[b] = reward_and_end(p, acc[b], acc2[b], target2, pos2, b)
    return bad


# --- the world: flight, target motion, bearings (theory §2.5, §7.7, §11.2) ---------------------


@njit(**_INLINE)
def fly_step(p, px, py, heading, speed, turn, dv):
    """One platform's ``(x, y, heading, speed)`` one step on under the command ``(ω, Δv)``
    (rad/s, m/s; clipped to the settings' limits), the exact arc of
    :func:`~sensorgym.envs.worlds.platform_kernels.fly_platform`."""
    return fly_platform(
        px, py, heading, speed, turn, dv, p.dt, p.max_turn, p.max_dv, p.min_speed, p.max_speed
    )


@njit(**_INLINE)
def fly(p, pos, heading, speed, action, b, pos2, heading2, speed2):
    """Row ``b``'s platforms fly the commanded arcs ``(a₀ ω_max, a₁ Δv_max)``, ``a`` clipped to
    ``[−1, 1]`` (:func:`.reference.fly`), into ``pos2``, ``heading2``, ``speed2``. Returns the
    number of non-finite action entries."""
    bad = 0
    for k in range(heading.shape[1]):
        a0, a1 = action[b, k, 0], action[b, k, 1]
        if not (np.isfinite(a0) and np.isfinite(a1)):
            bad += 1
        a0 = min(max(a0, -1.0), 1.0)
        a1 = min(max(a1, -1.0), 1.0)
        pos2[b, k, 0], pos2[b, k, 1], heading2[b, k], speed2[b, k] = fly_step(
            p, pos[b, k, 0], pos[b, k, 1], heading[b, k], speed[b, k], a0 * p.max_turn,
            a1 * p.max_dv,
        )  # fmt: skip
    return bad


@njit(**_INLINE)
def move_target(p, x, noise, G, b, out, spare):
    """The target ``x (4,)`` one step on into ``out`` (:func:`.reference.move_target`):
    ``x' = F x + G ε`` (``ε = noise[b]``, read only when ``q̃ > 0``; ``spare`` stands in)."""
    propagate_target(x, noise[b] if p.q_tilde > 0.0 else spare, G, p.dt, p.q_tilde, out)


@njit(**_INLINE)
def take_bearings(p, target, pos, noise, b, z):
    """Row ``b``'s noisy bearings ``z = wrap(β + σ ε)`` of the target from every platform
    (:func:`.reference.take_bearings`), written into ``z[b]``."""
    for k in range(z.shape[1]):
        z[b, k] = noisy_bearing(
            target[b, 0], target[b, 1], pos[b, k, 0], pos[b, k, 1], p.sigma, noise[b, k]
        )


# --- the tracker: range-parameterised bank of second-order EKFs (theory §7.9, §11.2) -----------


@njit(**_INLINE)
def prior_bank(p, prior, z, pos, b, lw, X, P):
    """Row ``b``'s bank from platform 1's first bearing (:func:`.reference.prior_bank`): range
    cells and spread factors ``prior``, the speed prior of the settings, course mean = the
    bearing."""
    r, sr, lw0, pos_f, vel_f = prior
    z0 = z[b, 0]
    range_bank_prior(z0, pos[b, 0, 0], pos[b, 0, 1], r, sr, lw0, pos_f, p.speed_mean,
                     p.speed_sigma, z0, vel_f, lw[b], X[b], P[b])  # fmt: skip


@njit(**_INLINE)
def update_bank(p, lw, X, P, z, pos, b, k):
    """The bank ``lw``, ``X``, ``P`` of one row fuses platform ``k``'s bearing ``z``
    (:func:`.reference.update_bank`)."""
    bank_update(lw, X, P, z, pos[b, k, 0], pos[b, k, 1], p.sigma)


@njit(**_INLINE)
def track(p, lw, X, P, z, pos, b, lw2, X2, P2):
    """One row's bank predicts (:func:`.reference.predict_bank`) into ``lw2``, ``X2``, ``P2``
    and fuses the new bearings ``z[b]``, taken from ``pos[b]``, in platform order."""
    copy1(lw, lw2)
    bank_predict(X, P, p.dt, p.q_tilde, X2, P2)
    for k in range(z.shape[1]):
        update_bank(p, lw2, X2, P2, z[b, k], pos, b, k)


# --- the bound: posterior CRLB on the true state, square-root form (theory §7.8, §11.2) --------


@njit(**_INLINE)
def update_bound(p, L_pred, target, pos, b, k, out, A):
    """``out``, the square root of ``(P̄⁻¹ + Hᵀ H / σ²)⁻¹`` from ``L_pred`` (the root of ``P̄``)
    after platform ``k``'s bearing at the true target (:func:`.reference.update_bound`)."""
    bound_update(L_pred, target[b, 0], target[b, 1], pos[b, k, 0], pos[b, k, 1], p.sigma, out, A)


@njit(**_INLINE)
def row_accuracy(p, L, target, pos, b):
    """The accuracy ``m(P)`` the reward measures of row ``b``'s bound root ``L``
    (:func:`.reference.accuracy`): relative range from platform 1, or the position RMS."""
    return accuracy(p.relative_range, L, target[b, 0], target[b, 1], pos[b, 0, 0], pos[b, 0, 1],
                    p.floor)  # fmt: skip


@njit(**_INLINE)
def bound(p, L_pred, target, pos, b, out, A):
    """Row ``b``'s bound after the prediction ``L_pred`` (the root of ``P̄ = F P Fᵀ + Q``,
    :func:`.reference.predict_bound`): each platform's bearing information in turn, into
    ``out``. Returns its accuracy."""
    K = pos.shape[1]
    for k in range(K):
        update_bound(p, L_pred, target, pos, b, k, out, A)
        if k + 1 < K:
            copy2(out, L_pred)
    return row_accuracy(p, out, target, pos, b)


# --- reward, observation -----------------------------------------------------------------------


@njit(**_INLINE)
def reward_and_end(p, m_before, m_after, target, pos, b):
    """Row ``b``'s ``(reward, terminated)`` (:func:`.reference.reward`): ``ln m_k − ln m_{k+1}``,
    less ``close_penalty`` when a platform came within ``min_range``."""
    r = math.log(m_before) - math.log(m_after)
    end = False
    for k in range(pos.shape[1]):
        if math.hypot(target[b, 0] - pos[b, k, 0], target[b, 1] - pos[b, k, 1]) < p.min_range:
            end = True
    return r - p.penalty * (1.0 if end else 0.0), end


@njit(**_INLINE)
def derive(p, s, b, ws):
    """Row ``b``'s derived fields of the state ``s`` (:func:`.reference.with_derived_fields`)
    from the bank's moment-matched estimate (into ``ws.x``, ``ws.Pe``): each platform's
    observation (:func:`observe_platform`), the nearest platform's range
    ``min_k ‖x_t − p_k‖`` and the estimate's position error ``‖x̂ − x_t‖``."""
    pos, heading, speed, target, z, obs = s.pos, s.heading, s.speed, s.target, s.z, s.obs
    x, Pe = ws.x, ws.Pe
    bank_estimate(s.lw[b], s.X[b], s.P[b], x, Pe, ws.w)
    K = heading.shape[1]
    for k in range(K):
        observe_platform(p, pos, heading, speed, z, b, k, x, Pe, obs)
    r = np.inf
    for k in range(K):
        r = min(r, math.hypot(target[b, 0] - pos[b, k, 0], target[b, 1] - pos[b, k, 1]))
    s.nearest[b] = r
    s.error[b] = math.hypot(x[0] - target[b, 0], x[1] - target[b, 1])


@njit(**_INLINE)
def observe_platform(p, pos, heading, speed, z, b, k, x, Pe, obs):
    """Platform ``k``'s observation ``obs[b, k]`` (float32, the table of
    :func:`.simulation.observe_agents`, every entry clipped to ``±clip``) from the estimate
    ``x``, ``Pe``: the bearing relative to the heading, the own speed, the estimated target's
    position and velocity relative to the platform, in its frame, their spreads, and each other
    platform's position relative to this one, in platform order."""
    clip, range_scale, speed_scale = p.clip, p.range_scale, p.speed_scale
    psi = heading[b, k]
    sn, co = math.sin(psi), math.cos(psi)
    rel = z[b, k] - psi
    _put(obs, b, k, 0, math.sin(rel), clip)
    _put(obs, b, k, 1, math.cos(rel), clip)
    _put(obs, b, k, 2, speed[b, k] / max(p.max_speed, 1e-12), clip)
    r0, r1 = body_frame(sn, co, x[0] - pos[b, k, 0], x[1] - pos[b, k, 1])
    _put(obs, b, k, 3, r0 / range_scale, clip)
    _put(obs, b, k, 4, r1 / range_scale, clip)
    v0, v1 = body_frame(sn, co, x[2] - speed[b, k] * sn, x[3] - speed[b, k] * co)
    _put(obs, b, k, 5, v0 / speed_scale, clip)
    _put(obs, b, k, 6, v1 / speed_scale, clip)
    # the position and the velocity covariance in the platform frame, as spreads
    _put_spread(obs, b, k, 7, sn, co, Pe[0, 0], Pe[0, 1], Pe[1, 1], range_scale, clip)
    _put_spread(obs, b, k, 10, sn, co, Pe[2, 2], Pe[2, 3], Pe[3, 3], speed_scale, clip)
    i = 13
    for j in range(heading.shape[1]):
        if j != k:
            o0, o1 = body_frame(sn, co, pos[b, j, 0] - pos[b, k, 0], pos[b, j, 1] - pos[b, k, 1])
            _put(obs, b, k, i, o0 / range_scale, clip)
            _put(obs, b, k, i + 1, o1 / range_scale, clip)
            i += 2


# a world vector v in the platform frame (starboard, ahead): (c v₀ − s v₁, s v₀ + c v₁)
@njit(**_JIT)
def body_frame(s, c, v0, v1):
    return c * v0 - s * v1, s * v0 + c * v1


# every entry clipped to [−clip, clip]. _put and _put_spread are called with constant
# indices: register_jitable types them on plain integers (one compile each), where a
# dispatcher compiles one specialisation per literal index
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


# --- the planners: the bound along a plan (agents.bearings_maneuver) ---------------------------


# one platform flies command (ω, Δv) for len(out) steps: its positions ``out (H, 2)``
@njit(**_JIT)
def _fly_hold(p, px, py, h, v, turn, dv, out):
    for s in range(out.shape[0]):
        px, py, h, v = fly_step(p, px, py, h, v, turn, dv)
        out[s, 0], out[s, 1] = px, py


# the target's mean path x' = F x (no noise draw) from x0 (4,): ``path (H, 4)``
@njit(**_JIT)
def _mean_path(p, x0, path, x, x_next, G):
    copy1(x0, x)
    for s in range(path.shape[0]):
        propagate_target(x, x, G, p.dt, 0.0, x_next)
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
def _plan_accuracy(p, L0, path, track, others, use_others, too_close, origin, Lc, L_pred, A_pred,
                   A_update):  # fmt: skip
    """The bound recursion of :func:`step_kernel` along a plan: from the square root ``L0``,
    each step predicts and fuses the bearing from ``track[s]`` on the target's mean path
    ``path[s]``; with ``use_others``, together with the other platforms' position
    information ``others[s]`` (``(i00, i01, i11)``): the 2×2 sum enters as two rank-one
    updates, the columns of its Cholesky factor (information adds, so this is the env's
    sequential fusion of every bearing). Returns the accuracy the reward measures at the end
    (relative range from ``origin[-1]``), or ``inf`` when the track comes within
    ``too_close`` of the path."""
    copy2(L0, Lc)
    close = False
    for s in range(path.shape[0]):
        bound_predict(Lc, p.dt, p.q_tilde, L_pred, A_pred)
        dx, dy = path[s, 0] - track[s, 0], path[s, 1] - track[s, 1]
        if use_others:
            r = math.hypot(dx, dy)
            n0, n1 = dy / r, -dx / r
            a = 1.0 / (r * p.sigma) ** 2
            i00 = others[s, 0] + a * n0 * n0
            i01 = others[s, 1] + a * n0 * n1
            i11 = others[s, 2] + a * n1 * n1
            _fuse_position_information(L_pred, i00, i01, i11, Lc, A_update)
        else:
            bound_update(L_pred, path[s, 0], path[s, 1], track[s, 0], track[s, 1], p.sigma, Lc,
                         A_update)  # fmt: skip
        if math.hypot(dx, dy) < too_close:
            close = True
    if close:
        return np.inf
    H = path.shape[0] - 1
    return accuracy(p.relative_range, Lc, path[H, 0], path[H, 1], origin[-1, 0], origin[-1, 1],
                    p.floor)  # fmt: skip


# q̃ = 0: the plan's own bearings fuse last (trackers.bearings.kernels.late_bearing_information),
# so the recursion of the prior and the other platforms' bearings runs once per platform, not
# once per candidate: ``Lo`` is its square root at the end of the horizon
@njit(**_JIT)
def _others_root(p, L0, others, Lo, L_pred, A_pred, A_update):
    copy2(L0, Lo)
    for s in range(others.shape[0]):
        bound_predict(Lo, p.dt, p.q_tilde, L_pred, A_pred)
        _fuse_position_information(L_pred, others[s, 0], others[s, 1], others[s, 2], Lo, A_update)


@njit(**_JIT)
def _late_plan_accuracy(p, Lo, path, track, too_close, origin, C, u, Lc):
    """:func:`_plan_accuracy` for ``q̃ = 0`` from the others' root ``Lo``
    (:func:`_others_root`): the plan's bearings enter at the end in one update (equal up to
    rounding)."""
    H = path.shape[0]
    for i in range(STATE_DIM):
        for j in range(STATE_DIM):
            C[i, j] = 1.0 if i == j else 0.0
    for s in range(H):
        if math.hypot(path[s, 0] - track[s, 0], path[s, 1] - track[s, 1]) < too_close:
            return np.inf
        late_bearing_information(Lo, path[s, 0], path[s, 1], track[s, 0], track[s, 1], p.sigma,
                                 (H - 1 - s) * p.dt, C, u)  # fmt: skip
    late_update_root(Lo, C, Lc)
    return accuracy(p.relative_range, Lc, path[H - 1, 0], path[H - 1, 1], origin[-1, 0],
                    origin[-1, 1], p.floor)  # fmt: skip


@njit(**_JIT)
def plan_kernel(lo, hi, settings, pos, heading, speed, target, L, command, horizon, too_close,
                out):  # fmt: skip
    """The truth-informed lookahead's plans for one platform (:meth:`sensorgym.agents.bearings_maneuver.
    TruthLookahead.plan_bounds`) for scenarios ``lo ≤ b < hi``: platform 1 of ``pos (B, K, 2)``,
    ``heading``, ``speed`` ``(B, K)`` holds each command ``command (C, 2)`` (rad/s, m/s; clipped
    as the step does) for ``horizon`` steps while the target follows its mean path ``F x`` from
    ``target (B, 4)`` and the bound's square root ``L (B, 4, 4)`` runs the env's recursion
    (:func:`step_kernel`'s predict and bearing update on the true state). Writes the accuracy
    the reward measures at the end, ``out (B, C)``, or ``inf`` for a plan that comes within
    ``too_close`` (m). ``settings`` is the params' record."""
    p = settings[0]
    x, x_next, G, path, track, _, _, others, none, Lc, L_pred, A_pred, A_update, Lo, C, u = (
        plan_workspace(horizon, 0)
    )
    late = p.q_tilde == 0.0
    for b in range(lo, hi):
        _mean_path(p, target[b], path, x, x_next, G)
        if late:
            _others_root(p, L[b], others, Lo, L_pred, A_pred, A_update)
        for j in range(command.shape[0]):
            _fly_hold(p, pos[b, 0, 0], pos[b, 0, 1], heading[b, 0], speed[b, 0], command[j, 0],
                      command[j, 1], track)  # fmt: skip
            if late:
                out[b, j] = _late_plan_accuracy(p, Lo, path, track, too_close, track, C, u, Lc)
            else:
                out[b, j] = _plan_accuracy(p, L[b], path, track, none, False, too_close, track, Lc,
                                           L_pred, A_pred, A_update)  # fmt: skip


@njit(**_JIT)
def joint_plan_kernel(lo, hi, settings, pos, heading, speed, target, L, command, horizon,
                      too_close, choice):  # fmt: skip
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
    ``choice (B, K)``; a plan within ``too_close`` (m) of the target's mean path is ruled out.
    ``settings`` is the params' record."""
    p = settings[0]
    K = heading.shape[1]
    x, x_next, G, path, track, tracks, info, others, _, Lc, L_pred, A_pred, A_update, Lo, C, u = (
        plan_workspace(horizon, K)
    )
    late = p.q_tilde == 0.0
    for b in range(lo, hi):
        _mean_path(p, target[b], path, x, x_next, G)
        for k in range(K):
            _fly_hold(p, pos[b, k, 0], pos[b, k, 1], heading[b, k], speed[b, k], 0.0, 0.0,
                      tracks[k])  # fmt: skip
            _bearing_information(path, tracks[k], p.sigma, info[k])
        for k in range(K):
            _sum_others(info, k, others)
            if late:
                _others_root(p, L[b], others, Lo, L_pred, A_pred, A_update)
            best, best_value = 0, np.inf
            for j in range(command.shape[0]):
                _fly_hold(p, pos[b, k, 0], pos[b, k, 1], heading[b, k], speed[b, k],
                          command[j, 0], command[j, 1], track)  # fmt: skip
                origin = track if k == 0 else tracks[0]
                if late:
                    value = _late_plan_accuracy(p, Lo, path, track, too_close, origin, C, u, Lc)
                else:
                    value = _plan_accuracy(p, L[b], path, track, others, K > 1, too_close, origin,
                                           Lc, L_pred, A_pred, A_update)  # fmt: skip
                if value < best_value:
                    best, best_value = j, value
            choice[b, k] = best
            _fly_hold(p, pos[b, k, 0], pos[b, k, 1], heading[b, k], speed[b, k],
                      command[best, 0], command[best, 1], tracks[k])  # fmt: skip
            _bearing_information(path, tracks[k], p.sigma, info[k])


# the information of every platform's bearings but platform k's, summed: ``others (H, 3)``
@njit(**_INLINE)
def _sum_others(info, k, others):
    others[:, :] = 0.0
    for i in range(info.shape[0]):
        if i != k:
            for s in range(others.shape[0]):
                for e in range(3):
                    others[s, e] += info[i, s, e]


@njit(**_JIT)
def greedy_kernel(settings, obs, sd, delta, command, too_close, choice):
    """The greedy rule (:class:`sensorgym.agents.bearings_maneuver.GreedyManeuver`) on every
    platform's view ``obs (n, K, obs_dim)``, platform by platform (sequential greedy): platform
    ``k`` flies each command ``command (C, 2)`` (rad/s, m/s) from its own frame
    (:func:`fly_step` from the origin, heading 0 = ahead); the estimated target moves on by
    its estimated velocity; the command with the largest information gain ``hᵀ P h`` of the next
    bearing, ``h = n̂/r`` at the new relative position (``-inf`` within ``too_close``, m), is
    taken, and its information updates ``P ← P − P h hᵀ P / (hᵀ P h + σ²)`` before the next
    platform chooses. ``P`` is the estimate's position covariance in platform 1's frame, from
    its standard deviations ``sd (n, 2)`` (m) and correlation (obs 9); ``delta (n, K)`` turns
    platform ``k``'s frame into platform 1's (its heading relative to platform 1's, rad).
    Writes each platform's first best command index into ``choice (n, K)``. ``settings`` is
    the params' record."""
    p = settings[0]
    K = obs.shape[1]
    dt, sigma = p.dt, p.sigma
    range_scale, speed_scale = p.range_scale, p.speed_scale
    for b in range(obs.shape[0]):
        # estimated position covariance from the log standard deviations and the correlation
        p00, p11 = sd[b, 0] * sd[b, 0], sd[b, 1] * sd[b, 1]
        p01 = sd[b, 0] * sd[b, 1] * obs[b, 0, 9]
        for k in range(K):
            v = obs[b, k, 2] * p.max_speed
            d0, d1 = obs[b, k, 3] * range_scale, obs[b, k, 4] * range_scale
            # estimated target velocity in the platform frame: relative velocity + own (0, v)
            vt0, vt1 = obs[b, k, 5] * speed_scale, obs[b, k, 6] * speed_scale + v
            cd, sdl = math.cos(delta[b, k]), math.sin(delta[b, k])
            best, best_gain, h0, h1 = 0, -np.inf, 0.0, 0.0
            for j in range(command.shape[0]):
                e0, e1, _, _ = fly_step(p, 0.0, 0.0, 0.0, v, command[j, 0], command[j, 1])
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
