"""The GimbalTracking step, reset lock-on, observation and diagnostics as compiled row passes.

:func:`step_kernel` is :func:`.reference.step` for the scenarios ``lo ≤ b < hi`` (so that
:func:`sensorgym.envs.shells.rows.run_rows` can split a batch over threads),
:func:`lock_on_kernel` is :func:`.reference.lock_on` after its draws, and :func:`observe_kernel`
and :func:`info_kernel` are :func:`.reference.observe` and :func:`.reference.info`. They follow
the stages of the readable numpy form, :mod:`.reference` (theory §8, §9, §11.8), one inlined
function per stage under the reference's name: :func:`drive_gimbal`, :func:`fly_target`,
:func:`carrier_attitude` (and :func:`body_to_level`), :func:`schedule_occlusions`,
:func:`step_views`, :func:`view_geometry` (with :func:`in_sector`), :func:`gate_centre`,
:func:`render_gate`, :func:`fuse_gate` (both planes of one gimbal: :func:`fuse_channels` with
:func:`channel_terms`, paper 004's :meth:`~sensorgym.trackers.fusion.tracker.FusionTracker.
update` of one image plane), :func:`measures_better` (:func:`.reference.measuring_gimbal`),
:func:`advance_predictor` (paper 001's
:meth:`~sensorgym.trackers.angles.prediction.ABCPredictor.update` as :func:`push_window`,
:func:`abc_estimates` and :func:`abc_commit`, then :func:`recentre`), :func:`predicted_angles`,
:func:`los_sigma` and :func:`reward`. The random draws are made by the caller with
numpy's Generator, in the order and shapes of the numpy form, and passed in: seeded episodes do
not depend on the kernel or on the split of the rows.

The step reads the old state's arrays and writes freshly allocated ones (states are values).
Per scenario it runs the gimbals' stages (drives, views, view geometry, gate, fusion) in a
loop over the gimbal axis, then the one track's.

What the kernels take:

- the **settings**: one record of dtype :data:`SETTINGS`, read by field name (``p.dt``,
  ``p.half_field``); :attr:`.simulation.GimbalParams.kernel_settings` builds it once per params;
- the **model**: the arrays of the world and of the tracker's model in the order of
  :data:`ModelArrays` (:attr:`.simulation.GimbalParams.kernel_model`);
- a **state** as the tuple of its arrays in the order of :data:`StateArrays` (what
  :func:`.simulation.state_arrays` returns); the step takes it apart once per call and hands
  every stage the arrays it reads and writes;
- **scratch** from :func:`workspace`, allocated once per call and reused over the rows.

Rows are independent; ``prange`` is not used (seconds of cold compile, and numba's OpenMP layer
does not survive ``fork()``): the caller splits a large batch over threads.
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit

from sensorgym.envs.shells.contract import OBS_CLIP
from sensorgym.trackers.stereo.kernels import INLINE, JIT, clip, wrap_angle

#: the fused tracker works in milliradians (:data:`.reference.MRAD`)
MRAD = 1000.0

#: The scalar settings the kernels read, one record per params
#: (:attr:`.simulation.GimbalParams.kernel_settings`), read by field name.
SETTINGS = np.dtype(
    [
        ("dt", np.float64),  # frame period T, s
        ("max_rate", np.float64),  # drive rate limit, rad/s
        ("max_acceleration", np.float64),  # drive acceleration limit, rad/s²
        ("elevation_low", np.float64),  # elevation stops, rad
        ("elevation_high", np.float64),
        ("half_field", np.float64),  # h, rad
        ("vignetting", np.float64),  # v
        ("target_size", np.float64),  # in the image plane, mrad
        ("blur", np.float64),  # the optics' blur σ, mrad
        ("sensor_noise", np.float64),  # angle sensors' σ_s, rad
        ("sigma_ref", np.float64),  # the reward's reference angle, rad
        ("reward_clip", np.float64),  # R
        ("attitude_scale", np.float64),  # attitude and its rates are observed divided by this
        ("correlation", np.float64),  # paper 004's R_λ
        ("transition_variance", np.float64),  # d₀ = (1 − R_λ²) σ_λ², mrad²
        ("open_threshold", np.float64),  # the loop opens below this object posterior
        ("predictor_gain", np.float64),  # paper 001's filter gain γ
        ("initial_scale", np.float64),  # paper 001's ρ₀
        ("gap_low", np.int64),  # occlusion gaps and lengths, frames (inclusive bounds)
        ("gap_high", np.int64),
        ("length_low", np.int64),
        ("length_high", np.int64),
        ("search_after", np.int64),  # frames without detection before the gate searches
        ("reacquire_limit", np.int64),  # frames out of view that end the episode
        ("relock", np.bool_),  # re-lock the predictor on a re-acquisition (theory §13.42)
    ],
    align=True,
)

#: The arrays of the world and the tracker's model (:attr:`.simulation.GimbalParams.
#: kernel_model`): the carrier's sinusoids ``amp``, ``omega``, ``axis`` ``(K,)``; the views'
#: chains ``view_pi (N, 3, 3)`` and contrasts ``contrast (N, 3)``; the pixel noise
#: ``noise (N,)``; the gate's pixel centres ``gate (J,)`` (mrad); paper 004's templates ``s``
#: and slopes ``ds`` ``(N, M, J)``, its energy terms ``ss = Σ_j s²`` and ``sds = Σ_j s s′``,
#: its Fisher information ``info`` ``(N, M)`` and its view chains ``model_pi (N, M, M)``; the
#: gimbals' clear sectors ``sectors (G, 2)`` as ``(low, width)`` (rad, body azimuth).
ModelArrays = namedtuple(
    "ModelArrays", "amp omega axis view_pi contrast noise gate s ds ss sds info model_pi sectors"
)

#: The arrays of a :class:`.simulation.GimbalState`, in the order the kernels take them
#: (:func:`.simulation.state_arrays`); the predictor's (``ABCState``) fields sit between
#: ``view_posterior`` and ``origin`` (``predictor_origin``).
StateArrays = namedtuple(
    "StateArrays",
    "frame position velocity turn_rate turn_start turn_end phase gimbal rates views "
    "occ_start occ_end out_of_view since variance posterior "
    "azimuths elevations count slope delta anchor origin "
    "reference estimate predicted detected in_view occluded visible sigma",
)

#: Scratch of one call (:func:`workspace`): the attitude ``att (3,)`` and its rotation
#: ``R (3, 3)``, the gate's images ``images (2, N, J)`` and profiles ``profile (2, J)``, the
#: tracker's LLRs ``Pi`` and discriminator outputs ``dPi`` ``(N, M)``, each gimbal's fused
#: offsets ``offsets (G, 2)`` and the predictor's ``work (9,)`` (:func:`advance_predictor`).
Workspace = namedtuple("Workspace", "att R images profile Pi dPi offsets work")


@njit(**INLINE)
def workspace(channels, views, pixels, gimbals):
    """Scratch for the rows of one call: ``channels`` N, ``views`` M, ``pixels`` J, ``gimbals``
    G."""
    return Workspace(
        np.empty(3),
        np.empty((3, 3)),
        np.empty((2, channels, pixels)),
        np.empty((2, pixels)),
        np.empty((channels, views)),
        np.empty((channels, views)),
        np.empty((gimbals, 2)),
        np.empty(9),
    )


# --- the contract: the step and the reset's lock-on --------------------------------------------
#
# The kernels take the tuples apart once per call and hand each stage plain arrays: a tuple
# handed to a stage, or a field read from one, counts a reference to each of its arrays every
# time (research/kernel_spine/README.md).


@njit(**JIT)
def step_kernel(lo, hi, settings, model, old, action, draws, new, out):
    """One frame of the scenarios ``lo ≤ b < hi`` (:func:`.reference.step`): reads the state
    ``old`` and writes the next into ``new`` (tuples of arrays in the order of
    :data:`StateArrays`; ``new`` shares ``turn_rate`` … ``phase`` with ``old``) and
    ``out = (reward, terminated)`` ``(B,)``. ``action (B, G, 2)`` is clipped to ``[−1, 1]``;
    ``draws = (gap, length, view, pixel, sensor)``: the occlusions' uniforms ``(B,)`` and
    ``(B,)``, the views' ``(B, G, N)``, the gates' standard normal pixel noise
    ``(B, G, 2, N, J)`` and the angle sensors' ``(B, 2)``. ``model`` is in the order of
    :data:`ModelArrays`."""
    p = settings[0]
    amp, omega, axis, view_pi, contrast, noise, gate, s = model[:8]
    sectors = model[13]
    frame, pos, vel, turn_rate, turn_start, turn_end, phase, gimbal, rates, views = old[:10]
    occ_start, occ_end, out_of_view, since, variance, posterior = old[10:16]
    th, ph, count, slope, delta, anchor, origin, _, _, predicted = old[16:26]
    frame2, pos2, vel2, _, _, _, _, gimbal2, rates2, views2 = new[:10]
    occ_start2, occ_end2, out_of_view2, since2, variance2, posterior2 = new[10:16]
    th2, ph2, count2, slope2, delta2, anchor2, origin2, reference2, estimate2 = new[16:25]
    predicted2, detected2, in_view2, occluded2, visible2, sigma2 = new[25:]
    u_gap, u_length, u_view, pixel_noise, sensor_noise = draws
    reward_out, terminated = out
    ws = workspace(s.shape[0], s.shape[1], s.shape[2], gimbal.shape[1])
    att, R, images, profile, Pi, dPi, offsets, work = ws
    for b in range(lo, hi):
        f = frame[b] + 1
        frame2[b] = f
        # 2. the target flies on (a level turn in its interval), the carrier rolls, pitches
        # and yaws; occlusions hide the target from every gimbal (§11.8)
        w = turn_rate[b] if turn_start[b] < f <= turn_end[b] else 0.0
        fly_target(p, pos[b], vel[b], w, pos2[b], vel2[b])
        carrier_attitude(p, amp, omega, axis, phase[b], f, att)
        body_to_level(att, R)
        occluded2[b] = schedule_occlusions(
            p, f, occ_start, occ_end, u_gap[b], u_length[b], b, occ_start2, occ_end2
        )
        seen_any, found, best = False, False, 0
        for g in range(gimbal.shape[1]):
            # 1. the gimbal's drives under its rate command (§11.8)
            drive_gimbal(p, gimbal[b, g], rates[b, g], action[b, g], gimbal2[b, g], rates2[b, g])
            # 3. its channels' view chains (§9.1); its field of view, clear sector, vignetting
            step_views(view_pi, views[b, g], u_view[b, g], views2[b, g])
            seen, gain = view_geometry(p, pos2[b], R, gimbal2[b, g], sectors[g])
            seen_any = seen_any or seen
            for n in range(views2.shape[2]):
                visible2[b, g, n] = views2[b, g, n] > 0 and seen and not occluded2[b]
            # 4. its gate's images about the track's prediction (or its boresight in search),
            # paper 004's fused offsets and its MAP detection, in both planes (§9.2)
            gate_centre(p, since[b], predicted[b], gimbal2[b, g], R, reference2[b, g])
            render_gate(
                p, gate, contrast, noise, pos2[b], reference2[b, g], views2[b, g], visible2[b, g],
                gain, pixel_noise[b, g], profile, images,
            )  # fmt: skip
            here = fuse_gate(
                p, model, images, Pi, dPi, variance[b, g], posterior[b, g], variance2[b, g],
                posterior2[b, g], offsets[g],
            )  # fmt: skip
            # the measuring gimbal: of the detecting ones, the least d_α + d_β (first of equals)
            if g > 0 and measures_better(here, found, variance2[b, g], variance2[b, best]):
                best = g
            found = found or here
        in_view2[b] = seen_any
        detected2[b] = found
        # 5. the measuring gimbal's fused direction, with the angle sensors' noise, is paper
        # 001's measurement; its predictor coasts where no gimbal detected the target (§8.6)
        az, el = from_tangent_offsets(
            reference2[b, best], offsets[best, 0] / MRAD, offsets[best, 1] / MRAD
        )
        az = az + sensor_noise[b, 0] * p.sensor_noise
        el = el + sensor_noise[b, 1] * p.sensor_noise
        copy_predictor(th[b], ph[b], delta[b], anchor[b], th2[b], ph2[b], delta2[b], anchor2[b])
        if p.relock and found and since[b] > 0 and count[b] >= th.shape[1]:
            # re-acquired after a loss: the coasted track moved onto the measurement (§13.42)
            relock(th2[b], ph2[b], delta2[b], anchor2[b], wrap_angle(az - origin[b]), el, work)
        count2[b], slope2[b], origin2[b] = advance_predictor(
            p, th2[b], ph2[b], count[b], slope[b], delta2[b], anchor2[b], origin[b], az, el,
            found, work,
        )  # fmt: skip
        ready = count2[b] >= th.shape[1]
        predicted_angles(th2[b], ph2[b], ready, delta2[b], anchor2[b], origin2[b], 0.0,
                         estimate2[b])  # fmt: skip
        predicted_angles(th2[b], ph2[b], ready, delta2[b], anchor2[b], origin2[b], 1.0,
                         predicted2[b])  # fmt: skip
        # 6. σ_LOS of the measuring gimbal's fused direction, the reward (−R out of every
        # gimbal's view), the episode's end (§11.8)
        sigma2[b] = los_sigma(p, variance2[b, best, 0], variance2[b, best, 1])
        reward_out[b] = reward(p, sigma2[b], seen_any)
        out_of_view2[b] = 0 if seen_any else out_of_view[b] + 1
        since2[b] = 0 if found else since[b] + 1
        terminated[b] = out_of_view2[b] > p.reacquire_limit


@njit(**JIT)
def lock_on_kernel(settings, azimuth, elevation, noise, predictor, origin):
    """The lock-on frames of :func:`.reference.lock_on` after its draws: the true angles
    ``azimuth``, ``elevation`` ``(B, N + 1)`` of frames ``−N … 0`` and the sensors' standard
    normal ``noise (B, N + 1, 2)``; updates the predictor's arrays ``predictor`` (``azimuths``
    … ``anchor`` of :data:`StateArrays`, an empty predictor's on entry) in place and writes
    its frame's ``origin (B,)``."""
    p = settings[0]
    th, ph, count, slope, delta, anchor = predictor
    work = np.empty(9)
    for b in range(th.shape[0]):
        o = wrap_angle(azimuth[b, 0] + noise[b, 0, 0] * p.sensor_noise)
        c, sl = count[b], slope[b]
        for j in range(azimuth.shape[1]):
            az = azimuth[b, j] + noise[b, j, 0] * p.sensor_noise
            el = elevation[b, j] + noise[b, j, 1] * p.sensor_noise
            c, sl, o = advance_predictor(
                p, th[b], ph[b], c, sl, delta[b], anchor[b], o, az, el, True, work
            )
        count[b], slope[b], origin[b] = c, sl, o


