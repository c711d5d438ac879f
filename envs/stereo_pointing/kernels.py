"""The fused compiled step and observation of the receiver-pointing environments.

:func:`step_kernel` loops over a range of the scenarios of a batch; each scenario runs the
compiled primitives of :mod:`sensorgym.trackers.stereo.kernels` (lines of sight, field-of-view
test, noisy directions, weighted fix and its in-front test, Kalman predict/update, the bound and
the reward) in the order :func:`~sensorgym.envs.stereo_pointing.simulation.step` documents, then
writes the new state's observation (:func:`observe_row`) and diagnostics (:func:`info_row`), so
that ``observe`` and ``info`` only read them. The random draws stay with numpy's Generator: the
caller draws them (same order and shapes as the numpy form had) and passes them in.

The step runs the stages of :func:`.reference.step` in its order (marked 1–5 in the loop). The
settings come as one record of dtype :data:`SETTINGS`, read by field name
(:attr:`.simulation.PointingParams.kernel_settings`); a state comes as the tuple of its arrays
in the order of :data:`StateArrays` (:func:`.simulation.state_arrays`), and the scratch from
:func:`workspace`. The step takes both apart into locals once per call: a field read from a
tuple inside the loops would count a reference each time.

Rows are independent, so the caller splits a large batch over threads
(:func:`sensorgym.envs.shells.rows.run_drawn_rows`; the kernels release the GIL) with bit-identical
results; ``prange`` is not used (seconds of cold compile, and numba's OpenMP layer kills any
``fork()`` child, the way subprocess vector envs start their workers).
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit

from sensorgym.envs.shells.contract import OBS_CLIP
from sensorgym.trackers.stereo.kernels import (
    INLINE,
    JIT,
    MIN_FIX_RANGE,
    angles_from_unit,
    clip,
    copy1,
    copy2,
    count_views,
    cv_predict,
    cv_prior,
    cv_update,
    fix_in_front,
    inverse3,
    line_of_sight,
    log_ratio_reward,
    observable,
    perturb_direction,
    position_information,
    position_sigma,
    unit_from_angles,
    weighted_fix,
    wrap_angle,
)


@njit(**INLINE)
def in_view(boresight, u, cos_fov):
    """Field-of-view test: the line of sight ``u`` lies in the cone ``u · b ≥ cos fov`` around the
    boresight ``b`` (a zero ``u``, a point on the receiver, is never seen)."""
    return boresight[0] * u[0] + boresight[1] * u[1] + boresight[2] * u[2] >= cos_fov


@njit(**INLINE)
def pointing_offset(azimuth, elevation, u):
    """World-angle offset ``(wrap(α_u − α), ε_u − ε)`` of the direction ``u`` from a boresight at
    ``(α, ε)``; a zero ``u`` (no direction) reads as ``(0, 0)``."""
    # as a tuple: angles_from_unit compiles once, for the tuples geometry_kernels passes too
    az, el, has = angles_from_unit((u[0], u[1], u[2]))
    if not has:
        return 0.0, 0.0
    return wrap_angle(az - azimuth), el - elevation


#: The scalar settings the kernels read, one record per params
#: (:attr:`.simulation.PointingParams.kernel_settings`), read by field name.
SETTINGS = np.dtype(
    [
        ("slew", np.float64),  # the largest turn of a gimbal in one step, ω dt, rad
        ("max_elevation", np.float64),  # rad
        ("dt", np.float64),  # step length, s
        ("q", np.float64),  # the tracker's process noise
        ("cos_fov", np.float64),  # cos of the field-of-view half-angle
        ("sigma_ang", np.float64),  # angular noise σ, rad
        ("sigma_ref", np.float64),  # the reward's reference bound, m
        ("reward_clip", np.float64),
        ("fov", np.float64),  # field-of-view half-angle, rad
        ("length_scale", np.float64),  # observation scales: m, m/s
        ("velocity_scale", np.float64),
    ],
    align=True,
)

#: The arrays of a :class:`.simulation.PointingState`, in the order the kernels take them
#: (:func:`.simulation.state_arrays`): time ``t (B,)``, gimbals ``azimuth``, ``elevation``
#: ``(B, n)``, drones ``position``, ``velocity`` ``(B, m, 3)``, tracks ``x (B, m, 6)``,
#: ``P (B, m, 6, 6)``, who saw whom ``seen (B, n, m)``, ``fixed (B, m)`` and the bound
#: ``(B, m)``.
StateArrays = namedtuple(
    "StateArrays", "t azimuth elevation position velocity x P seen fixed bound"
)

#: Scratch of one step call (:func:`workspace`): per receiver ``ones``, the true lines of
#: sight ``u (n, 3)``, ranges ``r``, measured lines of sight ``z (n, 3)``, boresights
#: ``bore (n, 3)``, the fix's ranges ``r_fix`` and the view ``mask``; the fix ``M (3,)``, its
#: information ``G``, the true geometry's ``G_true``, the fix covariance ``R``, the prediction
#: ``x_pred``, ``P_pred``, and the solvers' ``rhs``, ``LU``, ``piv``, ``S``, ``K``, ``work``,
#: ``inv``.
Workspace = namedtuple(
    "Workspace",
    "ones u r z bore r_fix mask M G G_true R x_pred P_pred rhs LU piv S K work inv",
)

#: rows of the diagnostics array ``info (N_DIAG, B)`` (``simulation.info``)
I_ERROR, I_FIXED, I_VIEWS, I_UNFIXED, I_SIGMA_SUM, I_SIGMA_COUNT = range(6)
#: the number of those rows
N_DIAG = 6


@njit(**INLINE)
def workspace(n):
    """Scratch for the rows of one step call with ``n`` receivers: views of one buffer (one
    allocation per call, not twenty)."""
    buf = np.empty(12 * n + 138)
    ones = buf[:n]
    ones[:] = 1.0
    o = 12 * n
    return Workspace(
        ones,
        buf[n : 4 * n].reshape((n, 3)),
        buf[4 * n : 5 * n],
        buf[5 * n : 8 * n].reshape((n, 3)),
        buf[8 * n : 11 * n].reshape((n, 3)),
        buf[11 * n : 12 * n],
        np.empty(n, dtype=np.bool_),
        buf[o : o + 3],
        buf[o + 3 : o + 12].reshape((3, 3)),
        buf[o + 12 : o + 21].reshape((3, 3)),
        buf[o + 21 : o + 30].reshape((3, 3)),
        buf[o + 30 : o + 36],
        buf[o + 36 : o + 72].reshape((6, 6)),
        buf[o + 72 : o + 75].reshape((3, 1)),
        buf[o + 75 : o + 84].reshape((3, 3)),
        np.empty(3, np.int64),
        buf[o + 84 : o + 93].reshape((3, 3)),
        buf[o + 93 : o + 111].reshape((6, 3)),
        buf[o + 111 : o + 129].reshape((3, 6)),
        buf[o + 129 : o + 138].reshape((3, 3)),
    )


@njit(**JIT)
def step_kernel(lo, hi, receivers, settings, old, action, noise, new, out):
    """One step of scenarios ``lo … hi − 1`` (:func:`.reference.step`, its stages in order):
    the gimbals slew, the drones fly on, each receiver sees and measures them, each drone is
    fixed and its track predicted and updated, the bound and the reward; then the new state's
    observation and diagnostics. Reads the state ``old`` and writes the next into ``new``
    (tuples of arrays in the order of :data:`StateArrays`; ``new.velocity`` is
    ``old.velocity``, the drones fly straight) and ``out = (reward (B,), obs (B, obs_dim)
    float32, info (N_DIAG, B))``. ``receivers (n, 3)``; ``settings`` the params' record;
    ``action (B, n, 2)`` raw actions; ``noise (B, n, m, 3)`` standard normal draws (ignored
    where ``σ_ang = 0``). No output may alias an input. Returns False (and stops) if an
    action is NaN or infinite.

    The arrays are taken out of their tuples once, into locals: a field read inside the loops
    would count a reference each time."""
    p = settings[0]
    t, azimuth, elevation, position, velocity, x, P = old[:7]
    t_out, az_out, el_out, p_out, _, x_out, P_out, seen, fixed, bound = new
    reward, obs, info = out
    n, m = azimuth.shape[1], position.shape[1]
    for b in range(lo, hi):
        for k in range(n):
            if not (math.isfinite(action[b, k, 0]) and math.isfinite(action[b, k, 1])):
                return False
    slew, max_elevation, dt, q = p.slew, p.max_elevation, p.dt, p.q
    cos_fov, sigma_ang, sigma_ref, reward_clip = p.cos_fov, p.sigma_ang, p.sigma_ref, p.reward_clip
    (
        ones,
        u,
        r,
        z,
        bore,
        r_fix,
        mask,
        M,
        G,
        G_true,
        R,
        x_pred,
        P_pred,
        rhs,
        LU,
        piv,
        S,
        K,
        work,
        inv,
    ) = workspace(n)
    s2 = StateArrays(t_out, az_out, el_out, p_out, velocity, x_out, P_out, seen, fixed, bound)
    for b in range(lo, hi):
        t_out[b] = t[b] + dt
        # 1. slew the gimbals (actions clipped to [−1, 1]), move the drones
        for k in range(n):
            az_out[b, k] = wrap_angle(azimuth[b, k] + clip(action[b, k, 0], -1.0, 1.0) * slew)
            el_out[b, k] = clip(
                elevation[b, k] + clip(action[b, k, 1], -1.0, 1.0) * slew,
                -max_elevation,
                max_elevation,
            )
            unit_from_angles(az_out[b, k], el_out[b, k], bore[k])
        total = 0.0
        for j in range(m):
            for i in range(3):
                p_out[b, j, i] = position[b, j, i] + velocity[b, j, i] * dt
            # 2. who sees drone j, and what each receiver measures
            for k in range(n):
                r[k] = line_of_sight(receivers[k], p_out[b, j], u[k])
                mask[k] = in_view(bore[k], u[k], cos_fov)
                seen[b, k, j] = mask[k]
                if sigma_ang > 0.0:
                    perturb_direction(u[k], noise[b, k, j], sigma_ang, z[k])
                else:
                    copy1(u[k], z[k])
            # 3. the fix, trusted only in front of its receivers; the track predicted and updated
            ok = weighted_fix(receivers, z, mask, ones, 2, M, G, r_fix, rhs, LU, piv)
            ok = ok and fix_in_front(M, receivers, z, mask, MIN_FIX_RANGE)
            fixed[b, j] = ok
            cv_predict(x[b, j], P[b, j], dt, q, x_pred, P_pred)
            if ok:
                fix_covariance(G, sigma_ang, LU, piv, R)
                cv_update(x_pred, P_pred, M, R, x_out[b, j], P_out[b, j], S, K, LU, piv, work)
            else:
                copy1(x_pred, x_out[b, j])
                copy2(P_pred, P_out[b, j])
            # 4. the bound of the true geometry of the receivers that see the drone, the reward
            position_information(u, r, ones, mask, G_true)
            ok_true = observable(G_true, count_views(mask))
            bound[b, j] = position_sigma(G_true, ok_true, sigma_ang, LU, piv, inv)
            total += log_ratio_reward(bound[b, j], sigma_ref, reward_clip)
        reward[b] = total / m
        # 5. what the new state shows: the observation and the diagnostics
        observe_row(p, receivers, s2, b, obs, x_pred, P_pred, u[0])
        info_row(s2, b, info)
    return True


@njit(**INLINE)
def fix_covariance(G, sigma_ang, LU, piv, R):
    """The fix's covariance ``R = σ² G⁻¹`` at its own ranges (:func:`.reference.fix_covariance`)."""
    inverse3(G, LU, piv, R)
    for i in range(3):
        for col in range(3):
            R[i, col] *= sigma_ang**2


