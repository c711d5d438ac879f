"""The compiled step of the receiver-placement environments: one loop over the scenarios.

The maths is that of :mod:`.scan` and :mod:`.simulation` (theory §3, §11.4); each formula is a
primitive of the module that owns it — :mod:`sensorgym.trackers.geometry_kernels` (look-at
rotation, relative poses, angular noise, angles between lines of sight),
:mod:`sensorgym.trackers.stereo.conjugation_kernels` (the order-1 conjugation: the n = 3 closed form,
the normal equations for more receivers; called per scenario) and :mod:`sensorgym.trackers.stereo.kernels` (information, bound, reward) — and
these kernels only chain them per scenario. Each stage is a row function (scenario ``i``):

* :func:`drive` — the action's velocities and the receivers' new positions held in the disc;
* :func:`systems_row` (:func:`period_systems`) — one scan period's true geometry, the receivers'
  frames, the noisy and the exact conjugation systems and their compiled solves;
* :func:`finish_row` (:func:`period_finish`) — the covariance mapping, the fix in the world
  frame, the estimate (or the coasted one), the Cramér–Rao bound and the reward;
* :func:`observe_row`, :func:`info_row` — the observation blocks (clipped, float32) and the
  diagnostics.

:func:`period_rows` chains them all for a range of scenarios: one kernel call per step (run
over threads by :func:`sensorgym.envs.shells.rows.run_rows`). Random draws stay with numpy's
Generator (drawn before the kernels, in a fixed order); the rare systems whose ``κ_F`` exceeds
``cond_max`` are left to the caller, which re-solves them on the generic SVD path of
:func:`~sensorgym.trackers.stereo.conjugation.solve_conjugation` with the batch kernels.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from sensorgym.envs.shells.contract import OBS_CLIP
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
from sensorgym.trackers.stereo.conjugation_kernels import triple_velocity_kernel, velocity_kernel
from sensorgym.trackers.stereo.kernels import (
    MIN_RANGE,
    line_of_sight,
    log_ratio_reward,
    observable,
    position_information,
    position_sigma,
)

_JIT = {"cache": True, "nogil": True, "error_model": "numpy", "boundscheck": False}

#: row functions are inlined into the kernels that loop over scenarios: a call per scenario
#: would pass (and reference-count) some thirty arrays
_ROW = {**_JIT, "inline": "always"}

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


@njit(inline="always")
def _in_disc(x, y, z, radius):
    """``(x, y, z)`` pulled radially back onto the disc of ``radius`` where outside it
    (:func:`.simulation.in_arena`)."""
    scale = min(1.0, radius / max(np.hypot(x, z), 1e-12))
    return (x * scale, y * scale, z * scale)


@njit(inline="always")
def _drive_row(receivers, action, period, max_speed, radius, end, i):
    """Row ``i`` of :func:`drive`."""
    for k in range(receivers.shape[1]):
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
        end[i, k, 0], end[i, k, 1], end[i, k, 2] = _in_disc(p[0], p[1], p[2], radius)


@njit(**_JIT)
def drive(receivers, action, period, max_speed, radius, end):
    """``end (B, n, 3)``: receivers driven for ``τ`` at the velocities of ``action (B, n, 2)``
    (components clipped to ``[−1, 1]``, speed capped at ``max_speed``), pulled back onto the disc
    of ``radius``."""
    for i in range(receivers.shape[0]):
        _drive_row(receivers, action, period, max_speed, radius, end, i)


@njit(inline="always")
def _velocity_solve(a1, ak, P, b, dt, s, X, J, Q, kappa, position):
    """Row ``s``'s order-1 conjugation (checked): the n = 3 closed form, else the normal
    equations; returns the kernel's input-check code. The row is passed as a plain int64: the
    literal row 0 of :func:`period_rows` would compile the kernels once more (numba
    specialises a call on a literal integer argument: another cold compile)."""
    lo = np.int64(s)
    if ak.shape[1] == 2:
        return triple_velocity_kernel(a1, ak, P, b, dt, 1.0, np.bool_(True), lo, lo + 1, X, J, Q,
                                      kappa, position)  # fmt: skip
    return velocity_kernel(a1, ak, P, b, dt, 1.0, np.bool_(True), lo, lo + 1, X, J, Q, kappa,
                           position)  # fmt: skip


@njit(**_ROW)
def systems_row(
    i, s, delays, scalars, start, end, drone_end, drone_velocity, previous, normals, truth, R,
    a1, ak, P, b, dt, e1, ek, X, J, Q, kappa, position, Xe, Qe, kappa_e, sight,
):  # fmt: skip
    """Scenario ``i`` of :func:`period_systems`: its inputs and the true geometry ``truth =
    (origins, los, ranges)`` at row ``i``, the frames, systems and solves at row ``s`` of their
    (scratch) arrays (``J`` and ``position`` serve both solves); ``scalars = (τ, σ_ang,
    max_elevation)``, ``sight (3,)`` scratch. The solves: the closed form for n = 3, the
    normal equations for n ≥ 4 (:func:`velocity_kernel`); ``κ_F`` is ``inf`` where they leave
    a system to the SVD path."""
    origins, los, ranges = truth
    period, sigma_ang, max_elevation = scalars
    n = start.shape[1]
    noisy = sigma_ang > 0.0
    kappa[s] = np.inf
    kappa_e[s] = np.inf
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
        at_fix = (
            drone_end[i, 0] - drone_velocity[i, 0] * back,
            drone_end[i, 1] - drone_velocity[i, 1] * back,
            drone_end[i, 2] - drone_velocity[i, 2] * back,
        )
        r = line_of_sight(o, at_fix, sight)
        u = (sight[0], sight[1], sight[2])
        Rk = boresight3(o, aim, max_elevation)
        ranges[i, k] = r
        for j in range(3):
            origins[i, k, j] = o[j]
            los[i, k, j] = u[j]
            for c in range(3):
                R[s, k, j, c] = Rk[c][j]
        # a_k = R_kᵀ z_k: each receiver reports the direction in its own frame
        z = perturbed_direction3(u, _row3(normals, i, k), sigma_ang) if noisy else u
        if not r > MIN_RANGE:
            z = (0.0, 0.0, 0.0)  # no direction to measure (the solve's check names it)
        a = to_local3(Rk, z)
        e = to_local3(Rk, u)
        if k == 0:
            for j in range(3):
                a1[s, j], e1[s, j] = a[j], e[j]
        else:
            for j in range(3):
                ak[s, k - 1, j], ek[s, k - 1, j] = a[j], e[j]
            dt[s, k - 1] = delays[k] - delays[0]
    # P_k = R_1ᵀ R_k,  b_k = R_1ᵀ (O_k − O_1)
    R1, o1 = _columns(R, s, 0), _row3(origins, i, 0)
    for k in range(1, n):
        Pk, bk = relative_pose3(R1, o1, _columns(R, s, k), _row3(origins, i, k))
        for j in range(3):
            b[s, k - 1, j] = bk[j]
            for c in range(3):
                P[s, k - 1, j, c] = Pk[c][j]
    code = _velocity_solve(a1, ak, P, b, dt, s, X, J, Q, kappa, position)
    if code != 0 or not noisy:
        return code
    return _velocity_solve(e1, ek, P, b, dt, s, Xe, J, Qe, kappa_e, position)


@njit(**_JIT)
def period_systems(
    delays, period, sigma_ang, max_elevation, start, end, drone_end, drone_velocity, previous,
    normals, origins, los, ranges, R, a1, ak, P, b, dt, e1, ek, X, J, Q, kappa, position,
    Xe, Qe, kappa_e,
):  # fmt: skip
    """One scan period of every scenario: true geometry, frames, both conjugation systems.

    Receivers move from ``start`` to ``end`` ``(B, n, 3)``; the drone is at ``drone_end (B, 3)``
    at the period end; the frames look at the coasted ``previous (B, 6)`` estimate's mid-period
    point; ``normals (B, n, 3)`` are the noise draws (unused when ``sigma_ang = 0``). Fills the
    true ``origins``, ``los``, ``ranges``, rotations ``R (B, n, 3, 3)``, the noisy system
    ``(a1, ak, P, b, dt)`` and the exact one ``(e1, ek)``, and their solves
    ``(X, J, Q, κ, M̂_1)`` and ``(Xe, Qe, κ_e)`` (``κ_F`` > ``cond_max``, or ``inf`` where the
    compiled solve leaves the system, for the caller). Returns 0 or the input-check code of :func:`triple_velocity_kernel` (a zero
    line of sight).
    """
    sight = np.empty(3)
    for i in range(start.shape[0]):
        code = systems_row(
            i, i, delays, (period, sigma_ang, max_elevation), start, end, drone_end,
            drone_velocity, previous, normals, (origins, los, ranges), R, a1, ak, P, b, dt, e1,
            ek, X, J, Q, kappa, position, Xe, Qe, kappa_e, sight,
        )  # fmt: skip
        if code != 0:
            return code
    return 0


@njit(**_ROW)
def finish_row(
    i, s, delays, period, sigma_ang, sigma_ref, reward_clip, origins, los, ranges, R, a1, X, Q,
    degenerate, degenerate_true, previous, position, velocity, range_sigma, velocity_sigma,
    estimate, bound, reward, G, LU, piv, inv, unit, every,
):  # fmt: skip
    """Scenario ``i`` of :func:`period_finish`, its solve (``R``, ``a1``, ``X``, ``Q``) at row
    ``s``; ``G``, ``LU``, ``inv (3, 3)``, ``piv (3,)`` scratch, ``unit``, ``every (n,)`` ones."""
    n = origins.shape[1]
    to_end = period - delays[0]
    # σ_e = σ_ang · mean_k |r̂_k|
    total = 0.0
    for k in range(n):
        total += abs(X[s, k])
    sigma_e = sigma_ang * (total / n)
    s2 = sigma_e**2
    for k in range(n):
        range_sigma[i, k] = np.sqrt(max(s2 * Q[s, k, k], 0.0))
    vv = 0.0
    for j in range(n, n + 3):
        vv += max(s2 * Q[s, j, j], 0.0)
    velocity_sigma[i] = np.sqrt(vv)
    # frame 1 → world: M = O_1(d_1) + R_1 M̂_1 (M̂_1 = r̂_1 a_1), V = R_1 V̂_1; then on to
    # the period end
    R1 = _columns(R, s, 0)
    r1 = X[s, 0]
    m = to_world3(R1, (r1 * a1[s, 0], r1 * a1[s, 1], r1 * a1[s, 2]))
    v = to_world3(R1, (X[s, n], X[s, n + 1], X[s, n + 2]))
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
    n = origins.shape[1]
    # scratch of the bound (the stereo tracker kernels' information, test and bound)
    G, LU, inv = np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3))
    piv = np.empty(3, np.int64)
    unit = np.ones(n)
    every = np.ones(n, np.bool_)
    for i in range(origins.shape[0]):
        finish_row(
            i, i, delays, period, sigma_ang, sigma_ref, reward_clip, origins, los, ranges, R, a1,
            X, Q, degenerate, degenerate_true, previous, position, velocity, range_sigma,
            velocity_sigma, estimate, bound, reward, G, LU, piv, inv, unit, every,
        )  # fmt: skip


@njit(inline="always")
def _clip_obs(x):
    """``np.clip(x, −OBS_CLIP, OBS_CLIP)`` of one value (NaN stays NaN)."""
    if x > OBS_CLIP:
        return OBS_CLIP
    if x < -OBS_CLIP:
        return -OBS_CLIP
    return x


@njit(**_ROW)
def observe_row(
    i, receivers, estimate, range_sigma, velocity_sigma, condition, degenerate, length, speed,
    sigma_ref, period, pairs, out, sights,
):  # fmt: skip
    """Scenario ``i``'s observation blocks of :func:`.simulation.observe`, clipped to
    ``±OBS_CLIP``, into ``out[i]`` (float32); ``sights (n, 3)`` scratch."""
    n = receivers.shape[1]
    tiny = 1e-12
    half_pi = np.pi / 2
    p = _row(estimate, i)
    c = 0
    for k in range(n):
        out[i, c] = _clip_obs(receivers[i, k, 0] / length)
        out[i, c + 1] = _clip_obs(receivers[i, k, 2] / length)
        c += 2
    for k in range(n):
        out[i, c] = _clip_obs((receivers[i, k, 0] - p[0]) / length)
        out[i, c + 1] = _clip_obs((receivers[i, k, 2] - p[2]) / length)
        c += 2
    for j in range(3):
        out[i, c + j] = _clip_obs(estimate[i, j] / length)
        out[i, c + 3 + j] = _clip_obs(estimate[i, 3 + j] / speed)
    c += 6
    for k in range(n):
        out[i, c + k] = _clip_obs(np.log(max(range_sigma[i, k], tiny) / sigma_ref))
    c += n
    out[i, c] = _clip_obs(np.log(max(velocity_sigma[i], tiny) * period / sigma_ref))
    out[i, c + 1] = _clip_obs(np.log10(min(condition[i], 1e300)))
    c += 2
    _sights(receivers, i, p, sights)
    for q in range(pairs.shape[0]):
        angle = _pair_angle(sights, pairs[q, 0], pairs[q, 1])
        out[i, c + q] = _clip_obs(angle / half_pi)
    c += pairs.shape[0]
    out[i, c] = 1.0 if degenerate[i] else 0.0


@njit(**_JIT)
def observe_kernel(
    rows, receivers, estimate, range_sigma, velocity_sigma, condition, degenerate, length, speed,
    sigma_ref, period, pairs, out,
):  # fmt: skip
    """:func:`observe_row` for the scenarios ``rows``."""
    sights = np.empty((receivers.shape[1], 3))
    for i in rows:
        observe_row(
            i, receivers, estimate, range_sigma, velocity_sigma, condition, degenerate, length,
            speed, sigma_ref, period, pairs, out, sights,
        )  # fmt: skip


@njit(inline="always")
def _sights(receivers, i, point, sights):
    """Unit lines of sight ``sights (n, 3)`` from every receiver of scenario ``i`` to ``point``
    (the stereo tracker kernels' :func:`line_of_sight`), each computed once for all its pairs."""
    for k in range(receivers.shape[1]):
        line_of_sight(_row3(receivers, i, k), point, sights[k])


@njit(inline="always")
def _pair_angle(sights, k, l):
    """The angle between the lines of sight ``k`` and ``l`` of :func:`_sights`."""
    return los_angle3(_row(sights, k), _row(sights, l))


@njit(**_JIT)
def los_angles_kernel(receivers, point, pairs, out):
    """Angles ``γ_kl (B, pairs)`` between the lines of sight from ``receivers (B, n, 3)`` to
    ``point (B, 3)``, rad."""
    sights = np.empty((receivers.shape[1], 3))
    for i in range(receivers.shape[0]):
        _sights(receivers, i, _row(point, i), sights)
        for q in range(pairs.shape[0]):
            out[i, q] = _pair_angle(sights, pairs[q, 0], pairs[q, 1])


@njit(**_ROW)
def info_row(i, receivers, estimate, drone_position, pairs, error, min_angle, sights):
    """Scenario ``i``'s position error ``‖p̂ − p‖`` and the smallest angle between the lines of
    sight to the drone (``sights (n, 3)`` scratch)."""
    p = _row(drone_position, i)
    error[i] = norm3((estimate[i, 0] - p[0], estimate[i, 1] - p[1], estimate[i, 2] - p[2]))
    smallest = np.inf
    _sights(receivers, i, p, sights)
    for q in range(pairs.shape[0]):
        smallest = min(smallest, _pair_angle(sights, pairs[q, 0], pairs[q, 1]))
    min_angle[i] = smallest


@njit(**_JIT)
def info_kernel(rows, receivers, estimate, drone_position, pairs, error, min_angle):
    """:func:`info_row` for the scenarios ``rows``."""
    sights = np.empty((receivers.shape[1], 3))
    for i in rows:
        info_row(i, receivers, estimate, drone_position, pairs, error, min_angle, sights)


#: flags returned by :func:`period_rows` (or-ed over its scenarios)
SLOW = 1
"""some scenarios are left to the caller (``slow``): ``κ_F > cond_max`` (or left by the compiled
solve), or a zero line of sight."""
BAD_ACTION = 2
"""an action holds NaN or infinite values (the kernel stopped there)."""

#: positions in the ``constants`` array of :func:`period_rows`
C_PERIOD, C_SIGMA, C_ELEVATION, C_SPEED, C_RADIUS, C_REF, C_CLIP, C_COND, C_LENGTH, C_SCALE = range(
    10
)


@njit(**_JIT)
def period_rows(
    lo, hi, moving, constants, delays, pairs, t, receivers, action, drone, drone_velocity,
    previous, normals, t_out, end, drone_end, origins, los, ranges, position, velocity,
    range_sigma, velocity_sigma, condition, degenerate, degenerate_true, estimate, bound, reward,
    observation, error, min_angle, slow,
):  # fmt: skip
    """The whole step of scenarios ``lo..hi−1`` in one pass: drive, period, finish, observation
    and diagnostics (:func:`drive`, :func:`period_systems`, :func:`period_finish`,
    :func:`observe_row`, :func:`info_row`, row by row).

    ``moving``: the receivers drive under ``action (B, n, 2)`` for ``τ`` and the drone flies
    on from ``drone`` (a step); else ``end``, ``drone_end`` and ``t_out`` copy ``receivers``,
    ``drone`` and ``t`` (the first fix of :func:`.simulation.start`). ``constants`` holds the
    params' scalars (``C_*``). A scenario whose conjugation the closed form does not settle
    (``κ_F > cond_max`` in either system, or left by the compiled solve, a zero line of sight) is marked in ``slow``
    and left unfinished: the caller solves it on the generic path. Returns the or-ed flags
    :data:`SLOW`, :data:`BAD_ACTION` (checked before anything of that scenario is written).
    """
    n = receivers.shape[1]
    m, p = n - 1, n + 3
    period, sigma_ang = constants[C_PERIOD], constants[C_SIGMA]
    cond_max = constants[C_COND]
    noisy = sigma_ang > 0.0
    # one scenario's systems and solves (row 0), the bound's scratch
    R, a1, ak = np.empty((1, n, 3, 3)), np.empty((1, 3)), np.empty((1, m, 3))
    P, b, dt = np.empty((1, m, 3, 3)), np.empty((1, m, 3)), np.empty((1, m))
    e1, ek = np.empty((1, 3)), np.empty((1, m, 3))
    X, J, Q = np.empty((1, p)), np.empty(1), np.empty((1, p, p))
    kappa, M1 = np.empty(1), np.empty((1, 3))
    Xe, Qe, kappa_e = np.empty((1, p)), np.empty((1, p, p)), np.empty(1)
    G, LU, inv = np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3))
    piv = np.empty(3, np.int64)
    unit = np.ones(n)
    every = np.ones(n, np.bool_)
    sight, sights = np.empty(3), np.empty((n, 3))
    flags = 0
    for i in range(lo, hi):
        if moving:
            for k in range(n):
                if not (np.isfinite(action[i, k, 0]) and np.isfinite(action[i, k, 1])):
                    return flags | BAD_ACTION
            _drive_row(receivers, action, period, constants[C_SPEED], constants[C_RADIUS], end, i)
            t_out[i] = t[i] + period
            for j in range(3):
                drone_end[i, j] = drone[i, j] + period * drone_velocity[i, j]
        else:
            t_out[i] = t[i]
            for j in range(3):
                drone_end[i, j] = drone[i, j]
                for k in range(n):
                    end[i, k, j] = receivers[i, k, j]
        code = systems_row(
            i, 0, delays, (period, sigma_ang, constants[C_ELEVATION]), receivers, end, drone_end,
            drone_velocity, previous, normals, (origins, los, ranges), R, a1, ak, P, b, dt, e1,
            ek, X, J, Q, kappa, M1, Xe, Qe, kappa_e, sight,
        )  # fmt: skip
        condition[i] = kappa[0]
        degenerate[i] = degenerate_true[i] = False
        if code != 0 or not (kappa[0] <= cond_max) or (noisy and not (kappa_e[0] <= cond_max)):
            slow[i] = True
            flags |= SLOW
            continue
        slow[i] = False
        finish_row(
            i, 0, delays, period, sigma_ang, constants[C_REF], constants[C_CLIP], origins, los,
            ranges, R, a1, X, Q, degenerate, degenerate_true, previous, position, velocity, range_sigma,
            velocity_sigma, estimate, bound, reward, G, LU, piv, inv, unit, every,
        )  # fmt: skip
        observe_row(
            i, end, estimate, range_sigma, velocity_sigma, condition, degenerate,
            constants[C_LENGTH], constants[C_SCALE], constants[C_REF], period, pairs, observation,
            sights,
        )  # fmt: skip
        info_row(i, end, estimate, drone_end, pairs, error, min_angle, sights)
    return flags