@njit(**JIT)
def observe_kernel(settings, model, state, obs):
    """The joint observation ``obs (B, G · A)`` float32 of every row of ``state``: each gimbal's
    ``A`` entries in turn (the table of :func:`.simulation.observe`, :func:`.reference.
    observe_agents`), clipped to ``±OBS_CLIP``."""
    p = settings[0]
    amp, omega, axis = model[:3]
    sectors = model[13]
    frame, _, _, _, _, _, phase, gimbal, rates = state[:9]
    variance, posterior = state[14], state[15]
    estimate, predicted, detected = state[24:27]
    since, sigma = state[13], state[30]
    att, att_rates, R = np.empty(3), np.empty(3), np.empty((3, 3))
    G, N = posterior.shape[1], posterior.shape[3]
    A = obs.shape[1] // G
    half_pi = np.pi / 2
    for b in range(frame.shape[0]):
        carrier_attitude(p, amp, omega, axis, phase[b], frame[b], att)
        carrier_rates(p, amp, omega, axis, phase[b], frame[b], att_rates)
        body_to_level(att, R)
        for g in range(G):
            o = obs[b, g * A : (g + 1) * A]
            put(o, 0, gimbal[b, g, 0] / np.pi)
            put(o, 1, gimbal[b, g, 1] / half_pi)
            for i in range(2):
                put(o, 2 + i, rates[b, g, i] / p.max_rate)
            for i in range(3):
                put(o, 4 + i, att[i] / p.attitude_scale)
                put(o, 7 + i, att_rates[i] / p.attitude_scale)
            body_offset(p, R, gimbal[b, g], estimate[b], o, 10)
            ahead = body_offset(p, R, gimbal[b, g], predicted[b], o, 12)
            put(o, 14, estimate[b, 0] / np.pi)
            put(o, 15, estimate[b, 1] / half_pi)
            put(o, 16, predicted[b, 0] / np.pi)
            put(o, 17, predicted[b, 1] / half_pi)
            put(o, 18, math.log(sigma[b] / p.sigma_ref))
            for n in range(N):
                # each channel's object probability, the mean of the two planes'
                q_az, q_el = 1.0 - posterior[b, g, 0, n, 0], 1.0 - posterior[b, g, 1, n, 0]
                put(o, 19 + n, (q_az + q_el) / 2.0)
            put(o, 19 + N, 1.0 if detected[b] else 0.0)
            put(o, 20 + N, since[b] / (p.reacquire_limit + 1))
            if G > 1:
                own = detects(posterior[b, g, 0]) and detects(posterior[b, g, 1])
                put(o, 21 + N, 1.0 if in_sector(ahead, sectors[g]) else 0.0)
                put(o, 22 + N, sectors[g, 0] / np.pi)
                put(o, 23 + N, (sectors[g, 0] + sectors[g, 1]) / np.pi)
                put(o, 24 + N, 1.0 if own else 0.0)
                own_sigma = los_sigma(p, variance[b, g, 0], variance[b, g, 1])
                put(o, 25 + N, math.log(own_sigma / p.sigma_ref))


