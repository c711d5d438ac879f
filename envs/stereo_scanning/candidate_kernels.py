"""The compiled candidates of the scanning-receiver environments: one period's spatial fixes.

:func:`candidates` runs :func:`.reference.candidates` for one scenario (theory §3.3, §5.2–5.3,
§13.6): the pair pre-gates of receivers 1–3 (:func:`triple_pregates`), every surviving triple
(proposed tracker) or pair (the others) of fixes solved at once by the shared closed forms of
:mod:`sensorgym.trackers.stereo.conjugation_kernels`, then each one's checks
(:func:`screen_candidates`): the ``κ_F`` and range tests, its ``σ``s, receivers 4 … n joined
(:func:`nearest_fix`, with the negative information of :func:`surely_seen`) and the joint fit
(:func:`join_receivers`), the speed limit.

The candidates come out as a table ``cand (C, 10)`` (columns ``K_*``), their fixes
``cmem (C, n)`` and the flags ``cok``, ``ctaken (C,)``: the input of :mod:`.association_kernels`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from sensorgym.trackers.geometry_kernels import norm3, unit_from_angles3
from sensorgym.trackers.stereo.conjugation_kernels import (
    pair_kernel,
    velocity_element,
    velocity_fix_element,
)

JIT = {"cache": True, "nogil": True, "error_model": "numpy", "boundscheck": False}
_INLINE = {**JIT, "inline": "always"}

# Constant arguments of the shared primitives are passed as ``np.int64(…)`` / ``np.bool_(…)``:
# a bare literal (``0``, ``False``) makes numba compile one more specialisation per value.

#: floor of the tracker's gates, m (and m/s): noise-free fixes of an unaccelerated drone give
#: zero gates, which rounding would fail
GATE_FLOOR = 1e-3
#: margin of the gates' square-root-free bounds over round-off (:func:`nearest_fix`,
#: :func:`.association_kernels.outside_gate`)
GATE_SLACK = 1.000001
#: columns of the candidates' table ``cand (C, 10)``: world position (3) at the time of
#: receiver 1's fix, velocity (3), that time, ``(σ_pos, σ_vel)``, receiver 2's delay ``Δt_2``
K_POS, K_VEL, K_TIME, K_SIG, K_DT = 0, 3, 6, 7, 9
K_COLUMNS = 10


@njit(**JIT)
def local(R, k, d):
    """``R_kᵀ d`` for ``R (n, 3, 3)`` (``R[k, j, c]`` = component ``j`` of column ``c``)."""
    return (
        R[k, 0, 0] * d[0] + R[k, 1, 0] * d[1] + R[k, 2, 0] * d[2],
        R[k, 0, 1] * d[0] + R[k, 1, 1] * d[1] + R[k, 2, 1] * d[2],
        R[k, 0, 2] * d[0] + R[k, 1, 2] * d[1] + R[k, 2, 2] * d[2],
    )


@njit(**JIT)
def world(R, k, v):
    """``R_k v`` (receiver ``k``'s frame → world)."""
    return (
        R[k, 0, 0] * v[0] + R[k, 0, 1] * v[1] + R[k, 0, 2] * v[2],
        R[k, 1, 0] * v[0] + R[k, 1, 1] * v[1] + R[k, 1, 2] * v[2],
        R[k, 2, 0] * v[0] + R[k, 2, 1] * v[1] + R[k, 2, 2] * v[2],
    )


@njit(inline="always")
def candidate_sigmas(Q, ranges, row, sigmas, n_used, position_sigma, velocity):
    """``(σ_e, σ_pos, σ_vel)`` of a candidate from its ``Q = (AᵀA)⁻¹`` (``σ_e = 1``;
    :func:`.reference.papers_sigmas`): row ``row`` of ``Q`` and of its solution ``ranges``
    (indexed in place: a row view costs a reference count; numba-IR inlined for the same
    reason).

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


@njit(**JIT)
def pair_passes(J, r1, r2, s1, s2, position_sigma, gate_q, max_speed, dt):
    """The pair gate ``J ≤ ε_J``, ``ε_J = (q √2 σ_e + v_max |Δt|)²`` (000 eq. 9, theory §13.6;
    :func:`.reference.pair_gate`), ``σ_e² = σ_x² + ((σ_1 r̂_1)² + (σ_2 r̂_2)²)/2``: noise plus
    the largest miss distance the unmodelled motion opens between the rays; both ranges in
    front of the receivers."""
    if not (r1 > 0.0 and r2 > 0.0):
        return False
    x1, x2 = s1 * r1, s2 * r2
    sigma_e = np.sqrt(position_sigma * position_sigma + 0.5 * (x1 * x1 + x2 * x2))
    eps = gate_q * np.sqrt(2.0) * sigma_e + max_speed * abs(dt)
    return J <= eps * eps


@njit(**_INLINE)
def _frame1(P, r, la, k, j):
    """``c_k = P_k a_k``: fix ``j`` of receiver ``k``'s local direction in frame 1 (``P[r]``,
    ``r = k − 1``)."""
    return (
        P[r, 0, 0] * la[k, j, 0] + P[r, 0, 1] * la[k, j, 1] + P[r, 0, 2] * la[k, j, 2],
        P[r, 1, 0] * la[k, j, 0] + P[r, 1, 1] * la[k, j, 1] + P[r, 1, 2] * la[k, j, 2],
        P[r, 2, 0] * la[k, j, 0] + P[r, 2, 1] * la[k, j, 1] + P[r, 2, 2] * la[k, j, 2],
    )


@njit(**_INLINE)
def triple_sigmas(c, la, P, cmem, dt, X, Q, sig, position_sigma, C, work):
    """``(σ_pos, σ_vel)`` of triple candidate ``c`` (:func:`.reference.triple_covariance_sigmas`):
    the square roots of the traces of the exact first-order covariance of its ``n = 3``
    solution under the env's angle noise
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


