"""The compiled step of the scanning-receiver environments: one loop over the scenarios.

:func:`step_rows` runs one scan period of scenarios ``lo..hi`` through the stages of
:func:`.reference.step`, in its order and under its names (theory §3, §5.2–5.3, §6), each a
marked block of its row loop calling the stage functions:

1.–2. the sectors and the scan — each receiver's sector and noise (:func:`sense`:
   :func:`sector_of`, :func:`sector_sigma`), the fixes of the drones present
   (:func:`scan_drones` on their :func:`apparent_motion`; :func:`raster_fix`, the pixel-visit
   rule of theory §6.3) and the false detections (:func:`false_detections`);
3. the tracker — the candidates (:mod:`.candidate_kernels`: ``triple_pregates``,
   ``enumerate_candidates``, the closed-form solve, ``screen_candidates``), then the
   association (:mod:`.association_kernels`: ``continuation_costs``, ``continue_confirmed``,
   ``grow_children``, ``coast``, ``open_births``);
4. the reward at the period end (:func:`truth_distances`, :func:`nearest_pairs`,
   :func:`score_period`); 5. the drones fly on (:func:`fly_on`);
6. what the new state shows (:func:`observation`; :func:`observe_kernel` for a state built by
   hand).

Out of place: the state before the period is read, the new one written to fresh arrays. Each
formula is a primitive of the module that owns it — :mod:`sensorgym.trackers.geometry_kernels`
(look-at rotation, relative poses, angular noise), :mod:`sensorgym.trackers.stereo.conjugation_kernels`
(the ``n = 2`` pair and the ``n = 3`` velocity-aware closed forms, ``σ_e² (AᵀA)⁻¹``) and
:mod:`sensorgym.trackers.stereo.kernels` (the clipped log-ratio reward).

The settings come as one record of dtype :data:`SETTINGS`, read by field name
(:attr:`.simulation.ScanningParams.kernel_settings`), the receivers' geometry as the tuple
:data:`Geometry` (:attr:`.simulation.ScanningParams.kernel_geometry`), a state as tuples of its
arrays, and the scratch from :func:`workspace`. The step takes the tuples apart once per call
and calls the stages on the row path with plain arrays: every array a stage receives is
reference-counted at each call, which a row of a couple of microseconds feels. Random draws
stay with numpy's Generator (drawn before the kernels, in a fixed order).
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit
from numba.extending import register_jitable

from sensorgym.envs.shells.contract import OBS_CLIP
from sensorgym.envs.shells.uncounted import uncounted
from sensorgym.envs.stereo_scanning.association_kernels import (
    ALGORITHMIC,
    ALTERNATIVE,
    CONFIRMED,
    EMPTY,
    I_STATUS,
    PROPOSED,
    T_SIG,
    T_TIME,
    TENTATIVE,
    algorithmic_costs,
    clear_taken,
    coast,
    continuation_costs,
    continue_confirmed,
    grow_children,
    open_births,
    predicted_position,
    predicted_sigma,
)
from sensorgym.envs.stereo_scanning.candidate_kernels import (
    GATE_FLOOR,
    GATE_SLACK,
    JIT,
    K_COLUMNS,
    enumerate_candidates,
    local,
    screen_candidates,
    sector_cone,
    triple_pregates,
    world,
)
from sensorgym.envs.worlds.scanning_kernels import in_sector, raster_cell, raster_time
from sensorgym.trackers.geometry_kernels import (
    ATAN2_NEAR_ERROR,
    atan2_near,
    norm3,
    perturbed_direction3,
    unit_from_angles3,
)
from sensorgym.trackers.stereo.conjugation_kernels import (
    pair_kernel,
    triple_velocity_kernel,
    velocity_work,
)
from sensorgym.trackers.stereo.kernels import clip, log_ratio_reward

__all__ = [
    "ALGORITHMIC", "ALTERNATIVE", "CONFIRMED", "EMPTY", "GATE_FLOOR", "GATE_SLACK", "PROPOSED",
    "SETTINGS", "TENTATIVE", "Geometry", "observe_kernel", "sector_of", "sector_sigma",
    "step_rows", "workspace",
]  # fmt: skip

_JIT = JIT
_INLINE = {**JIT, "inline": "always"}

#: The scalar settings the kernels read, one record per params
#: (:attr:`.simulation.ScanningParams.kernel_settings`), read by field name.
SETTINGS = np.dtype(
    [
        ("scene_half", np.float64),  # the scene: ±half-width in X and Z, floor, ceiling, m
        ("scene_floor", np.float64),
        ("scene_height", np.float64),
        ("sweep", np.float64),  # one raster sweep, s
        ("lines", np.float64),  # raster lines L (L × L pixels)
        ("period", np.float64),  # scan period τ, s
        ("lo_w", np.float64),  # smallest and largest sector width, rad
        ("hi_w", np.float64),
        ("half_regard", np.float64),  # half the field of regard, rad
        ("kappa", np.float64),  # angular noise per sector width
        ("sigma_min", np.float64),  # its floor, rad
        ("position_sigma", np.float64),  # σ_x, the apparent-position error, m
        ("max_speed", np.float64),  # m/s
        ("max_accel", np.float64),  # m/s²
        ("gate_q", np.float64),  # q, the gates' quantile
        ("cond_max", np.float64),  # largest κ_F of a candidate's system
        ("sigma_ref", np.float64),  # the reward's reference σ, m
        ("reward_clip", np.float64),
        ("false_penalty", np.float64),  # per false confirmed track
        ("truth_gate", np.float64),  # a track farther from every drone is false, m
        ("length", np.float64),  # observation scales: m, m/s, fixes
        ("speed", np.float64),
        ("max_fix", np.float64),
        ("tracker", np.int64),  # PROPOSED, ALTERNATIVE or ALGORITHMIC
        ("iters", np.int64),  # fixed-point iterations of the pixel-visit rule
        ("confirm_hits", np.int64),
        ("max_misses", np.int64),
        ("ghost_misses", np.int64),  # negative information (0: off)
        ("centre", np.float64, (3,)),  # the scene centre, m
    ],
    align=True,
)

#: The receivers' geometry, in the order of the tuple the kernels take
#: (:attr:`.simulation.ScanningParams.kernel_geometry`, a plain tuple: it dispatches faster): places
#: ``O (n, 3)``, local→world rotations ``R (n, 3, 3)``, poses in receiver 1's frame
#: ``P (n − 1, 3, 3)`` and ``b (n − 1, 3)``, sweep offsets ``(n,)``, and the joint fits' χ²
#: thresholds ``(n − 3,)`` (:attr:`.simulation.ScanningParams.fit_thresholds`).
Geometry = namedtuple("Geometry", "O R P b offsets chi2_max")

#: The arrays of the state before a period that :func:`step_rows` reads (``old``), and of the
#: state it writes (``new``, :data:`.simulation._WRITTEN` order).
OldState = namedtuple("OldState", "t position velocity acceleration enter exited tracks "
                                  "track_int next_id")  # fmt: skip
NewState = namedtuple("NewState", "t position velocity exited tracks track_int next_id "
                                  "sectors fixes fix_count fix_drone assigned drone_sigma parts "
                                  "obs")  # fmt: skip
#: The period's draws: direction normals ``(B, n, m, 3)``, apparent-position errors
#: ``(B, m, 3)``, false detections' counts ``(B, n)`` and places ``(B, n, max_clutter, 2)``.
Draws = namedtuple("Draws", "normals apparent clutter_count clutter_uv")


@register_jitable(**_JIT)
def _carve1(buf, o, a):
    """The next ``a`` entries of the scratch buffer ``buf`` from offset ``o``, and the offset
    after them."""
    return buf[o : o + a], o + a


@register_jitable(**_JIT)
def _carve2(buf, o, a, b):
    return buf[o : o + a * b].reshape((a, b)), o + a * b


@register_jitable(**_JIT)
def _carve3(buf, o, a, b, c):
    return buf[o : o + a * b * c].reshape((a, b, c)), o + a * b * c


@register_jitable(**_JIT)
def _carve4(buf, o, a, b, c, d):
    return buf[o : o + a * b * c * d].reshape((a, b, c, d)), o + a * b * c * d


@njit(**_INLINE)
def _system(buf, o, rows, others, unknowns):
    """A conjugation system of ``rows`` rows on ``others`` receivers past the first and
    ``unknowns`` unknowns, carved from ``buf`` at ``o``: ``(a1, ak, P, b, dt, ones, X, J, Q,
    κ, M1)`` (the arguments of ``pair_kernel`` / ``triple_velocity_kernel``; ``ones`` set)."""
    a1, o = _carve2(buf, o, rows, 3)
    ak, o = _carve3(buf, o, rows, others, 3)
    P, o = _carve4(buf, o, rows, others, 3, 3)
    b, o = _carve3(buf, o, rows, others, 3)
    dt, o = _carve2(buf, o, rows, 2)
    ones, o = _carve1(buf, o, rows)
    ones[:] = 1.0
    X, o = _carve2(buf, o, rows, unknowns)
    J, o = _carve1(buf, o, rows)
    Q, o = _carve3(buf, o, rows, unknowns, unknowns)
    kap, o = _carve1(buf, o, rows)
    M1, o = _carve2(buf, o, rows, 3)
    return (a1, ak, P, b, dt, ones, X, J, Q, kap, M1), o


@njit(**_INLINE)
def _system_size(rows, others, unknowns):
    return rows * (3 + 15 * others + 2 + 1 + unknowns + 1 + unknowns * unknowns + 1 + 3)


@njit(**_INLINE)
def workspace(n, F, T, m, used_n):
    """Scratch of one step call (``n`` receivers, ``F`` fixes each, ``T`` track rows, ``m``
    drones, candidates of ``used_n`` receivers): views of four buffers (one allocation per
    dtype, not fifty), as the groups the stages take —

    * ``fx = (la (n, F, 3), sig (n,), cones (n, 7))``: the period's fixes in local frames,
      their noise, the sector cones (:func:`.candidate_kernels.sector_cone`);
    * ``pairs``: the pair pre-gates' system of ``F²`` rows, ``gates = (g12, g13, g23, every,
      need23)`` ``(F, F)``;
    * ``solved``: the candidates' system of ``C = F^used_n`` rows; ``found = (cmem (C, n),
      cand (C, 10), cok, ctaken (C,))``;
    * ``refine``: the joint fit's system over all ``n`` receivers
      (:func:`.candidate_kernels.join_receivers`);
    * ``assoc = (fused (n, F), t_took (T,), scores, kids, births (C,))``: the association's
      (:mod:`.association_kernels`);
    * ``truth = (d_dist (T, m), t_end_pos (T, 3), t_cmp (T,), g_rows (T,))``: the reward's;
    * ``motion (m, 10)``: the drones' apparent motion (:func:`apparent_motion`)."""
    C = F**used_n
    nx = used_n + (3 if used_n == 3 else 0)
    u1, FF, TC = used_n - 1, F * F, T * C
    fbuf = np.empty(
        n * F * 3 + n + n * 7
        + _system_size(C, u1, nx) + C * K_COLUMNS
        + _system_size(FF, 1, 2)
        + TC * 14
        + T * (20 + m + 3 + 1)
        + m * 10
    )  # fmt: skip
    ibuf = np.empty(C * (n + 1) + TC * 4 + 2 * T, np.int64)
    bbuf = np.empty(2 * C + n * F + T + 5 * FF, np.bool_)
    # the refinement's system, sized for all n receivers (receivers 4 … n)
    rbuf = np.empty(3 + 16 * (n - 1) + (n + 3) * (n + 4) + 5 + n + velocity_work(n - 1))
    o = 0
    la, o = _carve3(fbuf, o, n, F, 3)
    sig, o = _carve1(fbuf, o, n)
    cones, o = _carve2(fbuf, o, n, 7)
    solved, o = _system(fbuf, o, C, u1, nx)
    cand, o = _carve2(fbuf, o, C, K_COLUMNS)
    pairs_full, o = _system(fbuf, o, FF, 1, 2)
    pairs_s, o = _carve1(fbuf, o, TC)
    pairs_mv, o = _carve2(fbuf, o, TC, 6)
    child_mv, o = _carve2(fbuf, o, TC, 6)
    child_s, o = _carve1(fbuf, o, TC)
    old, o = _carve2(fbuf, o, T, 20)
    d_dist, o = _carve2(fbuf, o, T, m)
    t_end_pos, o = _carve2(fbuf, o, T, 3)
    t_cmp, o = _carve1(fbuf, o, T)
    motion, o = _carve2(fbuf, o, m, 10)
    o = 0
    cmem, o = _carve2(ibuf, o, C, n)
    births, o = _carve1(ibuf, o, C)
    pairs_t, o = _carve1(ibuf, o, TC)
    pairs_c, o = _carve1(ibuf, o, TC)
    child_t, o = _carve1(ibuf, o, TC)
    child_c, o = _carve1(ibuf, o, TC)
    old_slot, o = _carve1(ibuf, o, T)
    g_rows, o = _carve1(ibuf, o, T)
    o = 0
    cok, o = _carve1(bbuf, o, C)
    ctaken, o = _carve1(bbuf, o, C)
    fused, o = _carve2(bbuf, o, n, F)
    t_took, o = _carve1(bbuf, o, T)
    g12, o = _carve2(bbuf, o, F, F)
    g13, o = _carve2(bbuf, o, F, F)
    g23, o = _carve2(bbuf, o, F, F)
    every, o = _carve2(bbuf, o, F, F)
    need23, o = _carve2(bbuf, o, F, F)
    g12[:] = True
    g13[:] = True
    g23[:] = True
    every[:] = True
    o = 0
    r_a1, o = _carve2(rbuf, o, 1, 3)
    r_ak, o = _carve3(rbuf, o, 1, n - 1, 3)
    r_P, o = _carve4(rbuf, o, 1, n - 1, 3, 3)
    r_b, o = _carve3(rbuf, o, 1, n - 1, 3)
    r_dt, o = _carve2(rbuf, o, 1, n - 1)
    r_X, o = _carve2(rbuf, o, 1, n + 3)
    r_J, o = _carve1(rbuf, o, 1)
    r_Q, o = _carve3(rbuf, o, 1, n + 3, n + 3)
    r_kap, o = _carve1(rbuf, o, 1)
    r_M1, o = _carve2(rbuf, o, 1, 3)
    r_sg, o = _carve1(rbuf, o, n)
    r_work, o = _carve1(rbuf, o, velocity_work(n - 1))
    pa1, pa2, pP, pb, _, pones, pX, pJ, pQ, pk, pM = pairs_full
    return (
        (la, sig, cones),
        (pa1, pa2, pP, pb, pones, pX, pJ, pQ, pk, pM),
        (g12, g13, g23, every, need23),
        solved,
        (cmem, cand, cok, ctaken),
        (r_a1, r_ak, r_P, r_b, r_dt, r_X, r_J, r_Q, r_kap, r_M1, r_sg, r_work),
        (fused, t_took, (pairs_t, pairs_c, pairs_s, pairs_mv),
         (child_t, child_c, child_s, child_mv, old, old_slot), births),
        (d_dist, t_end_pos, t_cmp, g_rows),
        motion,
    )  # fmt: skip