@njit(**INLINE)
def detects(post):
    """The MAP detection of one plane's view posteriors ``post (N, M)``: some channel's object
    posterior beats the background's (:func:`.reference.gimbal_detections`)."""
    for n in range(post.shape[0]):
        if 1.0 - post[n, 0] > 0.5:
            return True
    return False


@njit(**JIT)
def info_kernel(settings, model, state, diag):
    """The diagnostics ``diag (10, B)`` of every row of ``state``, in the order of
    :data:`.simulation.INFO_KEYS` (:func:`.reference.info`)."""
    p = settings[0]
    amp, omega, axis = model[:3]
    sectors = model[13]
    frame, pos, _, _, _, _, phase, gimbal = state[:8]
    variance, posterior = state[14], state[15]
    estimate, _, detected, in_view, occluded, visible, sigma = state[24:]
    att, R = np.empty(3), np.empty((3, 3))
    for b in range(frame.shape[0]):
        carrier_attitude(p, amp, omega, axis, phase[b], frame[b], att)
        body_to_level(att, R)
        r = math.sqrt(pos[b, 0] * pos[b, 0] + pos[b, 1] * pos[b, 1] + pos[b, 2] * pos[b, 2])
        lx, ly, lz = pos[b, 0] / r, pos[b, 1] / r, pos[b, 2] / r
        ex, ey, ez = unit_from_zup(estimate[b, 0], estimate[b, 1])
        # the target's body azimuth (u_B = Rᵀ u_L): which gimbals' clear sectors hold it
        body_az = math.atan2(
            R[0, 0] * lx + R[1, 0] * ly + R[2, 0] * lz, R[0, 1] * lx + R[1, 1] * ly + R[2, 1] * lz
        )
        clear_any, best, found = False, 0, False
        for g in range(gimbal.shape[1]):
            clear_any = clear_any or in_sector(body_az, sectors[g])
            here = detects(posterior[b, g, 0]) and detects(posterior[b, g, 1])
            if g > 0 and measures_better(here, found, variance[b, g], variance[b, best]):
                best = g
            found = found or here
        pointing, seen = np.inf, 0.0
        for g in range(gimbal.shape[1]):
            ux, uy, uz = unit_from_zup(gimbal[b, g, 0], gimbal[b, g, 1])
            # the boresight in the level frame, R u_B
            bx = R[0, 0] * ux + R[0, 1] * uy + R[0, 2] * uz
            by = R[1, 0] * ux + R[1, 1] * uy + R[1, 2] * uz
            bz = R[2, 0] * ux + R[2, 1] * uy + R[2, 2] * uz
            if in_sector(body_az, sectors[g]) or not clear_any:
                pointing = min(pointing, angle_between(bx, by, bz, lx, ly, lz))
            for n in range(visible.shape[2]):
                seen += 1.0 if visible[b, g, n] else 0.0
        az, el = zup_angles(lx, ly, lz)
        diag[0, b] = angle_between(ex, ey, ez, lx, ly, lz)
        diag[1, b] = pointing
        diag[2, b] = wrap_angle(estimate[b, 0] - az)
        diag[3, b] = estimate[b, 1] - el
        diag[4, b] = sigma[b]
        diag[5, b] = 1.0 if in_view[b] else 0.0
        diag[6, b] = 1.0 if occluded[b] else 0.0
        diag[7, b] = 1.0 if detected[b] else 0.0
        diag[8, b] = seen
        diag[9, b] = best


