"""The compiled step of the receiver-placement environments: one loop over the scenarios.

:func:`period_rows` is :func:`.simulation.step` (and the first fix of
:func:`.simulation.start`) for the scenarios ``lo ≤ i < hi``, so that
:func:`sensorgym.envs.shells.rows.run_rows` can split a batch over threads. It runs the stages
of the readable numpy form, :func:`.reference.step` and :func:`.reference.scan_period` (theory
§6.4, §11.4), in their order, one inlined function per stage under the reference's name:

1. :func:`drive`, :func:`fly` — the vehicles drive (held in the disc), the drone flies on;
2. :func:`geometry_at_fix_times`, :func:`boresight_rotations`, :func:`own_frame` (the noisy
   and the exact directions in each receiver's frame), :func:`conjugation_system` and
   :func:`least_squares` (the compiled solve, once for each system), then
   :func:`fix_accuracy`, :func:`fix_in_world` and :func:`tracker_estimate`;
3. :func:`position_bound` and :func:`reward`;
4. :func:`observation` and :func:`diagnostics` of the new state.

Each formula is a primitive of the module that owns it — :mod:`sensorgym.trackers.geometry_kernels`
(look-at rotation, relative poses, angular noise, angles between lines of sight),
:mod:`sensorgym.trackers.stereo.conjugation_kernels` (the order-1 conjugation: the n = 3 closed
form, the normal equations for more receivers) and :mod:`sensorgym.trackers.stereo.kernels`
(information, bound, reward) — and the stages only chain them per scenario.

What the kernels take:

- the **settings**: one record of dtype :data:`SETTINGS`, read by field name
  (:attr:`.simulation.PlacementParams.kernel_settings` builds it once per params);
- the scenarios' arrays as tuples (the old state's, the new state's, the outputs), taken
  apart once per call: every stage gets the plain arrays it reads and writes (a field read
  from a tuple inside the loop would count a reference each time);
- **scratch** from :func:`workspace`, allocated once per call and reused over the rows.

Random draws stay with numpy's Generator (drawn before the kernels, in a fixed order). The rare
systems whose ``κ_F`` exceeds ``cond_max`` are left to the caller, which re-solves them on the
generic SVD path of :func:`~sensorgym.trackers.stereo.conjugation.solve_conjugation` with the
batch kernels :func:`period_systems` and :func:`period_finish` (the same stages).
"""

from __future__ import annotations

from collections import namedtuple

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

#: stages are inlined into the kernels that loop over scenarios: a call per scenario would
#: pass (and reference-count) every array it touches
_ROW = {**_JIT, "inline": "always"}

_UP = (0.0, 1.0, 0.0)

#: The scalar settings the step reads, one record per params
#: (:attr:`.simulation.PlacementParams.kernel_settings`), read by field name.
SETTINGS = np.dtype(
    [
        ("period", np.float64),  # scan period τ = one step, s
        ("sigma_ang", np.float64),  # angular noise σ_ang of each fixed direction, rad
        ("max_elevation", np.float64),  # the receivers' boresight elevation limit, rad
        ("max_speed", np.float64),  # a vehicle's speed limit, m/s
        ("arena_radius", np.float64),  # the permitted disc, m
        ("sigma_ref", np.float64),  # the position accuracy that earns zero reward, m
        ("reward_clip", np.float64),  # R: the reward lies in [−R, R]
        ("cond_max", np.float64),  # κ_F above which the generic path solves
        ("length_scale", np.float64),  # observation scales: m, m/s
        ("speed_scale", np.float64),
    ],
    align=True,
)

#: Scratch of one :func:`period_rows` call (:func:`workspace`): one scenario's rotations
#: ``R (1, n, 3, 3)``, its noisy system ``a1``, ``ak``, ``P``, ``b``, ``dt`` and exact one
#: ``e1``, ``ek``; their solves ``X``, ``J``, ``Q``, ``kappa``, ``M1`` and ``Xe``, ``Qe``,
#: ``kappa_e`` (row 0 of each); the bound's ``G``, ``LU``, ``inv``, ``piv``, ``unit``,
#: ``every``; a line of sight ``sight (3,)`` and those of every receiver ``sights (n, 3)``.
Workspace = namedtuple(
    "Workspace",
    "R a1 ak P b dt e1 ek X J Q kappa M1 Xe Qe kappa_e G LU inv piv unit every sight sights",
)


