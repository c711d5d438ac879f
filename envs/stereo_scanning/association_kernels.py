"""The compiled track table of the scanning-receiver environments: costs, updates, association.

One scenario's table is row ``i`` of the state's ``tracks (B, T, 19)`` and ``track_int (B, T,
4)``, read and written in place by the column positions below (:class:`.reference.Table`
names the same columns). The period's candidates come as a table ``cand (C, 10)`` (columns
``K_*``: world position and velocity, time of receiver 1's fix, ``σ_pos``, ``σ_vel`` and the
delay of receiver 2) with their fixes ``cmem (C, n)`` (``−1``: none of that receiver), from
:mod:`.candidate_kernels`.

The step (:func:`.kernels.step_rows`) runs :func:`.reference.associate`'s four stages in order
(theory §11.5 step 3): :func:`continue_confirmed`, :func:`grow_children`, :func:`coast` and
:func:`open_births`, after :func:`continuation_costs` (and :func:`algorithmic_costs`) has
scored every passing (track, candidate) pair.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numba.extending import register_jitable

from sensorgym.envs.stereo_scanning.candidate_kernels import (
    GATE_FLOOR,
    GATE_SLACK,
    JIT,
    K_DT,
    K_SIG,
    K_TIME,
    K_VEL,
    local,
    world,
)
from sensorgym.trackers.geometry_kernels import norm3
from sensorgym.trackers.stereo.conjugation_kernels import pair_kernel

_INLINE = {**JIT, "inline": "always"}

#: track status codes of the table
EMPTY, TENTATIVE, CONFIRMED = 0, 1, 2
#: tracker codes
PROPOSED, ALTERNATIVE, ALGORITHMIC = 0, 1, 2
#: float columns of the table (``tracks``): the state ``(M̂, V̂)`` from ``T_X`` (6), its time,
#: ``(σ_pos, σ_vel)`` from ``T_SIG``, the cumulative index, the alternative's line-fit sums
#: from ``T_SUMS`` (9)
T_X, T_TIME, T_SIG, T_SCORE, T_SUMS = 0, 6, 7, 9, 10
#: integer columns of the table (``track_int``)
I_HITS, I_MISSES, I_STATUS, I_ID = 0, 1, 2, 3


@njit(**JIT)
def predicted_position(i, q, s, tracks):
    """Track ``q``'s position predicted ``s`` after its time, ``M̂ + V̂ s`` (m): the
    constant-velocity prediction of the gates, the costs and the observation."""
    return (
        tracks[i, q, 0] + tracks[i, q, 3] * s,
        tracks[i, q, 1] + tracks[i, q, 4] * s,
        tracks[i, q, 2] + tracks[i, q, 5] * s,
    )


@njit(**JIT)
def _prediction_residual(i, q, s, tracks, cand, c):
    """``p − (M̂ + V̂ s)``: candidate ``c``'s position's miss of track ``q``'s prediction
    (:func:`predicted_position`), m."""
    pred = predicted_position(i, q, s, tracks)
    return cand[c, 0] - pred[0], cand[c, 1] - pred[1], cand[c, 2] - pred[2]


@njit(**JIT)
def _predicted_variance(i, q, s, tracks):
    """``σ_pos² + (σ_vel s)²``: variance of track ``q``'s position predicted ``s`` after its
    time, m²."""
    return tracks[i, q, T_SIG] ** 2 + (tracks[i, q, T_SIG + 1] * s) ** 2


@njit(**JIT)
def predicted_sigma(i, q, s, tracks):
    """``√`` of :func:`_predicted_variance`, m."""
    return np.sqrt(_predicted_variance(i, q, s, tracks))


@njit(**JIT)
def outside_gate(p, i, q, c, tracks, cand):
    """Whether candidate ``c`` surely fails track ``q``'s position gate in :func:`step_cost`
    (proposed tracker), without a square root: ``(q s + m)² ≤ 2 (q² s² + m²)``, so a
    candidate further than that from the prediction (and than the floor) is out. Most
    track–candidate pairs are other objects'; the rest are scored in full."""
    gate_q, max_accel = p.gate_q, p.max_accel
    s = cand[c, K_TIME] - tracks[i, q, T_TIME]
    e0, e1, e2 = _prediction_residual(i, q, s, tracks, cand, c)
    spread2 = (cand[c, K_SIG] ** 2 + _predicted_variance(i, q, s, tracks)) / 3.0
    margin = 0.5 * max_accel * s * s
    bound = max(2.0 * (gate_q * gate_q * spread2 + margin * margin), GATE_FLOOR * GATE_FLOOR)
    return e0 * e0 + e1 * e1 + e2 * e2 > GATE_SLACK * bound