@njit(**INLINE)
def put(o, i, value):
    """``o[i]``: ``value`` clipped to ``±OBS_CLIP``, as float32."""
    o[i] = clip(value, -OBS_CLIP, OBS_CLIP)


@njit(**INLINE)
def body_offset(p, R, gimbal, angles, o, i):
    """``o[i], o[i + 1]``: the body-frame offset of the level direction at ``angles (2,)`` from
    the gimbal's ``(α, β)``, azimuth wrapped, ``/ h`` (``u_B = Rᵀ u_L``); returns the
    direction's body azimuth."""
    x, y, z = unit_from_zup(angles[0], angles[1])
    bx = R[0, 0] * x + R[1, 0] * y + R[2, 0] * z
    by = R[0, 1] * x + R[1, 1] * y + R[2, 1] * z
    bz = R[0, 2] * x + R[1, 2] * y + R[2, 2] * z
    az, el = zup_angles(bx, by, bz)
    put(o, i, wrap_angle(az - gimbal[0]) / p.half_field)
    put(o, i + 1, (el - gimbal[1]) / p.half_field)
    return az


@njit(**INLINE)
def angle_between(ux, uy, uz, wx, wy, wz):
    """The angle between two directions, ``atan2(‖u × w‖, u · w)``."""
    cx, cy, cz = uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx
    return math.atan2(math.sqrt(cx * cx + cy * cy + cz * cz), ux * wx + uy * wy + uz * wz)


# --- geometry (theory §2.2, §8.2) --------------------------------------------------------------


@njit(**INLINE)
def unit_from_zup(azimuth, elevation):
    """``(cos ϕ sin θ, cos ϕ cos θ, sin ϕ)``: paper 001's unit vector of ``(θ, ϕ)``."""
    ce = math.cos(elevation)
    return ce * math.sin(azimuth), ce * math.cos(azimuth), math.sin(elevation)


@njit(**INLINE)
def zup_angles(x, y, z):
    """``θ = atan2(X, Y)``, ``ϕ = atan2(Z, √(X² + Y²))`` of a (not necessarily unit) vector."""
    return math.atan2(x, y), math.atan2(z, math.hypot(x, y))


@njit(**INLINE)
def body_to_level(att, R):
    """``R = R_z(ψ) R_x(p) R_y(r)`` for ``att = (r, p, ψ)`` (:func:`.reference.body_to_level`),
    the products in the order of the reference's matrix products."""
    cr, sr = math.cos(att[0]), math.sin(att[0])
    cp, sp = math.cos(att[1]), math.sin(att[1])
    cy, sy = math.cos(att[2]), math.sin(att[2])
    # R_z R_x = [[cy, −sy cp, sy sp], [sy, cy cp, −cy sp], [0, sp, cp]]
    m00, m01, m02 = cy, -sy * cp, -sy * -sp
    m10, m11, m12 = sy, cy * cp, cy * -sp
    m20, m21, m22 = 0.0, sp, cp
    # (R_z R_x) R_y,  R_y = [[cr, 0, sr], [0, 1, 0], [−sr, 0, cr]]
    R[0, 0], R[0, 1], R[0, 2] = m00 * cr + m02 * -sr, m01, m00 * sr + m02 * cr
    R[1, 0], R[1, 1], R[1, 2] = m10 * cr + m12 * -sr, m11, m10 * sr + m12 * cr
    R[2, 0], R[2, 1], R[2, 2] = m20 * cr + m22 * -sr, m21, m20 * sr + m22 * cr


@njit(**INLINE)
def tangent_offsets(x, y, z, a, e):
    """Offsets (rad) of the direction ``(x, y, z)`` from the axis at azimuth ``a``, elevation
    ``e`` in the image plane (:func:`.reference.tangent_offsets`):
    ``(atan2(u·e_α, u·b), atan2(u·e_β, u·b))``."""
    sa, ca, se, ce = math.sin(a), math.cos(a), math.sin(e), math.cos(e)
    # b = (cos e sin a, cos e cos a, sin e), e_α = (cos a, −sin a, 0),
    # e_β = (−sin e sin a, −sin e cos a, cos e)
    along = x * (ce * sa) + y * (ce * ca) + z * se
    across_az = x * ca + y * -sa + z * 0.0
    across_el = x * (-se * sa) + y * (-se * ca) + z * ce
    return math.atan2(across_az, along), math.atan2(across_el, along)


