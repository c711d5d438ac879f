"""The compiled step of the scanning-receiver environments: one loop over the scenarios.

The maths is that of :mod:`.simulation` (theory §3, §5.2–5.3, §6); each formula is a primitive
of the module that owns it — :mod:`sensorgym.trackers.geometry_kernels` (look-at rotation,
relative poses, angular noise), :mod:`sensorgym.trackers.stereo.conjugation_kernels` (the
``n = 2`` pair and the ``n = 3`` velocity-aware closed forms, ``σ_e² (AᵀA)⁻¹``) and
:mod:`sensorgym.trackers.stereo.kernels` (the clipped log-ratio reward) — and these kernels
chain them per scenario:

* :func:`raster_fix` — the pixel-visit rule of one object in one receiver's sector raster
  (theory §6.3): the fix time ``t = T_raster(φ(t), θ(t))`` by fixed-point iteration, on
  angles good to the pixel (:func:`_pixel_angles`: a polynomial arctangent, libm's near an edge);
* :func:`step_rows` — one scan period of scenarios ``lo..hi``, out of place (the state before
  the period is read, the new one written to fresh arrays): sectors from the action, fixes
  (drones and false detections), the candidates of the selected algorithm, association over
  periods, track initiation and confirmation, the reward; drones then move on; last the new
  state's observation;
* :func:`observe_row` — the observation of one scenario (track table and sectors), float32 and
  clipped, which the step writes into the state (:func:`observe_kernel` for a state built by
  hand).

Random draws stay with numpy's Generator (drawn before the kernels, in a fixed order). The
per-params scalars and the receivers' geometry travel in one constants array (``C_*``): each
array argument costs the dispatcher time, a sizeable share of a one-scenario step.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numba.extending import register_jitable

from sensorgym.envs.shells.contract import OBS_CLIP
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
    velocity_element,
    velocity_fix_element,
    velocity_work,
)
from sensorgym.trackers.stereo.kernels import clip, log_ratio_reward

_JIT = {"cache": True, "nogil": True, "error_model": "numpy", "boundscheck": False}

# Constant arguments of the shared primitives are passed as ``np.int64(…)`` / ``np.bool_(…)``:
# a bare literal (``0``, ``False``) makes numba compile one more specialisation per value.

#: track status codes of the table
EMPTY, TENTATIVE, CONFIRMED = 0, 1, 2
#: tracker codes
PROPOSED, ALTERNATIVE, ALGORITHMIC = 0, 1, 2
#: floor of the tracker's gates, m (and m/s): noise-free fixes of an unaccelerated drone give
#: zero gates, which rounding would fail
GATE_FLOOR = 1e-3
#: margin of the gates' square-root-free bounds over round-off (:func:`screen_candidates`,
#: :func:`_step_cost`)
GATE_SLACK = 1.000001

#: layout of the per-params constants (``simulation.ScanningParams.kernel_constants``): the
#: scalars, the integer settings (stored as floats), the scene centre ``(3,)``, the receivers'
#: geometry (:func:`geometry`), then the joint fits' χ² thresholds (:func:`fit_thresholds`)
(C_SCENE_HALF, C_FLOOR, C_HEIGHT, C_SWEEP, C_LINES, C_PERIOD, C_LO_W, C_HI_W, C_HALF_REGARD,
 C_KAPPA, C_SIGMA_MIN, C_POS_SIGMA, C_MAX_SPEED, C_MAX_ACCEL, C_GATE_Q, C_COND, C_SIGMA_REF,
 C_REWARD_CLIP, C_FALSE_PENALTY, C_TRUTH_GATE, C_LENGTH, C_SPEED, C_MAX_FIX, C_TRACKER,
 C_ITERS, C_CONFIRM, C_MISSES, C_GHOST, C_CENTRE) = range(29)  # fmt: skip
#: the geometry of ``n`` receivers starts here: places ``O (n, 3)``, rotations ``R (n, 3, 3)``,
#: relative poses ``P (n − 1, 3, 3)`` and ``b (n − 1, 3)``, sweep offsets ``(n,)``
C_GEOMETRY = C_CENTRE + 3


@register_jitable
def geometry_size(n: int) -> int:
    """Length of the receivers' geometry of ``n`` receivers in the constants (:func:`geometry`)."""
    return 3 * n + 9 * n + 9 * (n - 1) + 3 * (n - 1) + n


def n_constants(n: int) -> int:
    """Length of the constants array of ``n`` receivers: the scalars, the geometry and ``n − 3``
    χ² thresholds."""
    return C_GEOMETRY + geometry_size(n) + (n - 3)


@njit(**_JIT)
def geometry(c, n):
    """Views ``(O, R, P, b, offsets)`` of the receivers' geometry in the constants ``c``."""
    o = C_GEOMETRY
    O = c[o : o + 3 * n].reshape((n, 3))
    o += 3 * n
    R = c[o : o + 9 * n].reshape((n, 3, 3))
    o += 9 * n
    P = c[o : o + 9 * (n - 1)].reshape((n - 1, 3, 3))
    o += 9 * (n - 1)
    b = c[o : o + 3 * (n - 1)].reshape((n - 1, 3))
    o += 3 * (n - 1)
    return O, R, P, b, c[o : o + n]


@njit(**_JIT)
def fit_thresholds(c, n):
    """View ``(n − 3,)`` of the χ² thresholds in the constants ``c``: entry ``n' − 4`` is the
    upper ``fit_false_alarm`` point of ``χ²`` on ``2 n' − 6`` degrees of freedom, which the
    joint fit of ``n'`` receivers must not exceed (:func:`_joint_fit`;
    ``simulation.ScanningParams.fit_thresholds``)."""
    o = C_GEOMETRY + geometry_size(n)
    return c[o : o + n - 3]


@njit(**_JIT)
def _local(R, k, d):
    """``R_kᵀ d`` for ``R (n, 3, 3)`` (``R[k, j, c]`` = component ``j`` of column ``c``)."""
    return (
        R[k, 0, 0] * d[0] + R[k, 1, 0] * d[1] + R[k, 2, 0] * d[2],
        R[k, 0, 1] * d[0] + R[k, 1, 1] * d[1] + R[k, 2, 1] * d[2],
        R[k, 0, 2] * d[0] + R[k, 1, 2] * d[1] + R[k, 2, 2] * d[2],
    )


@njit(**_JIT)
def _world(R, k, v):
    """``R_k v`` (receiver ``k``'s frame → world)."""
    return (
        R[k, 0, 0] * v[0] + R[k, 0, 1] * v[1] + R[k, 0, 2] * v[2],
        R[k, 1, 0] * v[0] + R[k, 1, 1] * v[1] + R[k, 1, 2] * v[2],
        R[k, 2, 0] * v[0] + R[k, 2, 1] * v[1] + R[k, 2, 2] * v[2],
    )


@njit(**_JIT)
def sector_of(action, lo_w, hi_w, half_regard):
    """``(φ_c, θ_c, w)`` of a receiver's normalised action ``(3,)`` (clipped to ``[−1, 1]``):
    centre ``a · regard/2`` in azimuth and elevation about the boresight, width
    ``w_min + (a + 1)/2 (w_max − w_min)``, rad."""
    a0 = min(max(action[0], -1.0), 1.0)
    a1 = min(max(action[1], -1.0), 1.0)
    a2 = min(max(action[2], -1.0), 1.0)
    return a0 * half_regard, a1 * half_regard, lo_w + 0.5 * (a2 + 1.0) * (hi_w - lo_w)


@njit(**_JIT)
def sector_sigma(width, kappa, sigma_min):
    """Angular noise of a fix from a sector of ``width``: ``max(κ w, σ_min)`` rad — the raster
    has a fixed pixel count, so a wider sector has coarser pixels (the sector trade-off)."""
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
def raster_fix(R, k, o, p, v, a, centre_az, centre_el, width, lines, offset, sweep, iters):
    """Pixel-visit rule (theory §6.3) for an object ``p + v s + ½ a s²`` (``s`` from the period
    start) seen from receiver ``k`` at ``o``: iterates ``s ← T_raster(φ(s), θ(s))`` from the
    middle of the sweep. Returns ``(seen, s, local offset d)``; not seen outside the sector or
    behind the receiver."""
    s = offset + 0.5 * sweep
    d = (0.0, 0.0, 1.0)
    for _ in range(iters):
        q = _at(p, v, a, s)
        d = _local(R, k, (q[0] - o[0], q[1] - o[1], q[2] - o[2]))
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
    d = _local(R, k, (q[0] - o[0], q[1] - o[1], q[2] - o[2]))
    phi, theta = _pixel_angles(d, centre_az, centre_el, width, lines)
    seen = _inside(phi, theta, d, centre_az, centre_el, width) and norm3(d) > 0.0
    return seen, s, d