# ---------------------------------------------------------------- the heuristic rules' searches


@njit(**_JIT)
def in_disc_batch(positions, radius, out):
    """:func:`_in_disc` of every row of ``positions (N, 3)`` into ``out (N, 3)``."""
    for i in range(positions.shape[0]):
        out[i, 0], out[i, 1], out[i, 2] = _in_disc(
            positions[i, 0], positions[i, 1], positions[i, 2], radius
        )


@njit(inline="always")
def _move_views(receivers, i, position, velocity, shifts, period, radius, horizon, U, Rm, sight):
    """Scenario ``i``'s lines of sight ``U (H, n, M, 3)`` and ranges ``Rm (H, n, M)``: receiver
    ``k`` after ``h + 1`` periods of move ``m`` (held in the disc after each, as :func:`drive`)
    to the drone at ``p̂ + (h + 1)τ v̂``."""
    for k in range(receivers.shape[1]):
        for m in range(shifts.shape[0]):
            o = _row3(receivers, i, k)
            for h in range(horizon):
                # the receiver at the end of its h+1-th move, the drone at p̂ + (h+1)τ v̂
                o = _in_disc(o[0] + shifts[m, 0], o[1] + shifts[m, 1], o[2] + shifts[m, 2],
                             radius)  # fmt: skip
                at = (h + 1) * period
                Rm[h, k, m] = line_of_sight(
                    o,
                    (position[i, 0] + at * velocity[i, 0],
                     position[i, 1] + at * velocity[i, 1],
                     position[i, 2] + at * velocity[i, 2]),
                    sight,
                )  # fmt: skip
                for j in range(3):
                    U[h, k, m, j] = sight[j]