@njit(**INLINE)
def observe_row(p, receivers, s, b, obs, x_pred, P_pred, u):
    """``simulation.observe`` of scenario ``b`` of the state ``s`` into ``obs[b]`` (float32,
    clipped to ``±OBS_CLIP``): gimbals, offsets of the predicted drones from each boresight and
    who saw whom, the predicted positions and velocities and their log accuracies. Scratch
    ``x_pred (6,)``, ``P_pred (6, 6)``, ``u (3,)``."""
    azimuth, elevation, x, P, seen = s.azimuth, s.elevation, s.x, s.P, s.seen
    n, m = azimuth.shape[1], x.shape[1]
    fov, length, speed, sigma_ref = p.fov, p.length_scale, p.velocity_scale, p.sigma_ref
    for k in range(n):
        obs[b, 3 * k] = clip(math.sin(azimuth[b, k]), -OBS_CLIP, OBS_CLIP)
        obs[b, 3 * k + 1] = clip(math.cos(azimuth[b, k]), -OBS_CLIP, OBS_CLIP)
        obs[b, 3 * k + 2] = clip(elevation[b, k] / (np.pi / 2), -OBS_CLIP, OBS_CLIP)
    for j in range(m):
        # the tracker's prediction for the next measurement time
        cv_predict(x[b, j], P[b, j], p.dt, p.q, x_pred, P_pred)
        for k in range(n):
            line_of_sight(receivers[k], x_pred, u)
            d_az, d_el = pointing_offset(azimuth[b, k], elevation[b, k], u)
            col = 3 * n + 3 * (k * m + j)
            obs[b, col] = clip(d_az / fov, -OBS_CLIP, OBS_CLIP)
            obs[b, col + 1] = clip(d_el / fov, -OBS_CLIP, OBS_CLIP)
            obs[b, col + 2] = 1.0 if seen[b, k, j] else 0.0
        col = 3 * n + 3 * n * m + 8 * j
        for i in range(3):
            obs[b, col + i] = clip(x_pred[i] / length, -OBS_CLIP, OBS_CLIP)
            obs[b, col + 4 + i] = clip(x_pred[3 + i] / speed, -OBS_CLIP, OBS_CLIP)
        # σ̂ = √tr P_pp
        sigma = math.sqrt(max(P_pred[0, 0] + P_pred[1, 1] + P_pred[2, 2], 0.0))
        obs[b, col + 3] = clip(math.log(max(sigma, 1e-12) / sigma_ref), -OBS_CLIP, OBS_CLIP)
        # σ̂_v = √tr P_vv, per second
        sigma = math.sqrt(max(P_pred[3, 3] + P_pred[4, 4] + P_pred[5, 5], 0.0))
        obs[b, col + 7] = clip(math.log(max(sigma, 1e-12) / sigma_ref), -OBS_CLIP, OBS_CLIP)


