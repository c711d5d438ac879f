"""The compiled step of the receiver-placement environments: one loop over the scenarios.

The maths is that of :mod:`.scan` and :mod:`.simulation` (theory §3, §11.4); each formula is a
primitive of the module that owns it — :mod:`sensorgym.trackers.geometry_kernels` (look-at
rotation, relative poses, angular noise, angles between lines of sight),
:mod:`sensorgym.trackers.stereo.conjugation_kernels` (the n = 3 order-1 conjugation, called per
scenario) and :mod:`sensorgym.trackers.stereo.kernels` (information, bound, reward) — and
these kernels only chain them per scenario:

* :func:`drive` — the action's velocities and the receivers' new positions held in the disc;
* :func:`period_systems` — one scan period's true geometry, the receivers' frames, the noisy and
  the exact conjugation systems and (n = 3) their closed-form solves;
* :func:`period_finish` — the covariance mapping, the fix in the world frame, the estimate (or the
  coasted one), the Cramér–Rao bound and the reward;
* :func:`observe_kernel`, :func:`info_kernel` — the observation blocks and the diagnostics.

Random draws stay with numpy's Generator (drawn before the kernels, in today's order); the rare
systems whose ``κ_F`` exceeds ``cond_max`` are re-solved by the caller on the generic SVD path of
:func:`~sensorgym.trackers.stereo.conjugation.solve_conjugation`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from sensorgym.trackers.geometry_kernels import (
    look_at3,
    los_angle3,
    norm3,
    perturbed_direction3,
    relative_pose3,
    to_local3,
    to_world3,
    unit_from_angles3,
)
from sensorgym.trackers.stereo.conjugation_kernels import triple_velocity_kernel
from sensorgym.trackers.stereo.kernels import (
    log_ratio_reward,
    observable,
    position_information,
    position_sigma,
)

_JIT = {"cache": True, "nogil": True, "error_model": "numpy", "boundscheck": False}

_UP = (0.0, 1.0, 0.0)


@njit(inline="always")
def _row(x, i):
    return (x[i, 0], x[i, 1], x[i, 2])


@njit(inline="always")
def _row3(x, i, k):
    return (x[i, k, 0], x[i, k, 1], x[i, k, 2])


@njit(inline="always")
def _columns(R, i, k):
    """Columns of ``R[i, k] (3, 3)``."""
    return (
        (R[i, k, 0, 0], R[i, k, 1, 0], R[i, k, 2, 0]),
        (R[i, k, 0, 1], R[i, k, 1, 1], R[i, k, 2, 1]),
        (R[i, k, 0, 2], R[i, k, 1, 2], R[i, k, 2, 2]),
    )


@njit(inline="always")
def boresight3(origin, aim, max_elevation):
    """Columns of the local→world rotation of a receiver at ``origin`` looking at ``aim``, the
    boresight elevation held within ``±max_elevation`` so that the roll (``Y`` towards world
    up) stays defined even right under the aim point (``atan2(0, 0) = 0``: any azimuth)."""
    d = (aim[0] - origin[0], aim[1] - origin[1], aim[2] - origin[2])
    azimuth = np.arctan2(d[0], d[2])
    elevation = np.arctan2(d[1], np.hypot(d[0], d[2]))
    elevation = min(max(elevation, -max_elevation), max_elevation)
    w = unit_from_angles3(azimuth, elevation)
    R, _ = look_at3(origin, (origin[0] + w[0], origin[1] + w[1], origin[2] + w[2]), _UP)
    return R


@njit(**_JIT)
def boresight_batch(origins, aim, max_elevation, out):
    """:func:`boresight3` for ``origins (B, n, 3)`` and ``aim (B, 3)`` into ``out (B, n, 3, 3)``."""
    for i in range(origins.shape[0]):
        a = _row(aim, i)
        for k in range(origins.shape[1]):
            R = boresight3(_row3(origins, i, k), a, max_elevation)
            for j in range(3):
                for c in range(3):
                    out[i, k, j, c] = R[c][j]


@njit(**_JIT)
def any_true(flags):
    """``flags.any()`` without numpy's dispatch cost."""
    for f in flags:
        if f:
            return True
    return False