@njit(**INLINE)
def from_tangent_offsets(angles, o_az, o_el):
    """The level angles of the direction seen at offsets ``(o_az, o_el)`` (rad) from the axis
    at ``angles (2,)`` (:func:`.reference.from_tangent_offsets`):
    ``u = b + tan(o_α) e_α + tan(o_β) e_β``."""
    a, e = angles[0], angles[1]
    sa, ca, se, ce = math.sin(a), math.cos(a), math.sin(e), math.cos(e)
    ta, te = math.tan(o_az), math.tan(o_el)
    x = ce * sa + ta * ca + te * (-se * sa)
    y = ce * ca + ta * -sa + te * (-se * ca)
    z = se + ta * 0.0 + te * ce
    return zup_angles(x, y, z)


# --- the world: drives, target, carrier, losses, views (theory §9.1, §11.8) ------------------


@njit(**INLINE)
def drive_gimbal(p, angles, rates, action, angles2, rates2):
    """One frame of the rate- and acceleration-limited drives (:func:`.reference.drive_gimbal`):
    ``ω_k = ω_{k−1} + clip(a · max_rate − ω_{k−1}, −A T, A T)``, the angles move by ``ω_k T``;
    the azimuth wraps, the elevation stops at its limits (its rate zeroed there)."""
    step = p.max_acceleration * p.dt
    for i in range(2):
        command = clip(action[i], -1.0, 1.0) * p.max_rate
        rates2[i] = rates[i] + clip(command - rates[i], -step, step)
        angles2[i] = angles[i] + rates2[i] * p.dt
    angles2[0] = wrap_angle(angles2[0])
    el = angles2[1]
    if el < p.elevation_low or el > p.elevation_high:
        angles2[1] = clip(el, p.elevation_low, p.elevation_high)
        rates2[1] = 0.0


@njit(**INLINE)
def fly_target(p, position, velocity, turn_rate, position2, velocity2):
    """One frame of the target (:func:`.reference.fly_target`): ``v ← R_z(ω T) v`` (its
    horizontal components; ``ω = 0`` outside the turn), then ``p ← p + v T``."""
    w = turn_rate * p.dt
    c, s = math.cos(w), math.sin(w)
    vx, vy = velocity[0], velocity[1]
    velocity2[0] = c * vx - s * vy
    velocity2[1] = s * vx + c * vy
    velocity2[2] = velocity[2]
    for i in range(3):
        position2[i] = position[i] + velocity2[i] * p.dt


@njit(**INLINE)
def carrier_attitude(p, amp, omega, axis, phase, frame, att):
    """The carrier's roll, pitch and yaw ``att (3,)`` at ``frame`` (:func:`.reference.
    carrier_attitude`): per axis ``a(t) = Σ_i A_i sin(ω_i t + φ_i)``, summed in term order."""
    t = frame * p.dt
    att[0], att[1], att[2] = 0.0, 0.0, 0.0
    for k in range(amp.shape[0]):
        att[axis[k]] += amp[k] * math.sin(omega[k] * t + phase[k])


@njit(**INLINE)
def carrier_rates(p, amp, omega, axis, phase, frame, rates):
    """The rates ``rates (3,)`` of :func:`carrier_attitude`: ``ȧ = Σ_i A_i ω_i cos(ω_i t + φ_i)``."""
    t = frame * p.dt
    rates[0], rates[1], rates[2] = 0.0, 0.0, 0.0
    for k in range(amp.shape[0]):
        rates[axis[k]] += amp[k] * omega[k] * math.cos(omega[k] * t + phase[k])


@njit(**INLINE)
def draw_integer(u, low, high):
    """An integer uniform in ``[low, high]`` from the uniform ``u``
    (:func:`.reference.draw_integers`): ``min(low + ⌊u (high − low + 1)⌋, high)``."""
    return min(np.int64(low + math.floor(u * (high - low + 1))), high)


@njit(**INLINE)
def schedule_occlusions(p, frame, start, end, u_gap, u_length, b, start2, end2):
    """Row ``b``'s occlusion ``[start, end)`` after ``frame``, renewed once it has passed
    (:func:`.reference.schedule_occlusions`): the next onset a drawn gap after its end, a drawn
    length. Returns whether ``frame`` is occluded."""
    gap = draw_integer(u_gap, p.gap_low, p.gap_high)
    length = draw_integer(u_length, p.length_low, p.length_high)
    s, e = start[b], end[b]
    if frame >= e:
        s = e + gap
        e = s + length
    start2[b], end2[b] = s, e
    return s <= frame < e


@njit(**INLINE)
def step_views(view_pi, views, u, views2):
    """Each channel's view one step along its Markov chain ``π^{(n)}`` (theory §9.1,
    :func:`.reference.step_views`): the number of cumulative row sums below the uniform ``u``."""
    M = view_pi.shape[2]
    for n in range(views.shape[0]):
        total, m = 0.0, 0
        for j in range(M):
            total += view_pi[n, views[n], j]
            if total < u[n]:
                m += 1
        views2[n] = min(m, M - 1)


@njit(**INLINE)
def view_geometry(p, target, R, gimbal, sector):
    """Whether the target at ``target (3,)`` lies in the square field of view (and in front)
    of the gimbal at ``gimbal (2,)`` on a carrier turned by ``R`` and in its clear ``sector``
    ``(low, width)`` (:func:`in_sector`), and the optics' contrast factor
    ``clip(1 − v (ρ/h)², 0, 1)`` (:func:`.reference.view_geometry`)."""
    r = math.sqrt(target[0] * target[0] + target[1] * target[1] + target[2] * target[2])
    lx, ly, lz = target[0] / r, target[1] / r, target[2] / r
    # u_B = Rᵀ u_L
    x = R[0, 0] * lx + R[1, 0] * ly + R[2, 0] * lz
    y = R[0, 1] * lx + R[1, 1] * ly + R[2, 1] * lz
    z = R[0, 2] * lx + R[1, 2] * ly + R[2, 2] * lz
    o_az, o_el = tangent_offsets(x, y, z, gimbal[0], gimbal[1])
    h = p.half_field
    bx, by, bz = unit_from_zup(gimbal[0], gimbal[1])
    front = x * bx + y * by + z * bz > 0.0
    seen = front and abs(o_az) <= h and abs(o_el) <= h and in_sector(math.atan2(x, y), sector)
    rho2 = (o_az * o_az + o_el * o_el) / (h * h)
    return seen, clip(1.0 - p.vignetting * rho2, 0.0, 1.0)