@njit(**INLINE)
def info_row(s, b, info):
    """``simulation.info`` of scenario ``b`` of the state ``s`` into ``info[:, b]``: the mean
    position error of the tracks ``mean_j ‖x̂_j − p_j‖``, the number of drones fixed and of
    receiver-drone views; for the tail measures (:func:`.simulation.tail_info`) the share of
    drones without a fix and the sum and count of the fixed drones' finite CRLB ``σ_pos``."""
    x, position, seen, fixed, bound = s.x, s.position, s.seen, s.fixed, s.bound
    n, m = seen.shape[1], seen.shape[2]
    error = 0.0
    n_fixed = 0.0
    sigma_sum = 0.0
    sigma_count = 0.0
    for j in range(m):
        d0 = x[b, j, 0] - position[b, j, 0]
        d1 = x[b, j, 1] - position[b, j, 1]
        d2 = x[b, j, 2] - position[b, j, 2]
        error += math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        n_fixed += 1.0 if fixed[b, j] else 0.0
        if fixed[b, j] and math.isfinite(bound[b, j]):
            sigma_sum += bound[b, j]
            sigma_count += 1.0
    views = 0.0
    for k in range(n):
        for j in range(m):
            views += 1.0 if seen[b, k, j] else 0.0
    info[I_ERROR, b] = error / m
    info[I_FIXED, b] = n_fixed
    info[I_VIEWS, b] = views
    info[I_UNFIXED, b] = (m - n_fixed) / m
    info[I_SIGMA_SUM, b] = sigma_sum
    info[I_SIGMA_COUNT, b] = sigma_count