@njit(**_JIT)
def sector_of(action, lo_w, hi_w, half_regard):
    """``(φ_c, θ_c, w)`` of a receiver's normalised action ``(3,)`` (clipped to ``[−1, 1]``;
    :func:`.reference.sectors_of`): centre ``a · regard/2`` in azimuth and elevation about the
    boresight, width ``w_min + (a + 1)/2 (w_max − w_min)``, rad."""
    a0 = min(max(action[0], -1.0), 1.0)
    a1 = min(max(action[1], -1.0), 1.0)
    a2 = min(max(action[2], -1.0), 1.0)
    return a0 * half_regard, a1 * half_regard, lo_w + 0.5 * (a2 + 1.0) * (hi_w - lo_w)


@njit(**_JIT)
def sector_sigma(width, kappa, sigma_min):
    """Angular noise of a fix from a sector of ``width``: ``max(κ w, σ_min)`` rad
    (:func:`.reference.fix_sigma`) — the raster has a fixed pixel count, so a wider sector has
    coarser pixels (the sector trade-off)."""
    return max(kappa * width, sigma_min)


@njit(**_JIT)
def _angles(d):
    """Local azimuth ``atan2(x, z)`` and elevation ``atan2(y, ‖(x, z)‖)`` of ``d`` (theory §2.2)."""
    return np.arctan2(d[0], d[2]), np.arctan2(d[1], np.hypot(d[0], d[2]))