@njit(**_JIT)
def drive(receivers, action, period, max_speed, radius, end):
    """``end (B, n, 3)``: receivers driven for ``τ`` at the velocities of ``action (B, n, 2)``
    (components clipped to ``[−1, 1]``, speed capped at ``max_speed``), pulled back onto the disc
    of ``radius``."""
    B, n = receivers.shape[0], receivers.shape[1]
    for i in range(B):
        for k in range(n):
            ax = min(max(action[i, k, 0], -1.0), 1.0)
            az = min(max(action[i, k, 1], -1.0), 1.0)
            s = max(np.sqrt(ax * ax + az * az), 1.0)
            # v = max_speed (a_x, 0, a_z) / max(‖a‖, 1)
            v = (max_speed * (ax / s), max_speed * 0.0, max_speed * (az / s))
            p = (
                receivers[i, k, 0] + period * v[0],
                receivers[i, k, 1] + period * v[1],
                receivers[i, k, 2] + period * v[2],
            )
            # radially back onto the disc where outside it
            scale = min(1.0, radius / max(np.hypot(p[0], p[2]), 1e-12))
            end[i, k, 0], end[i, k, 1], end[i, k, 2] = p[0] * scale, p[1] * scale, p[2] * scale


@njit(**_JIT)
def period_systems(
    delays, period, sigma_ang, max_elevation, start, end, drone_end, drone_velocity, previous,
    normals, origins, los, ranges, R, a1, ak, P, b, dt, e1, ek, X, J, Q, kappa, position,
    Xe, Je, Qe, kappa_e, position_e,
):  # fmt: skip
    """One scan period of every scenario: true geometry, frames, both conjugation systems.

    Receivers move from ``start`` to ``end`` ``(B, n, 3)``; the drone is at ``drone_end (B, 3)``
    at the period end; the frames look at the coasted ``previous (B, 6)`` estimate's mid-period
    point; ``normals (B, n, 3)`` are the noise draws (unused when ``sigma_ang = 0``). Fills the
    true ``origins``, ``los``, ``ranges``, rotations ``R (B, n, 3, 3)``, the noisy system
    ``(a1, ak, P, b, dt)`` and the exact one ``(e1, ek)``; for n = 3 also their solves
    ``(X, J, Q, κ, M̂_1)`` and ``(Xe, …)`` (``κ_F`` > ``cond_max`` left to the caller). Returns 0
    or the input-check code of :func:`triple_velocity_kernel` (a zero line of sight).
    """
    B, n = start.shape[0], start.shape[1]
    noisy = sigma_ang > 0.0
    for i in range(B):
        # the aim of the receivers' frames: the previous estimate coasted to mid-period
        aim = (
            previous[i, 0] + 0.5 * period * previous[i, 3],
            previous[i, 1] + 0.5 * period * previous[i, 4],
            previous[i, 2] + 0.5 * period * previous[i, 5],
        )
        for k in range(n):
            f = delays[k] / period
            # O_k(d_k): receivers drive straight from start to end during the period
            o = (
                start[i, k, 0] + (end[i, k, 0] - start[i, k, 0]) * f,
                start[i, k, 1] + (end[i, k, 1] - start[i, k, 1]) * f,
                start[i, k, 2] + (end[i, k, 2] - start[i, k, 2]) * f,
            )
            # M(d_k) = M(τ) − V (τ − d_k)
            back = period - delays[k]
            off = (
                drone_end[i, 0] - drone_velocity[i, 0] * back - o[0],
                drone_end[i, 1] - drone_velocity[i, 1] * back - o[1],
                drone_end[i, 2] - drone_velocity[i, 2] * back - o[2],
            )
            r = norm3(off)
            rr = max(r, 1e-9)
            u = (off[0] / rr, off[1] / rr, off[2] / rr)
            Rk = boresight3(o, aim, max_elevation)
            ranges[i, k] = r
            for j in range(3):
                origins[i, k, j] = o[j]
                los[i, k, j] = u[j]
                for c in range(3):
                    R[i, k, j, c] = Rk[c][j]
            # a_k = R_kᵀ z_k: each receiver reports the direction in its own frame
            z = perturbed_direction3(u, _row3(normals, i, k), sigma_ang) if noisy else u
            if r == 0.0:
                z = (0.0, 0.0, 0.0)  # no direction to measure (the solve's check names it)
            a = to_local3(Rk, z)
            e = to_local3(Rk, u)
            if k == 0:
                for j in range(3):
                    a1[i, j], e1[i, j] = a[j], e[j]
            else:
                for j in range(3):
                    ak[i, k - 1, j], ek[i, k - 1, j] = a[j], e[j]
                dt[i, k - 1] = delays[k] - delays[0]
        # P_k = R_1ᵀ R_k,  b_k = R_1ᵀ (O_k − O_1)
        R1, o1 = _columns(R, i, 0), _row3(origins, i, 0)
        for k in range(1, n):
            Pk, bk = relative_pose3(R1, o1, _columns(R, i, k), _row3(origins, i, k))
            for j in range(3):
                b[i, k - 1, j] = bk[j]
                for c in range(3):
                    P[i, k - 1, j, c] = Pk[c][j]
        if n == 3:
            code = triple_velocity_kernel(a1, ak, P, b, dt, 1.0, True, i, i + 1, X, J, Q, kappa,
                                          position)  # fmt: skip
            if code != 0:
                return code
            if noisy:
                code = triple_velocity_kernel(e1, ek, P, b, dt, 1.0, True, i, i + 1, Xe, Je, Qe,
                                              kappa_e, position_e)  # fmt: skip
                if code != 0:
                    return code
    return 0