@njit(**JIT)
def observe_kernel(receivers, settings, state, obs, info):
    """The observation ``obs (B, obs_dim)`` float32 and diagnostics ``info (N_DIAG, B)`` of a state
    (a tuple in the order of :data:`StateArrays`) that :func:`step_kernel` did not make (a
    reset, or a state built by hand)."""
    p = settings[0]
    s = StateArrays(*state)
    x_pred, P_pred, u = np.empty(6), np.empty((6, 6)), np.empty(3)
    for b in range(s.azimuth.shape[0]):
        observe_row(p, receivers, s, b, obs, x_pred, P_pred, u)
        info_row(s, b, info)


@njit(**JIT)
def lines_of_sight_batch(receivers, points, u, r):
    """Unit lines of sight ``u (B, n, m, 3)`` and ranges ``r (B, n, m)`` from each receiver to
    each of ``points (B, m, 3)`` (:func:`~sensorgym.trackers.stereo.kernels.line_of_sight`)."""
    for b in range(points.shape[0]):
        for k in range(receivers.shape[0]):
            for j in range(points.shape[1]):
                r[b, k, j] = line_of_sight(receivers[k], points[b, j], u[b, k, j])


@njit(**JIT)
def pointing_offsets_batch(receivers, azimuth, elevation, points, out):
    """Offsets ``out (B, n, m, 2)`` of ``points (B, m, 3)`` from each boresight
    (:func:`pointing_offset`)."""
    u = np.empty(3)
    for b in range(points.shape[0]):
        for k in range(receivers.shape[0]):
            for j in range(points.shape[1]):
                line_of_sight(receivers[k], points[b, j], u)
                out[b, k, j, 0], out[b, k, j, 1] = pointing_offset(
                    azimuth[b, k], elevation[b, k], u
                )