@njit(**INLINE)
def in_sector(azimuth, sector):
    """Whether the body ``azimuth`` lies in the clear ``sector`` ``(low, width)``:
    ``(a − low) mod 2π <= width`` (:func:`.reference.in_sector`)."""
    return (azimuth - sector[0]) % (2.0 * math.pi) <= sector[1]


# --- the tracker: gate, images, paper 004's fusion (theory §9.1–9.2) ---------------------------


@njit(**INLINE)
def gate_centre(p, since, predicted, gimbal, R, out):
    """Level angles ``out (2,)`` the gate is centred on (:func:`.reference.gate_centre`): the
    prediction ``predicted (2,)``, or the boresight ``R u_B(α, β)`` once the target has gone
    undetected for ``search_after`` frames."""
    if since >= p.search_after:
        bx, by, bz = unit_from_zup(gimbal[0], gimbal[1])
        x = R[0, 0] * bx + R[0, 1] * by + R[0, 2] * bz
        y = R[1, 0] * bx + R[1, 1] * by + R[1, 2] * bz
        z = R[2, 0] * bx + R[2, 1] * by + R[2, 2] * bz
        out[0], out[1] = zup_angles(x, y, z)
    else:
        out[0], out[1] = predicted[0], predicted[1]


@njit(**INLINE)
def render_gate(p, gate, contrast, noise, target, centre, views, visible, gain, draws, profile,
                images):  # fmt: skip
    """The gate's images ``images (2, N, J)`` (theory §9.1 eq. (2), :func:`.reference.
    render_gate`): each view's blurred rectangle (:func:`~sensorgym.envs.worlds.imaging.
    box_profile`) shifted by the target's offset from the gate ``centre`` (mrad, in the
    level frame's image plane), times the view's contrast and the optics' ``gain`` where
    ``visible (N,)``, plus the pixel noise ``σ_n`` times ``draws (2, N, J)``."""
    r = math.sqrt(target[0] * target[0] + target[1] * target[1] + target[2] * target[2])
    o_az, o_el = tangent_offsets(target[0] / r, target[1] / r, target[2] / r, centre[0], centre[1])
    a = math.sqrt(2.0) * p.blur
    half = 0.5 * p.target_size
    for plane in range(2):
        residual = (o_az if plane == 0 else o_el) * MRAD
        for j in range(gate.shape[0]):
            x = gate[j] - residual
            # ½ (erf((x + g/2)/a) − erf((x − g/2)/a)),  a = √2 σ_blur
            profile[plane, j] = 0.5 * (math.erf((x + half) / a) - math.erf((x - half) / a))
    for n in range(views.shape[0]):
        c = contrast[n, views[n]] * gain if visible[n] else 0.0
        for plane in range(2):
            for j in range(gate.shape[0]):
                images[plane, n, j] = c * profile[plane, j] + noise[n] * draws[plane, n, j]


@njit(**INLINE)
def fuse_gate(p, model, images, Pi, dPi, variance, prior, variance2, post, offsets):
    """Paper 004's update of both planes of one gimbal's gate images ``images (2, N, J)``
    (:func:`channel_terms`, :func:`fuse_channels`): the prior ``variance (2,)`` and view
    posteriors ``prior (2, N, M)`` to ``variance2``, ``post``; writes the fused offsets
    ``offsets (2,)`` (mrad) and returns the MAP detection (an object view in both planes)."""
    noise, _, s, ds, ss, sds, info, model_pi = model[5:13]
    found = True
    for plane in range(2):
        channel_terms(s, ds, ss, sds, noise, images[plane], Pi, dPi)
        offsets[plane], variance2[plane], seen_here = fuse_channels(
            p, info, model_pi, variance[plane], prior[plane], Pi, dPi, post[plane]
        )
        found = found and seen_here
    return found


@njit(**INLINE)
def measures_better(detected, best_detected, variance, best_variance):
    """Whether a gimbal's fused direction (``detected``, ``variance (2,)``) replaces the best so
    far as the track's measurement (:func:`.reference.measuring_gimbal`): a detection beats
    none, and of equals the smaller ``d_α + d_β``."""
    if detected != best_detected:
        return detected
    return variance[0] + variance[1] < best_variance[0] + best_variance[1]


@njit(**INLINE)
def channel_terms(s, ds, ss, sds, noise_std, y, Pi, dPi):
    """Per channel and view (theory §9.2, §13.37): the LLR ``Π = σ⁻² (Σ y s − ½ Σ s²)`` and the
    discriminator output ``Π′ = −σ⁻² (Σ y s′ − Σ s s′)`` of the images ``y (N, J)``."""
    for n in range(s.shape[0]):
        inv_var = 1.0 / (noise_std[n] * noise_std[n])
        for m in range(s.shape[1]):
            ys, yds = 0.0, 0.0
            for j in range(s.shape[2]):
                ys += y[n, j] * s[n, m, j]
                yds += y[n, j] * ds[n, m, j]
            Pi[n, m] = inv_var * (ys - 0.5 * ss[n, m])
            dPi[n, m] = -inv_var * (yds - sds[n, m])