@njit(**JIT)
def step_cost(p, i, q, c, tracks, track_int, cand):
    """ΔJ = ‖M(i, j) − (M̂_s + V̂_s (t − t_s))‖ if it passes the gate δ, else inf (000 step 3-4;
    :func:`.reference.continuation_costs`).

    ``δ = q · s + margin``, ``s² = (σ_pos,c² + σ_pos,pred²)/3`` per axis; margin ``½ a_max Δ²``
    (proposed) or ``v_max |Δt|`` (the alternative's dynamic error may drift by its size); the
    proposed also needs ``‖V − V̂_s‖ ≤ q √((σ_vel,c² + σ_vel,s²)/3) + a_max Δ``. An
    alternative track of one point has no velocity: any candidate within ``2 v_max Δ`` continues
    it at zero cost (000 temporal step 1, theory §13.11). Both gates are floored at
    :data:`GATE_FLOOR` (noise-free fixes of an unaccelerated drone would otherwise need an
    exact zero)."""
    tracker, gate_q, max_speed, max_accel = p.tracker, p.gate_q, p.max_speed, p.max_accel
    s = cand[c, K_TIME] - tracks[i, q, T_TIME]
    if not s > 0.0:
        return np.inf
    d = norm3(_prediction_residual(i, q, s, tracks, cand, c))
    if tracker != PROPOSED and track_int[i, q, I_HITS] < 2:
        return 0.0 if d <= 2.0 * max_speed * s else np.inf
    if tracker == ALGORITHMIC:
        return 0.0  # scored by algorithmic_cost
    sp = predicted_sigma(i, q, s, tracks)
    spread = np.sqrt((cand[c, K_SIG] ** 2 + sp**2) / 3.0)
    if tracker == ALTERNATIVE:
        margin = max_speed * abs(cand[c, K_DT])
    else:
        margin = 0.5 * max_accel * s * s
        # velocity consistency (003's J_3, theory §5.5): a ghost triple of two close drones
        # fixes near them with a velocity of neither
        dv = norm3((cand[c, K_VEL] - tracks[i, q, 3], cand[c, K_VEL + 1] - tracks[i, q, 4],
                    cand[c, K_VEL + 2] - tracks[i, q, 5]))  # fmt: skip
        dv_gate = (gate_q * np.sqrt((cand[c, K_SIG + 1] ** 2 + tracks[i, q, T_SIG + 1] ** 2) / 3.0)
                   + max_accel * s)  # fmt: skip
        if not dv <= max(dv_gate, GATE_FLOOR):
            return np.inf
    return d if d <= max(gate_q * spread + margin, GATE_FLOOR) else np.inf