@njit(**JIT)
def sector_cone(R, k, centre_az, centre_el, width, offset, sweep, t0, cones):
    """``cones[k] (7,)``: receiver ``k``'s sector as a cone inside it — world axis ``ĉ`` (3),
    ``cos ρ``, ``sin ρ`` of its half-angle ``ρ = min(w/2, asin(cos θ_c sin(w/2)))`` (the angle
    from the centre to the nearer elevation edge, a small circle, and to the great circles
    through the azimuth edges), the time the sweep is half done and its half-length, s
    (:func:`.reference.surely_seen`)."""
    cw = world(R, k, unit_from_angles3(centre_az, centre_el))
    rho = min(0.5 * width, np.arcsin(np.cos(centre_el) * np.sin(0.5 * width)))
    cones[k, 0], cones[k, 1], cones[k, 2] = cw
    cones[k, 3], cones[k, 4] = np.cos(rho), np.sin(rho)
    cones[k, 5] = t0 + offset + 0.5 * sweep
    cones[k, 6] = 0.5 * sweep


@njit(**JIT)
def surely_seen(p, k, cones, O, t1, pos, vel, speed, sp, sv):
    """Whether an object at the candidate's prediction ``M + V s`` (``pos``, ``vel``; ``s``
    from ``t_1`` to the middle of receiver ``k``'s sweep) lies inside ``k``'s sector cone
    (:func:`sector_cone`) by more than the margin ``μ = q √(σ_pos² + (σ_vel s)²) + |V|
    T_sweep/2 + ½ a_max s² + δ_0`` (its uncertainty, its motion during the sweep, the
    unmodelled drift): then the raster must have fixed it (:func:`.reference.surely_seen`).
    The angle test ``∠(d, ĉ) ≤ ρ − asin(μ/‖d‖)`` runs on cosines."""
    s = cones[k, 5] - t1
    ox, oy, oz = O[k, 0], O[k, 1], O[k, 2]
    d = (pos[0] + vel[0] * s - ox, pos[1] + vel[1] * s - oy, pos[2] + vel[2] * s - oz)
    nd = np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
    mu = (p.gate_q * np.sqrt(sp * sp + (sv * s) ** 2) + speed * cones[k, 6]
          + 0.5 * p.max_accel * s * s + GATE_FLOOR)  # fmt: skip
    sin_m = mu / nd  # nd = 0: inf, not seen
    if not sin_m < cones[k, 4]:
        return False
    cos_m = np.sqrt(1.0 - sin_m * sin_m)
    along = d[0] * cones[k, 0] + d[1] * cones[k, 1] + d[2] * cones[k, 2]
    # cos ∠(d, ĉ) ≥ cos(ρ − m) = cos ρ cos m + sin ρ sin m
    return along >= nd * (cones[k, 3] * cos_m + cones[k, 4] * sin_m)