@njit(**INLINE)
def fuse_channels(p, info, model_pi, variance, prior, Pi, dPi, post):
    """Paper 004's update of one image plane (theory §9.2, :meth:`~sensorgym.trackers.fusion.
    tracker.FusionTracker.update`, its gate centred on the prediction: ``λ^э = 0``) from the
    channels' ``Pi``, ``dPi`` (:func:`channel_terms`), the prior ``variance`` and view
    posteriors ``prior (N, M)``: writes the posteriors ``post (N, M)`` and returns the offset
    ``λ̂`` (mrad), its variance, and whether some channel's object posterior beats the
    background's (the MAP detection)."""
    N, M = Pi.shape
    R = p.correlation
    # D_k = R_λ² d_{k−1} + d₀
    D = R * R * variance + p.transition_variance
    total_info, total_dPi = 0.0, 0.0
    closed, detected = False, False
    for n in range(N):
        top = -np.inf
        for m in range(M):
            # g = (1 + D I)^{-1/2} exp{½ D Π′² / (1 + D I)}
            DI = 1.0 + D * info[n, m]
            like = Pi[n, m] - 0.5 * math.log(DI) + 0.5 * D * dPi[n, m] ** 2 / DI
            # (3) P_k(ϑ_m) ∝ exp{…} Σ_μ π(ϑ_m | ϑ_μ) P_{k−1}(ϑ_μ)
            predicted = 0.0
            for u in range(M):
                predicted += prior[n, u] * model_pi[n, u, m]
            post[n, m] = like + np.log(predicted)
            top = max(top, post[n, m])
        norm = 0.0
        for m in range(M):
            post[n, m] = math.exp(post[n, m] - top)
            norm += post[n, m]
        for m in range(M):
            post[n, m] /= norm
            total_info += post[n, m] * info[n, m]
            total_dPi += post[n, m] * dPi[n, m]
        # theory §9.3: the loop stays closed while some channel holds the object
        closed = closed or not 1.0 - post[n, 0] < p.open_threshold
        detected = detected or 1.0 - post[n, 0] > 0.5
    if not closed:
        return 0.0, D, detected
    # (5) d_k = [D_k⁻¹ + Σ_n Σ_m P I]⁻¹;  (4) λ̂_k = λ^э + d_k Σ_n Σ_m P Π′
    d = 1.0 / (1.0 / D + total_info)
    return d * total_dPi, d, detected


# --- paper 001's predictor (theory §8.3–8.6) ---------------------------------------------------


@njit(**INLINE)
def copy_predictor(th, ph, delta, anchor, th2, ph2, delta2, anchor2):
    """A row of the predictor's arrays into the new state's, to be advanced there."""
    for i in range(th.shape[0]):
        th2[i], ph2[i] = th[i], ph[i]
    for i in range(3):
        delta2[i], anchor2[i] = delta[i], anchor[i]


@njit(**INLINE)
def advance_predictor(p, th, ph, count, slope, delta, anchor, origin, az, el, detected, work):
    """Paper 001's predictor one frame on, in place (theory §8.6, :func:`.reference.
    advance_predictor`): the window ``th``, ``ph`` ``(N + 1,)``, ``delta``, ``anchor`` ``(3,)``
    and the scalars ``count``, ``slope`` take the measured level angles ``az``, ``el`` where
    ``detected`` (coasting elsewhere), in the frame turned by ``origin``; then the frame turns
    onto the latest azimuth once it lies over 45° off. Returns ``(count, slope, origin)``.
    ``work (9,)`` is scratch."""
    W = th.shape[0]
    coast, raw, anchor_new = work[:3], work[3:6], work[6:]
    # the measured azimuth in the predictor's frame (wrapped again as ABCPredictor.update
    # wraps its input)
    a = wrap_angle(wrap_angle(az - origin))
    was_ready = count >= W
    count2 = push_window(th, ph, count, delta, anchor, a, el, detected, coast)
    first = detected and count2 == W
    alpha = abc_estimates(p, th, ph, first, slope, delta, anchor, raw, anchor_new)
    update = detected and count2 >= W
    abc_commit(p, update, was_ready and not detected, first, delta, anchor, coast, raw,
               anchor_new)  # fmt: skip
    return recentre(th, alpha if update else slope, delta, anchor, count2, origin)


@njit(**INLINE)
def relock(th, ph, delta, anchor, az, el, work):
    """The coasted track moved onto the measured angles ``az`` (in the predictor's frame),
    ``el`` before they are pushed (theory §13.42, :meth:`~sensorgym.trackers.angles.
    prediction.ABCPredictor.relock`): ``C′ = OC′ (sin θ, cos θ, tan ϕ)`` at the horizontal
    range ``OC′`` of ``C + δ̂``, the window's samples the angles of ``C′ − (N + 1 − i) δ̂``,
    point C ``C′ − δ̂``; unchanged where a value is not finite or a sample at the origin.
    ``work (9,)`` is scratch."""
    W = th.shape[0]
    C = work[:3]
    a = wrap_angle(az)
    # OC′ = |C + δ̂|ₓᵧ;  C′ = OC′ (sin θ, cos θ, tan ϕ)
    rho = math.hypot(anchor[0] + delta[0], anchor[1] + delta[1])
    C[0], C[1], C[2] = rho * math.sin(a), rho * math.cos(a), rho * math.tan(el)
    ok = np.isfinite(rho) and rho > 0.0
    for i in range(3):
        ok = ok and np.isfinite(C[i])
    for i in range(W):
        k = W - i
        x, y, z = C[0] - k * delta[0], C[1] - k * delta[1], C[2] - k * delta[2]
        ok = ok and np.isfinite(x) and np.isfinite(y) and np.isfinite(z)
        ok = ok and (x != 0.0 or y != 0.0 or z != 0.0)
    if not ok:
        return
    for i in range(W):
        k = W - i
        x, y, z = C[0] - k * delta[0], C[1] - k * delta[1], C[2] - k * delta[2]
        th[i], ph[i] = zup_angles(x, y, z)
    for i in range(3):
        anchor[i] = C[i] - delta[i]


@njit(**INLINE)
def push_window(th, ph, count, delta, anchor, az, el, detected, coast):
    """The window's new sample (§8.6): the measurement where ``detected``, else — coasting —
    the angles of ``C + δ̂`` (written to ``coast``), or of the latest sample before the first
    estimate; a track that loses the image before it restarts its warm-up. Returns the new
    count."""
    W = th.shape[0]
    was_ready = count >= W
    for i in range(3):
        coast[i] = anchor[i] + delta[i]
    if was_ready:
        coast_az, coast_el = zup_angles(coast[0], coast[1], coast[2])
    else:
        x, y, z = unit_from_zup(th[W - 1], ph[W - 1])
        coast_az, coast_el = zup_angles(x, y, z)
    if not (detected or was_ready):
        return 0
    for i in range(W - 1):
        th[i], ph[i] = th[i + 1], ph[i + 1]
    th[W - 1] = az if detected else coast_az
    ph[W - 1] = el if detected else coast_el
    return count + 1


@njit(**INLINE)
def wrap_half_turn(angle):
    """A line direction (modulo π) in ``[−π/2, π/2)``: ``½ wrap(2 α)``."""
    return 0.5 * wrap_angle(2.0 * angle)