@njit(**JIT)
def algorithmic_cost(p, geometry, i, q, c, tracks, cand, cmem, fx, pairs, out, row):
    """Paper 003's algorithmic index of extending track ``q`` by pair ``c`` (theory §5.5,
    online; :func:`.reference.continuation_costs`): the pair re-solved with the track's motion
    moved to the right-hand side, ``B̂_2 = b_2 − V Δt_2`` (steps 2.1–2.2, the range re-solve of
    theory §3.3), then ``J = c_1 J_1 + c_2 J_2 + c_3 J_3`` with the compensated miss
    ``J_1 = ‖e_2‖``, the proximity ``J_2 = ‖M* − (M̂_s + V̂_s Δ)‖`` and the velocity
    consistency ``J_3 = ‖V̂ − V̂_s‖``, ``V̂ = (M* − M̂_s)/Δ``; ``c_1 = 1/√(σ_e² + (σ_vel Δt_2)²)``,
    ``c_2 = 1/(2√2 σ_p)``, ``c_3 = Δ/(2√2 σ_p)`` (theory §13.6; ``σ_p`` per axis of the
    candidate and the track's prediction; both floored at 1 mm); ``J_2``, ``J_3`` less the
    gentle acceleration's ``½ a_max Δ²``, ``a_max Δ``; ``J ≤ α_3 = 3 q``, else inf. Writes
    ``(M*, V̂)`` to ``out[row]``. ``fx = (la, sig, cones)`` the period's fixes,
    ``pairs`` the pair system's scratch (:func:`.candidate_kernels.triple_pregates`)."""
    O, R, P, b = geometry[:4]
    la, sig = fx[0], fx[1]
    pa1, pa2, pP, pb, pones, pX, pJ, pQ, pk, pM = pairs
    position_sigma, gate_q, max_accel = p.position_sigma, p.gate_q, p.max_accel
    s = cand[c, K_TIME] - tracks[i, q, T_TIME]
    cdt = cand[c, K_DT]
    # V in frame 1: R_1ᵀ V
    v1 = local(R, 0, (tracks[i, q, 3], tracks[i, q, 4], tracks[i, q, 5]))
    j1, j2 = cmem[c, 0], cmem[c, 1]
    for x in range(3):
        pa1[0, x] = la[0, j1, x]
        pa2[0, 0, x] = la[1, j2, x]
        # B̂_2 = b_2 − V Δt_2
        pb[0, 0, x] = b[0, x] - v1[x] * cdt
        for y in range(3):
            pP[0, 0, x, y] = P[0, x, y]
    pair_kernel(
        pa1, pa2, pP, pb, pones, 1.0, np.bool_(False), np.int64(0), np.int64(1), pX, pJ, pQ, pk, pM
    )
    if not (pX[0, 0] > 0.0 and pX[0, 1] > 0.0):
        return np.inf
    mw = world(R, 0, (pM[0, 0], pM[0, 1], pM[0, 2]))
    m = (O[0, 0] + mw[0], O[0, 1] + mw[1], O[0, 2] + mw[2])
    x1, x2 = sig[0] * pX[0, 0], sig[1] * pX[0, 1]
    sigma_e = np.sqrt(position_sigma * position_sigma + 0.5 * (x1 * x1 + x2 * x2))
    # σ_p per axis: the candidate's and the track's prediction (its velocity error over Δ)
    sp = np.sqrt((cand[c, K_SIG] ** 2 + predicted_sigma(i, q, s, tracks) ** 2) / 3.0)
    J1 = np.sqrt(pJ[0])
    pred = predicted_position(i, q, s, tracks)
    d = (m[0] - pred[0], m[1] - pred[1], m[2] - pred[2])
    J2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
    J3 = 0.0
    for x in range(3):
        v = (m[x] - tracks[i, q, x]) / s
        out[row, x] = m[x]
        out[row, 3 + x] = v
        dv = v - tracks[i, q, 3 + x]
        J3 += dv * dv
    # the drones accelerate gently: J_2, J_3 allow ½ a_max Δ² and a_max Δ; normalisers are
    # floored at 1 mm (noise-free fixes)
    k = 2.0 * np.sqrt(2.0) * max(sp, 1e-3)
    J2 = max(np.sqrt(J2) - 0.5 * max_accel * s * s, 0.0)
    J3 = max(np.sqrt(J3) - max_accel * s, 0.0)
    # J_1's spread also holds the track velocity's error over the delay (the compensation)
    s1 = np.sqrt(sigma_e * sigma_e + (tracks[i, q, T_SIG + 1] * cdt) ** 2)
    cost = J1 / max(s1, 1e-3) + J2 / k + s * J3 / k
    return cost if cost <= 3.0 * gate_q else np.inf


@njit(**JIT)
def _shares(cmem, c, fused):
    """Whether candidate ``c`` uses a fix already taken (``cmem[c, k] = −1``: none of ``k``)."""
    for k in range(cmem.shape[1]):
        j = cmem[c, k]
        if j >= 0 and fused[k, j]:
            return True
    return False


@njit(**JIT)
def _mark(cmem, c, fused):
    for k in range(cmem.shape[1]):
        j = cmem[c, k]
        if j >= 0:
            fused[k, j] = True


@njit(**JIT)
def _free(track_int, i):
    """The first empty row of scenario ``i``'s table, −1 when it is full
    (:meth:`.reference.Table.free_row`)."""
    for q in range(track_int.shape[1]):
        if track_int[i, q, I_STATUS] == EMPTY:
            return q
    return -1


@register_jitable(**JIT)
def _save(old, r, i, q, tracks, track_int):
    """Row ``q``'s state, time, ``σ``s, index, hits and sums into ``old[r] (20,)``."""
    for x in range(10):
        old[r, x] = tracks[i, q, x]
    old[r, 10] = track_int[i, q, I_HITS]
    for x in range(9):
        old[r, 11 + x] = tracks[i, q, T_SUMS + x]


@njit(**JIT)
def _load(old, r, i, q, tracks, track_int):
    """:func:`_save`'s reverse."""
    for x in range(10):
        tracks[i, q, x] = old[r, x]
    track_int[i, q, I_HITS] = int(old[r, 10])
    for x in range(9):
        tracks[i, q, T_SUMS + x] = old[r, 11 + x]