@njit(inline="always")
def _pixel_angles(d, centre_az, centre_el, width, lines):
    """:func:`_angles` as far as the sector and pixel tests can tell: fast angles
    (:func:`atan2_near`, ``hypot`` as a square root) when they lie in a pixel (or outside the
    sector) by more than their error ``ε`` (:data:`ATAN2_NEAR_ERROR`) and rounding, else
    libm's. The exact angles then lie in the same pixel, or outside too: :func:`in_sector` and
    :func:`raster_time` answer alike, and the fix, its time and the episode are bit for bit
    those of :func:`_angles`."""
    if d[2] > 0.0:
        phi = atan2_near(d[0], d[2])
        theta = atan2_near(d[1], np.sqrt(d[0] * d[0] + d[2] * d[2]))
        row, col = raster_cell(phi, theta, centre_az, centre_el, width, width, lines, lines)
        # ε in pixels, and 1e-9 pixel for the rounding of a few operations on numbers ≤ lines
        m = ATAN2_NEAR_ERROR * lines / width + 1e-9
        if row < -m or row > lines + m or col < -m or col > lines + m:
            return phi, theta  # outside the sector by more than the error
        fr, fc = row - np.floor(row), col - np.floor(col)
        if m < fr < 1.0 - m and m < fc < 1.0 - m and m < row < lines - m and m < col < lines - m:
            return phi, theta  # inside a pixel by more than the error
    return _angles(d)