@njit(**_ROW)
def workspace(n):
    """Scratch for the rows of one call with ``n`` receivers (:data:`Workspace`)."""
    m, p = n - 1, n + 3
    return Workspace(
        np.empty((1, n, 3, 3)),
        np.empty((1, 3)),
        np.empty((1, m, 3)),
        np.empty((1, m, 3, 3)),
        np.empty((1, m, 3)),
        np.empty((1, m)),
        np.empty((1, 3)),
        np.empty((1, m, 3)),
        np.empty((1, p)),
        np.empty(1),
        np.empty((1, p, p)),
        np.empty(1),
        np.empty((1, 3)),
        np.empty((1, p)),
        np.empty((1, p, p)),
        np.empty(1),
        np.empty((3, 3)),
        np.empty((3, 3)),
        np.empty((3, 3)),
        np.empty(3, np.int64),
        np.ones(n),
        np.ones(n, np.bool_),
        np.empty(3),
        np.empty((n, 3)),
    )


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


# ------------------------------------------- step 1: the vehicles drive, the drone flies on


@njit(**_ROW)
def drive(i, receivers, action, period, max_speed, radius, end):
    """Scenario ``i``'s receivers ``end[i] (n, 3)`` after one period at the velocities of
    ``action[i] (n, 2)`` (:func:`.reference.drive`, theory §11.4 step 1): components clipped to
    ``[−1, 1]``, speed capped at ``max_speed``, held in the disc of ``radius``."""
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


@njit(**_ROW)
def fly(i, drone, drone_velocity, period, drone_end):
    """Scenario ``i``'s drone after one period of its straight line (:func:`.reference.fly`,
    theory §11.4): ``M ← M + τ V``."""
    for j in range(3):
        drone_end[i, j] = drone[i, j] + period * drone_velocity[i, j]


@njit(**_ROW)
def stand_still(i, receivers, drone, end, drone_end):
    """The first fix's period (:func:`.reference.start`): receivers and drone stay where they
    are."""
    for j in range(3):
        drone_end[i, j] = drone[i, j]
        for k in range(receivers.shape[1]):
            end[i, k, j] = receivers[i, k, j]


@njit(**_JIT)
def drive_batch(receivers, action, period, max_speed, radius, end):
    """:func:`drive` of every scenario: ``end (B, n, 3)`` the receivers driven for ``τ`` at the
    velocities of ``action (B, n, 2)``."""
    for i in range(receivers.shape[0]):
        drive(i, receivers, action, period, max_speed, radius, end)


# --------------------------------------------------- step 2: the scan period and the tracker


@njit(**_ROW)
def geometry_at_fix_times(
    i, delays, period, start, end, drone_end, drone_velocity, origins, los, ranges, sight
):  # fmt: skip
    """Scenario ``i``'s true geometry at each receiver's fix time ``d_k``: ``origins``
    ``O_k(d_k)``, lines of sight ``los`` ``u_k`` and ``ranges`` ``r_k``
    (:func:`.reference.geometry_at_fix_times`, theory §6.4); ``sight (3,)`` scratch. A zero
    line of sight (a receiver on the drone) is left to :func:`least_squares`' input check."""
    for k in range(start.shape[1]):
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
        ranges[i, k] = line_of_sight(o, at_fix, sight)
        for j in range(3):
            origins[i, k, j] = o[j]
            los[i, k, j] = sight[j]


@njit(**_ROW)
def boresight_rotations(i, s, origins, previous, period, max_elevation, R):
    """Scenario ``i``'s receiver frames ``R[s] (n, 3, 3)`` looking at the ``previous``
    estimate coasted to mid-period (:func:`.reference.boresight_rotations`, theory §6.4,
    §2.2)."""
    aim = (
        previous[i, 0] + 0.5 * period * previous[i, 3],
        previous[i, 1] + 0.5 * period * previous[i, 4],
        previous[i, 2] + 0.5 * period * previous[i, 5],
    )
    for k in range(origins.shape[1]):
        Rk = boresight3(_row3(origins, i, k), aim, max_elevation)
        for j in range(3):
            for c in range(3):
                R[s, k, j, c] = Rk[c][j]