@njit(**JIT)
def update(p, i, q, c, cost, mv, cand, tracks, track_int):
    """Extend track ``q`` by candidate ``c``: ``I ← I + ΔJ`` (:meth:`.reference.Table.extend`).
    Proposed (000 step 3): the track takes the latest spatial estimate ``mv = (M, V)``.
    Alternative (theory §13.11): a least-squares line ``M(t) = M̂ + V̂ (t − t_latest)`` over
    all members, kept as running sums. Algorithmic: :func:`_update_algorithmic`."""
    tracks[i, q, T_SCORE] += cost
    before = track_int[i, q, I_HITS]
    track_int[i, q, I_HITS] += 1
    track_int[i, q, I_MISSES] = 0
    tc = cand[c, K_TIME]
    if p.tracker == PROPOSED:
        for x in range(3):
            tracks[i, q, x] = mv[x]
            tracks[i, q, 3 + x] = mv[3 + x]
        tracks[i, q, T_SIG], tracks[i, q, T_SIG + 1] = cand[c, K_SIG], cand[c, K_SIG + 1]
        tracks[i, q, T_TIME] = tc
    elif p.tracker == ALGORITHMIC:
        _update_algorithmic(i, q, c, before, mv, cand, tracks, p.max_speed)
    else:
        _update_line(i, q, c, mv, cand, tracks, p.max_speed)


@njit(**_INLINE)
def _update_algorithmic(i, q, c, before, mv, cand, tracks, max_speed):
    """003 steps 2.5 and 3 (theory §5.5): the motion-compensated fix; the velocity from the
    previous fix (first continuation), then averaged recursively,
    ``V_i = V_{i−1} + (V̂ − V_{i−1})/(i − 1)``."""
    tc = cand[c, K_TIME]
    s = tc - tracks[i, q, T_TIME]
    for x in range(3):
        if before == 0:
            v = 0.0
        elif before == 1:
            v = (mv[x] - tracks[i, q, x]) / s
        else:
            v = tracks[i, q, 3 + x] + (mv[3 + x] - tracks[i, q, 3 + x]) / before
        tracks[i, q, x] = mv[x]
        tracks[i, q, 3 + x] = v
    tracks[i, q, T_SIG] = cand[c, K_SIG]
    # σ_vel: a difference of two fixes s apart, averaged over the continuations, plus the
    # dynamic error ‖V‖ |Δt| of the uncompensated first fixes, diluted by the average
    if before == 0:
        tracks[i, q, T_SIG + 1] = max_speed
    else:
        speed = norm3((tracks[i, q, 3], tracks[i, q, 4], tracks[i, q, 5]))
        tracks[i, q, T_SIG + 1] = (np.sqrt(2.0) * cand[c, K_SIG] + speed * abs(cand[c, K_DT])) / (
            s * np.sqrt(before)
        )
    tracks[i, q, T_TIME] = tc


@njit(**_INLINE)
def _update_line(i, q, c, mv, cand, tracks, max_speed):
    """The alternative's least-squares line over all members (theory §13.11): running sums of
    ``(1, t, t², M, t M)`` with ``t`` measured from the new member's time (well scaled)."""
    tc = cand[c, K_TIME]
    S = T_SUMS
    s0 = tracks[i, q, S]
    st = 0.0
    shift = tracks[i, q, T_TIME] - tc
    # re-centre the stored sums on tc: Σ(t − tc) = Σt' + S0 (t_old − tc) etc.
    if s0 > 0:
        st = tracks[i, q, S + 1] + s0 * shift
        stt = tracks[i, q, S + 2] + 2.0 * shift * tracks[i, q, S + 1] + s0 * shift * shift
        stm = np.empty(3)
        for x in range(3):
            stm[x] = tracks[i, q, S + 6 + x] + shift * tracks[i, q, S + 3 + x]
    else:
        stt = 0.0
        stm = np.zeros(3)
    s0 += 1.0
    tracks[i, q, S], tracks[i, q, S + 1], tracks[i, q, S + 2] = s0, st, stt
    for x in range(3):
        tracks[i, q, S + 3 + x] += mv[x]
        tracks[i, q, S + 6 + x] = stm[x]
    tracks[i, q, T_TIME] = tc
    det = s0 * stt - st * st
    if s0 >= 2.0 and det > 0.0:
        for x in range(3):
            # V̂ = (S0 ΣtM − Σt ΣM)/(S0 Σt² − (Σt)²) ;  M̂(tc) = (ΣM − V̂ Σt)/S0
            v = (s0 * tracks[i, q, S + 6 + x] - st * tracks[i, q, S + 3 + x]) / det
            tracks[i, q, 3 + x] = v
            tracks[i, q, x] = (tracks[i, q, S + 3 + x] - v * st) / s0
        tracks[i, q, T_SIG] = cand[c, K_SIG]
        tracks[i, q, T_SIG + 1] = cand[c, K_SIG] * np.sqrt(s0 / det)
    else:
        for x in range(3):
            tracks[i, q, x] = mv[x]
            tracks[i, q, 3 + x] = 0.0
        tracks[i, q, T_SIG], tracks[i, q, T_SIG + 1] = cand[c, K_SIG], max_speed