@njit(**INLINE)
def trajectory_direction(sA, cA, sB, cB, sC, cC):
    """``α = atan(Δ_Y/Δ_X)`` of eq. (6) in its homogeneous form (:func:`~sensorgym.trackers.
    angles.prediction.trajectory_direction`), from the sines and cosines of θ_A, θ_B, θ_C."""
    # T₃·cAcBcC = sA cB cC − 2 cA sB cC + cA cB sC
    T3 = sA * cB * cC - 2.0 * cA * sB * cC + cA * cB * sC
    # (2T₁T₂ + tB T₃)·cAcBcC = 2 sA cB sC − sA sB cC − cA sB sC
    den = 2.0 * sA * cB * sC - sA * sB * cC - cA * sB * sC
    return wrap_half_turn(math.atan2(T3, den))


@njit(**INLINE)
def abc_estimates(p, th, ph, first, slope, delta, anchor, raw, anchor_new):
    """The frame's raw increments ``raw (3,)`` and point C ``anchor_new (3,)`` from the samples
    A, B, C of the window (§8.3–8.5; the previous estimates where a value is not finite), and
    returns the smoothed direction ``α̂``."""
    W = th.shape[0]
    N = W - 1
    th_A, th_B, th_C, ph_A, ph_C = th[0], th[N // 2], th[N], ph[0], ph[N]
    sA, cA, cC = math.sin(th_A), math.cos(th_A), math.cos(th_C)
    alpha_raw = trajectory_direction(sA, cA, math.sin(th_B), math.cos(th_B), math.sin(th_C), cC)
    if first:
        alpha = alpha_raw
    else:
        # α̂_n = α̂_{n−1} + γ (α_n − α̂_{n−1}), the difference taken modulo π        (§8.4)
        alpha = wrap_half_turn(slope + p.predictor_gain * wrap_half_turn(alpha_raw - slope))
    # Y_C^{n+1} = Y_C^n + δ̂_Y^n (first: ρ₀ cos θ_C);  X_C = Y_C tan θ_C              (4), §8.4
    Y_C = p.initial_scale * cC if first else anchor[1] + delta[1]
    X_C = Y_C * math.tan(th_C)
    # θ_P = −α̂;  R = OC′ cos(θ_P − θ_C);  OA′ = R / cos(θ_P − θ_A)                   (§8.5)
    theta_P = -alpha
    OC = math.hypot(X_C, Y_C)
    OA = OC * math.cos(theta_P - th_C) / math.cos(theta_P - th_A)
    # A = OA′ (sin θ_A, cos θ_A);  Z_A = OA′ tan ϕ_A,  Z_C = OC′ tan ϕ_C
    Z_C = OC * math.tan(ph_C)
    raw[0] = (X_C - OA * sA) / N
    raw[1] = (Y_C - OA * cA) / N
    raw[2] = (Z_C - OA * math.tan(ph_A)) / N
    anchor_new[0], anchor_new[1], anchor_new[2] = X_C, Y_C, Z_C
    finite = True
    for i in range(3):
        finite = finite and np.isfinite(raw[i]) and np.isfinite(anchor_new[i])
    if not finite:
        # a degenerate frame keeps the previous estimates (zero velocity at the first)
        for i in range(3):
            raw[i] = 0.0 if first else delta[i]
            anchor_new[i] = anchor[i]
    return alpha


@njit(**INLINE)
def abc_commit(p, update, coasting, first, delta, anchor, coast, raw, anchor_new):
    """The increments and point C after the frame, in place (§8.4, §8.6 step 7): smoothed
    ``δ̂ ← δ̂ + γ (δ − δ̂)`` (the raw value at the first estimate) and the new C where updated;
    ``C ← C + δ̂`` while coasting; kept otherwise."""
    for i in range(3):
        if update:
            delta_i = delta[i]
            delta[i] = raw[i] if first else delta_i + p.predictor_gain * (raw[i] - delta_i)
            anchor[i] = anchor_new[i]
        elif coasting:
            anchor[i] = coast[i]


@njit(**INLINE)
def recentre(th, slope, delta, anchor, count, origin):
    """The predictor's frame turned about ``OZ`` onto its latest azimuth once it lies more than
    45° off ``OY`` (theory §13.20, :func:`~sensorgym.trackers.angles.prediction.recentre`;
    turned by 0 otherwise, which still wraps as the reference does). Returns ``(count,
    slope, origin)``."""
    latest = th[th.shape[0] - 1]
    psi = latest if abs(latest) > math.pi / 4 else 0.0
    c, s = math.cos(psi), math.sin(psi)
    for i in range(th.shape[0]):
        th[i] = wrap_angle(th[i] - psi)
    for v in (delta, anchor):
        # (X′, Y′) = (X cos ψ − Y sin ψ, Y cos ψ + X sin ψ)
        x, y = v[0], v[1]
        v[0], v[1] = x * c - y * s, y * c + x * s
    return count, wrap_half_turn(slope + psi), wrap_angle(origin + psi)


@njit(**INLINE)
def predicted_angles(th, ph, ready, delta, anchor, origin, k, out):
    """The predictor's level angles ``out (2,)`` ``k`` frames after its last frame (§8.6):
    those of ``C + k δ̂``, or of the latest sample before the first estimate."""
    if ready:
        x, y, z = anchor[0] + k * delta[0], anchor[1] + k * delta[1], anchor[2] + k * delta[2]
    else:
        W = th.shape[0]
        x, y, z = unit_from_zup(th[W - 1], ph[W - 1])
    az, el = zup_angles(x, y, z)
    out[0], out[1] = wrap_angle(az + origin), el


# --- the reward (theory §11.8) -----------------------------------------------------------------


@njit(**INLINE)
def los_sigma(p, variance_az, variance_el):
    """``σ_LOS = √(d_α + d_β + 2 σ_s²)`` (rad) from the planes' variances (mrad²)."""
    return math.sqrt((variance_az + variance_el) / (MRAD * MRAD) + 2.0 * (p.sensor_noise**2))


@njit(**INLINE)
def reward(p, sigma, seen):
    """``clip(ln(σ_ref/σ_LOS), −R, R)``, ``−R`` while the target is out of the field of view."""
    R = p.reward_clip
    return clip(math.log(p.sigma_ref / sigma), -R, R) if seen else -R