@njit(**_ROW)
def own_frame(i, s, sigma_ang, R, los, ranges, normals, a1, ak, e1, ek):
    """What scenario ``i``'s receivers report, ``a_k = R_kᵀ z_k`` with the noisy directions
    ``z_k`` (draws ``normals``), into ``a1[s]``, ``ak[s]``, and the exact ones
    ``e_k = R_kᵀ u_k`` into ``e1[s]``, ``ek[s]`` (:func:`.reference.noisy_directions`,
    :func:`.reference.own_frame`, theory §4.1, §2.1)."""
    noisy = sigma_ang > 0.0
    for k in range(los.shape[1]):
        u = _row3(los, i, k)
        z = perturbed_direction3(u, _row3(normals, i, k), sigma_ang) if noisy else u
        if not ranges[i, k] > MIN_RANGE:
            z = (0.0, 0.0, 0.0)  # no direction to measure (the solve's check names it)
        Rk = _columns(R, s, k)
        a = to_local3(Rk, z)
        e = to_local3(Rk, u)
        if k == 0:
            for j in range(3):
                a1[s, j], e1[s, j] = a[j], e[j]
        else:
            for j in range(3):
                ak[s, k - 1, j], ek[s, k - 1, j] = a[j], e[j]


@njit(**_ROW)
def conjugation_system(i, s, delays, origins, R, P, b, dt):
    """Scenario ``i``'s relative poses ``P_k = R_1ᵀ R_k``, ``b_k = R_1ᵀ (O_k − O_1)`` and
    delays ``Δt_k = d_k − d_1`` into row ``s`` of ``P``, ``b``, ``dt``
    (:func:`.reference.conjugation_system`, theory §6.4, §3.2–3.3)."""
    R1, o1 = _columns(R, s, 0), _row3(origins, i, 0)
    for k in range(1, origins.shape[1]):
        Pk, bk = relative_pose3(R1, o1, _columns(R, s, k), _row3(origins, i, k))
        for j in range(3):
            b[s, k - 1, j] = bk[j]
            for c in range(3):
                P[s, k - 1, j, c] = Pk[c][j]
        dt[s, k - 1] = delays[k] - delays[0]


@njit(**_ROW)
def least_squares(a1, ak, P, b, dt, s, X, J, Q, kappa, position):
    """Row ``s``'s order-1 conjugation (checked; :func:`.reference.least_squares`, theory
    §3.3): the n = 3 closed form, else the normal equations; ``κ_F`` stays ``inf`` where they
    leave the system to the generic path. Returns the kernel's input-check code. The row is
    passed on as a plain int64: the literal row 0 of :func:`period_rows` would compile the
    kernels once more (numba specialises a call on a literal integer argument)."""
    kappa[s] = np.inf
    lo = np.int64(s)
    if ak.shape[1] == 2:
        return triple_velocity_kernel(a1, ak, P, b, dt, 1.0, np.bool_(True), lo, lo + 1, X, J, Q,
                                      kappa, position)  # fmt: skip
    return velocity_kernel(a1, ak, P, b, dt, 1.0, np.bool_(True), lo, lo + 1, X, J, Q, kappa,
                           position)  # fmt: skip


@njit(**_ROW)
def fix_accuracy(i, s, sigma_ang, X, Q, range_sigma, velocity_sigma):
    """Scenario ``i``'s reported accuracy from its solve at row ``s`` (the covariance mapping
    of :func:`.reference.fix_in_world`, theory §13.4): ``σ_e = σ_ang · mean_k |r̂_k|``,
    ``σ[r̂_k] = σ_e √Q_kk``, ``σ_V = σ_e √tr Q_VV`` (negative round-off counts as 0)."""
    n = range_sigma.shape[1]
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