@njit(**_JIT)
def _inside(phi, theta, d, centre_az, centre_el, width):
    return d[2] > 0.0 and in_sector(phi, theta, centre_az, centre_el, width, width)


@njit(**_JIT)
def _at(p, v, a, s):
    """``p + v s + ½ a s²``."""
    h = 0.5 * s * s
    return (p[0] + v[0] * s + a[0] * h, p[1] + v[1] * s + a[1] * h, p[2] + v[2] * s + a[2] * h)


@njit(inline="always")
def raster_fix(R, k, o, motion, sector, lines, offset, sweep, iters):
    """Pixel-visit rule (theory §6.3, :func:`.reference.pixel_visit`) for an object
    ``motion = (p, v, a)``, at ``p + v s + ½ a s²`` (``s`` from the period start), seen from
    receiver ``k`` at ``o`` with its ``sector = (φ_c, θ_c, w)``: iterates
    ``s ← T_raster(φ(s), θ(s))`` from the middle of the sweep. Returns ``(seen, s, local
    offset d)``; not seen outside the sector or behind the receiver."""
    p, v, a = motion
    centre_az, centre_el, width = sector
    s = offset + 0.5 * sweep
    d = (0.0, 0.0, 1.0)
    for _ in range(iters):
        q = _at(p, v, a, s)
        d = local(R, k, (q[0] - o[0], q[1] - o[1], q[2] - o[2]))
        phi, theta = _pixel_angles(d, centre_az, centre_el, width, lines)
        if not _inside(phi, theta, d, centre_az, centre_el, width):
            return False, s, d
        s_new = raster_time(
            phi, theta, centre_az, centre_el, width, width, lines, lines, offset, sweep
        )
        if s_new == s:
            # converged: the raster reaches this pixel at s, where the object is at d
            return norm3(d) > 0.0, s, d
        s = s_new
    q = _at(p, v, a, s)
    d = local(R, k, (q[0] - o[0], q[1] - o[1], q[2] - o[2]))
    phi, theta = _pixel_angles(d, centre_az, centre_el, width, lines)
    seen = _inside(phi, theta, d, centre_az, centre_el, width) and norm3(d) > 0.0
    return seen, s, d


@njit(**_INLINE)
def _present(i, j, t0, enter, exited):
    """Whether drone ``j`` is in the scene at ``t0`` (:func:`.reference.in_scene`)."""
    return not (exited[i, j] or enter[i, j] > t0 + 1e-9)