@njit(**JIT)
def nearest_fix(p, i, k, O, fixes, fix_count, sig_k, t1, pos, vel, sp, sv):
    """The fix of receiver ``k`` whose line of sight passes nearest the prediction
    ``p = M + V (t_k − t_1)`` at that fix's time, within its gate, or −1
    (:func:`.reference.nearest_fix`): the miss ``e = ‖d − (d·u) u‖`` (``d = p − O_k``, ``u``
    the measured direction, in front of the receiver) within
    ``q √(σ_pos² + (σ_vel Δ)² + (σ_k d·u)²) + ½ a_max Δ²`` (floored at :data:`GATE_FLOOR`)."""
    gate_q, max_accel = p.gate_q, p.max_accel
    px, py, pz = pos
    vx, vy, vz = vel
    best, bj = np.inf, -1
    ox, oy, oz = O[k, 0], O[k, 1], O[k, 2]
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
        # (q σ + a)² ≤ 2 (q² σ² + a²): a fix missing by more (and by more than the floor) is
        # out of the gate without the square root (most fixes are other objects')
        if miss2 > GATE_SLACK * max(2.0 * (gate_q * gate_q * var + drift * drift),
                                    GATE_FLOOR * GATE_FLOOR):  # fmt: skip
            continue
        tol = max(gate_q * np.sqrt(var) + drift, GATE_FLOOR)
        if miss2 <= tol * tol:
            best, bj = miss2, j
    return bj


@njit(**JIT)
def join_receivers(p, geometry, i, c, mk, fx, fixes, cmem, cand, refine):
    """Candidate ``c`` (a triple of receivers 1–3) re-solved by least squares over all its
    fixes, ``mk`` receivers past the first (receivers 4 … n joined in ``cmem[c]`` by
    :func:`screen_candidates`; :func:`.reference.join_receivers`, theory §3.3, any n ≥ 3).

    The velocity-aware system of all ``n_used = mk + 1`` receivers (normal equations with the
    ranges ``r_2 … r_n`` eliminated, :func:`velocity_element` on this scratch, the block of
    ``(r_1, V)`` only) gives ``(M, V)`` and ``σ_e² (AᵀA)⁻¹`` (:func:`candidate_sigmas`), kept if
    it passes the triple's checks (``κ_F ≤ cond_max``, positive ranges, speed ≤
    ``max_speed``); otherwise the triple's solution stands and the joined fixes are released.
    Returns False, and the candidate is dropped, where the kept joint fit of ``n'`` receivers
    fails its χ² test (``chi2_max[n' − 4]``, the thresholds of
    :attr:`.simulation.ScanningParams.fit_thresholds`). The system's arrays ``refine`` come
    from the step's scratch, sized for all ``n`` receivers (``a1 (1, 3)``, ``ak``,
    ``bk (1, n − 1, 3)``, ``Pk (1, n − 1, 3, 3)``, ``dt (1, n − 1)``, ``X (1, n + 3)``, ``J``,
    ``Q (1, n + 3, n + 3)``, ``kap (1,)``, ``M1 (1, 3)``, ``sg (n,)``, ``work`` of
    :func:`~sensorgym.trackers.stereo.conjugation_kernels.velocity_work` ``(n − 1)``): a
    candidate fills their first rows."""
    O, R, P, b, _, chi2_max = geometry
    la, sig = fx[0], fx[1]
    a1, ak, Pk, bk, dt, X, J, Q, kap, M1, sg, work = refine
    n = la.shape[0]
    t1 = cand[c, K_TIME]
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
    ok = kap[0] <= p.cond_max
    for k in range(nu):
        ok = ok and X[0, k] > 0.0
    vw = world(R, 0, (X[0, nu], X[0, nu + 1], X[0, nu + 2]))
    if not (ok and norm3(vw) <= p.max_speed):
        for k in range(3, n):
            cmem[c, k] = -1
        return True
    sigma_e, sp, sv = candidate_sigmas(Q, X, np.int64(0), sg, nu, p.position_sigma, np.bool_(True))
    # the joint fit's χ² = J / σ_e² on 3 (nu − 1) − (nu + 3) = 2 nu − 6 degrees of freedom
    # (a triple's is 0): beyond its upper fit_false_alarm point (chi2_max[nu − 4]), plus each
    # fix's unmodelled drift ½ a_max Δ² and the gates' floor, the fixes are not one object's —
    # a ghost triple that gathered other objects' fixes; the candidate is dropped
    unmodelled = 0.0
    for r in range(mk):
        e = 0.5 * p.max_accel * dt[0, r] * dt[0, r] + GATE_FLOOR
        unmodelled += e * e
    if J[0] > sigma_e * sigma_e * chi2_max[nu - 4] + unmodelled:
        return False
    mw = world(R, 0, (M1[0, 0], M1[0, 1], M1[0, 2]))
    for x in range(3):
        cand[c, K_POS + x] = O[0, x] + mw[x]
        cand[c, K_VEL + x] = vw[x]
    cand[c, K_SIG], cand[c, K_SIG + 1] = sp, sv
    return True