@njit(inline="always")
def _joint_score(U, Rm, choice, scalars, u, r, unit, every, G, LU, piv, inv):
    """The predicted reward of the joint move ``choice (n,)`` (each receiver's move index)
    summed over the periods of :func:`_move_views`: ``clip(ln(σ_ref/σ_pos), −R, R)``,
    ``σ_pos = σ_ang √tr G⁻¹``, ``G = Σ_k Π_k/r_k²`` (the stereo tracker kernels' information,
    test, bound and reward); ``u (n, 3)``, ``r (n,)`` and the rest scratch."""
    _, sigma_ang, sigma_ref, clip_r, _ = scalars
    n = U.shape[1]
    score = 0.0
    for h in range(U.shape[0]):
        for k in range(n):
            m = choice[k]
            r[k] = Rm[h, k, m]
            for j in range(3):
                u[k, j] = U[h, k, m, j]
        position_information(u, r, unit, every, G)
        sigma_pos = position_sigma(G, observable(G, n), sigma_ang, LU, piv, inv)
        score += log_ratio_reward(sigma_pos, sigma_ref, clip_r)
    return score


@njit(**_JIT)
def plan_search(receivers, position, velocity, shifts, joint, scalars, horizon, best, value):
    """:class:`~sensorgym.agents.stereo_placement.GreedyPlacement`'s exhaustive choice for each
    row: ``best[i]`` the joint candidate ``c`` (row of ``joint (C, n)``, indices into
    ``shifts (M, 3)``, each receiver's displacement over one period) that maximises the sum of
    the env's reward over the next ``horizon`` periods when every receiver keeps its move
    (held in the disc after each period, as :func:`drive`) and the drone flies on from
    ``position[i]`` at ``velocity[i]``: period ``h = 1 … H`` is scored at the receivers' ends
    of their ``h``-th move and the drone at ``p̂ + hτ v̂`` (:func:`_joint_score`);
    ``value[i]`` its score. ``scalars = (τ, σ_ang, σ_ref, R, radius)``; the first best on ties.

    Why the period's end and not the fix times ``d_k``: the receiver fixing at ``d_1 = 0``
    has not moved yet at its fix, so a one-period search at the fix times never moves it
    (and scores lower); the end of the move stands for where the receiver will fix from
    next."""
    period, radius = scalars[0], scalars[4]
    n, M = receivers.shape[1], shifts.shape[0]
    u, r = np.empty((n, 3)), np.empty(n)
    U, Rm = np.empty((horizon, n, M, 3)), np.empty((horizon, n, M))  # per period, receiver, move
    unit, every = np.ones(n), np.ones(n, np.bool_)
    G, LU, inv = np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3))
    piv = np.empty(3, np.int64)
    sight = np.empty(3)
    for i in range(receivers.shape[0]):
        _move_views(receivers, i, position, velocity, shifts, period, radius, horizon, U, Rm, sight)
        top, pick = -np.inf, 0
        for c in range(joint.shape[0]):
            score = _joint_score(U, Rm, joint[c], scalars, u, r, unit, every, G, LU, piv, inv)
            if score > top:
                top, pick = score, c
        best[i] = pick
        value[i] = top