@njit(**_INLINE)
def apparent_motion(i, t0, drone_p, drone_v, drone_a, enter, exited, apparent, motion):
    """``motion[j] (10,)`` of scenario ``i``'s drones this period: the apparent position (one
    shared error per drone and period, theory §4.1), velocity and acceleration, and 1 where
    the drone is in the scene (:func:`.reference.in_scene`), else 0."""
    for j in range(drone_p.shape[1]):
        for x in range(3):
            motion[j, x] = drone_p[i, j, x] + apparent[i, j, x]
            motion[j, 3 + x] = drone_v[i, j, x]
            motion[j, 6 + x] = drone_a[i, j, x]
        motion[j, 9] = 1.0 if _present(i, j, t0, enter, exited) else 0.0


@njit(**_INLINE)
def sense(p, R, offsets, i, k, t0, action, sectors, sig, cones):
    """Receiver ``k``'s sector and its noise (:func:`.reference.sectors_of`,
    :func:`.reference.fix_sigma`) into ``sectors[i, k]`` and ``sig[k]``, and for receivers
    4 … n its cone (negative information on); returns ``(φ_c, θ_c, w, σ)``."""
    az, el, w = sector_of(action[i, k], p.lo_w, p.hi_w, p.half_regard)
    sectors[i, k, 0], sectors[i, k, 1], sectors[i, k, 2] = az, el, w
    sig[k] = sector_sigma(w, p.kappa, p.sigma_min)
    if k >= 3 and p.ghost_misses > 0:
        sector_cone(R, k, az, el, w, offsets[k], p.sweep, t0, cones)
    return az, el, w, sig[k]


@njit(**_INLINE)
def _put_fix(R, i, k, c, u, time, drone, la, fixes, fix_drone):
    """Fix ``c`` of receiver ``k``: local direction ``u`` into ``la``, its world direction and
    ``time`` into ``fixes``, its source (drone, −1: false) into ``fix_drone``."""
    la[k, c, 0], la[k, c, 1], la[k, c, 2] = u
    uw = world(R, k, u)
    fixes[i, k, c, 0], fixes[i, k, c, 1], fixes[i, k, c, 2] = uw
    fixes[i, k, c, 3] = time
    fix_drone[i, k, c] = drone


@njit(**_INLINE)
def scan_drones(p, O, R, i, k, when, sector, motion, normals, la, fixes, fix_drone):
    """Receiver ``k``'s fixes of the drones present (:func:`.reference.scan`, theory §6.3):
    each drone's apparent position (``motion``, :func:`apparent_motion`) where the raster
    visits it (:func:`raster_fix`), its direction perturbed by the sector's noise.
    ``when = (t0, the sweep's offset)``, ``sector = (φ_c, θ_c, w, σ)``. Returns the number
    of fixes."""
    t0, offset = when
    az, el, w, sigma = sector
    o = (O[k, 0], O[k, 1], O[k, 2])
    c = 0
    for j in range(motion.shape[0]):
        if motion[j, 9] == 0.0:
            continue
        pa = (motion[j, 0], motion[j, 1], motion[j, 2])
        v = (motion[j, 3], motion[j, 4], motion[j, 5])
        acc = (motion[j, 6], motion[j, 7], motion[j, 8])
        seen, s, d = raster_fix(R, k, o, (pa, v, acc), (az, el, w), p.lines, offset, p.sweep,
                                p.iters)  # fmt: skip
        if not seen:
            continue
        r = norm3(d)
        u = (d[0] / r, d[1] / r, d[2] / r)
        if sigma > 0.0:
            z = (normals[i, k, j, 0], normals[i, k, j, 1], normals[i, k, j, 2])
            u = perturbed_direction3(u, z, sigma)
        _put_fix(R, i, k, c, u, t0 + s, j, la, fixes, fix_drone)
        c += 1
    return c


@njit(**_INLINE)
def false_detections(p, R, i, k, c, when, sector, clutter_count, clutter_uv, la, fixes,
                     fix_drone):  # fmt: skip
    """Receiver ``k``'s false detections after its ``c`` drone fixes
    (:func:`.reference.false_detections`): uniform in the sector, fixed when the raster
    passes them. Returns the number of fixes."""
    t0, offset = when
    az, el, w = sector[0], sector[1], sector[2]
    for q in range(min(clutter_count[i, k], clutter_uv.shape[2])):
        phi = az + (clutter_uv[i, k, q, 0] - 0.5) * w
        theta = el + (clutter_uv[i, k, q, 1] - 0.5) * w
        u = unit_from_angles3(phi, theta)
        time = t0 + raster_time(phi, theta, az, el, w, w, p.lines, p.lines, offset, p.sweep)
        _put_fix(R, i, k, c, u, time, -1, la, fixes, fix_drone)
        c += 1
    return c