@njit(**JIT)
def _join_or_drop(p, geometry, i, c, fx, fixes, fix_count, cmem, cand, refine):
    """Receivers 4 … n join triple ``c`` (:func:`.reference.join_receivers`, theory §3.3):
    each contributes its :func:`nearest_fix` (``cmem[c, k]``, −1: none), then the joint fit
    (:func:`join_receivers`). Returns False where the triple is dropped: ``ghost_misses``
    receivers had it :func:`surely_seen` without a fix in its gate (negative information;
    ``0``: off), or its joint fit failed."""
    O = geometry[0]
    sig, cones = fx[1], fx[2]
    n = sig.shape[0]
    ghost_misses = p.ghost_misses
    t1 = cand[c, K_TIME]
    pos = (cand[c, 0], cand[c, 1], cand[c, 2])
    vel = (cand[c, K_VEL], cand[c, K_VEL + 1], cand[c, K_VEL + 2])
    vn = np.sqrt(vel[0] * vel[0] + vel[1] * vel[1] + vel[2] * vel[2])
    sp, sv = cand[c, K_SIG], cand[c, K_SIG + 1]
    mk = np.int64(2)
    misses = 0
    for k in range(3, n):
        bj = nearest_fix(p, i, k, O, fixes, fix_count, sig[k], t1, pos, vel, sp, sv)
        cmem[c, k] = bj
        if bj >= 0:
            mk += 1
        elif ghost_misses > 0 and surely_seen(p, k, cones, O, t1, pos, vel, vn, sp, sv):
            # negative information: detection is certain inside a sector (the raster visits
            # every pixel), so a real object there has a fix, which misses its gate with
            # probability 1 − gate_probability
            misses += 1
            if misses >= ghost_misses:
                break
    if ghost_misses > 0 and misses >= ghost_misses:
        for k in range(3, n):
            cmem[c, k] = -1
        return False
    return not (mk > 2 and not join_receivers(p, geometry, i, c, mk, fx, fixes, cmem, cand,
                                              refine))  # fmt: skip


@njit(**JIT)
def screen_candidates(p, geometry, i, nc, fx, fixes, fix_count, solved, found, refine):
    """The checks of scenario ``i``'s ``nc`` solved candidates (``solved`` = the system and the
    solution ``X``, ``J``, ``Q``, ``κ``, ``M̂_1`` of
    :func:`~sensorgym.trackers.stereo.conjugation_kernels.triple_velocity_kernel` or
    ``pair_kernel``; :func:`.reference.candidates`): ``cok[c]`` where candidate ``c`` passes
    them, its world position, velocity, time and ``(σ_pos, σ_vel)`` in ``cand``
    (``found = (cmem, cand, cok, ctaken)``); a triple is refined over receivers 4 … n first
    (:func:`_join_or_drop` on the ``refine`` scratch). One call per scenario: a call per
    candidate would count references to its arrays each time."""
    O, R, P = geometry[0], geometry[1], geometry[2]
    la, sig = fx[0], fx[1]
    dt, X, J, Q, kap, M1 = solved[4], solved[6], solved[7], solved[8], solved[9], solved[10]
    cmem, cand, cok, ctaken = found
    used_n = 3 if p.tracker == 0 else 2
    position_sigma, max_speed, cond_max = p.position_sigma, p.max_speed, p.cond_max
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
            sp, sv = triple_sigmas(c, la, P, cmem, dt, X, Q, sig, position_sigma, C, work)
        else:
            _, sp, sv = candidate_sigmas(Q, X, c, sig, used_n, position_sigma, False)
        # world position M = O_1 + R_1 r̂_1 a_1 at t_1, velocity R_1 V̂
        mw = world(R, 0, (M1[c, 0], M1[c, 1], M1[c, 2]))
        for x in range(3):
            cand[c, K_POS + x] = O[0, x] + mw[x]
        cand[c, K_DT] = dt[c, 0]
        cand[c, K_SIG], cand[c, K_SIG + 1] = sp, sv
        if used_n == 3:
            vw = world(R, 0, (X[c, 3], X[c, 4], X[c, 5]))
            cand[c, K_VEL], cand[c, K_VEL + 1], cand[c, K_VEL + 2] = vw
            # a triple whose speed exceeds the limit by more than q σ_vel is infeasible at
            # the gate's confidence: dropped before receivers 4 … n are searched for it
            # (at n = 3 the check below, on the speed alone, drops it as well)
            if not norm3(vw) - p.gate_q * sv <= max_speed:
                continue
            if not _join_or_drop(p, geometry, i, c, fx, fixes, fix_count, cmem, cand, refine):
                continue
            speed = norm3((cand[c, K_VEL], cand[c, K_VEL + 1], cand[c, K_VEL + 2]))
            if not speed <= max_speed:
                continue
        else:
            if not pair_passes(J[c], X[c, 0], X[c, 1], sig[0], sig[1], position_sigma,
                               p.gate_q, max_speed, dt[c, 0]):  # fmt: skip
                continue
            cand[c, K_VEL], cand[c, K_VEL + 1], cand[c, K_VEL + 2] = 0.0, 0.0, 0.0
        cok[c] = True