@njit(inline="always")
def candidate_sigmas(Q, ranges, row, sigmas, n_used, position_sigma, velocity):
    """``(σ_e, σ_pos, σ_vel)`` of a candidate from its ``Q = (AᵀA)⁻¹`` (``σ_e = 1``): row
    ``row`` of ``Q`` and of its solution ``ranges`` (indexed in place: a row view costs a
    reference count; numba-IR inlined for the same reason).

    ``σ_e² = σ_x² + (1/n) Σ_k (σ_k r̂_k)²`` maps the direction noise to the papers' i.i.d.
    conjugation error (theory §13.4) plus the apparent-position error ``σ_x``;
    ``σ_pos = σ_e √([(AᵀA)⁻¹]_11 + 2)``: the range error along receiver 1's line of sight and
    ``σ_e`` on each axis across it; ``σ_vel = σ_e √tr Q_VV`` (``velocity``: order-1 systems,
    ``Q`` of ``n_used + 3`` unknowns ``(r_1 … r_n, V)`` in its first rows; else 0).
    """
    s2 = position_sigma * position_sigma
    acc = 0.0
    for k in range(n_used):
        x = sigmas[k] * abs(ranges[row, k])
        acc += x * x
    s2 += acc / n_used
    sigma_e = np.sqrt(s2)
    sp = sigma_e * np.sqrt(max(Q[row, 0, 0], 0.0) + 2.0)
    sv = 0.0
    if velocity:
        v = n_used
        sv = sigma_e * np.sqrt(max(Q[row, v, v] + Q[row, v + 1, v + 1] + Q[row, v + 2, v + 2], 0.0))
    return sigma_e, sp, sv


@njit(**_JIT)
def pair_passes(J, r1, r2, s1, s2, position_sigma, gate_q, max_speed, dt):
    """The pair gate ``J ≤ ε_J``, ``ε_J = (q √2 σ_e + v_max |Δt|)²`` (000 eq. 9, theory §13.6),
    ``σ_e² = σ_x² + ((σ_1 r̂_1)² + (σ_2 r̂_2)²)/2``: noise plus the largest miss distance the
    unmodelled motion opens between the rays; both ranges in front of the receivers."""
    if not (r1 > 0.0 and r2 > 0.0):
        return False
    x1, x2 = s1 * r1, s2 * r2
    sigma_e = np.sqrt(position_sigma * position_sigma + 0.5 * (x1 * x1 + x2 * x2))
    eps = gate_q * np.sqrt(2.0) * sigma_e + max_speed * abs(dt)
    return J <= eps * eps


@njit(**_JIT)
def _pair_gates(i, h, k, la, fix_time, count_h, count_k, P, b, sig, position_sigma, gate_q,
                max_speed, pa1, pa2, pP, pb, ones, pX, pJ, pQ, pk, pM, need, out):  # fmt: skip
    """``out[jh, jk]``: whether fixes ``jh`` (receiver ``h``) and ``jk`` (receiver ``k > h``)
    pass :func:`pair_passes` — the cheap pre-gate of the triples (a true triple's three pairs
    pass it) — for the pairs with ``need[jh, jk]`` (the others are left unset). In receiver 1's
    frame receiver ``h``'s line of sight is ``P_h a`` from ``b_h`` (``P_1 = I``, ``b_1 = 0``),
    so the pair solves ``r_h (P_h a_h) − r_k (P_k a_k) = b_k − b_h``."""
    npair = 0
    for jh in range(count_h):
        for jk in range(count_k):
            if not need[jh, jk]:
                continue
            for x in range(3):
                if h == 0:
                    pa1[npair, x] = la[0, jh, x]
                else:
                    pa1[npair, x] = (
                        P[h - 1, x, 0] * la[h, jh, 0]
                        + P[h - 1, x, 1] * la[h, jh, 1]
                        + P[h - 1, x, 2] * la[h, jh, 2]
                    )
                pa2[npair, 0, x] = la[k, jk, x]
                pb[npair, 0, x] = b[k - 1, x] - (b[h - 1, x] if h > 0 else 0.0)
                for y in range(3):
                    pP[npair, 0, x, y] = P[k - 1, x, y]
            npair += 1
    pair_kernel(
        pa1,
        pa2,
        pP,
        pb,
        ones,
        1.0,
        np.bool_(False),
        np.int64(0),
        np.int64(npair),
        pX,
        pJ,
        pQ,
        pk,
        pM,
    )
    e = 0
    for jh in range(count_h):
        for jk in range(count_k):
            if not need[jh, jk]:
                continue
            dt = fix_time[i, k, jk] - fix_time[i, h, jh]
            out[jh, jk] = pair_passes(pJ[e], pX[e, 0], pX[e, 1], sig[h], sig[k], position_sigma,
                                      gate_q, max_speed, dt)  # fmt: skip
            e += 1


# The scratch carvers and _save are called with constant sizes and with float and int buffers,
# contiguous or not: register_jitable types them on plain integers inside each caller, where a
# dispatcher compiled one specialisation per literal size and layout (18 copies, each a cold
# compile)
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


@njit(inline="always")
def _joint_fit(i, c, mk, la, fixes, O, R, P, b, sig, limits, chi2_max, cmem, cpos, cvel, ctime,
               csig, a1, ak, Pk, bk, dt, X, J, Q, kap, M1, sg, work):  # fmt: skip
    """Candidate ``c`` (a triple of receivers 1–3) re-solved by least squares over all its
    fixes, ``mk`` receivers past the first (receivers 4 … n joined in ``cmem[c]`` by
    :func:`screen_candidates`; theory §3.3, any n ≥ 3).

    The velocity-aware system of all ``n_used = mk + 1`` receivers (normal equations with the
    ranges ``r_2 … r_n`` eliminated, :func:`velocity_element` on this scratch, the block of
    ``(r_1, V)`` only) gives ``(M, V)`` and ``σ_e² (AᵀA)⁻¹`` (:func:`candidate_sigmas`), kept if
    it passes the triple's checks (``κ_F ≤ cond_max``, positive ranges, speed ≤
    ``max_speed``); otherwise the triple's solution stands and the joined fixes are released.
    Returns False, and the candidate is dropped, where the kept joint fit of ``n'`` receivers
    fails its χ² test (``chi2_max[n' − 4]``, the thresholds of :func:`fit_thresholds`). The
    system's arrays come from the step's scratch, sized for all ``n`` receivers (``a1 (1, 3)``,
    ``ak``, ``bk (1, n − 1, 3)``, ``Pk (1, n − 1, 3, 3)``, ``dt (1, n − 1)``, ``X (1, n + 3)``,
    ``J``, ``kap (1,)``, ``Q (1, n + 3, n + 3)``, ``M1 (1, 3)``, ``sg (n,)``, ``work`` of
    :func:`velocity_work` ``(n − 1)``): a candidate fills their first rows."""
    # numba-IR inlined into its one caller (at most 30 arguments: CPython passes more as
    # *args, which numba does not inline): a call would reference-count its 20 arrays
    position_sigma, max_speed, max_accel, cond_max = limits
    n = la.shape[0]
    t1 = ctime[c]
    nu = mk + 1
    sg[0] = sig[0]
    for x in range(3):
        a1[0, x] = la[0, cmem[c, 0], x]
    r = 0
    for k in range(1, n):
        j = cmem[c, k]
        if j < 0:
            continue
        for x in range(3):
            ak[0, r, x] = la[k, j, x]
            bk[0, r, x] = b[k - 1, x]
            for y in range(3):
                Pk[0, r, x, y] = P[k - 1, x, y]
        dt[0, r] = fixes[i, k, j, 3] - t1
        sg[r + 1] = sig[k]
        r += 1
    velocity_element(np.int64(0), mk, a1, ak, Pk, bk, dt, 1.0, np.bool_(False), X, J, Q, kap,
                     M1, work, np.bool_(False))  # fmt: skip
    ok = kap[0] <= cond_max
    for k in range(nu):
        ok = ok and X[0, k] > 0.0
    vw = _world(R, 0, (X[0, nu], X[0, nu + 1], X[0, nu + 2]))
    if not (ok and norm3(vw) <= max_speed):
        for k in range(3, n):
            cmem[c, k] = -1
        return True
    sigma_e, sp, sv = candidate_sigmas(Q, X, np.int64(0), sg, nu, position_sigma, np.bool_(True))
    # the joint fit's χ² = J / σ_e² on 3 (nu − 1) − (nu + 3) = 2 nu − 6 degrees of freedom
    # (a triple's is 0): beyond its upper fit_false_alarm point (chi2_max[nu − 4]), plus each
    # fix's unmodelled drift ½ a_max Δ² and the gates' floor, the fixes are not one object's —
    # a ghost triple that gathered other objects' fixes; the candidate is dropped
    unmodelled = 0.0
    for r in range(mk):
        e = 0.5 * max_accel * dt[0, r] * dt[0, r] + GATE_FLOOR
        unmodelled += e * e
    if J[0] > sigma_e * sigma_e * chi2_max[nu - 4] + unmodelled:
        return False
    mw = _world(R, 0, (M1[0, 0], M1[0, 1], M1[0, 2]))
    for x in range(3):
        cpos[c, x] = O[0, x] + mw[x]
        cvel[c, x] = vw[x]
    csig[c, 0], csig[c, 1] = sp, sv
    return True