@njit(**_INLINE)
def truth_distances(p, i, t0, drone_p, drone_v, drone_a, enter, exited, tracks, track_int,
                    truth):  # fmt: skip
    """Each confirmed track's distance to each drone present within the truth gate (else inf)
    in ``d_dist``, compared at the track's own time if it was updated this period, else at the
    period end (:func:`.reference.score_period`); returns the number of such tracks near some
    drone (in ``g_rows``). ``truth = (d_dist (T, m), t_end_pos (T, 3), t_cmp (T,),
    g_rows (T,))``."""
    d_dist, t_end_pos, t_cmp, g_rows = truth
    t_end = t0 + p.period
    ng = 0  # the confirmed tracks within the gate of some drone, in ascending order
    for q in range(tracks.shape[1]):
        if track_int[i, q, I_STATUS] != CONFIRMED:
            continue
        tq = tracks[i, q, T_TIME]
        tc = tq if tq >= t0 else t_end
        s = tc - tq
        t_cmp[q] = tc
        t_end_pos[q, 0], t_end_pos[q, 1], t_end_pos[q, 2] = predicted_position(i, q, s, tracks)
        near = False
        for j in range(drone_p.shape[1]):
            d_dist[q, j] = np.inf
            if not _present(i, j, t0, enter, exited):
                continue
            pe = _at(
                (drone_p[i, j, 0], drone_p[i, j, 1], drone_p[i, j, 2]),
                (drone_v[i, j, 0], drone_v[i, j, 1], drone_v[i, j, 2]),
                (drone_a[i, j, 0], drone_a[i, j, 1], drone_a[i, j, 2]),
                tc - t0,
            )
            dd = norm3((t_end_pos[q, 0] - pe[0], t_end_pos[q, 1] - pe[1],
                        t_end_pos[q, 2] - pe[2]))  # fmt: skip
            if dd <= p.truth_gate:
                d_dist[q, j] = dd
                near = True
        if near:
            g_rows[ng] = q
            ng += 1
    return ng


@njit(**_INLINE)
def nearest_pairs(i, ng, tracks, truth, assigned, drone_sigma):
    """Greedy nearest (track, drone) pairs within the truth gate, one-to-one
    (:func:`.reference.score_period`): ``assigned`` the drone's track (−1: none),
    ``drone_sigma`` that track's predicted ``σ_pos`` at the comparison time (inf: none)."""
    d_dist, t_cmp, g_rows = truth[0], truth[2], truth[3]
    m = d_dist.shape[1]
    for j in range(m):
        assigned[i, j] = -1
        drone_sigma[i, j] = np.inf
    while True:
        best = np.inf
        bq, bj = -1, -1
        for e in range(ng):
            q = g_rows[e]
            for j in range(m):
                if d_dist[q, j] < best:
                    best, bq, bj = d_dist[q, j], q, j
        if bq < 0:
            break
        assigned[i, bj] = bq
        s = t_cmp[bq] - tracks[i, bq, T_TIME]
        drone_sigma[i, bj] = predicted_sigma(i, bq, s, tracks)
        for e in range(ng):
            d_dist[g_rows[e], bj] = np.inf
        for j in range(m):
            d_dist[bq, j] = np.inf


@njit(**_INLINE)
def score_period(p, i, t0, enter, exited, track_int, assigned, drone_sigma, parts, reward):
    """The reward at the period end (:func:`.reference.score_period`, theory §11.5 step 4),
    from the confirmed tracks matched one-to-one to the drones present (:func:`truth_distances`,
    :func:`nearest_pairs`): the mean per-drone clipped log-ratio reward less
    ``false_penalty`` per unmatched confirmed track. ``parts[i]``: drones present, drones with
    a confirmed track, false confirmed tracks, mean per-drone reward, mean ``σ_pos`` of the
    tracked drones, confirmed tracks."""
    m, T = enter.shape[1], track_int.shape[1]
    npresent = 0
    total = 0.0
    found = 0
    for j in range(m):
        if not _present(i, j, t0, enter, exited):
            continue
        npresent += 1
        if assigned[i, j] >= 0:
            found += 1
            total += log_ratio_reward(drone_sigma[i, j], p.sigma_ref, p.reward_clip)
        else:
            total -= p.reward_clip
    n_false = 0
    n_conf = 0
    for q in range(T):
        if track_int[i, q, I_STATUS] == CONFIRMED:
            n_conf += 1
            hit = False
            for j in range(m):
                if assigned[i, j] == q:
                    hit = True
            if not hit:
                n_false += 1
    mean = total / npresent if npresent > 0 else 0.0
    reward[i] = mean - p.false_penalty * n_false
    parts[i, 0], parts[i, 1], parts[i, 2], parts[i, 3] = npresent, found, n_false, mean
    total_sigma = 0.0
    for j in range(m):
        if assigned[i, j] >= 0:
            total_sigma += drone_sigma[i, j]
    parts[i, 4] = total_sigma / found if found > 0 else 0.0
    parts[i, 5] = n_conf


@njit(**_INLINE)
def fly_on(p, i, t0, drone_p, drone_v, drone_a, enter, exited):
    """The drones present fly on to the period end; leaving the scene is for good
    (:func:`.reference.fly_on`). Returns whether every drone has left."""
    period = p.period
    for j in range(drone_p.shape[1]):
        if exited[i, j]:
            continue
        if enter[i, j] <= t0 + 1e-9:
            pe = _at(
                (drone_p[i, j, 0], drone_p[i, j, 1], drone_p[i, j, 2]),
                (drone_v[i, j, 0], drone_v[i, j, 1], drone_v[i, j, 2]),
                (drone_a[i, j, 0], drone_a[i, j, 1], drone_a[i, j, 2]),
                period,
            )
            for x in range(3):
                drone_v[i, j, x] += drone_a[i, j, x] * period
            drone_p[i, j, 0], drone_p[i, j, 1], drone_p[i, j, 2] = pe
            if (
                abs(pe[0]) > p.scene_half
                or abs(pe[2]) > p.scene_half
                or pe[1] < p.scene_floor
                or pe[1] > p.scene_height
            ):
                exited[i, j] = True
    gone = True
    for j in range(drone_p.shape[1]):
        if not exited[i, j]:
            gone = False
    return gone