@njit(**_INLINE)
def continuation_costs(p, i, nc, cand, cok, tracks, track_int, pairs_t, pairs_c, pairs_s,
                       pairs_mv):  # fmt: skip
    """Every passing (track, candidate) pair of scenario ``i``, its cost ``ΔJ`` and the
    ``(M, V)`` the track would take, in the order of the tracks and then of the candidates
    (:func:`.reference.continuation_costs`, theory §11.5 step 3): the ``nc`` candidates that
    passed their checks (``cok``) against every live track. Returns the number of pairs; the
    algorithmic tracker then rescores them (:func:`algorithmic_costs`)."""
    tracker = p.tracker
    npair = 0
    for q in range(tracks.shape[1]):
        if track_int[i, q, I_STATUS] == EMPTY:
            continue
        for c in range(nc):
            if not cok[c]:
                continue
            if tracker == PROPOSED and outside_gate(p, i, q, c, tracks, cand):
                continue
            cost = step_cost(p, i, q, c, tracks, track_int, cand)
            if cost < np.inf:
                for x in range(3):
                    pairs_mv[npair, x] = cand[c, x]
                    pairs_mv[npair, 3 + x] = cand[c, K_VEL + x]
                pairs_t[npair], pairs_c[npair], pairs_s[npair] = q, c, cost
                npair += 1
    return npair


@njit(**JIT)
def algorithmic_costs(p, geometry, i, npair, found, fx, pairs, table, scores):
    """The algorithmic tracker's costs of the ``npair`` pairs :func:`continuation_costs` let
    through: a track of two members or more is rescored by :func:`algorithmic_cost` (which
    writes its ``(M*, V̂)``), and the pairs it fails are dropped, the others keeping their
    order. Returns the number of pairs left."""
    cmem, cand = found[0], found[1]
    tracks, track_int = table
    pairs_t, pairs_c, pairs_s, pairs_mv = scores
    w = 0
    for e in range(npair):
        q, c = pairs_t[e], pairs_c[e]
        if track_int[i, q, I_HITS] >= 2:
            cost = algorithmic_cost(p, geometry, i, q, c, tracks, cand, cmem, fx, pairs, pairs_mv,
                                    np.int64(w))  # fmt: skip
        else:
            cost = pairs_s[e]
            for x in range(6):
                pairs_mv[w, x] = pairs_mv[e, x]
        if cost < np.inf:
            pairs_t[w], pairs_c[w], pairs_s[w] = q, c, cost
            w += 1
    return w


@njit(**_INLINE)
def continue_confirmed(p, i, order, cmem, cand, ctaken, tracks, track_int, scores, fused,
                       t_took):  # fmt: skip
    """Confirmed tracks take, greedily in ascending ``ΔJ``, a candidate sharing no fix with one
    already taken (:func:`.reference.associate`, its stage 1; ``fused (n, F)``: the fixes
    taken, ``t_took (T,)``: the tracks continued)."""
    pairs_t, pairs_c, pairs_s, pairs_mv = scores
    for e in order:
        q, c = pairs_t[e], pairs_c[e]
        if track_int[i, q, I_STATUS] != CONFIRMED or t_took[q] or _shares(cmem, c, fused):
            continue
        t_took[q] = True
        _mark(cmem, c, fused)
        ctaken[c] = True
        update(p, i, q, c, pairs_s[e], pairs_mv[e], cand, tracks, track_int)