@njit(**_JIT)
def coordinate_search(
    receivers, position, velocity, shifts, scalars, horizon, max_sweeps, best, value, start
):  # fmt: skip
    """:class:`~sensorgym.agents.stereo_placement.GreedyPlacement`'s coordinate-wise choice for
    each row, the objective of :func:`plan_search` (:func:`_joint_score`) at polynomial cost.

    Start: every receiver's best single move while the others stand still (move 0), all taken
    together; ``start[i]`` that joint move's score. Then sweeps over the receivers: each in
    turn takes its best move with the others fixed (a strictly better score, else it keeps its
    move), until a sweep changes nothing or after ``max_sweeps`` sweeps. ``best (N, n)`` the
    move of each receiver, ``value[i]`` its score: never below ``start[i]``, never above the
    exhaustive optimum. Cost ``O((1 + sweeps) · n · M · H · n)`` per row (``M`` moves,
    ``H = horizon``)."""
    period, radius = scalars[0], scalars[4]
    n, M = receivers.shape[1], shifts.shape[0]
    u, r = np.empty((n, 3)), np.empty(n)
    U, Rm = np.empty((horizon, n, M, 3)), np.empty((horizon, n, M))
    unit, every = np.ones(n), np.ones(n, np.bool_)
    G, LU, inv = np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3))
    piv = np.empty(3, np.int64)
    sight = np.empty(3)
    choice, alone = np.zeros(n, np.int64), np.zeros(n, np.int64)
    for i in range(receivers.shape[0]):
        _move_views(receivers, i, position, velocity, shifts, period, radius, horizon, U, Rm, sight)
        # the start: each receiver's best move with the others standing still
        for k in range(n):
            alone[k] = 0
        for k in range(n):
            top, pick = -np.inf, 0
            for m in range(M):
                alone[k] = m
                score = _joint_score(U, Rm, alone, scalars, u, r, unit, every, G, LU, piv, inv)
                if score > top:
                    top, pick = score, m
            alone[k] = 0
            choice[k] = pick
        current = _joint_score(U, Rm, choice, scalars, u, r, unit, every, G, LU, piv, inv)
        start[i] = current
        for _ in range(max_sweeps):
            changed = False
            for k in range(n):
                keep = choice[k]
                pick = keep
                for m in range(M):
                    if m == keep:
                        continue
                    choice[k] = m
                    score = _joint_score(U, Rm, choice, scalars, u, r, unit, every, G, LU, piv, inv)
                    if score > current:
                        current, pick = score, m
                choice[k] = pick
                changed = changed or pick != keep
            if not changed:
                break
        for k in range(n):
            best[i, k] = choice[k]
        value[i] = current