@njit(**_ROW)
def fix_in_world(i, s, period, delays, origins, R, a1, X, position, velocity):
    """Scenario ``i``'s fix in the world at the period end from its solve at row ``s``
    (:func:`.reference.fix_in_world`, theory §6.4, §13.5): ``M(d_1) = O_1(d_1) + R_1 M̂_1``
    (``M̂_1 = r̂_1 a_1``), ``V = R_1 V̂``, ``M(τ) = M(d_1) + V (τ − d_1)``."""
    n = origins.shape[1]
    R1 = _columns(R, s, 0)
    r1 = X[s, 0]
    m = to_world3(R1, (r1 * a1[s, 0], r1 * a1[s, 1], r1 * a1[s, 2]))
    v = to_world3(R1, (X[s, n], X[s, n + 1], X[s, n + 2]))
    to_end = period - delays[0]
    for j in range(3):
        velocity[i, j] = v[j]
        position[i, j] = (origins[i, 0, j] + m[j]) + v[j] * to_end


@njit(**_ROW)
def tracker_estimate(i, period, degenerate, previous, position, velocity, estimate):
    """Scenario ``i``'s estimate ``(p̂, v̂)`` at the period end (:func:`.reference.tracker_estimate`,
    theory §11.4): the fix, or where it is degenerate the ``previous`` one coasted by ``τ``."""
    for j in range(3):
        if degenerate[i]:  # not trusted: the previous estimate coasted by τ
            estimate[i, j] = previous[i, j] + period * previous[i, 3 + j]
            estimate[i, 3 + j] = previous[i, 3 + j]
        else:
            estimate[i, j] = position[i, j]
            estimate[i, 3 + j] = velocity[i, j]


# ------------------------------------------------------------- step 3: the bound and reward


@njit(**_ROW)
def position_bound(i, los, ranges, sigma_ang, unit, every, G, LU, piv, inv, bound):
    """Scenario ``i``'s Cramér–Rao ``σ_pos = σ_ang √tr G⁻¹`` of the true geometry,
    ``G = Σ_k (I − u_k u_kᵀ)/r_k²`` (:func:`.reference.position_bound`, theory §4.2, §4.3);
    ``unit``, ``every (n,)`` ones, ``G``, ``LU``, ``inv (3, 3)``, ``piv (3,)`` scratch."""
    position_information(los[i], ranges[i], unit, every, G)
    bound[i] = position_sigma(G, observable(G, los.shape[1]), sigma_ang, LU, piv, inv)


@njit(**_ROW)
def reward(i, bound, degenerate, degenerate_true, sigma_ref, reward_clip, out):
    """Scenario ``i``'s reward ``clip(ln(σ_ref/σ_pos), −R, R)``, ``−R`` where either solve is
    degenerate (:func:`.reference.reward`, theory §11.1, §11.4)."""
    if degenerate[i] or degenerate_true[i]:
        out[i] = -reward_clip
    else:
        out[i] = log_ratio_reward(bound[i], sigma_ref, reward_clip)


# ------------------------------------------------------ the observation and the diagnostics


@njit(inline="always")
def _clip_obs(x):
    """``np.clip(x, −OBS_CLIP, OBS_CLIP)`` of one value (NaN stays NaN)."""
    if x > OBS_CLIP:
        return OBS_CLIP
    if x < -OBS_CLIP:
        return -OBS_CLIP
    return x


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