@njit(**_JIT)
def sector_cone(R, k, centre_az, centre_el, width, offset, sweep, t0, cones):
    """``cones[k] (7,)``: receiver ``k``'s sector as a cone inside it — world axis ``ĉ`` (3), ``cos ρ``,
    ``sin ρ`` of its half-angle ``ρ = min(w/2, asin(cos θ_c sin(w/2)))`` (the angle from the
    centre to the nearer elevation edge, a small circle, and to the great circles through the
    azimuth edges), the time the sweep is half done and its half-length, s."""
    cw = _world(R, k, unit_from_angles3(centre_az, centre_el))
    rho = min(0.5 * width, np.arcsin(np.cos(centre_el) * np.sin(0.5 * width)))
    cones[k, 0], cones[k, 1], cones[k, 2] = cw
    cones[k, 3], cones[k, 4] = np.cos(rho), np.sin(rho)
    cones[k, 5] = t0 + offset + 0.5 * sweep
    cones[k, 6] = 0.5 * sweep


@njit(inline="always")
def _surely_seen(k, cones, O, t1, px, py, pz, vx, vy, vz, speed, sp, sv, gate_q, max_accel):
    """Whether an object at the candidate's prediction ``M + V s`` (``s`` from ``t_1`` to the
    middle of receiver ``k``'s sweep) lies inside ``k``'s sector cone (:func:`sector_cone`)
    by more than the margin ``μ = q √(σ_pos² + (σ_vel s)²) + |V| T_sweep/2 + ½ a_max s² + δ_0``
    (its uncertainty, its motion during the sweep, the unmodelled drift): then the raster
    must have fixed it. The angle test ``∠(d, ĉ) ≤ ρ − asin(μ/‖d‖)`` runs on cosines."""
    s = cones[k, 5] - t1
    ox, oy, oz = O[k, 0], O[k, 1], O[k, 2]
    d = (px + vx * s - ox, py + vy * s - oy, pz + vz * s - oz)
    nd = np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
    mu = (gate_q * np.sqrt(sp * sp + (sv * s) ** 2) + speed * cones[k, 6]
          + 0.5 * max_accel * s * s + GATE_FLOOR)  # fmt: skip
    sin_m = mu / nd  # nd = 0: inf, not seen
    if not sin_m < cones[k, 4]:
        return False
    cos_m = np.sqrt(1.0 - sin_m * sin_m)
    along = d[0] * cones[k, 0] + d[1] * cones[k, 1] + d[2] * cones[k, 2]
    # cos ∠(d, ĉ) ≥ cos(ρ − m) = cos ρ cos m + sin ρ sin m
    return along >= nd * (cones[k, 3] * cos_m + cones[k, 4] * sin_m)


@njit(inline="always")
def _frame1(P, r, la, k, j):
    """``c_k = P_k a_k``: fix ``j`` of receiver ``k``'s local direction in frame 1 (``P[r]``,
    ``r = k − 1``)."""
    return (
        P[r, 0, 0] * la[k, j, 0] + P[r, 0, 1] * la[k, j, 1] + P[r, 0, 2] * la[k, j, 2],
        P[r, 1, 0] * la[k, j, 0] + P[r, 1, 1] * la[k, j, 1] + P[r, 1, 2] * la[k, j, 2],
        P[r, 2, 0] * la[k, j, 0] + P[r, 2, 1] * la[k, j, 1] + P[r, 2, 2] * la[k, j, 2],
    )


@njit(inline="always")
def _triple_sigmas(c, la, P, cmem, dt, X, Q, sig, position_sigma, C, work):
    """``(σ_pos, σ_vel)`` of triple candidate ``c``: the square roots of the traces of the
    exact first-order covariance of its ``n = 3`` solution under the env's angle noise
    (:func:`~sensorgym.trackers.stereo.conjugation_kernels.velocity_fix_element`, theory §3.5,
    §11.6), on the scratch ``C (1, 6, 6)``, ``work (9, 3)``. The papers' ``σ_e² (AᵀA)⁻¹``
    (:func:`candidate_sigmas`) takes the two blocks' conjugation errors as independent and
    isotropic, where both share receiver 1's direction error: it understates ``σ_vel``
    (theory §11.6, ``research/nees``)."""
    j1, j2, j3 = cmem[c, 0], cmem[c, 1], cmem[c, 2]
    ok = velocity_fix_element(
        (la[0, j1, 0], la[0, j1, 1], la[0, j1, 2]),
        _frame1(P, 0, la, 1, j2),
        _frame1(P, 1, la, 2, j3),
        dt[c, 0], dt[c, 1], X[c, 0], X[c, 1], X[c, 2], sig[0], sig[1], sig[2],
        position_sigma * position_sigma, C, np.int64(0), work,
    )  # fmt: skip
    if not ok:  # M singular to rounding (the κ_F test drops such a triple first)
        _, sp, sv = candidate_sigmas(Q, X, c, sig, np.int64(3), position_sigma, np.bool_(True))
        return sp, sv
    return (np.sqrt(max(C[0, 0, 0] + C[0, 1, 1] + C[0, 2, 2], 0.0)),
            np.sqrt(max(C[0, 3, 3] + C[0, 4, 4] + C[0, 5, 5], 0.0)))  # fmt: skip


@njit(**_JIT)
def screen_candidates(i, nc, used_n, la, fixes, fix_count, O, R, P, b, sig,
                      position_sigma, gate_q, max_speed, max_accel, cond_max, chi2_max, X, J, Q,
                      kap, M1, dt, cmem, cpos, cvel, ctime, csig, cdt, cok, ctaken, r_a1, r_ak,
                      r_P, r_b, r_dt, r_X, r_J, r_Q, r_kap, r_M1, r_sg, r_work, cones,
                      ghost_misses):  # fmt: skip
    """The checks of scenario ``i``'s ``nc`` solved candidates (``X``, ``J``, ``Q``, ``κ``,
    ``M̂_1`` of :func:`~sensorgym.trackers.stereo.conjugation_kernels.triple_velocity_kernel`
    or ``pair_kernel``): ``cok[c]`` where candidate ``c`` passes them, its world position,
    velocity, time and ``(σ_pos, σ_vel)`` in ``cpos``, ``cvel``, ``ctime``, ``csig``; a triple
    is refined over receivers 4 … n first (their fixes joined here, then :func:`_joint_fit` on
    the ``r_*`` scratch). A triple whose prediction lies inside the sectors of
    ``ghost_misses`` of receivers 4 … n (``cones``, :func:`sector_cone`) with no fix in its
    gate there is a ghost and dropped at once (negative information; ``0``: off). One call per
    scenario: a call per candidate cost some fifty reference counts of its array
    arguments."""
    n = la.shape[0]
    limits = (position_sigma, max_speed, max_accel, cond_max)
    C = np.empty((1, 6, 6))  # a triple's exact covariance and its scratch
    work = np.empty((9, 3))
    for c in range(nc):
        ok = kap[c] <= cond_max
        for k in range(used_n):
            ok = ok and X[c, k] > 0.0
        cok[c] = False
        ctaken[c] = False
        if not ok:
            continue
        if used_n == 3:
            sp, sv = _triple_sigmas(c, la, P, cmem, dt, X, Q, sig, position_sigma, C, work)
        else:
            _, sp, sv = candidate_sigmas(Q, X, c, sig, used_n, position_sigma, False)
        # world position M = O_1 + R_1 r̂_1 a_1 at t_1, velocity R_1 V̂
        mw = _world(R, 0, (M1[c, 0], M1[c, 1], M1[c, 2]))
        for x in range(3):
            cpos[c, x] = O[0, x] + mw[x]
        cdt[c] = dt[c, 0]
        csig[c, 0], csig[c, 1] = sp, sv
        if used_n == 3:
            vw = _world(R, 0, (X[c, 3], X[c, 4], X[c, 5]))
            cvel[c, 0], cvel[c, 1], cvel[c, 2] = vw
            # a triple whose speed exceeds the limit by more than q σ_vel is infeasible at
            # the gate's confidence: dropped before receivers 4 … n are searched for it
            # (at n = 3 the check below, on the speed alone, drops it as well)
            if not norm3(vw) - gate_q * sv <= max_speed:
                continue
            # receivers 4 … n join (theory §3.3, any n ≥ 3); the speed check applies to the
            # joint solution. Receiver k contributes the fix whose line of sight passes nearest
            # the prediction p = M + V (t_k − t_1) at that fix's time: the miss
            # e = ‖d − (d·u) u‖ (d = p − O_k, u the measured direction, in front of the
            # receiver) within q √(σ_pos² + (σ_vel Δ)² + (σ_k d·u)²) + ½ a_max Δ² (floored at
            # GATE_FLOOR); cmem[c, k] records it (−1: none). O(n F) per candidate.
            t1 = ctime[c]
            px, py, pz = cpos[c, 0], cpos[c, 1], cpos[c, 2]
            vx, vy, vz = cvel[c, 0], cvel[c, 1], cvel[c, 2]
            vn = np.sqrt(vx * vx + vy * vy + vz * vz)
            mk = np.int64(2)
            misses = 0
            for k in range(3, n):
                best, bj = np.inf, -1
                ox, oy, oz = O[k, 0], O[k, 1], O[k, 2]
                sig_k = sig[k]
                for j in range(fix_count[i, k]):
                    # fixes[i, k, j] = (world direction u, time): C-contiguous rows
                    s = fixes[i, k, j, 3] - t1
                    d = (px + vx * s - ox, py + vy * s - oy, pz + vz * s - oz)
                    u = (fixes[i, k, j, 0], fixes[i, k, j, 1], fixes[i, k, j, 2])
                    along = d[0] * u[0] + d[1] * u[1] + d[2] * u[2]
                    if not along > 0.0:
                        continue
                    miss2 = max(d[0] * d[0] + d[1] * d[1] + d[2] * d[2] - along * along, 0.0)
                    if not miss2 < best:
                        continue
                    var = sp * sp + (sv * s) ** 2 + (sig_k * along) ** 2
                    drift = 0.5 * max_accel * s * s
                    # (q σ + a)² ≤ 2 (q² σ² + a²): a fix missing by more (and by more than the
                    # floor) is out of the gate without the square root (most fixes are other
                    # objects')
                    if miss2 > GATE_SLACK * max(2.0 * (gate_q * gate_q * var + drift * drift),
                                                GATE_FLOOR * GATE_FLOOR):  # fmt: skip
                        continue
                    tol = max(gate_q * np.sqrt(var) + drift, GATE_FLOOR)
                    if miss2 <= tol * tol:
                        best, bj = miss2, j
                cmem[c, k] = bj
                if bj >= 0:
                    mk += 1
                elif ghost_misses > 0 and _surely_seen(k, cones, O, t1, px, py, pz, vx, vy,
                                                       vz, vn, sp, sv, gate_q, max_accel):  # fmt: skip
                    # negative information: detection is certain inside a sector (the raster
                    # visits every pixel), so a real object there has a fix, which misses its
                    # gate with probability 1 − gate_probability
                    misses += 1
                    if misses >= ghost_misses:
                        break
            if ghost_misses > 0 and misses >= ghost_misses:
                for k in range(3, n):
                    cmem[c, k] = -1
                continue
            if mk > 2 and not _joint_fit(i, c, mk, la, fixes, O, R, P, b, sig, limits, chi2_max,
                                         cmem, cpos, cvel, ctime, csig, r_a1, r_ak, r_P, r_b,
                                         r_dt, r_X, r_J, r_Q, r_kap, r_M1, r_sg,
                                         r_work):  # fmt: skip
                continue
            speed = norm3((cvel[c, 0], cvel[c, 1], cvel[c, 2]))
            if not speed <= max_speed:
                continue
        else:
            if not pair_passes(J[c], X[c, 0], X[c, 1], sig[0], sig[1], position_sigma,
                               gate_q, max_speed, dt[c, 0]):  # fmt: skip
                continue
            cvel[c, 0], cvel[c, 1], cvel[c, 2] = 0.0, 0.0, 0.0
        cok[c] = True