@njit(inline="always")
def _circle_row(receivers, i, centre, rho, perms, radius, margin, goal, pts):
    """Row ``i`` of :func:`circle_search` over the assignments ``perms (P, n)``; ``pts (n, 3)``
    scratch."""
    n = receivers.shape[1]
    top, pick_phase, pick_perm = np.inf, 0, 0
    for q in range(n):
        phase = np.arctan2(receivers[i, q, 0] - centre[i, 0], receivers[i, q, 2] - centre[i, 2])
        for j in range(n):
            slot = phase + 2.0 * np.pi * j / n
            pts[j, 0], pts[j, 1], pts[j, 2] = _in_disc(
                centre[i, 0] + rho[i] * np.sin(slot),
                centre[i, 1] + rho[i] * 0.0,
                centre[i, 2] + rho[i] * np.cos(slot),
                radius - margin,
            )
        for c in range(perms.shape[0]):
            longest, total = 0.0, 0.0
            for k in range(n):
                j = perms[c, k]
                dist = norm3(
                    (
                        pts[j, 0] - receivers[i, k, 0],
                        pts[j, 1] - receivers[i, k, 1],
                        pts[j, 2] - receivers[i, k, 2],
                    )
                )
                longest = max(longest, dist)
                total += dist
            cost = longest + 1e-3 * total
            if cost < top:
                top, pick_phase, pick_perm = cost, q, c
    # the winning slots, recomputed
    phase = np.arctan2(
        receivers[i, pick_phase, 0] - centre[i, 0], receivers[i, pick_phase, 2] - centre[i, 2]
    )
    for k in range(n):
        slot = phase + 2.0 * np.pi * perms[pick_perm, k] / n
        goal[i, k, 0], goal[i, k, 1], goal[i, k, 2] = _in_disc(
            centre[i, 0] + rho[i] * np.sin(slot),
            centre[i, 1] + rho[i] * 0.0,
            centre[i, 2] + rho[i] * np.cos(slot),
            radius - margin,
        )