@njit(**_INLINE)
def _carry_drones(i, t_in, p_in, v_in, exited_in, t, drone_p, drone_v, exited):
    """Scenario ``i``'s clock and drones before the period copied into the outputs (then
    updated there)."""
    t[i] = t_in[i]
    for j in range(drone_p.shape[1]):
        exited[i, j] = exited_in[i, j]
        for x in range(3):
            drone_p[i, j, x] = p_in[i, j, x]
            drone_v[i, j, x] = v_in[i, j, x]


@njit(**_INLINE)
def _carry_table(i, tracks_in, track_int_in, next_id_in, tracks, track_int, next_id):
    """Scenario ``i``'s track table before the period copied into the outputs."""
    next_id[i] = next_id_in[i]
    for q in range(tracks.shape[1]):
        for x in range(tracks.shape[2]):
            tracks[i, q, x] = tracks_in[i, q, x]
        for x in range(track_int.shape[2]):
            track_int[i, q, x] = track_int_in[i, q, x]


@njit(**_INLINE)
def _clear_fixes(i, fixes, fix_drone):
    for k in range(fixes.shape[1]):
        for f in range(fixes.shape[2]):
            fix_drone[i, k, f] = 0
            for x in range(4):
                fixes[i, k, f, x] = 0.0


@njit(**_JIT)
def step_rows(lo, hi, settings, geometry, action, old, draws, new, out):
    """One scan period of scenarios ``lo..hi`` (:func:`.reference.step`, its stages in order),
    written to the output arrays; then the new state's observation. ``settings`` the params'
    record (``(1,)`` of :data:`SETTINGS`), ``geometry`` the tuple of :data:`Geometry`,
    ``action (B, n, 3)`` raw actions, ``old`` the state before the period (:data:`OldState`),
    ``draws`` the period's noise (:data:`Draws`), ``new`` the state written
    (:data:`NewState`), ``out = (reward, terminated)`` ``(B,)``. No output may alias an input.
    Returns False (and stops) if an action is NaN or infinite."""
    p = settings[0]
    for i in range(lo, hi):
        for k in range(action.shape[1]):
            for x in range(3):
                if not math.isfinite(action[i, k, x]):
                    return False
    # the tuples taken apart once: the stages get plain arrays, uncounted (the caller holds
    # its arguments, and ``scratch`` its buffers, until the row loop is done)
    geometry, action, old, draws, new, out = uncounted((geometry, action, old, draws, new, out))
    t_in, p_in, v_in, acceleration, enter, exited_in, tracks_in, track_int_in, next_id_in = old
    normals, apparent, clutter_count, clutter_uv = draws
    t, drone_p, drone_v, exited, tracks, track_int, next_id = new[:7]
    sectors, fixes, fix_count, fix_drone, assigned, drone_sigma, parts, obs = new[7:]
    reward, terminated = out
    n, F, T, m = fixes.shape[1], fixes.shape[2], tracks.shape[1], drone_p.shape[1]
    used_n = 3 if p.tracker == PROPOSED else 2
    scratch = workspace(n, F, T, m, used_n)
    fx, pairs, gates, solved, found, refine, assoc, truth, motion = uncounted(scratch)
    la, sig, cones = fx
    O, R, P, b, offsets = geometry[:5]
    a1, ak, Pc, bc, dt, ones, X, J, Q, kap, M1 = solved
    cmem, cand, cok, ctaken = found
    fused, t_took, scores, kids, births = assoc
    pairs_t, pairs_c, pairs_s, pairs_mv = scores
    gates3, system = gates[:3], (a1, ak, Pc, bc, dt)
    for i in range(lo, hi):
        _carry_drones(i, t_in, p_in, v_in, exited_in, t, drone_p, drone_v, exited)
        _carry_table(i, tracks_in, track_int_in, next_id_in, tracks, track_int, next_id)
        _clear_fixes(i, fixes, fix_drone)
        t0 = t[i]
        # 1.–2. the sectors; the fixes of the drones present and the false detections
        apparent_motion(i, t0, drone_p, drone_v, acceleration, enter, exited, apparent, motion)
        for k in range(n):
            sector = sense(p, R, offsets, i, k, t0, action, sectors, sig, cones)
            when = (t0, offsets[k])
            c = scan_drones(p, O, R, i, k, when, sector, motion, normals, la, fixes, fix_drone)
            fix_count[i, k] = false_detections(p, R, i, k, c, when, sector, clutter_count,
                                               clutter_uv, la, fixes, fix_drone)  # fmt: skip
        # 3. the tracker: the period's candidates (reference.candidates): the pre-gates, every
        # triple or pair solved at once, their checks ...
        if used_n == 3:
            triple_pregates(p, P, b, i, la, sig, fixes, fix_count, pairs, gates)
        nc = enumerate_candidates(P, b, i, used_n, la, fixes, fix_count, gates3, system, cmem, cand)
        if used_n == 3:
            triple_velocity_kernel(a1, ak, Pc, bc, dt, 1.0, np.bool_(False), np.int64(0),
                                   np.int64(nc), X, J, Q, kap, M1)  # fmt: skip
        else:
            pair_kernel(a1, ak, Pc, bc, ones, 1.0, np.bool_(False), np.int64(0), np.int64(nc), X,
                        J, Q, kap, M1)  # fmt: skip
        screen_candidates(p, geometry, i, np.int64(nc), fx, fixes, fix_count, solved, found, refine)
        # ... then the association (reference.associate)
        clear_taken(fused, t_took)
        npair = continuation_costs(p, i, nc, cand, cok, tracks, track_int, pairs_t, pairs_c,
                                   pairs_s, pairs_mv)  # fmt: skip
        if p.tracker == ALGORITHMIC:
            npair = algorithmic_costs(p, geometry, i, npair, found, fx, pairs, (tracks, track_int),
                                      scores)  # fmt: skip
        order = np.argsort(pairs_s[:npair])
        continue_confirmed(p, i, order, cmem, cand, ctaken, tracks, track_int, scores, fused,
                           t_took)  # fmt: skip
        grow_children(p, i, order, found, tracks, track_int, next_id, scores, (fused, t_took),
                      kids)  # fmt: skip
        coast(p, i, track_int, t_took)
        open_births(p, i, nc, found, tracks, track_int, next_id, fused, births, kids[3][0])
        # 4. the reward at the period end; 5. the drones fly on
        ng = truth_distances(p, i, t0, drone_p, drone_v, acceleration, enter, exited, tracks,
                             track_int, truth)  # fmt: skip
        nearest_pairs(i, ng, tracks, truth, assigned, drone_sigma)
        score_period(p, i, t0, enter, exited, track_int, assigned, drone_sigma, parts, reward)
        terminated[i] = fly_on(p, i, t0, drone_p, drone_v, acceleration, enter, exited)
        t[i] = t0 + p.period
        # 6. what the new state shows
        observation(i, p, t, tracks, track_int, sectors, fix_count, obs)
    return _held(scratch)