@njit(**_JIT)
def step_rows(
    lo,  # first scenario row
    hi,  # end of the rows (the caller splits a batch over threads, envs/shells/rows.py)
    cf,  # per-params constants (C_* layout, with the receivers' geometry)
    action,  # (B, n, 3) raw actions
    t_in,  # (B,) the state before the period
    p_in,  # (B, m, 3)
    v_in,  # (B, m, 3)
    drone_a,  # (B, m, 3) (constant)
    enter,  # (B, m) (constant)
    exited_in,  # (B, m)
    tracks_in,  # (B, T, 19)
    track_int_in,  # (B, T, 4)
    next_id_in,  # (B,)
    dir_normals,  # (B, n, m, 3) standard normal draws of the direction noise
    pos_noise,  # (B, m, 3) apparent-position errors (or (B or 0, ...) zeros if σ_x = 0)
    clutter_count,  # (B, n) false detections (or zeros)
    clutter_uv,  # (B, n, max_clutter, 2) their places in the sector
    # outputs (out of place: none may alias an input)
    t,  # (B,)
    drone_p,  # (B, m, 3)
    drone_v,  # (B, m, 3)
    exited,  # (B, m)
    tracks,  # (B, T, 19)
    track_int,  # (B, T, 4)
    next_id,  # (B,)
    sectors,  # (B, n, 3)
    fixes,  # (B, n, F, 4)
    fix_count,  # (B, n)
    fix_drone,  # (B, n, F)
    assigned,  # (B, m)
    drone_sigma,  # (B, m)
    parts,  # (B, 6)
    obs,  # (B, obs_dim) float32: the observation of the new state (observe_row)
    reward,  # (B,)
    terminated,  # (B,) bool: every drone has left
):
    """One scan period of scenarios ``lo..hi`` (module docstring), written to the output
    arrays; then the new state's observation. Returns False (and stops) if an action is NaN or
    infinite.

    ``parts (B, 6)``: drones present, drones with a confirmed track, false confirmed tracks,
    mean per-drone reward, mean ``σ_pos`` of the tracked drones, confirmed tracks.
    """
    for i in range(lo, hi):
        for k in range(action.shape[1]):
            for x in range(3):
                if not math.isfinite(action[i, k, x]):
                    return False
    scene_half, scene_floor, scene_height = cf[C_SCENE_HALF], cf[C_FLOOR], cf[C_HEIGHT]
    sweep, lines, period = cf[C_SWEEP], cf[C_LINES], cf[C_PERIOD]
    lo_w, hi_w, half_regard = cf[C_LO_W], cf[C_HI_W], cf[C_HALF_REGARD]
    kappa, sigma_min, position_sigma = cf[C_KAPPA], cf[C_SIGMA_MIN], cf[C_POS_SIGMA]
    max_speed, max_accel, gate_q, cond_max = (
        cf[C_MAX_SPEED],
        cf[C_MAX_ACCEL],
        cf[C_GATE_Q],
        cf[C_COND],
    )
    sigma_ref, reward_clip = cf[C_SIGMA_REF], cf[C_REWARD_CLIP]
    false_penalty, truth_gate = cf[C_FALSE_PENALTY], cf[C_TRUTH_GATE]
    tracker, iters = int(cf[C_TRACKER]), int(cf[C_ITERS])
    confirm_hits, max_misses = int(cf[C_CONFIRM]), int(cf[C_MISSES])
    ghost_misses = int(cf[C_GHOST])
    O, R, P, b, offsets = geometry(cf, action.shape[1])
    chi2_max = fit_thresholds(cf, action.shape[1])
    # views of the outputs by role (the table's columns, the fixes' direction and time)
    fix_world, fix_time = fixes[:, :, :, 0:3], fixes[:, :, :, 3]
    tx, tt, tsig, tscore = tracks[:, :, 0:6], tracks[:, :, 6], tracks[:, :, 7:9], tracks[:, :, 9]
    tsums = tracks[:, :, 10:19]
    thits, tmiss = track_int[:, :, 0], track_int[:, :, 1]
    tstatus, tid = track_int[:, :, 2], track_int[:, :, 3]
    n = action.shape[1]
    m = drone_p.shape[1]
    F = fix_world.shape[2]
    T = tx.shape[1]
    cm = clutter_uv.shape[2]
    used_n = 3 if tracker == PROPOSED else 2
    C = F**used_n
    # scratch: views of three buffers, allocated once per call (one allocation per dtype
    # instead of fifty)
    nx = used_n + (3 if used_n == 3 else 0)
    u1, FF, TC = used_n - 1, F * F, T * C
    fbuf = np.empty(
        n * F * 3
        + n
        + C * (3 + 15 * u1 + 2 + 1 + nx + 1 + nx * nx + 1 + 3 + 3 + 3 + 1 + 2 + 1)
        + TC * 14
        + T * (20 + m + 3 + 1)
        + FF * 30
        + n * 7
    )
    ibuf = np.empty(C * (n + 2) + TC * 4 + 2 * T, np.int64)
    # the refinement's system, sized for all n receivers (receivers 4 … n, :func:`_joint_fit`)
    rbuf = np.empty(3 + 16 * (n - 1) + (n + 3) * (n + 4) + 5 + n + velocity_work(n - 1))
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
    bbuf = np.empty(2 * C + n * F + T + 5 * FF, np.bool_)
    o = 0
    la, o = _carve3(fbuf, o, n, F, 3)
    sig, o = _carve1(fbuf, o, n)
    a1, o = _carve2(fbuf, o, C, 3)
    ak, o = _carve3(fbuf, o, C, u1, 3)
    Pc, o = _carve4(fbuf, o, C, u1, 3, 3)
    bc, o = _carve3(fbuf, o, C, u1, 3)
    dt, o = _carve2(fbuf, o, C, 2)
    ones, o = _carve1(fbuf, o, C)
    ones[:] = 1.0
    X, o = _carve2(fbuf, o, C, nx)
    J, o = _carve1(fbuf, o, C)
    Q, o = _carve3(fbuf, o, C, nx, nx)
    kap, o = _carve1(fbuf, o, C)
    M1, o = _carve2(fbuf, o, C, 3)
    cpos, o = _carve2(fbuf, o, C, 3)
    cvel, o = _carve2(fbuf, o, C, 3)
    ctime, o = _carve1(fbuf, o, C)
    csig, o = _carve2(fbuf, o, C, 2)
    cdt, o = _carve1(fbuf, o, C)
    pairs_s, o = _carve1(fbuf, o, TC)
    pairs_mv, o = _carve2(fbuf, o, TC, 6)
    child_mv, o = _carve2(fbuf, o, TC, 6)
    child_s, o = _carve1(fbuf, o, TC)
    old, o = _carve2(fbuf, o, T, 20)
    d_dist, o = _carve2(fbuf, o, T, m)
    t_end_pos, o = _carve2(fbuf, o, T, 3)
    t_cmp, o = _carve1(fbuf, o, T)
    # the triples' pair pre-gates
    pa1, o = _carve2(fbuf, o, FF, 3)
    pa2, o = _carve3(fbuf, o, FF, 1, 3)
    pP, o = _carve4(fbuf, o, FF, 1, 3, 3)
    pb, o = _carve3(fbuf, o, FF, 1, 3)
    pones, o = _carve1(fbuf, o, FF)
    pones[:] = 1.0
    pX, o = _carve2(fbuf, o, FF, 2)
    pJ, o = _carve1(fbuf, o, FF)
    pQ, o = _carve3(fbuf, o, FF, 2, 2)
    pk, o = _carve1(fbuf, o, FF)
    pM, o = _carve2(fbuf, o, FF, 3)
    cones, o = _carve2(fbuf, o, n, 7)
    o = 0
    cmem, o = _carve2(ibuf, o, C, n)
    rng_idx, o = _carve1(ibuf, o, C)
    ok_c, o = _carve1(ibuf, o, C)
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
    for i in range(lo, hi):
        # the state before the period, copied into the outputs (then updated there)
        t[i] = t_in[i]
        next_id[i] = next_id_in[i]
        for j in range(m):
            exited[i, j] = exited_in[i, j]
            for x in range(3):
                drone_p[i, j, x] = p_in[i, j, x]
                drone_v[i, j, x] = v_in[i, j, x]
        for q in range(T):
            for x in range(tracks.shape[2]):
                tracks[i, q, x] = tracks_in[i, q, x]
            for x in range(track_int.shape[2]):
                track_int[i, q, x] = track_int_in[i, q, x]
        for k in range(n):
            for f in range(F):
                fix_drone[i, k, f] = 0
                for x in range(4):
                    fixes[i, k, f, x] = 0.0
        t0 = t[i]
        # ---- 1. sectors and fixes -------------------------------------------------------
        for k in range(n):
            az, el, w = sector_of(action[i, k], lo_w, hi_w, half_regard)
            sectors[i, k, 0], sectors[i, k, 1], sectors[i, k, 2] = az, el, w
            sig[k] = sector_sigma(w, kappa, sigma_min)
            if k >= 3 and ghost_misses > 0:
                sector_cone(R, k, az, el, w, offsets[k], sweep, t0, cones)
            o = (O[k, 0], O[k, 1], O[k, 2])
            c = 0
            for j in range(m):
                if exited[i, j] or enter[i, j] > t0 + 1e-9:
                    continue
                # the apparent position carries one shared error per object and period
                p = (
                    drone_p[i, j, 0] + pos_noise[i, j, 0],
                    drone_p[i, j, 1] + pos_noise[i, j, 1],
                    drone_p[i, j, 2] + pos_noise[i, j, 2],
                )
                v = (drone_v[i, j, 0], drone_v[i, j, 1], drone_v[i, j, 2])
                acc = (drone_a[i, j, 0], drone_a[i, j, 1], drone_a[i, j, 2])
                seen, s, d = raster_fix(
                    R, k, o, p, v, acc, az, el, w, lines, offsets[k], sweep, iters
                )
                if not seen:
                    continue
                r = norm3(d)
                u = (d[0] / r, d[1] / r, d[2] / r)
                if sig[k] > 0.0:
                    z = (dir_normals[i, k, j, 0], dir_normals[i, k, j, 1], dir_normals[i, k, j, 2])
                    u = perturbed_direction3(u, z, sig[k])
                la[k, c, 0], la[k, c, 1], la[k, c, 2] = u
                uw = _world(R, k, u)
                fix_world[i, k, c, 0], fix_world[i, k, c, 1], fix_world[i, k, c, 2] = uw
                fix_time[i, k, c] = t0 + s
                fix_drone[i, k, c] = j
                c += 1
            for q in range(min(clutter_count[i, k], cm)):
                phi = az + (clutter_uv[i, k, q, 0] - 0.5) * w
                theta = el + (clutter_uv[i, k, q, 1] - 0.5) * w
                u = unit_from_angles3(phi, theta)
                la[k, c, 0], la[k, c, 1], la[k, c, 2] = u
                uw = _world(R, k, u)
                fix_world[i, k, c, 0], fix_world[i, k, c, 1], fix_world[i, k, c, 2] = uw
                fix_time[i, k, c] = t0 + raster_time(
                    phi, theta, az, el, w, w, lines, lines, offsets[k], sweep
                )
                fix_drone[i, k, c] = -1
                c += 1
            fix_count[i, k] = c
        # ---- 2. candidates: every pair / triple of fixes, one per receiver ----------------
        nc = 0
        c1 = fix_count[i, 0]
        c2 = fix_count[i, 1]
        c3 = fix_count[i, 2] if used_n == 3 else 1
        if used_n == 3:
            _pair_gates(i, np.int64(0), np.int64(1), la, fix_time, c1, c2, P, b, sig,
                        position_sigma, gate_q, max_speed, pa1, pa2, pP, pb, pones, pX, pJ, pQ,
                        pk, pM, every, g12)  # fmt: skip
            _pair_gates(i, np.int64(0), np.int64(2), la, fix_time, c1, c3, P, b, sig,
                        position_sigma, gate_q, max_speed, pa1, pa2, pP, pb, pones, pX, pJ, pQ,
                        pk, pM, every, g13)  # fmt: skip
            # receivers 2–3: only the pairs some fix of receiver 1 joins through both its gates
            for j2 in range(c2):
                for j3 in range(c3):
                    need23[j2, j3] = False
            for j1 in range(c1):
                for j2 in range(c2):
                    if g12[j1, j2]:
                        for j3 in range(c3):
                            if g13[j1, j3]:
                                need23[j2, j3] = True
            _pair_gates(i, np.int64(1), np.int64(2), la, fix_time, c2, c3, P, b, sig,
                        position_sigma, gate_q, max_speed, pa1, pa2, pP, pb, pones, pX, pJ, pQ,
                        pk, pM, need23, g23)  # fmt: skip
        for j1 in range(c1):
            for j2 in range(c2):
                if used_n == 3 and not g12[j1, j2]:
                    continue
                for j3 in range(c3):
                    if used_n == 3 and not (g13[j1, j3] and g23[j2, j3]):
                        continue
                    for x in range(3):
                        a1[nc, x] = la[0, j1, x]
                        ak[nc, 0, x] = la[1, j2, x]
                        bc[nc, 0, x] = b[0, x]
                        for y in range(3):
                            Pc[nc, 0, x, y] = P[0, x, y]
                    dt[nc, 0] = fix_time[i, 1, j2] - fix_time[i, 0, j1]
                    for k in range(n):
                        cmem[nc, k] = -1
                    cmem[nc, 0], cmem[nc, 1] = j1, j2
                    if used_n == 3:
                        for x in range(3):
                            ak[nc, 1, x] = la[2, j3, x]
                            bc[nc, 1, x] = b[1, x]
                            for y in range(3):
                                Pc[nc, 1, x, y] = P[1, x, y]
                        dt[nc, 1] = fix_time[i, 2, j3] - fix_time[i, 0, j1]
                        cmem[nc, 2] = j3
                    ctime[nc] = fix_time[i, 0, j1]
                    nc += 1
        if used_n == 3:
            triple_velocity_kernel(
                a1,
                ak,
                Pc,
                bc,
                dt,
                1.0,
                np.bool_(False),
                np.int64(0),
                np.int64(nc),
                X,
                J,
                Q,
                kap,
                M1,
            )
        else:
            pair_kernel(
                a1,
                ak,
                Pc,
                bc,
                ones,
                1.0,
                np.bool_(False),
                np.int64(0),
                np.int64(nc),
                X,
                J,
                Q,
                kap,
                M1,
            )
        screen_candidates(i, np.int64(nc), used_n, la, fixes, fix_count, O, R, P, b, sig,
                          position_sigma, gate_q, max_speed, max_accel, cond_max, chi2_max, X, J,
                          Q, kap, M1, dt, cmem, cpos, cvel, ctime, csig, cdt, cok, ctaken, r_a1,
                          r_ak, r_P, r_b, r_dt, r_X, r_J, r_Q, r_kap, r_M1, r_sg,
                          r_work, cones, ghost_misses)  # fmt: skip
        # ---- 3. association: confirmed tracks first, one-to-one, no shared vectors --------
        for k in range(n):
            for j in range(F):
                fused[k, j] = False
        for q in range(T):
            t_took[q] = False
        n_ok = 0  # the candidates that passed, in ascending order
        for c in range(nc):
            if cok[c]:
                ok_c[n_ok] = c
                n_ok += 1
        npair = 0
        for q in range(T):
            if tstatus[i, q] == EMPTY:
                continue
            for e in range(n_ok):
                c = ok_c[e]
                if tracker == PROPOSED and _outside_gate(q, c, i, tx, tt, tsig, cpos, ctime, csig,
                                                         gate_q, max_accel):  # fmt: skip
                    continue
                cost = _step_cost(tracker, q, c, i, tx, tt, tsig, thits, cpos, cvel, ctime, csig,
                                  cdt, gate_q, max_speed, max_accel)  # fmt: skip
                if tracker == ALGORITHMIC and cost < np.inf and thits[i, q] >= 2:
                    cost = _algorithmic_cost(i, q, c, tx, tt, tsig, thits, cmem, la, O, R, P, b,
                                             cdt, ctime, csig, sig, position_sigma, gate_q,
                                             max_accel, pa1, pa2, pP, pb, pones, pX, pJ, pQ, pk,
                                             pM, pairs_mv, np.int64(npair))  # fmt: skip
                elif cost < np.inf:
                    for x in range(3):
                        pairs_mv[npair, x] = cpos[c, x]
                        pairs_mv[npair, 3 + x] = cvel[c, x]
                if cost < np.inf:
                    pairs_t[npair], pairs_c[npair], pairs_s[npair] = q, c, cost
                    npair += 1
        order = np.argsort(pairs_s[:npair])
        # confirmed tracks: greedy by ΔJ
        for e in order:
            q, c = pairs_t[e], pairs_c[e]
            if tstatus[i, q] != CONFIRMED or t_took[q] or _shares(cmem, c, fused):
                continue
            t_took[q] = True
            _mark(cmem, c, fused)
            ctaken[c] = True
            _update(tracker, i, q, c, pairs_s[e], pairs_mv[e], ctime, csig, cdt, tx, tt, tsig, tscore,
                    thits, tmiss, tsums, max_speed)  # fmt: skip
        # tentative tracks: every passing continuation is a child (000's groups), in ascending
        # cumulative index; a child reaching ``confirm_hits`` is confirmed if it shares no vector
        n_child = 0
        for e in order:
            q, c = pairs_t[e], pairs_c[e]
            if tstatus[i, q] != TENTATIVE or _shares(cmem, c, fused):
                continue
            child_t[n_child], child_c[n_child] = q, c
            child_s[n_child] = tscore[i, q] + pairs_s[e]
            for x in range(6):
                child_mv[n_child, x] = pairs_mv[e, x]
            n_child += 1
        child_order = np.argsort(child_s[:n_child])
        # old tentative tracks are replaced by their children (copied into a scratch first)
        r_ = 0
        for q in range(T):
            if tstatus[i, q] == TENTATIVE:
                _save(old, r_, i, q, tx, tt, tsig, tscore, thits, tsums)
                old_slot[q] = r_
                r_ += 1
                tstatus[i, q] = EMPTY
        for e in child_order:
            q, c = child_t[e], child_c[e]
            if _shares(cmem, c, fused):
                continue
            slot = _free(tstatus, i, T)
            if slot < 0:
                break
            _load(old, old_slot[q], i, slot, tx, tt, tsig, tscore, thits, tsums)
            tmiss[i, slot] = 0
            _update(tracker, i, slot, c, child_s[e] - tscore[i, slot], child_mv[e], ctime, csig, cdt,
                    tx, tt, tsig, tscore, thits, tmiss, tsums, max_speed)  # fmt: skip
            ctaken[c] = True
            if thits[i, slot] >= confirm_hits:
                tstatus[i, slot] = CONFIRMED
                tid[i, slot] = next_id[i]
                next_id[i] += 1
                t_took[slot] = True
                _mark(cmem, c, fused)
            else:
                tstatus[i, slot] = TENTATIVE
                t_took[slot] = True
        # confirmed tracks without a continuation coast; dropped after ``max_misses``
        for q in range(T):
            if tstatus[i, q] == CONFIRMED and not t_took[q]:
                tmiss[i, q] += 1
                if tmiss[i, q] > max_misses:
                    tstatus[i, q] = EMPTY
        # births: candidates sharing no vector with a continued track open tentative tracks
        nb = 0
        for c in range(nc):
            if cok[c] and not ctaken[c] and not _shares(cmem, c, fused):
                rng_idx[nb] = c
                nb += 1
        for e in range(nb):
            c = rng_idx[e]
            slot = _free(tstatus, i, T)
            if slot < 0:
                break
            thits[i, slot] = 0
            tscore[i, slot] = 0.0
            tmiss[i, slot] = 0
            for x in range(9):
                tsums[i, slot, x] = 0.0
            for x in range(3):
                child_mv[0, x] = cpos[c, x]
                child_mv[0, 3 + x] = cvel[c, x]
            _update(tracker, i, slot, c, 0.0, child_mv[0], ctime, csig, cdt, tx, tt, tsig, tscore,
                    thits, tmiss, tsums, max_speed)  # fmt: skip
            if confirm_hits <= 1:
                tstatus[i, slot] = CONFIRMED
                tid[i, slot] = next_id[i]
                next_id[i] += 1
            else:
                tstatus[i, slot] = TENTATIVE
        # ---- 4. reward at the period end --------------------------------------------------
        t_end = t0 + period
        npresent = 0
        for j in range(m):
            assigned[i, j] = -1
            drone_sigma[i, j] = np.inf
        ng = 0  # the confirmed tracks within the gate of some drone, in ascending order
        for q in range(T):
            if tstatus[i, q] != CONFIRMED:
                continue
            # compared at the track's own time if it was updated this period, else at the end
            tc = tt[i, q] if tt[i, q] >= t0 else t_end
            s = tc - tt[i, q]
            t_cmp[q] = tc
            t_end_pos[q, 0], t_end_pos[q, 1], t_end_pos[q, 2] = _predicted_position(i, q, s, tx)
            near = False
            for j in range(m):
                d_dist[q, j] = np.inf
                if exited[i, j] or enter[i, j] > t0 + 1e-9:
                    continue
                pe = _at(
                    (drone_p[i, j, 0], drone_p[i, j, 1], drone_p[i, j, 2]),
                    (drone_v[i, j, 0], drone_v[i, j, 1], drone_v[i, j, 2]),
                    (drone_a[i, j, 0], drone_a[i, j, 1], drone_a[i, j, 2]),
                    tc - t0,
                )
                dd = norm3((t_end_pos[q, 0] - pe[0], t_end_pos[q, 1] - pe[1],
                            t_end_pos[q, 2] - pe[2]))  # fmt: skip
                if dd <= truth_gate:
                    d_dist[q, j] = dd
                    near = True
            if near:
                g_rows[ng] = q
                ng += 1
        # greedy nearest (track, drone) pairs within the gate, one-to-one
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
            s = t_cmp[bq] - tt[i, bq]
            drone_sigma[i, bj] = _predicted_sigma(i, bq, s, tsig)
            for e in range(ng):
                d_dist[g_rows[e], bj] = np.inf
            for j in range(m):
                d_dist[bq, j] = np.inf
        total = 0.0
        found = 0
        for j in range(m):
            if exited[i, j] or enter[i, j] > t0 + 1e-9:
                continue
            npresent += 1
            if assigned[i, j] >= 0:
                found += 1
                total += log_ratio_reward(drone_sigma[i, j], sigma_ref, reward_clip)
            else:
                total -= reward_clip
        n_false = 0
        for q in range(T):
            if tstatus[i, q] == CONFIRMED:
                hit = False
                for j in range(m):
                    if assigned[i, j] == q:
                        hit = True
                if not hit:
                    n_false += 1
        mean = total / npresent if npresent > 0 else 0.0
        reward[i] = mean - false_penalty * n_false
        parts[i, 0], parts[i, 1], parts[i, 2], parts[i, 3] = npresent, found, n_false, mean
        total_sigma = 0.0
        for j in range(m):
            if assigned[i, j] >= 0:
                total_sigma += drone_sigma[i, j]
        parts[i, 4] = total_sigma / found if found > 0 else 0.0
        n_conf = 0
        for q in range(T):
            if tstatus[i, q] == CONFIRMED:
                n_conf += 1
        parts[i, 5] = n_conf
        # ---- 5. the drones fly on; leaving the scene is for good ---------------------------
        for j in range(m):
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
                    abs(pe[0]) > scene_half
                    or abs(pe[2]) > scene_half
                    or pe[1] < scene_floor
                    or pe[1] > scene_height
                ):
                    exited[i, j] = True
        t[i] = t_end
        gone = True
        for j in range(m):
            if not exited[i, j]:
                gone = False
        terminated[i] = gone
        # ---- 6. what the new state shows ----------------------------------------------------
        observe_row(i, cf, t, tracks, track_int, sectors, fix_count, obs)
    return True