@njit(**_ROW)
def observation(
    p, pairs, i, receivers, estimate, range_sigma, velocity_sigma, condition, degenerate, out,
    sights,
):  # fmt: skip
    """Scenario ``i``'s observation blocks of :func:`.simulation.observe`, clipped to
    ``±OBS_CLIP``, into ``out[i]`` (float32) (:func:`.reference.observation`); ``p`` the
    settings record, ``sights (n, 3)`` scratch."""
    n = receivers.shape[1]
    length, sigma_ref = p.length_scale, p.sigma_ref
    tiny = 1e-12
    half_pi = np.pi / 2
    e = _row(estimate, i)
    c = 0
    for k in range(n):
        out[i, c] = _clip_obs(receivers[i, k, 0] / length)
        out[i, c + 1] = _clip_obs(receivers[i, k, 2] / length)
        c += 2
    for k in range(n):
        out[i, c] = _clip_obs((receivers[i, k, 0] - e[0]) / length)
        out[i, c + 1] = _clip_obs((receivers[i, k, 2] - e[2]) / length)
        c += 2
    for j in range(3):
        out[i, c + j] = _clip_obs(estimate[i, j] / length)
        out[i, c + 3 + j] = _clip_obs(estimate[i, 3 + j] / p.speed_scale)
    c += 6
    for k in range(n):
        out[i, c + k] = _clip_obs(np.log(max(range_sigma[i, k], tiny) / sigma_ref))
    c += n
    out[i, c] = _clip_obs(np.log(max(velocity_sigma[i], tiny) * p.period / sigma_ref))
    out[i, c + 1] = _clip_obs(np.log10(min(condition[i], 1e300)))
    c += 2
    _sights(receivers, i, e, sights)
    for q in range(pairs.shape[0]):
        angle = _pair_angle(sights, pairs[q, 0], pairs[q, 1])
        out[i, c + q] = _clip_obs(angle / half_pi)
    c += pairs.shape[0]
    out[i, c] = 1.0 if degenerate[i] else 0.0


@njit(**_JIT)
def observe_kernel(
    rows, settings, pairs, receivers, estimate, range_sigma, velocity_sigma, condition,
    degenerate, out,
):  # fmt: skip
    """:func:`observation` for the scenarios ``rows``; ``settings`` the params' record (a
    structured array of one element, dtype :data:`SETTINGS`)."""
    p = settings[0]
    sights = np.empty((receivers.shape[1], 3))
    for i in rows:
        observation(
            p, pairs, i, receivers, estimate, range_sigma, velocity_sigma, condition, degenerate,
            out, sights,
        )  # fmt: skip


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
def diagnostics(i, receivers, estimate, drone_position, pairs, error, min_angle, sights):
    """Scenario ``i``'s position error ``‖p̂ − p‖`` and the smallest angle between the lines of
    sight to the drone (:func:`.reference.diagnostics`; ``sights (n, 3)`` scratch)."""
    p = _row(drone_position, i)
    error[i] = norm3((estimate[i, 0] - p[0], estimate[i, 1] - p[1], estimate[i, 2] - p[2]))
    smallest = np.inf
    _sights(receivers, i, p, sights)
    for q in range(pairs.shape[0]):
        smallest = min(smallest, _pair_angle(sights, pairs[q, 0], pairs[q, 1]))
    min_angle[i] = smallest


@njit(**_JIT)
def info_kernel(rows, receivers, estimate, drone_position, pairs, error, min_angle):
    """:func:`diagnostics` for the scenarios ``rows``."""
    sights = np.empty((receivers.shape[1], 3))
    for i in rows:
        diagnostics(i, receivers, estimate, drone_position, pairs, error, min_angle, sights)


# ------------------------------------------------------------------------ the whole step


#: flags returned by :func:`period_rows` (or-ed over its scenarios)
SLOW = 1
"""some scenarios are left to the caller (``slow``): ``κ_F > cond_max`` (or left by the compiled
solve), or a zero line of sight."""
BAD_ACTION = 2
"""an action holds NaN or infinite values (the kernel stopped there)."""


@njit(inline="always")
def _finite_action(action, i):
    """Every component of scenario ``i``'s action is finite."""
    for k in range(action.shape[1]):
        if not (np.isfinite(action[i, k, 0]) and np.isfinite(action[i, k, 1])):
            return False
    return True