@njit(**_JIT)
def _held(scratch):
    """True. The step's last use of its counted ``scratch``: numba releases a value after its
    last use, so the buffers the uncounted views borrow from outlive the row loop."""
    return len(scratch) > 0


@njit(**_JIT)
def _observed(v):
    """An observation entry: clipped to ``±OBS_CLIP`` (NaN stays NaN), stored as float32."""
    return clip(v, -OBS_CLIP, OBS_CLIP)


@njit(**_JIT)
def observation(i, p, t, tracks, track_int, sectors, fix_count, obs):
    """The observation of :func:`.reference.observation` (:func:`.simulation.observe`) of
    scenario ``i`` into ``obs[i]`` (float32, clipped to ``±OBS_CLIP``): the confirmed tracks'
    predictions, velocities, accuracies, ages and hits, then each receiver's sector and fix
    count."""
    T = tracks.shape[1]
    n = sectors.shape[1]
    slots = (obs.shape[1] - 4 * n) // 11
    length, speed, sigma_ref, period = p.length, p.speed, p.sigma_ref, p.period
    half_regard, lo_w, hi_w, max_fix = p.half_regard, p.lo_w, p.hi_w, p.max_fix
    tiny = 1e-12
    for x in range(obs.shape[1]):
        obs[i, x] = 0.0
    r = 0
    for q in range(T):
        if r >= slots:
            break
        if track_int[i, q, I_STATUS] != CONFIRMED:
            continue
        col = 11 * r
        s = t[i] - tracks[i, q, T_TIME]
        obs[i, col] = 1.0
        pred = predicted_position(i, q, s, tracks)
        for x in range(3):
            obs[i, col + 1 + x] = _observed((pred[x] - p.centre[x]) / length)
            obs[i, col + 4 + x] = _observed(tracks[i, q, 3 + x] / speed)
        sp = predicted_sigma(i, q, s, tracks)
        obs[i, col + 7] = _observed(np.log(max(sp, tiny) / sigma_ref))
        obs[i, col + 8] = _observed(np.log(max(tracks[i, q, T_SIG + 1] * period, tiny) / sigma_ref))
        obs[i, col + 9] = _observed(s / period)
        obs[i, col + 10] = _observed(track_int[i, q, 0] / 10.0)
        r += 1
    col = 11 * slots
    for k in range(n):
        obs[i, col + 4 * k] = _observed(sectors[i, k, 0] / half_regard)
        obs[i, col + 4 * k + 1] = _observed(sectors[i, k, 1] / half_regard)
        width = 2.0 * (sectors[i, k, 2] - lo_w) / max(hi_w - lo_w, tiny) - 1.0
        obs[i, col + 4 * k + 2] = _observed(width)
        obs[i, col + 4 * k + 3] = _observed(fix_count[i, k] / max_fix)


@njit(**_JIT)
def observe_kernel(settings, t, tracks, track_int, sectors, fix_count, obs):
    """:func:`observation` of every scenario (a state :func:`step_rows` did not make)."""
    p = settings[0]
    for i in range(t.shape[0]):
        observation(i, p, t, tracks, track_int, sectors, fix_count, obs)