@njit(**_JIT)
def _predicted_position(i, q, s, tx):
    """Track ``q``'s position predicted ``s`` after its time, ``M̂ + V̂ s`` (m): the
    constant-velocity prediction of the gates, the costs and the observation."""
    return (
        tx[i, q, 0] + tx[i, q, 3] * s,
        tx[i, q, 1] + tx[i, q, 4] * s,
        tx[i, q, 2] + tx[i, q, 5] * s,
    )


@njit(**_JIT)
def _prediction_residual(i, q, s, tx, p):
    """``p − (M̂ + V̂ s)``: point ``p (3,)``'s miss of track ``q``'s prediction
    (:func:`_predicted_position`), m."""
    pred = _predicted_position(i, q, s, tx)
    return p[0] - pred[0], p[1] - pred[1], p[2] - pred[2]


@njit(**_JIT)
def _predicted_variance(i, q, s, tsig):
    """``σ_pos² + (σ_vel s)²``: variance of track ``q``'s position predicted ``s`` after its
    time (``tsig[i, q]`` = ``σ_pos, σ_vel``), m²."""
    return tsig[i, q, 0] ** 2 + (tsig[i, q, 1] * s) ** 2


@njit(**_JIT)
def _predicted_sigma(i, q, s, tsig):
    """``√`` of :func:`_predicted_variance`, m."""
    return np.sqrt(_predicted_variance(i, q, s, tsig))