@njit(**JIT)
def drones_kernel(distance, bearing, height, speed, heading, climb, position, velocity):
    """Drone starts ``position``/``velocity (B, m, 3)`` from the reset's draws ``(B, m)``:
    ``p = (d sin β, h, d cos β)``, ``v = (s sin ψ, climb, s cos ψ)``."""
    for b in range(distance.shape[0]):
        for j in range(distance.shape[1]):
            position[b, j, 0] = distance[b, j] * math.sin(bearing[b, j])
            position[b, j, 1] = height[b, j]
            position[b, j, 2] = distance[b, j] * math.cos(bearing[b, j])
            velocity[b, j, 0] = speed[b, j] * math.sin(heading[b, j])
            velocity[b, j, 1] = climb[b, j]
            velocity[b, j, 2] = speed[b, j] * math.cos(heading[b, j])


@njit(**JIT)
def start_kernel(settings, cue_sigma, drones, noise, gimbals, out):
    """The start of every scenario (``simulation.start``, :func:`.reference.cue_track`,
    :func:`~.reference.hold_gimbals`): the tracker on its cue (truth plus ``σ``-scaled errors,
    covariance ``diag(σ_p², σ_v²)``: the primitive ``cv_prior`` of
    :mod:`sensorgym.trackers.stereo.kernels`), the gimbals wrapped and held within their
    elevation limit. ``cue_sigma = (σ_p, σ_v)`` (m, m/s); ``drones = (position, velocity)``
    ``(B, m, 3)``; ``noise = (noise_p, noise_v)`` ``(B, m, 3)`` standard normal draws of the
    cue's errors; ``gimbals = (azimuth, elevation)`` ``(B, n)`` as given; writes
    ``out = (x (B, m, 6), P (B, m, 6, 6), azimuth, elevation)``."""
    p = settings[0]
    sigma_p, sigma_v = cue_sigma
    position, velocity = drones
    noise_p, noise_v = noise
    azimuth, elevation = gimbals
    x, P, az_out, el_out = out
    B, m = position.shape[0], position.shape[1]
    cue_p, cue_v = np.empty(3), np.empty(3)
    for b in range(B):
        for j in range(m):
            for i in range(3):
                cue_p[i] = position[b, j, i] + sigma_p * noise_p[b, j, i]
                cue_v[i] = velocity[b, j, i] + sigma_v * noise_v[b, j, i]
            cv_prior(cue_p, cue_v, sigma_p, sigma_v, x[b, j], P[b, j])
        for k in range(azimuth.shape[1]):
            az_out[b, k] = wrap_angle(azimuth[b, k])
            el_out[b, k] = clip(elevation[b, k], -p.max_elevation, p.max_elevation)


@njit(**JIT)
def aim_lines_batch(receivers, points, u):
    """Unit lines of sight ``u (B, n, 3)`` from receiver ``k`` to ``points[:, k] (B, n, 3)``
    (:func:`~sensorgym.trackers.stereo.kernels.line_of_sight`: zero within ``MIN_RANGE``)."""
    for b in range(points.shape[0]):
        for k in range(receivers.shape[0]):
            line_of_sight(receivers[k], points[b, k], u[b, k])


@njit(**JIT)
def cue_lines_batch(receivers, x, u):
    """:func:`aim_lines_batch` to the tracks' positions: receiver ``k`` to drone ``k mod m``
    of ``x (B, m, 6)`` (the cued start)."""
    m = x.shape[1]
    for b in range(x.shape[0]):
        for k in range(receivers.shape[0]):
            line_of_sight(receivers[k], x[b, k % m, :3], u[b, k])


@njit(**JIT)
def aim_merge(u, azimuth, elevation, max_elevation, az, el):
    """Finish an aim in place: where the line of sight ``u (B, n, 3)`` is zero (the point on the
    receiver, no direction) ``az``/``el`` keep the given ``azimuth``/``elevation``; ``el`` is
    held within ``±max_elevation``."""
    for b in range(u.shape[0]):
        for k in range(u.shape[1]):
            if u[b, k, 0] == 0.0 and u[b, k, 1] == 0.0 and u[b, k, 2] == 0.0:
                az[b, k] = azimuth[b, k]
                el[b, k] = elevation[b, k]
            el[b, k] = clip(el[b, k], -max_elevation, max_elevation)
