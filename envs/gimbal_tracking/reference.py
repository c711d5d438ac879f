"""The readable reset and step of GimbalTracking: numpy over the batch, one stage a function.

The stages run in the order of a frame (theory §8, §9, §11.8): the gimbal drives under the
rate command (:func:`drive_gimbal`); the target flies on (:func:`fly_target`) and the carrier
rolls, pitches and yaws (:func:`carrier_attitude`); occlusions (:func:`schedule_occlusions`) and
each channel's Markov chain of views (:func:`step_views`) decide what can be seen; the target's
place in the field of view (:func:`view_geometry`) decides whether it is in view and how much
contrast the off-axis optics leave; each channel images the tracking gate
(:func:`render_gate`), centred on paper 001's predicted direction or, in search, on the
boresight (:func:`gate_centre`); paper 004's fused tracker measures the target's offset from it
(:func:`fuse_channels`); the predictor takes the fused direction as its
measurement, or coasts through a loss (:func:`advance_predictor`); the reward reads the fused
estimate's angular error bound (:func:`reward`). With several gimbals (theory §11.8.2) the
drives, views, view geometry (with each gimbal's clear sector, :func:`in_sector`), gates and
fused trackers run per gimbal on a gimbal axis after the scenario's, and the track measures
the direction of the gimbal :func:`measuring_gimbal` picks.

This module is the readable numpy spec of the env's reset and step, and the reference its
compiled kernels (:mod:`.kernels`, which :mod:`.simulation` runs) are checked against:
``tests/envs/gimbal_tracking/test_reference.py`` steps both from the same states with the same
draws over whole episodes. :func:`reset` and :func:`step` take the simulation's arguments and
make its draws in its order; :func:`observe` and :func:`info` are the observation and the
diagnostics the compiled ones are checked against. The trackers here are the package's own, called and not copied:
:class:`~sensorgym.trackers.fusion.tracker.FusionTracker` (paper 004, theory §9.2) and
:class:`~sensorgym.trackers.angles.prediction.ABCPredictor` (paper 001, theory §8.3–8.6).

Frames (theory §2.2, §8.2): the *level* frame is paper 001's ``OXYZ`` — ``OXY`` horizontal,
``OY`` the carrier's mean heading, ``OZ`` up; azimuth θ from ``OY`` towards ``OX``, elevation ϕ
from the horizontal. The *body* frame turns with the carrier: body to level is
``R = R_z(ψ) R_x(p) R_y(r)`` (yaw ψ about ``OZ``, pitch p about ``OX``, roll r about ``OY``,
each right-handed). The gimbal's azimuth α and elevation β are body-frame angles of its
boresight.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sensorgym.envs.shells.contract import clip_observation
from sensorgym.envs.worlds.imaging import box_profile
from sensorgym.trackers.angles.prediction import ABCPredictor, ABCState, recentre
from sensorgym.trackers.fusion.tracker import FusionState
from sensorgym.trackers.geometry import unit_from_zup_angles, wrap_angle, zup_angles_from_unit

if TYPE_CHECKING:
    from sensorgym.envs.gimbal_tracking.simulation import GimbalParams, GimbalState

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
IntArray = NDArray[np.int64]
#: a lock-on: ``(params, position, velocity, rng) -> (predictor, origin)`` (:func:`lock_on`)
LockOn = Callable[..., tuple[ABCState, FloatArray]]

#: the fused tracker works in milliradians (its templates, variances and prior)
MRAD = 1000.0


# -- draws ----------------------------------------------------------------------------------


def draw_integers(rng: np.random.Generator, bounds: tuple[int, int], size: object) -> IntArray:
    """Integers uniform in ``[low, high]`` (inclusive) from one uniform draw each (the
    episode streams' row generators draw uniforms and normals only)."""
    low, high = bounds
    u = rng.uniform(0.0, 1.0, size)
    return np.minimum(low + np.floor(u * (high - low + 1)), high).astype(np.int64)


def draw_signs(rng: np.random.Generator, size: object) -> FloatArray:
    """``±1`` with equal probability, from one uniform draw each."""
    return np.where(rng.uniform(0.0, 1.0, size) < 0.5, -1.0, 1.0)


# -- geometry -------------------------------------------------------------------------------


def body_to_level(attitude: FloatArray) -> FloatArray:
    """Rotations ``(..., 3, 3)`` from body to level frame for ``attitude (..., 3)`` = (roll r,
    pitch p, yaw ψ), rad: ``R = R_z(ψ) R_x(p) R_y(r)``."""
    r, p, y = attitude[..., 0], attitude[..., 1], attitude[..., 2]
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    one, zero = np.ones_like(r), np.zeros_like(r)
    Ry = np.stack([cr, zero, sr, zero, one, zero, -sr, zero, cr], -1).reshape(*r.shape, 3, 3)
    Rx = np.stack([one, zero, zero, zero, cp, -sp, zero, sp, cp], -1).reshape(*r.shape, 3, 3)
    Rz = np.stack([cy, -sy, zero, sy, cy, zero, zero, zero, one], -1).reshape(*r.shape, 3, 3)
    return Rz @ Rx @ Ry


def body_angles(direction: FloatArray, attitude: FloatArray) -> FloatArray:
    """Body-frame azimuth and elevation ``(..., 2)`` of level-frame ``direction (..., 3)`` seen
    from a carrier at ``attitude (..., 3)``: ``u_B = Rᵀ u_L``."""
    u_body = np.einsum("...ji,...j->...i", body_to_level(attitude), direction)
    az, el = zup_angles_from_unit(u_body)
    return np.stack([az, el], -1)


def level_direction(angles: FloatArray, attitude: FloatArray) -> FloatArray:
    """Level-frame unit vector ``(..., 3)`` of body-frame ``angles (..., 2)``: ``u_L = R u_B``."""
    u_body = unit_from_zup_angles(angles[..., 0], angles[..., 1])
    return np.einsum("...ij,...j->...i", body_to_level(attitude), u_body)


def tangent_offsets(direction: FloatArray, angles: FloatArray) -> FloatArray:
    """Offsets ``(..., 2)`` (rad) of ``direction (..., 3)`` from the axis at ``angles (..., 2)``
    (azimuth, elevation) in the same frame, as an image plane sees them:
    ``(atan2(u·e_α, u·b), atan2(u·e_β, u·b))`` with ``b`` the axis and ``e_α``, ``e_β`` the unit
    directions of growing azimuth and elevation at it."""
    a, e = angles[..., 0], angles[..., 1]
    b = unit_from_zup_angles(a, e)
    e_az = np.stack([np.cos(a), -np.sin(a), np.zeros_like(a)], -1)
    e_el = np.stack([-np.sin(e) * np.sin(a), -np.sin(e) * np.cos(a), np.cos(e)], -1)
    along = np.sum(direction * b, -1)
    return np.stack(
        [
            np.arctan2(np.sum(direction * e_az, -1), along),
            np.arctan2(np.sum(direction * e_el, -1), along),
        ],
        -1,
    )


def from_tangent_offsets(angles: FloatArray, offsets: FloatArray) -> FloatArray:
    """The inverse of :func:`tangent_offsets`: the angles ``(..., 2)`` of the direction seen at
    ``offsets (..., 2)`` (rad) from the axis at ``angles (..., 2)``."""
    a, e = angles[..., 0], angles[..., 1]
    b = unit_from_zup_angles(a, e)
    e_az = np.stack([np.cos(a), -np.sin(a), np.zeros_like(a)], -1)
    e_el = np.stack([-np.sin(e) * np.sin(a), -np.sin(e) * np.cos(a), np.cos(e)], -1)
    u = b + np.tan(offsets[..., :1]) * e_az + np.tan(offsets[..., 1:]) * e_el
    az, el = zup_angles_from_unit(u)
    return np.stack([az, el], -1)


# -- world ----------------------------------------------------------------------------------


def carrier_attitude(
    params: GimbalParams, phases: FloatArray, frame: ArrayLike
) -> tuple[FloatArray, FloatArray]:
    """Attitude ``(B, 3)`` (roll, pitch, yaw, rad) and its rates ``(B, 3)`` (rad/s) at
    ``frame (B,)``: per axis ``a(t) = Σ_i A_i sin(2π t/T_i + φ_i)`` with the random phases
    ``phases (B, K)`` (:attr:`~.simulation.GimbalParams.motion_terms`)."""
    amp, omega, axis = params.motion_terms
    t = np.asarray(frame, dtype=np.float64)[:, None] * params.frame_period
    arg = omega * t + phases  # (B, K)
    # a = Σ A sin(ωt + φ),  ȧ = Σ A ω cos(ωt + φ), summed per axis
    value, rate = np.zeros((t.shape[0], 3)), np.zeros((t.shape[0], 3))
    np.add.at(value.T, axis, (amp * np.sin(arg)).T)
    np.add.at(rate.T, axis, (amp * omega * np.cos(arg)).T)
    return value, rate


def drive_gimbal(
    params: GimbalParams, angles: FloatArray, rates: FloatArray, action: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """One frame of the rate- and acceleration-limited drives of every gimbal (``(..., 2)``:
    azimuth, elevation): the commanded rate ``ω_c = a · max_rate`` is approached by at most
    ``max_acceleration · T`` per frame and the angles move by the new rate over the frame;
    elevation stops at its limits (rate zeroed)."""
    T = params.frame_period
    command = np.clip(action, -1.0, 1.0) * params.max_rate
    step = params.max_acceleration * T
    # ω_k = ω_{k−1} + clip(ω_c − ω_{k−1}, −A T, A T)
    new_rates = rates + np.clip(command - rates, -step, step)
    new_angles = angles + new_rates * T
    low, high = params.elevation_limits
    stopped = (new_angles[..., 1] < low) | (new_angles[..., 1] > high)
    new_angles[..., 0] = wrap_angle(new_angles[..., 0])
    new_angles[..., 1] = np.clip(new_angles[..., 1], low, high)
    new_rates[..., 1] = np.where(stopped, 0.0, new_rates[..., 1])
    return new_angles, new_rates


def fly_target(
    params: GimbalParams,
    position: FloatArray,
    velocity: FloatArray,
    turn_rate: FloatArray,
    turning: BoolArray,
) -> tuple[FloatArray, FloatArray]:
    """One frame of the target: uniform rectilinear relative to the carrier, except while
    ``turning``, when its horizontal velocity turns at ``turn_rate`` (rad/s, a level turn)."""
    T = params.frame_period
    w = np.where(turning, turn_rate, 0.0) * T
    c, s = np.cos(w), np.sin(w)
    vx, vy = velocity[:, 0], velocity[:, 1]
    # v ← R_z(ω T) v  (horizontal components), then p ← p + v T
    new_velocity = np.stack([c * vx - s * vy, s * vx + c * vy, velocity[:, 2]], -1)
    return position + new_velocity * T, new_velocity


def schedule_occlusions(
    params: GimbalParams,
    frame: IntArray,
    start: IntArray,
    end: IntArray,
    rng: np.random.Generator,
) -> tuple[IntArray, IntArray, BoolArray]:
    """The occlusion interval ``[start, end)`` of each scenario after ``frame``, renewed once
    it has passed (the next onset a uniform gap after its end, a uniform length), and whether
    ``frame`` is occluded. Draws the gaps and lengths of every scenario, used or not."""
    gap = draw_integers(rng, params.occlusion_gap, frame.shape)
    length = draw_integers(rng, params.occlusion_length, frame.shape)
    renew = frame >= end
    start = np.where(renew, end + gap, start)
    end = np.where(renew, start + length, end)
    return start, end, (frame >= start) & (frame < end)


def step_views(params: GimbalParams, views: IntArray, rng: np.random.Generator) -> IntArray:
    """Each gimbal's channels' views ``(B, G, N)`` after one step of their Markov chains
    ``π^{(n)}`` (theory §9.1; view 0 is the background: the object does not stand out in that
    band); one uniform each, in the order of the array (scenario, gimbal, channel)."""
    pi = params.view_transition  # (N, M, M)
    rows = pi[np.arange(views.shape[-1]), views]  # (B, G, N, M)
    u = rng.uniform(size=views.shape)[..., None]
    return np.minimum(np.sum(np.cumsum(rows, -1) < u, -1), rows.shape[-1] - 1)


def in_sector(params: GimbalParams, azimuth: FloatArray) -> BoolArray:
    """Whether body azimuths ``azimuth (..., G)`` lie in each gimbal's clear sector
    (:attr:`~.simulation.GimbalParams.sectors`: ``(a − low) mod 2π <= width``)."""
    low, width = params.sectors[:, 0], params.sectors[:, 1]
    return np.mod(azimuth - low, 2.0 * np.pi) <= width


def nearest_in_sector(params: GimbalParams, azimuth: FloatArray) -> FloatArray:
    """Body azimuths ``azimuth (..., G)`` moved into each gimbal's clear sector: unchanged
    inside it, else the nearer of its edges (where a gimbal waits for the hand-over)."""
    low, width = params.sectors[:, 0], params.sectors[:, 1]
    past = np.mod(azimuth - low, 2.0 * np.pi)  # counter-clockwise from low, [0, 2π)
    # outside: past the high edge by past − width, short of the low edge by 2π − past
    edge = np.where(past - width <= 2.0 * np.pi - past, low + width, low)
    return np.where(past <= width, azimuth, wrap_angle(edge))


def view_geometry(
    params: GimbalParams, target: FloatArray, attitude: FloatArray, gimbal: FloatArray
) -> tuple[FloatArray, BoolArray, FloatArray]:
    """The target's offsets ``(B, G, 2)`` from each gimbal's boresight ``gimbal (B, G, 2)`` in
    its image (rad), whether it is in that gimbal's view — in its square field of view, in
    front, and in its clear sector (its body azimuth, :func:`in_sector`) — and the optics'
    contrast factor ``1 − v (ρ/h)²`` (``ρ`` the radial offset, ``h`` half the field of view,
    ``v`` the vignetting, floored at 0)."""
    los = target / np.linalg.norm(target, axis=-1, keepdims=True)
    u_body = np.einsum("bji,bj->bi", body_to_level(attitude), los)[:, None, :]
    offsets = tangent_offsets(u_body, gimbal)
    h = params.half_field
    front = np.sum(u_body * unit_from_zup_angles(gimbal[..., 0], gimbal[..., 1]), -1) > 0.0
    clear = in_sector(params, np.arctan2(u_body[..., 0], u_body[..., 1]))
    in_view = front & np.all(np.abs(offsets) <= h, -1) & clear
    rho2 = np.sum(offsets**2, -1) / h**2
    return offsets, in_view, np.clip(1.0 - params.vignetting * rho2, 0.0, 1.0)


# -- the tracker ----------------------------------------------------------------------------


def gate_centre(
    params: GimbalParams, state: GimbalState, gimbal: FloatArray, attitude: FloatArray
) -> FloatArray:
    """Level angles ``(B, G, 2)`` each gimbal's tracking gate is centred on this frame: the
    shared track's prediction, or — once the target has gone undetected for ``search_after``
    frames — the gimbal's own boresight (its angles ``gimbal (B, G, 2)`` seen from
    ``attitude (B, 3)``, both known to the tracker): a coasted prediction that has missed the
    target no longer finds it, and re-acquisition takes pointing a field of view's centre at
    it."""
    searching = state.since_detection >= params.search_after
    boresight = level_direction(gimbal, attitude[:, None, :])
    az, el = zup_angles_from_unit(boresight)
    return np.where(searching[:, None, None], np.stack([az, el], -1), state.predicted[:, None])


def render_gate(
    params: GimbalParams,
    residual: FloatArray,
    views: IntArray,
    visible: BoolArray,
    gain: FloatArray,
    rng: np.random.Generator,
) -> FloatArray:
    """Images ``(B, G, 2, N, J)`` of each gimbal's tracking gate in each channel and plane
    (theory §9.1 eq. (2)): the view's blurred rectangle shifted by the target's offset
    ``residual (B, G, 2)`` (mrad) from the gate centre, times the optics' ``gain (B, G)``,
    where ``visible (B, G, N)``; plus white pixel noise ``σ_n`` (drawn in the array's order)."""
    x = params.gate_centres_mrad - residual[..., None]  # (B, G, 2, J)
    profile, _ = box_profile(x, params.target_size * MRAD, params.blur * MRAD)
    contrast = params.view_contrast[np.arange(views.shape[-1]), views]  # (B, G, N)
    contrast = np.where(visible, contrast * gain[..., None], 0.0)
    noise = rng.standard_normal((*residual.shape, views.shape[-1], x.shape[-1]))
    sigma = np.asarray(params.channel_noise)[:, None]
    return contrast[..., None, :, None] * profile[..., :, None, :] + sigma * noise


def fuse_channels(params: GimbalParams, state: FusionState, images: FloatArray) -> FusionState:
    """Paper 004's update (theory §9.2) of both planes of every gimbal, ``images
    (B, G, 2, N, J)``: the tracker runs on ``2BG`` rows (each scenario's gimbals' azimuth and
    elevation planes), its gate centred on the prediction, so its extrapolated offset is 0."""
    return params.fusion_tracker.update(state, images.reshape(-1, *images.shape[-2:]))


def advance_predictor(
    params: GimbalParams,
    predictor: ABCState,
    origin: FloatArray,
    measured: FloatArray,
    detected: BoolArray,
    reacquired: BoolArray | None = None,
) -> tuple[ABCState, FloatArray]:
    """Paper 001's predictor (theory §8.6) one frame on: the measured level angles ``(B, 2)``
    where ``detected``, coasting along its conditional trajectory elsewhere (step 7). Where
    ``reacquired`` (detected after a loss) and :attr:`~.simulation.GimbalParams.relock`, the
    coasted track is first moved onto the measurement (theory §13.42).

    It runs in the level frame turned about ``OZ`` by ``origin (B,)`` (its ``OY`` there); once
    its latest azimuth lies more than 45° off that ``OY``, the frame is turned onto it
    (:func:`~sensorgym.trackers.angles.prediction.recentre`): the predictor's formulas are
    singular at ±90° (theory §13.20). Returns the predictor and its frame's origin."""
    az = wrap_angle(measured[:, 0] - origin)
    if params.relock and reacquired is not None:
        predictor = params.predictor.relock(predictor, az, measured[:, 1], reacquired)
    state = params.predictor.update(predictor, az, measured[:, 1], detected)
    latest = state.azimuth_window[:, -1]
    turn = np.where(np.abs(latest) > np.pi / 4, latest, 0.0)
    return recentre(state, turn), wrap_angle(origin + turn)


def predicted_angles(
    predictor: ABCPredictor, state: ABCState, origin: FloatArray, k: float
) -> FloatArray:
    """The predictor's level angles ``(B, 2)`` ``k`` frames after its last frame."""
    az, el = predictor.predict(state, k)
    return np.stack([wrap_angle(az + origin), el], -1)


def los_sigma(params: GimbalParams, variance: FloatArray) -> FloatArray:
    """``σ_LOS`` (rad): the angular error bound of the fused direction,
    ``√(d_α + d_β + 2 σ_s²)`` with ``d`` the fused tracker's posterior variances ``(..., 2)``
    (mrad²) and ``σ_s`` the angle sensors' noise."""
    return np.sqrt(np.sum(variance, -1) / MRAD**2 + 2.0 * params.sensor_noise**2)


def gimbal_detections(view_posterior: FloatArray) -> BoolArray:
    """Each gimbal's MAP detection ``(B, G)`` from its view posteriors ``(B, G, 2, N, M)``
    (theory §9.2): some channel's object posterior beats the background's, in both planes."""
    return np.all(np.any(1.0 - view_posterior[..., 0] > 0.5, -1), -1)


def measuring_gimbal(variance: FloatArray, detected: BoolArray) -> IntArray:
    """The gimbal ``(B,)`` whose fused direction is the track's measurement: of the gimbals
    that detected the target (``detected (B, G)``), the one of least posterior variance
    ``d_α + d_β`` (``variance (B, G, 2)``); of all of them where none did (its ``σ_LOS`` is
    the track's); the first of equals."""
    total = variance.sum(-1)
    key = np.where(detected.any(-1, keepdims=True) & ~detected, np.inf, total)
    return np.argmin(key, -1)


def reward(params: GimbalParams, sigma: FloatArray, in_view: BoolArray) -> FloatArray:
    """``clip(ln(σ_ref/σ_LOS), −R, R)``, and ``−R`` while the target is out of the field of view
    (theory §11.8)."""
    R = params.reward_clip
    return np.where(in_view, np.clip(np.log(params.sigma_ref / sigma), -R, R), -R)


# -- reset and step -------------------------------------------------------------------------


def lock_on(
    params: GimbalParams, position: FloatArray, velocity: FloatArray, rng: np.random.Generator
) -> tuple[ABCState, FloatArray]:
    """The predictor after the ``N + 1`` frames of lock-on before the episode (frames ``−N … 0``
    of the straight track back from ``position`` at ``velocity``): its window full, so that it
    predicts from the first step. Measured angles carry the sensors' noise. Its frame's ``OY``
    starts at the first measured azimuth (:func:`advance_predictor`). Returns the predictor and
    that origin."""
    N, T = params.predictor_window, params.frame_period
    frames = np.arange(-N, 1, dtype=np.float64)
    past = position[:, None, :] + frames[None, :, None] * T * velocity[:, None, :]
    az, el = zup_angles_from_unit(past)
    noise = rng.standard_normal((position.shape[0], N + 1, 2)) * params.sensor_noise
    state = params.predictor.initial_state(position.shape[0])
    origin = wrap_angle(az[:, 0] + noise[:, 0, 0])
    for j in range(N + 1):
        measured = np.stack([az[:, j] + noise[:, j, 0], el[:, j] + noise[:, j, 1]], -1)
        state, origin = advance_predictor(params, state, origin, measured, np.ones(len(az), bool))
    return state, origin


def start(
    params: GimbalParams,
    target_position: FloatArray,
    target_velocity: FloatArray,
    rng: np.random.Generator,
    lock: LockOn | None = None,
) -> GimbalState:
    """Scenarios with the target at ``target_position (B, 3)`` (m, level frame) flying at
    ``target_velocity (B, 3)`` (m/s) at frame 0, after lock-on: the rest is drawn, in this
    order — its turn (rate, sign, onset, length), the carrier's phases, the first occlusion,
    the channels' views ``(B, G, N)``, the gimbals' cue errors ``(B, G, 2)``, the lock-on's
    sensor noise. ``lock`` replaces :func:`lock_on` (same signature and draws: the
    simulation's compiled one). Each gimbal points at the target within its cue error where
    its clear sector holds the target, else at the target's elevation and the nearer edge of
    its sector (:func:`nearest_in_sector`); all at rest."""
    from sensorgym.envs.gimbal_tracking.simulation import GimbalState

    B, G = target_position.shape[0], params.n_gimbals
    rate = rng.uniform(*params.turn_rate, B) * draw_signs(rng, B)
    onset = draw_integers(rng, params.turn_start, B)
    length = draw_integers(rng, params.turn_length, B)
    phases = rng.uniform(-np.pi, np.pi, (B, params.motion_terms[0].shape[0]))
    gap = draw_integers(rng, params.occlusion_gap, B)
    occ = draw_integers(rng, params.occlusion_length, B)
    views = draw_integers(rng, (1, params.view_contrast.shape[1] - 1), (B, G, params.n_channels))
    cue = rng.standard_normal((B, G, 2)) * params.cue_error
    lock = lock_on if lock is None else lock
    predictor, origin = lock(params, target_position, target_velocity, rng)

    frame = np.zeros(B, dtype=np.int64)
    attitude, _ = carrier_attitude(params, phases, frame)
    los = target_position / np.linalg.norm(target_position, axis=-1, keepdims=True)
    aim = np.repeat(body_angles(los, attitude)[:, None, :], G, 1)
    aim[..., 0] = nearest_in_sector(params, aim[..., 0])
    gimbal = aim + cue
    gimbal[..., 1] = np.clip(gimbal[..., 1], *params.elevation_limits)
    _, seen, _ = view_geometry(params, target_position, attitude, gimbal)
    in_view = seen.any(-1)
    fusion = params.fusion_tracker.initial_state(
        2 * B * G, variance=(params.pixel_pitch * MRAD) ** 2
    )
    estimate = predicted_angles(params.predictor, predictor, origin, 0.0)
    variance = fusion.variance.reshape(B, G, 2)
    return GimbalState(
        frame=frame,
        target_position=target_position.copy(),
        target_velocity=target_velocity.copy(),
        turn_rate=rate,
        turn_start=onset,
        turn_end=onset + length,
        carrier_phase=phases,
        gimbal_angles=gimbal,
        gimbal_rates=np.zeros((B, G, 2)),
        views=views,
        occlusion_start=gap,
        occlusion_end=gap + occ,
        out_of_view=np.where(in_view, 0, 1),
        since_detection=np.zeros(B, dtype=np.int64),
        fusion_variance=variance,
        view_posterior=fusion.view_posterior.reshape(B, G, 2, *fusion.view_posterior.shape[1:]),
        predictor=predictor,
        predictor_origin=origin,
        reference=np.repeat(estimate[:, None, :], G, 1),
        estimate=estimate,
        predicted=predicted_angles(params.predictor, predictor, origin, 1.0),
        detected=np.ones(B, dtype=bool),
        in_view=in_view,
        occluded=np.zeros(B, dtype=bool),
        visible=np.ones((B, G, params.n_channels), dtype=bool) & seen[..., None],
        sigma_los=los_sigma(params, variance[:, 0]),
    )


def reset(
    params: GimbalParams, rng: np.random.Generator, batch: int, like: GimbalState | None = None
) -> GimbalState:
    """``batch`` fresh scenarios (:func:`.simulation.reset`): the target drawn
    (:func:`~.simulation.draw_target`), then :func:`start` with the numpy lock-on."""
    from sensorgym.envs.gimbal_tracking.simulation import draw_target

    p, v = draw_target(params, rng, batch)
    return start(params, p, v, rng)


def step(
    params: GimbalParams, state: GimbalState, action: FloatArray, rng: np.random.Generator
) -> tuple[GimbalState, FloatArray, BoolArray]:
    """One frame of every scenario under ``action (B, G, 2)`` (already checked finite).

    Every gimbal images its gate and runs its fused tracker; the track (one paper 001
    predictor) takes the fused direction of the detecting gimbal of least posterior variance
    (:func:`measuring_gimbal`), whose ``σ_LOS`` is the reward's; the target is in view while
    it is in some gimbal's (field of view and clear sector)."""
    from sensorgym.envs.gimbal_tracking.simulation import GimbalState

    B, G = state.frame.shape[0], params.n_gimbals
    frame = state.frame + 1
    gimbal, rates = drive_gimbal(params, state.gimbal_angles, state.gimbal_rates, action)
    turning = (frame > state.turn_start) & (frame <= state.turn_end)
    position, velocity = fly_target(
        params, state.target_position, state.target_velocity, state.turn_rate, turning
    )
    attitude, _ = carrier_attitude(params, state.carrier_phase, frame)
    occ_start, occ_end, occluded = schedule_occlusions(
        params, frame, state.occlusion_start, state.occlusion_end, rng
    )
    views = step_views(params, state.views, rng)
    _, seen, gain = view_geometry(params, position, attitude, gimbal)  # (B, G)
    in_view = seen.any(-1)
    visible = (views > 0) & (seen & ~occluded[:, None])[..., None]

    reference = gate_centre(params, state, gimbal, attitude)
    # the target's offset from each gate's centre, in the level frame's image plane (the
    # images derotated with the known attitude)
    los = position / np.linalg.norm(position, axis=-1, keepdims=True)
    residual = tangent_offsets(los[:, None, :], reference) * MRAD
    images = render_gate(params, residual, views, visible, gain, rng)
    rows = 2 * B * G
    prior = FusionState(
        estimate=np.zeros(rows),
        variance=state.fusion_variance.reshape(rows),
        view_posterior=state.view_posterior.reshape(rows, *state.view_posterior.shape[3:]),
        loop_open=np.zeros(rows, dtype=bool),
    )
    fused = fuse_channels(params, prior, images)
    posterior = fused.view_posterior.reshape(B, G, 2, *fused.view_posterior.shape[1:])
    variance = fused.variance.reshape(B, G, 2)
    # each gimbal's MAP decision (theory §9.2); the track measures the direction of the
    # detecting gimbal of least variance, and detects where some gimbal does
    seen_by = gimbal_detections(posterior)
    best = measuring_gimbal(variance, seen_by)
    detected = seen_by.any(-1)
    rows_b = np.arange(B)
    offsets = fused.estimate.reshape(B, G, 2)[rows_b, best] / MRAD
    measured = from_tangent_offsets(reference[rows_b, best], offsets)
    measured = measured + rng.standard_normal((B, 2)) * params.sensor_noise
    predictor, origin = advance_predictor(
        params,
        state.predictor,
        state.predictor_origin,
        measured,
        detected,
        reacquired=detected & (state.since_detection > 0),
    )

    sigma = los_sigma(params, variance[rows_b, best])
    out_of_view = np.where(in_view, 0, state.out_of_view + 1)
    new = GimbalState(
        frame=frame,
        target_position=position,
        target_velocity=velocity,
        turn_rate=state.turn_rate,
        turn_start=state.turn_start,
        turn_end=state.turn_end,
        carrier_phase=state.carrier_phase,
        gimbal_angles=gimbal,
        gimbal_rates=rates,
        views=views,
        occlusion_start=occ_start,
        occlusion_end=occ_end,
        out_of_view=out_of_view,
        since_detection=np.where(detected, 0, state.since_detection + 1),
        fusion_variance=variance,
        view_posterior=posterior,
        predictor=predictor,
        predictor_origin=origin,
        reference=reference,
        estimate=predicted_angles(params.predictor, predictor, origin, 0.0),
        predicted=predicted_angles(params.predictor, predictor, origin, 1.0),
        detected=detected,
        in_view=in_view,
        occluded=occluded,
        visible=visible,
        sigma_los=sigma,
    )
    terminated = out_of_view > params.reacquire_limit
    return new, reward(params, sigma, in_view), terminated


# -- what the agent sees, and the diagnostics -----------------------------------------------


def observe_agents(params: GimbalParams, state: GimbalState) -> NDArray[np.float32]:
    """Each gimbal's observation ``(B, G, agent_obs_dim)`` float32 (the table of
    :func:`.simulation.observe`): its drives, the carrier's attitude and rates, the body
    offsets of the track's estimate and prediction from its boresight and their level angles,
    ``ln(σ_LOS/σ_ref)``, its channels' object probabilities, the track's detection and the
    frames since it; for ``G > 1`` also whether its clear sector holds the prediction, the
    sector's edges, its own detection and its own ``ln(σ/σ_ref)``."""
    from sensorgym.envs.gimbal_tracking.simulation import ATTITUDE_SCALE

    B, G = state.frame.shape[0], params.n_gimbals
    attitude, rates = carrier_attitude(params, state.carrier_phase, state.frame)
    g = state.gimbal_angles  # (B, G, 2)
    h = params.half_field
    scale = np.array([np.pi, np.pi / 2])

    def body(angles: FloatArray) -> FloatArray:
        return body_angles(unit_from_zup_angles(angles[:, 0], angles[:, 1]), attitude)[:, None]

    def offset(angles: FloatArray) -> FloatArray:
        d = body(angles) - g
        d[..., 0] = wrap_angle(d[..., 0])
        return d / h

    def shared(x: FloatArray) -> FloatArray:
        return np.broadcast_to(x[:, None, :], (B, G, x.shape[-1]))

    probability = 1.0 - state.view_posterior[..., 0]  # (B, G, 2, N)
    blocks = [
        g / scale,
        state.gimbal_rates / params.max_rate,
        shared(attitude / ATTITUDE_SCALE),
        shared(rates / ATTITUDE_SCALE),
        offset(state.estimate),
        offset(state.predicted),
        shared(state.estimate / scale),
        shared(state.predicted / scale),
        shared(np.log(state.sigma_los / params.sigma_ref)[:, None]),
        probability.mean(2),
        shared(state.detected[:, None].astype(np.float64)),
        shared((state.since_detection / (params.reacquire_limit + 1))[:, None]),
    ]
    if G > 1:
        low, width = params.sectors[:, 0], params.sectors[:, 1]
        clear = in_sector(params, body(state.predicted)[..., 0])
        own = los_sigma(params, state.fusion_variance)
        blocks += [
            clear[..., None].astype(np.float64),
            np.broadcast_to(np.stack([low, low + width], -1) / np.pi, (B, G, 2)),
            gimbal_detections(state.view_posterior)[..., None].astype(np.float64),
            np.log(own / params.sigma_ref)[..., None],
        ]
    return clip_observation(np.concatenate(blocks, -1))


def observe(params: GimbalParams, state: GimbalState) -> NDArray[np.float32]:
    """The joint observation ``(B, obs_dim)``: the gimbals' observations
    (:func:`observe_agents`) one after another."""
    obs = observe_agents(params, state)
    return obs.reshape(obs.shape[0], -1)


def info(params: GimbalParams, state: GimbalState) -> dict[str, FloatArray]:
    """The diagnostics of :func:`.simulation.info`."""
    los = state.target_position / np.linalg.norm(state.target_position, axis=-1, keepdims=True)
    est = unit_from_zup_angles(state.estimate[:, 0], state.estimate[:, 1])
    attitude, _ = carrier_attitude(params, state.carrier_phase, state.frame)
    boresight = level_direction(state.gimbal_angles, attitude[:, None, :])  # (B, G, 3)
    truth = np.stack(zup_angles_from_unit(los), -1)

    def angle(u: FloatArray, w: FloatArray) -> FloatArray:
        return np.arctan2(np.linalg.norm(np.cross(u, w), axis=-1), np.sum(u * w, -1))

    # the pointing error of the gimbals whose clear sector holds the target (of all if none)
    pointing = angle(boresight, los[:, None, :])
    clear = in_sector(params, body_angles(los, attitude)[:, None, 0])
    clear = clear | ~clear.any(-1, keepdims=True)
    return {
        "los_error": angle(est, los),
        "pointing_error": np.where(clear, pointing, np.inf).min(-1),
        "estimate_error_azimuth": wrap_angle(state.estimate[:, 0] - truth[:, 0]),
        "estimate_error_elevation": state.estimate[:, 1] - truth[:, 1],
        "sigma_los": state.sigma_los,
        "in_view": state.in_view.astype(np.float64),
        "occluded": state.occluded.astype(np.float64),
        "detected": state.detected.astype(np.float64),
        "visible_channels": state.visible.sum((-2, -1)).astype(np.float64),
        "measuring_gimbal": measuring_gimbal(
            state.fusion_variance, gimbal_detections(state.view_posterior)
        ).astype(np.float64),
    }