@njit(**_JIT)
def _outside_gate(q, c, i, tx, tt, tsig, cpos, ctime, csig, gate_q, max_accel):
    """Whether candidate ``c`` surely fails track ``q``'s position gate in :func:`_step_cost`
    (proposed tracker), without a square root: ``(q s + m)² ≤ 2 (q² s² + m²)``, so a
    candidate further than that from the prediction (and than the floor) is out. Most
    track–candidate pairs are other objects'; the rest are scored in full."""
    s = ctime[c] - tt[i, q]
    e0, e1, e2 = _prediction_residual(i, q, s, tx, cpos[c])
    spread2 = (csig[c, 0] ** 2 + _predicted_variance(i, q, s, tsig)) / 3.0
    margin = 0.5 * max_accel * s * s
    bound = max(2.0 * (gate_q * gate_q * spread2 + margin * margin), GATE_FLOOR * GATE_FLOOR)
    return e0 * e0 + e1 * e1 + e2 * e2 > GATE_SLACK * bound


@njit(**_JIT)
def _step_cost(tracker, q, c, i, tx, tt, tsig, thits, cpos, cvel, ctime, csig, cdt, gate_q,
               max_speed, max_accel):  # fmt: skip
    """ΔJ = ‖M(i, j) − (M̂_s + V̂_s (t − t_s))‖ if it passes the gate δ, else inf (000 step 3-4).

    ``δ = q · s + margin``, ``s² = (σ_pos,c² + σ_pos,pred²)/3`` per axis; margin ``½ a_max Δ²``
    (proposed) or ``v_max |Δt|`` (the alternative's dynamic error may drift by its size); the
    proposed also needs ``‖V − V̂_s‖ ≤ q √((σ_vel,c² + σ_vel,s²)/3) + a_max Δ``. An
    alternative track of one point has no velocity: any candidate within ``2 v_max Δ`` continues
    it at zero cost (000 temporal step 1, theory §13.11). Both gates are floored at
    :data:`GATE_FLOOR` (noise-free fixes of an unaccelerated drone would otherwise need an
    exact zero)."""
    s = ctime[c] - tt[i, q]
    if not s > 0.0:
        return np.inf
    d = norm3(_prediction_residual(i, q, s, tx, cpos[c]))
    if tracker != PROPOSED and thits[i, q] < 2:
        return 0.0 if d <= 2.0 * max_speed * s else np.inf
    if tracker == ALGORITHMIC:
        return 0.0  # scored by _algorithmic_cost
    sp = _predicted_sigma(i, q, s, tsig)
    spread = np.sqrt((csig[c, 0] ** 2 + sp**2) / 3.0)
    if tracker == ALTERNATIVE:
        margin = max_speed * abs(cdt[c])
    else:
        margin = 0.5 * max_accel * s * s
        # velocity consistency (003's J_3, theory §5.5): a ghost triple of two close drones
        # fixes near them with a velocity of neither
        dv = norm3((cvel[c, 0] - tx[i, q, 3], cvel[c, 1] - tx[i, q, 4], cvel[c, 2] - tx[i, q, 5]))
        dv_gate = gate_q * np.sqrt((csig[c, 1] ** 2 + tsig[i, q, 1] ** 2) / 3.0) + max_accel * s
        if not dv <= max(dv_gate, GATE_FLOOR):
            return np.inf
    return d if d <= max(gate_q * spread + margin, GATE_FLOOR) else np.inf