@njit(**_JIT)
def period_finish(
    delays, period, sigma_ang, sigma_ref, reward_clip, origins, los, ranges, R, a1, X, Q,
    degenerate, degenerate_true, previous, position, velocity, range_sigma, velocity_sigma,
    estimate, bound, reward,
):  # fmt: skip
    """The fix in the world frame, its reported accuracy, the estimate, bound and reward.

    ``a1 (B, 3)`` receiver 1's measured direction (own frame), ``X (B, n+3)`` and
    ``Q (B, n+3, n+3)`` the noisy solve at ``σ_e = 1``; ``degenerate`` its pseudo-inverse flag,
    ``degenerate_true`` that of the exact system. Covariance mapping (:mod:`.scan`):
    ``Q ← (σ_ang · mean_k |r̂_k|)² Q``; the estimate is the fix, or the previous one coasted by
    ``τ`` where the fix was degenerate; ``σ_pos = σ_ang √tr G⁻¹`` of the true geometry
    (``G = Σ_k Π_k/r_k²``); the reward ``clip(ln(σ_ref/σ_pos), −R, R)``, ``−R`` where degenerate.
    """
    B, n = origins.shape[0], origins.shape[1]
    to_end = period - delays[0]
    # scratch of the bound (the stereo tracker kernels' information, test and bound)
    G, LU, inv = np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3))
    piv = np.empty(3, np.int64)
    unit = np.ones(n)
    every = np.ones(n, np.bool_)
    for i in range(B):
        # σ_e = σ_ang · mean_k |r̂_k|
        total = 0.0
        for k in range(n):
            total += abs(X[i, k])
        sigma_e = sigma_ang * (total / n)
        s2 = sigma_e**2
        for k in range(n):
            range_sigma[i, k] = np.sqrt(max(s2 * Q[i, k, k], 0.0))
        vv = 0.0
        for j in range(n, n + 3):
            vv += max(s2 * Q[i, j, j], 0.0)
        velocity_sigma[i] = np.sqrt(vv)
        # frame 1 → world: M = O_1(d_1) + R_1 M̂_1 (M̂_1 = r̂_1 a_1), V = R_1 V̂_1; then on to
        # the period end
        R1 = _columns(R, i, 0)
        r1 = X[i, 0]
        m = to_world3(R1, (r1 * a1[i, 0], r1 * a1[i, 1], r1 * a1[i, 2]))
        v = to_world3(R1, (X[i, n], X[i, n + 1], X[i, n + 2]))
        for j in range(3):
            velocity[i, j] = v[j]
            position[i, j] = (origins[i, 0, j] + m[j]) + v[j] * to_end
            if degenerate[i]:  # not trusted: the previous estimate coasted by τ
                estimate[i, j] = previous[i, j] + period * previous[i, 3 + j]
                estimate[i, 3 + j] = previous[i, 3 + j]
            else:
                estimate[i, j] = position[i, j]
                estimate[i, 3 + j] = v[j]
        # σ_pos of the true geometry, G = Σ_k (I − u_k u_kᵀ)/r_k²
        position_information(los[i], ranges[i], unit, every, G)
        bound[i] = position_sigma(G, observable(G, n), sigma_ang, LU, piv, inv)
        if degenerate[i] or degenerate_true[i]:
            reward[i] = -reward_clip
        else:
            reward[i] = log_ratio_reward(bound[i], sigma_ref, reward_clip)