@njit(**_JIT)
def circle_search(receivers, centre, rho, perms, radius, margin, goal, cyclic):
    """:class:`~sensorgym.agents.stereo_placement.CirclePlacement`'s slots for each row:
    ``n`` points ``360°/n`` apart on the circle of radius ``rho[i]`` around ``centre[i]``
    (held ``margin`` inside the disc), the circle's phase the bearing of one of the receivers
    from the centre and the assignment (slot of receiver ``k``) a row of ``perms (P, n)`` — or,
    with ``cyclic``, one of the ``n`` rotations of the receivers' own order of bearing around
    the centre (``perms`` unused; ``O(n³)`` instead of ``O(n² n!)``). The phase and assignment
    minimising the longest drive (plus ``10⁻³`` × the total) win, the first on ties.
    ``goal (N, n, 3)`` gets each receiver's slot."""
    n = receivers.shape[1]
    pts = np.empty((n, 3))
    rotations = np.empty((n, n), np.int64)
    bearing, rank = np.empty(n), np.empty(n, np.int64)
    for i in range(receivers.shape[0]):
        if not cyclic:
            _circle_row(receivers, i, centre, rho, perms, radius, margin, goal, pts)
            continue
        for k in range(n):
            bearing[k] = np.arctan2(
                receivers[i, k, 0] - centre[i, 0], receivers[i, k, 2] - centre[i, 2]
            )
        order = np.argsort(bearing)
        for j in range(n):
            rank[order[j]] = j
        for c in range(n):
            for k in range(n):
                rotations[c, k] = (rank[k] + c) % n
        _circle_row(receivers, i, centre, rho, rotations, radius, margin, goal, pts)