@njit(**JIT)
def triple_pregates(p, P, b, i, la, sig, fixes, fix_count, pairs, gates):
    """The triples' pair pre-gates (:func:`.reference.pair_gate`): ``g12``, ``g13``, then,
    for the pairs some fix of receiver 1 joins through both its gates, ``g23``
    (``gates = (g12, g13, g23, every, need23)`` ``(F, F)``): whether fixes ``jh`` of receiver
    ``h`` and ``jk`` of receiver ``k > h`` pass :func:`pair_passes` — a true triple's three
    pairs pass it. In receiver 1's frame receiver ``h``'s line of sight is ``P_h a`` from
    ``b_h`` (``P_1 = I``, ``b_1 = 0``), so a pair solves ``r_h (P_h a_h) − r_k (P_k a_k) =
    b_k − b_h``, all of a pass at once on the ``F²`` rows of the pair system ``pairs``."""
    pa1, pa2, pP, pb, ones, pX, pJ, pQ, pk, pM = pairs
    g12, g13, g23, every, need23 = gates
    for e in range(3):
        h, k = (0, 1) if e == 0 else ((0, 2) if e == 1 else (1, 2))
        need, out = (every, g12) if e == 0 else ((every, g13) if e == 1 else (need23, g23))
        count_h, count_k = fix_count[i, h], fix_count[i, k]
        if e == 2:
            # receivers 2–3: only the pairs some fix of receiver 1 joins through both its gates
            for j2 in range(count_h):
                for j3 in range(count_k):
                    need23[j2, j3] = False
            for j1 in range(fix_count[i, 0]):
                for j2 in range(count_h):
                    if g12[j1, j2]:
                        for j3 in range(count_k):
                            if g13[j1, j3]:
                                need23[j2, j3] = True
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
        pair_kernel(pa1, pa2, pP, pb, ones, 1.0, np.bool_(False), np.int64(0), np.int64(npair),
                    pX, pJ, pQ, pk, pM)  # fmt: skip
        r = 0
        for jh in range(count_h):
            for jk in range(count_k):
                if not need[jh, jk]:
                    continue
                dt = fixes[i, k, jk, 3] - fixes[i, h, jh, 3]
                out[jh, jk] = pair_passes(pJ[r], pX[r, 0], pX[r, 1], sig[h], sig[k],
                                          p.position_sigma, p.gate_q, p.max_speed, dt)  # fmt: skip
                r += 1


@njit(**_INLINE)
def enumerate_candidates(P, b, i, used_n, la, fixes, fix_count, gates, system, cmem, cand):
    """Every triple (``used_n = 3``) of fixes of receivers 1–3 whose three pairs passed their
    pre-gates (``gates = (g12, g13, g23)``), or every pair of receivers 1–2, as rows of the
    ``system = (a1, ak, P, b, dt)`` (receiver 1's direction, the others', their poses in frame 1
    and delays), their fixes in ``cmem`` and receiver 1's fix time in ``cand``. Returns their
    number."""
    g12, g13, g23 = gates
    a1, ak, Pc, bc, dt = system
    n = la.shape[0]
    nc = 0
    c1 = fix_count[i, 0]
    c2 = fix_count[i, 1]
    c3 = fix_count[i, 2] if used_n == 3 else 1
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
                dt[nc, 0] = fixes[i, 1, j2, 3] - fixes[i, 0, j1, 3]
                for k in range(n):
                    cmem[nc, k] = -1
                cmem[nc, 0], cmem[nc, 1] = j1, j2
                if used_n == 3:
                    for x in range(3):
                        ak[nc, 1, x] = la[2, j3, x]
                        bc[nc, 1, x] = b[1, x]
                        for y in range(3):
                            Pc[nc, 1, x, y] = P[1, x, y]
                    dt[nc, 1] = fixes[i, 2, j3, 3] - fixes[i, 0, j1, 3]
                    cmem[nc, 2] = j3
                cand[nc, K_TIME] = fixes[i, 0, j1, 3]
                nc += 1
    return nc