@njit(**_JIT)
def _algorithmic_cost(i, q, c, tx, tt, tsig, thits, cmem, la, O, R, P, b, cdt, ctime, csig, sig,
                      position_sigma, gate_q, max_accel, pa1, pa2, pP, pb, pones, pX, pJ, pQ, pk,
                      pM, out, row):  # fmt: skip
    """Paper 003's algorithmic index of extending track ``q`` by pair ``c`` (theory §5.5, online):
    the pair re-solved with the track's motion moved to the right-hand side,
    ``B̂_2 = b_2 − V Δt_2`` (steps 2.1–2.2, the range re-solve of theory §3.3), then
    ``J = c_1 J_1 + c_2 J_2 + c_3 J_3`` with the compensated miss ``J_1 = ‖e_2‖``, the proximity
    ``J_2 = ‖M* − (M̂_s + V̂_s Δ)‖`` and the velocity consistency ``J_3 = ‖V̂ − V̂_s‖``,
    ``V̂ = (M* − M̂_s)/Δ``; ``c_1 = 1/√(σ_e² + (σ_vel Δt_2)²)``, ``c_2 = 1/(2√2 σ_p)``,
    ``c_3 = Δ/(2√2 σ_p)`` (theory §13.6; ``σ_p`` per axis of the candidate and the track's
    prediction; both floored at 1 mm); ``J_2``, ``J_3`` less the gentle
    acceleration's ``½ a_max Δ²``, ``a_max Δ``; ``J ≤ α_3 = 3 q``, else inf. Writes
    ``(M*, V̂)`` to ``out[row]``."""
    s = ctime[c] - tt[i, q]
    # V in frame 1: R_1ᵀ V
    v1 = _local(R, 0, (tx[i, q, 3], tx[i, q, 4], tx[i, q, 5]))
    j1, j2 = cmem[c, 0], cmem[c, 1]
    for x in range(3):
        pa1[0, x] = la[0, j1, x]
        pa2[0, 0, x] = la[1, j2, x]
        # B̂_2 = b_2 − V Δt_2
        pb[0, 0, x] = b[0, x] - v1[x] * cdt[c]
        for y in range(3):
            pP[0, 0, x, y] = P[0, x, y]
    pair_kernel(
        pa1, pa2, pP, pb, pones, 1.0, np.bool_(False), np.int64(0), np.int64(1), pX, pJ, pQ, pk, pM
    )
    if not (pX[0, 0] > 0.0 and pX[0, 1] > 0.0):
        return np.inf
    mw = _world(R, 0, (pM[0, 0], pM[0, 1], pM[0, 2]))
    m = (O[0, 0] + mw[0], O[0, 1] + mw[1], O[0, 2] + mw[2])
    x1, x2 = sig[0] * pX[0, 0], sig[1] * pX[0, 1]
    sigma_e = np.sqrt(position_sigma * position_sigma + 0.5 * (x1 * x1 + x2 * x2))
    # σ_p per axis: the candidate's and the track's prediction (its velocity error over Δ)
    sp = np.sqrt((csig[c, 0] ** 2 + _predicted_sigma(i, q, s, tsig) ** 2) / 3.0)
    J1 = np.sqrt(pJ[0])
    d = _prediction_residual(i, q, s, tx, m)
    J2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
    J3 = 0.0
    for x in range(3):
        v = (m[x] - tx[i, q, x]) / s
        out[row, x] = m[x]
        out[row, 3 + x] = v
        dv = v - tx[i, q, 3 + x]
        J3 += dv * dv
    # the drones accelerate gently: J_2, J_3 allow ½ a_max Δ² and a_max Δ; normalisers are
    # floored at 1 mm (noise-free fixes)
    k = 2.0 * np.sqrt(2.0) * max(sp, 1e-3)
    J2 = max(np.sqrt(J2) - 0.5 * max_accel * s * s, 0.0)
    J3 = max(np.sqrt(J3) - max_accel * s, 0.0)
    # J_1's spread also holds the track velocity's error over the delay (the compensation)
    s1 = np.sqrt(sigma_e * sigma_e + (tsig[i, q, 1] * cdt[c]) ** 2)
    cost = J1 / max(s1, 1e-3) + J2 / k + s * J3 / k
    return cost if cost <= 3.0 * gate_q else np.inf