@njit(**_JIT)
def observe_kernel(
    receivers, estimate, range_sigma, velocity_sigma, condition, degenerate, length, speed,
    sigma_ref, period, pairs, out,
):  # fmt: skip
    """The observation blocks of :func:`.simulation.observe` (before clipping) into
    ``out (B, obs_dim)``."""
    B, n = receivers.shape[0], receivers.shape[1]
    tiny = 1e-12
    half_pi = np.pi / 2
    for i in range(B):
        p = _row(estimate, i)
        c = 0
        for k in range(n):
            out[i, c] = receivers[i, k, 0] / length
            out[i, c + 1] = receivers[i, k, 2] / length
            c += 2
        for k in range(n):
            out[i, c] = (receivers[i, k, 0] - p[0]) / length
            out[i, c + 1] = (receivers[i, k, 2] - p[2]) / length
            c += 2
        for j in range(3):
            out[i, c + j] = estimate[i, j] / length
            out[i, c + 3 + j] = estimate[i, 3 + j] / speed
        c += 6
        for k in range(n):
            out[i, c + k] = np.log(max(range_sigma[i, k], tiny) / sigma_ref)
        c += n
        out[i, c] = np.log(max(velocity_sigma[i], tiny) * period / sigma_ref)
        out[i, c + 1] = np.log10(min(condition[i], 1e300))
        c += 2
        for q in range(pairs.shape[0]):
            out[i, c + q] = _pair_angle(receivers, i, pairs[q, 0], pairs[q, 1], p) / half_pi
        c += pairs.shape[0]
        out[i, c] = 1.0 if degenerate[i] else 0.0


@njit(inline="always")
def _sight(receivers, i, k, point):
    d = (
        point[0] - receivers[i, k, 0],
        point[1] - receivers[i, k, 1],
        point[2] - receivers[i, k, 2],
    )
    r = max(norm3(d), 1e-9)
    return (d[0] / r, d[1] / r, d[2] / r)


@njit(inline="always")
def _pair_angle(receivers, i, k, l, point):
    return los_angle3(_sight(receivers, i, k, point), _sight(receivers, i, l, point))


@njit(**_JIT)
def los_angles_kernel(receivers, point, pairs, out):
    """Angles ``γ_kl (B, pairs)`` between the lines of sight from ``receivers (B, n, 3)`` to
    ``point (B, 3)``, rad."""
    for i in range(receivers.shape[0]):
        p = _row(point, i)
        for q in range(pairs.shape[0]):
            out[i, q] = _pair_angle(receivers, i, pairs[q, 0], pairs[q, 1], p)


@njit(**_JIT)
def info_kernel(receivers, estimate, drone_position, pairs, error, min_angle):
    """Position error ``‖p̂ − p‖`` and the smallest angle between the lines of sight to the
    drone."""
    for i in range(receivers.shape[0]):
        p = _row(drone_position, i)
        error[i] = norm3((estimate[i, 0] - p[0], estimate[i, 1] - p[1], estimate[i, 2] - p[2]))
        smallest = np.inf
        for q in range(pairs.shape[0]):
            smallest = min(smallest, _pair_angle(receivers, i, pairs[q, 0], pairs[q, 1], p))
        min_angle[i] = smallest