@njit(**_INLINE)
def grow_children(p, i, order, found, tracks, track_int, next_id, scores, taken, kids):
    """Tentative tracks: every passing continuation is a child (000's groups), in ascending
    cumulative index; the children replace their parents in the first free rows, and a child
    reaching ``confirm_hits`` is confirmed if it shares no fix (:func:`.reference.associate`,
    its stage 2). ``taken = (fused, t_took)``, ``kids = (child_t, child_c, child_s, child_mv,
    old (T, 20), old_slot)``."""
    cmem, cand, ctaken = found[0], found[1], found[3]
    fused, t_took = taken
    pairs_t, pairs_c, pairs_s, pairs_mv = scores
    child_t, child_c, child_s, child_mv, old, old_slot = kids
    n_child = 0
    for e in order:
        q, c = pairs_t[e], pairs_c[e]
        if track_int[i, q, I_STATUS] != TENTATIVE or _shares(cmem, c, fused):
            continue
        child_t[n_child], child_c[n_child] = q, c
        child_s[n_child] = tracks[i, q, T_SCORE] + pairs_s[e]
        for x in range(6):
            child_mv[n_child, x] = pairs_mv[e, x]
        n_child += 1
    child_order = np.argsort(child_s[:n_child])
    # old tentative tracks are replaced by their children (copied into a scratch first)
    r_ = 0
    for q in range(tracks.shape[1]):
        if track_int[i, q, I_STATUS] == TENTATIVE:
            _save(old, r_, i, q, tracks, track_int)
            old_slot[q] = r_
            r_ += 1
            track_int[i, q, I_STATUS] = EMPTY
    for e in child_order:
        q, c = child_t[e], child_c[e]
        if _shares(cmem, c, fused):
            continue
        slot = _free(track_int, i)
        if slot < 0:
            break
        _load(old, old_slot[q], i, slot, tracks, track_int)
        track_int[i, slot, I_MISSES] = 0
        update(p, i, slot, c, child_s[e] - tracks[i, slot, T_SCORE], child_mv[e], cand, tracks,
               track_int)  # fmt: skip
        ctaken[c] = True
        if track_int[i, slot, I_HITS] >= p.confirm_hits:
            track_int[i, slot, I_STATUS] = CONFIRMED
            track_int[i, slot, I_ID] = next_id[i]
            next_id[i] += 1
            t_took[slot] = True
            _mark(cmem, c, fused)
        else:
            track_int[i, slot, I_STATUS] = TENTATIVE
            t_took[slot] = True


@njit(**_INLINE)
def coast(p, i, track_int, t_took):
    """Confirmed tracks without a continuation coast; dropped after ``max_misses``
    (:func:`.reference.associate`, its stage 3)."""
    for q in range(track_int.shape[1]):
        if track_int[i, q, I_STATUS] == CONFIRMED and not t_took[q]:
            track_int[i, q, I_MISSES] += 1
            if track_int[i, q, I_MISSES] > p.max_misses:
                track_int[i, q, I_STATUS] = EMPTY


@njit(**_INLINE)
def open_births(p, i, nc, found, tracks, track_int, next_id, fused, births, mv):
    """Candidates sharing no fix with a continued track open tentative tracks (confirmed at
    once where ``confirm_hits ≤ 1``) in the first free rows (:func:`.reference.associate`,
    its stage 4). Scratch ``births (C,)``, ``mv (6,)``."""
    cmem, cand, cok, ctaken = found
    nb = 0
    for c in range(nc):
        if cok[c] and not ctaken[c] and not _shares(cmem, c, fused):
            births[nb] = c
            nb += 1
    for e in range(nb):
        c = births[e]
        slot = _free(track_int, i)
        if slot < 0:
            break
        track_int[i, slot, I_HITS] = 0
        tracks[i, slot, T_SCORE] = 0.0
        track_int[i, slot, I_MISSES] = 0
        for x in range(9):
            tracks[i, slot, T_SUMS + x] = 0.0
        for x in range(3):
            mv[x] = cand[c, x]
            mv[3 + x] = cand[c, K_VEL + x]
        update(p, i, slot, c, 0.0, mv, cand, tracks, track_int)
        if p.confirm_hits <= 1:
            track_int[i, slot, I_STATUS] = CONFIRMED
            track_int[i, slot, I_ID] = next_id[i]
            next_id[i] += 1
        else:
            track_int[i, slot, I_STATUS] = TENTATIVE


@njit(**_INLINE)
def clear_taken(fused, t_took):
    """No fix and no track taken yet this period (:func:`.reference.associate`)."""
    for k in range(fused.shape[0]):
        for j in range(fused.shape[1]):
            fused[k, j] = False
    for q in range(t_took.shape[0]):
        t_took[q] = False