@njit(**_JIT)
def period_rows(lo, hi, moving, settings, layout, old, action, normals, new, out):
    """The whole step of scenarios ``lo..hi−1`` in one pass, the stages of
    :func:`.reference.step` and :func:`.reference.scan_period` in their order.

    ``settings``: the params' record (a structured array of one element, dtype
    :data:`SETTINGS`); ``layout = (delays (n,), pairs (n(n−1)/2, 2))``; the old state
    ``old = (t (B,), receivers (B, n, 3), drone (B, 3), drone_velocity (B, 3),
    previous (B, 6))``; ``normals (B, n, 3)`` the period's noise draws. ``moving``: the
    receivers drive under ``action (B, n, 2)`` for ``τ`` and the drone flies on (a step); else
    the period ends where they stand (the first fix of :func:`.simulation.start`). Writes the
    new state ``new = (t, end, drone_end, origins, los, ranges, position, velocity,
    range_sigma, velocity_sigma, condition, degenerate, degenerate_true, estimate, bound)`` and
    ``out = (reward, observation, error, min_angle, slow)``. A scenario whose conjugation the
    compiled solve does not settle (``κ_F > cond_max`` in either system, or a zero line of
    sight) is marked in ``slow`` and left unfinished: the caller solves it on the generic
    path. Returns the or-ed flags :data:`SLOW`, :data:`BAD_ACTION` (checked before anything
    of that scenario is written).
    """
    p = settings[0]
    period, sigma_ang, cond_max = p.period, p.sigma_ang, p.cond_max
    delays, pairs = layout
    t, receivers, drone, drone_velocity, previous = old
    t_out, end, drone_end, origins, los, ranges, position, velocity = new[:8]
    range_sigma, velocity_sigma, condition, degenerate, degenerate_true, estimate, bound = new[8:]
    rewards, obs, error, min_angle, slow = out
    noisy = sigma_ang > 0.0
    ws = workspace(receivers.shape[1])
    R, a1, ak, P, b, dt, e1, ek = ws[:8]
    X, J, Q, kappa, M1, Xe, Qe, kappa_e = ws[8:16]
    G, LU, inv, piv, unit, every, sight, sights = ws[16:]
    flags = 0
    for i in range(lo, hi):
        # 1. the vehicles drive, the drone flies on (or, the first fix, both stand still)
        if moving:
            if not _finite_action(action, i):
                return flags | BAD_ACTION
            drive(i, receivers, action, period, p.max_speed, p.arena_radius, end)
            fly(i, drone, drone_velocity, period, drone_end)
            t_out[i] = t[i] + period
        else:
            stand_still(i, receivers, drone, end, drone_end)
            t_out[i] = t[i]
        # 2. the period's true geometry, the frames, the noisy and the exact systems, solved
        geometry_at_fix_times(i, delays, period, receivers, end, drone_end, drone_velocity,
                              origins, los, ranges, sight)  # fmt: skip
        boresight_rotations(i, 0, origins, previous, period, p.max_elevation, R)
        own_frame(i, 0, sigma_ang, R, los, ranges, normals, a1, ak, e1, ek)
        conjugation_system(i, 0, delays, origins, R, P, b, dt)
        code = least_squares(a1, ak, P, b, dt, 0, X, J, Q, kappa, M1)
        kappa_e[0] = np.inf
        if code == 0 and noisy:
            code = least_squares(e1, ek, P, b, dt, 0, Xe, J, Qe, kappa_e, M1)
        condition[i] = kappa[0]
        degenerate[i] = degenerate_true[i] = False
        if code != 0 or not (kappa[0] <= cond_max) or (noisy and not (kappa_e[0] <= cond_max)):
            slow[i] = True
            flags |= SLOW
            continue
        slow[i] = False
        # the fix in the world and the tracker's estimate
        fix_accuracy(i, 0, sigma_ang, X, Q, range_sigma, velocity_sigma)
        fix_in_world(i, 0, period, delays, origins, R, a1, X, position, velocity)
        tracker_estimate(i, period, degenerate, previous, position, velocity, estimate)
        # 3. the bound of the true geometry and the reward
        position_bound(i, los, ranges, sigma_ang, unit, every, G, LU, piv, inv, bound)
        reward(i, bound, degenerate, degenerate_true, p.sigma_ref, p.reward_clip, rewards)
        # 4. what the new state shows: the observation and the diagnostics
        observation(p, pairs, i, end, estimate, range_sigma, velocity_sigma, condition,
                    degenerate, obs, sights)  # fmt: skip
        diagnostics(i, end, estimate, drone_end, pairs, error, min_angle, sights)
    return flags