@njit(**_JIT)
def _shares(cmem, c, fused):
    """Whether candidate ``c`` uses a fix already taken (``cmem[c, k] = −1``: none of ``k``)."""
    for k in range(cmem.shape[1]):
        j = cmem[c, k]
        if j >= 0 and fused[k, j]:
            return True
    return False


@njit(**_JIT)
def _mark(cmem, c, fused):
    for k in range(cmem.shape[1]):
        j = cmem[c, k]
        if j >= 0:
            fused[k, j] = True


@njit(**_JIT)
def _free(tstatus, i, T):
    for q in range(T):
        if tstatus[i, q] == EMPTY:
            return q
    return -1


@register_jitable(**_JIT)
def _save(old, r, i, q, tx, tt, tsig, tscore, thits, tsums):
    for x in range(6):
        old[r, x] = tx[i, q, x]
    old[r, 6] = tt[i, q]
    old[r, 7], old[r, 8] = tsig[i, q, 0], tsig[i, q, 1]
    old[r, 9] = tscore[i, q]
    old[r, 10] = thits[i, q]
    for x in range(9):
        old[r, 11 + x] = tsums[i, q, x]


@njit(**_JIT)
def _load(old, r, i, q, tx, tt, tsig, tscore, thits, tsums):
    for x in range(6):
        tx[i, q, x] = old[r, x]
    tt[i, q] = old[r, 6]
    tsig[i, q, 0], tsig[i, q, 1] = old[r, 7], old[r, 8]
    tscore[i, q] = old[r, 9]
    thits[i, q] = int(old[r, 10])
    for x in range(9):
        tsums[i, q, x] = old[r, 11 + x]


@njit(**_JIT)
def _update(tracker, i, q, c, cost, mv, ctime, csig, cdt, tx, tt, tsig, tscore, thits, tmiss,
            tsums, max_speed):  # fmt: skip
    """Extend track ``q`` by candidate ``c``: ``I ← I + ΔJ``. Proposed (000 step 3): the track
    takes the latest spatial estimate ``(M, V)``. Alternative (theory §13.11): a least-squares
    line ``M(t) = M̂ + V̂ (t − t_latest)`` over all members, kept as running sums."""
    tscore[i, q] += cost
    before = thits[i, q]
    thits[i, q] += 1
    tmiss[i, q] = 0
    tc = ctime[c]
    if tracker == PROPOSED:
        for x in range(3):
            tx[i, q, x] = mv[x]
            tx[i, q, 3 + x] = mv[3 + x]
        tsig[i, q, 0], tsig[i, q, 1] = csig[c, 0], csig[c, 1]
        tt[i, q] = tc
        return
    if tracker == ALGORITHMIC:
        # 003 steps 2.5 and 3: the motion-compensated fix; the velocity from the previous fix
        # (first continuation), then averaged recursively, V_i = V_{i−1} + (V̂ − V_{i−1})/(i − 1)
        s = tc - tt[i, q]
        for x in range(3):
            if before == 0:
                v = 0.0
            elif before == 1:
                v = (mv[x] - tx[i, q, x]) / s
            else:
                v = tx[i, q, 3 + x] + (mv[3 + x] - tx[i, q, 3 + x]) / before
            tx[i, q, x] = mv[x]
            tx[i, q, 3 + x] = v
        tsig[i, q, 0] = csig[c, 0]
        # σ_vel: a difference of two fixes s apart, averaged over the continuations, plus the
        # dynamic error ‖V‖ |Δt_2| of the uncompensated first fixes, diluted by the average
        if before == 0:
            tsig[i, q, 1] = max_speed
        else:
            speed = norm3((tx[i, q, 3], tx[i, q, 4], tx[i, q, 5]))
            tsig[i, q, 1] = (np.sqrt(2.0) * csig[c, 0] + speed * abs(cdt[c])) / (
                s * np.sqrt(before)
            )
        tt[i, q] = tc
        return
    # sums of (1, t, t², M, t M) with t measured from the new member's time (well scaled)
    s0 = tsums[i, q, 0]
    st = 0.0
    shift = tt[i, q] - tc
    # re-centre the stored sums on tc: Σ(t − tc) = Σt' + S0 (t_old − tc) etc.
    if s0 > 0:
        st = tsums[i, q, 1] + s0 * shift
        stt = tsums[i, q, 2] + 2.0 * shift * tsums[i, q, 1] + s0 * shift * shift
        stm = np.empty(3)
        for x in range(3):
            stm[x] = tsums[i, q, 6 + x] + shift * tsums[i, q, 3 + x]
    else:
        stt = 0.0
        stm = np.zeros(3)
    s0 += 1.0
    tsums[i, q, 0], tsums[i, q, 1], tsums[i, q, 2] = s0, st, stt
    for x in range(3):
        tsums[i, q, 3 + x] += mv[x]
        tsums[i, q, 6 + x] = stm[x]
    tt[i, q] = tc
    det = s0 * stt - st * st
    if s0 >= 2.0 and det > 0.0:
        for x in range(3):
            # V̂ = (S0 ΣtM − Σt ΣM)/(S0 Σt² − (Σt)²) ;  M̂(tc) = (ΣM − V̂ Σt)/S0
            v = (s0 * tsums[i, q, 6 + x] - st * tsums[i, q, 3 + x]) / det
            tx[i, q, 3 + x] = v
            tx[i, q, x] = (tsums[i, q, 3 + x] - v * st) / s0
        tsig[i, q, 0] = csig[c, 0]
        tsig[i, q, 1] = csig[c, 0] * np.sqrt(s0 / det)
    else:
        for x in range(3):
            tx[i, q, x] = mv[x]
            tx[i, q, 3 + x] = 0.0
        tsig[i, q, 0], tsig[i, q, 1] = csig[c, 0], max_speed


@njit(**_JIT)
def _observed(v):
    """An observation entry: clipped to ``±OBS_CLIP`` (NaN stays NaN), stored as float32."""
    return clip(v, -OBS_CLIP, OBS_CLIP)


@njit(**_JIT)
def observe_row(i, c, t, tracks, track_int, sectors, fix_count, obs):
    """The observation of :func:`.simulation.observe` of scenario ``i`` into ``obs[i]``
    (float32, clipped to ``±OBS_CLIP``)."""
    T = tracks.shape[1]
    n = sectors.shape[1]
    slots = (obs.shape[1] - 4 * n) // 11
    length, speed, sigma_ref, period = c[C_LENGTH], c[C_SPEED], c[C_SIGMA_REF], c[C_PERIOD]
    half_regard, lo_w, hi_w, max_fix = c[C_HALF_REGARD], c[C_LO_W], c[C_HI_W], c[C_MAX_FIX]
    tiny = 1e-12
    tsig = tracks[:, :, 7:9]
    for x in range(obs.shape[1]):
        obs[i, x] = 0.0
    r = 0
    for q in range(T):
        if r >= slots:
            break
        if track_int[i, q, 2] != CONFIRMED:
            continue
        col = 11 * r
        s = t[i] - tracks[i, q, 6]
        obs[i, col] = 1.0
        # the track table's columns 0–5 are the state (M̂, V̂), as ``tx`` of the step
        pred = _predicted_position(i, q, s, tracks)
        for x in range(3):
            obs[i, col + 1 + x] = _observed((pred[x] - c[C_CENTRE + x]) / length)
            obs[i, col + 4 + x] = _observed(tracks[i, q, 3 + x] / speed)
        sp = _predicted_sigma(i, q, s, tsig)
        obs[i, col + 7] = _observed(np.log(max(sp, tiny) / sigma_ref))
        obs[i, col + 8] = _observed(np.log(max(tracks[i, q, 8] * period, tiny) / sigma_ref))
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
def observe_kernel(c, t, tracks, track_int, sectors, fix_count, obs):
    """:func:`observe_row` of every scenario (a state :func:`step_rows` did not make)."""
    for i in range(t.shape[0]):
        observe_row(i, c, t, tracks, track_int, sectors, fix_count, obs)