@njit(**_JIT)
def period_systems(scalars, delays, inputs, normals, truth, system, solves):
    """Stage 2's systems of every scenario (the generic path's first half, :mod:`.scan`): the
    true geometry, the frames, both conjugation systems and their compiled solves.

    ``scalars = (τ, σ_ang, max_elevation)`` (floats); ``inputs = (start, end, drone_end,
    drone_velocity, previous)``: receivers move from ``start`` to ``end`` ``(B, n, 3)``, the
    drone is at ``drone_end (B, 3)`` at the period end, the frames look at the coasted
    ``previous (B, 6)`` estimate's mid-period point; ``normals (B, n, 3)`` the noise draws
    (unused when ``σ_ang = 0``). Fills ``truth = (origins, los, ranges)``, ``system = (R, a1,
    ak, P, b, dt, e1, ek)`` (rotations ``(B, n, 3, 3)``, the noisy system and the exact one's
    directions) and ``solves = (X, J, Q, κ, M̂_1, Xe, Qe, κ_e)`` (``κ_F`` > ``cond_max``, or
    ``inf`` where the compiled solve leaves the system, for the caller). Returns 0 or the
    input-check code of :func:`triple_velocity_kernel` (a zero line of sight).
    """
    period, sigma_ang, max_elevation = scalars
    start, end, drone_end, drone_velocity, previous = inputs
    origins, los, ranges = truth
    R, a1, ak, P, b, dt, e1, ek = system
    X, J, Q, kappa, M1, Xe, Qe, kappa_e = solves
    noisy = sigma_ang > 0.0
    sight = np.empty(3)
    for i in range(start.shape[0]):
        geometry_at_fix_times(i, delays, period, start, end, drone_end, drone_velocity,
                              origins, los, ranges, sight)  # fmt: skip
        boresight_rotations(i, i, origins, previous, period, max_elevation, R)
        own_frame(i, i, sigma_ang, R, los, ranges, normals, a1, ak, e1, ek)
        conjugation_system(i, i, delays, origins, R, P, b, dt)
        code = least_squares(a1, ak, P, b, dt, i, X, J, Q, kappa, M1)
        kappa_e[i] = np.inf
        if code == 0 and noisy:
            code = least_squares(e1, ek, P, b, dt, i, Xe, J, Qe, kappa_e, M1)
        if code != 0:
            return code
    return 0


@njit(**_JIT)
def period_finish(scalars, delays, truth, solve, flags, previous, fix, out):
    """Stage 2's fix and stage 3 of every scenario (the generic path's second half,
    :mod:`.scan`): the fix in the world, its reported accuracy, the estimate, bound and reward.

    ``scalars = (τ, σ_ang, σ_ref, R)`` (floats); ``truth = (origins, los, ranges)``;
    ``solve = (R, a1, X, Q)``: the rotations, receiver 1's measured direction (own frame), the
    noisy solve ``X (B, n+3)``, ``Q (B, n+3, n+3)`` at ``σ_e = 1``; ``flags = (degenerate,
    degenerate_true)`` the pseudo-inverse flags of the noisy and the exact system; writes
    ``fix = (position, velocity, range_sigma, velocity_sigma)`` and ``out = (estimate, bound,
    reward)``: the estimate the fix, or ``previous`` coasted by ``τ`` where degenerate.
    """
    period, sigma_ang, sigma_ref, reward_clip = scalars
    origins, los, ranges = truth
    R, a1, X, Q = solve
    degenerate, degenerate_true = flags
    position, velocity, range_sigma, velocity_sigma = fix
    estimate, bound, rewards = out
    ws = workspace(origins.shape[1])
    G, LU, inv, piv, unit, every = ws.G, ws.LU, ws.inv, ws.piv, ws.unit, ws.every
    for i in range(origins.shape[0]):
        fix_accuracy(i, i, sigma_ang, X, Q, range_sigma, velocity_sigma)
        fix_in_world(i, i, period, delays, origins, R, a1, X, position, velocity)
        tracker_estimate(i, period, degenerate, previous, position, velocity, estimate)
        position_bound(i, los, ranges, sigma_ang, unit, every, G, LU, piv, inv, bound)
        reward(i, bound, degenerate, degenerate_true, sigma_ref, reward_clip, rewards)


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
