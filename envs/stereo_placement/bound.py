"""A true upper bound on the ``sensorgym/StereoPlacement-v0`` reward, per step and per episode.

**What the reward depends on.** Step ``t`` (``t = 1, 2, …`` from a state at time ``t₀``) pays
(:mod:`.simulation`, :mod:`.kernels`)

    r_t = clip(ln(σ_ref / σ_pos), −R, R),   σ_pos = σ_ang √tr G⁻¹,
    G = Σ_k J_k(o_k),   J_k(o) = (I − u uᵀ)/r² = (r² I − w wᵀ)/r⁴,   w = o − M_k,  r = ‖w‖

at the receivers' *true* positions ``o_k`` at their fix times ``t₀ + (t − 1)τ + d_k`` and the
true drone ``M_k`` then (a straight line: no action moves it), or ``−R`` (degenerate solve,
failed test of theory §4.3). So ``r_t ≤ clip(c − ½ ln tr G⁻¹, −R, R)``, ``c = ln(σ_ref/σ_ang)``,
whatever the tracker did.

**Reachable sets.** A receiver moves at most ``max_speed`` (the kernel caps the speed) and is
held in the arena by the radial projection onto the disc, which never lengthens a move (the
projection onto a convex set is 1-Lipschitz and the start lies in it); within a period it
drives a straight segment between two points of the arena. So at its fix time receiver ``k`` is
in

    D_k(t) = {o : ‖o − o_k(t₀)‖ ≤ v_max ((t − 1)τ + d_k)} ∩ {o : ‖o‖ ≤ arena_radius}  (y = 0)

(radii widened by 1e-9 relative for rounding). The bound relaxes everything else: the coupling
between steps (each step may place the receivers anywhere in their discs), and — the second
relaxation, which makes the maximum computable with a certificate — each ``J_k`` may be any
point of the convex hull ``conv{J_k(o) : o ∈ D_k(t)}``.

**The certificate.** For ``Z ⪰ 0`` and ``G ≻ 0``,
``tr G⁻¹ + tr(Z G) − 2 tr Z^{1/2} = ‖G^{−1/2} − Z^{1/2} G^{1/2}‖_F² ≥ 0``; with
``tr(Z G) = Σ_k tr(Z J_k(o_k)) ≤ Σ_k h_k(Z)``, ``h_k(Z) = max_{o ∈ D_k} tr(Z J_k(o))``,

    tr G⁻¹ ≥ L(Z) = 2 tr Z^{1/2} − Σ_k h̄_k(Z)      for every placement, every Z ⪰ 0,

    B_t = clip(c − ½ ln L(Z), −R, R)   (R where L(Z) ≤ 0)   ≥   r_t,

for any ``h̄_k ≥ h_k``. ``Z`` only decides how tight it is: it comes from Frank–Wolfe (pairwise
steps, with atoms added by the oracle below) on the convex relaxation
``min tr G⁻¹ over G ∈ Σ_k conv J_k(D_k)``, ``Z = G⁻²`` at its iterate; at the relaxation's
optimum ``L(Z)`` equals it (strong duality). The iteration stops when the relaxation's value
and the best ``L`` lie within ``TOLERANCE`` (relative) of each other.

**The oracle** ``h̄_k`` is a branch and bound over squares covering ``D_k`` (dropped where a square
misses either disc). With ``g(o) = tr(Z J_k(o)) = (T r² − wᵀZw)/r⁴``, ``T = tr Z``, and
``r ≥ r_min`` over a square of centre ``c`` and half-diagonal ``δ``:

    ‖∇g‖ ≤ (2T + λ_max(Z))/r³ ≤ 3T/r³,     ‖∇²g‖ ≤ (6T + 46 λ_max(Z))/r⁴ ≤ 52T/r⁴,

    max_square g ≤ g(c) + min(3T δ/r_min³, ‖∇g(c)‖ δ + 26 T δ²/r_min⁴)

(the gradient of ``wᵀZw/r²``-type terms: ``‖(I − uuᵀ)Zu‖ ≤ (λ_max − λ_min)/2``). Squares whose
bound exceeds the best value found by more than ``TOLERANCE/4`` (relative) are split;
``h̄_k`` is the largest bound over the squares left, so ``h_k ≤ h̄_k ≤ h_k (1 + TOLERANCE/4)``.

**Floating point.** ``L`` is scaled down by ``1 − DUAL_MARGIN`` (1e-6: far above the rounding of
the 3×3 algebra, including ``tr Z^{1/2}`` taken as ``tr G⁻¹`` of the iterate whose square is
``Z``) and every square's bound up by 1e-12 relative. What the bound gives away against the
per-step maximum is the convex hull (a multi-start local search over the discs comes within
0.15 of it: ``tests/envs/stereo_placement/test_bound.py``) and the ``TOLERANCE`` (at most ``½ ln(1/(1 − TOLERANCE))`` ≈ 1e-3 per
step).

**The episode bound.** Nothing a policy does moves the drone, so ``Σ_t B_t`` from an episode's
first state is a number of the scenario alone, known before the episode is played, which no
policy's return exceeds. Proof sketch in prose: theory §11.4.1.
"""

from __future__ import annotations

import math

import gymnasium
import numpy as np
from numba import njit
from numpy.typing import NDArray

from sensorgym.envs.stereo_placement.simulation import PlacementParams, PlacementState
from sensorgym.trackers.stereo.kernels import JIT

FloatArray = NDArray[np.float64]

__all__ = [
    "DUAL_MARGIN",
    "TOLERANCE",
    "bound_path",
    "episode_bound",
    "reachable",
    "step_bound",
    "trace_bound_path",
]

#: relative gap at which the search for ``Z`` stops: ``tr G⁻¹`` of the relaxation and its
#: certified lower bound ``L(Z)`` within this (at most ``½ ln(1/(1 − TOLERANCE))`` per step)
TOLERANCE = 2e-3
#: ``L(Z)`` is scaled by ``1 − DUAL_MARGIN`` against the rounding of the 3×3 algebra
DUAL_MARGIN = 1e-6
#: the reachable discs' radii are widened by this relative amount against rounding of the drive
RADIUS_MARGIN = 1e-9
#: the initial atoms of each receiver: its disc's centre and ``RINGS × SPOKES`` polar points
RINGS, SPOKES = 6, 16
#: the most rounds of (Frank–Wolfe, oracle) per step; each adds one atom per receiver
MAX_ROUNDS = 12
#: the most pairwise Frank–Wolfe steps per round
MAX_STEPS = 4000
#: squares of the oracle are never split below this half-width relative to ``1 + ρ`` (m)
MIN_HALF = 1e-9


# ---------------------------------------------------------------- 3×3 symmetric algebra
# A symmetric 3×3 matrix is kept as its six entries (xx, yy, zz, xy, xz, yz).


@njit(inline="always")
def _atom(ox, oz, m, out, j):
    """``J(o) = (r² I − w wᵀ)/r⁴``, ``w = o − M`` (``o = (ox, 0, oz)``) into ``out[j] (6,)``."""
    wx, wy, wz = ox - m[0], -m[1], oz - m[2]
    r2 = wx * wx + wy * wy + wz * wz
    s = 1.0 / (r2 * r2)
    out[j, 0] = (r2 - wx * wx) * s
    out[j, 1] = (r2 - wy * wy) * s
    out[j, 2] = (r2 - wz * wz) * s
    out[j, 3] = -wx * wy * s
    out[j, 4] = -wx * wz * s
    out[j, 5] = -wy * wz * s


@njit(inline="always")
def _dot(Z, J, j):
    """``tr(Z J[j])`` of two symmetric matrices in six-entry form."""
    return (
        Z[0] * J[j, 0]
        + Z[1] * J[j, 1]
        + Z[2] * J[j, 2]
        + 2.0 * (Z[3] * J[j, 3] + Z[4] * J[j, 4] + Z[5] * J[j, 5])
    )


@njit(inline="always")
def _inverse(G, W):
    """``W = G⁻¹`` into ``W (6,)``; returns ``tr G⁻¹``, ``+inf`` (``W`` untouched) unless ``G`` is
    positive definite (Sylvester's leading minors)."""
    a, b, c, d, e, f = G[0], G[1], G[2], G[3], G[4], G[5]
    c00 = b * c - f * f
    c11 = a * c - e * e
    c22 = a * b - d * d
    c01 = e * f - d * c
    c02 = d * f - b * e
    c12 = d * e - a * f
    det = a * c00 + d * c01 + e * c02
    if not (a > 0.0 and c22 > 0.0 and det > 0.0):
        return np.inf
    W[0], W[1], W[2] = c00 / det, c11 / det, c22 / det
    W[3], W[4], W[5] = c01 / det, c02 / det, c12 / det
    return W[0] + W[1] + W[2]


@njit(inline="always")
def _square(W, Z):
    """``Z = W²`` of a symmetric ``W`` (six-entry form)."""
    a, b, c, d, e, f = W[0], W[1], W[2], W[3], W[4], W[5]
    Z[0] = a * a + d * d + e * e
    Z[1] = d * d + b * b + f * f
    Z[2] = e * e + f * f + c * c
    Z[3] = a * d + d * b + e * f
    Z[4] = a * e + d * f + e * c
    Z[5] = d * e + b * f + f * c


# ---------------------------------------------------------------- the oracle


@njit(inline="always")
def _g(Z, T, x, z, m):
    """``g(o) = tr(Z J(o)) = (T r² − wᵀZw)/r⁴`` and its gradient in the plane ``(x, z)``."""
    wx, wy, wz = x - m[0], -m[1], z - m[2]
    r2 = wx * wx + wy * wy + wz * wz
    zx = Z[0] * wx + Z[3] * wy + Z[4] * wz
    zy = Z[3] * wx + Z[1] * wy + Z[5] * wz
    zz = Z[4] * wx + Z[5] * wy + Z[2] * wz
    q = wx * zx + wy * zy + wz * zz
    r4 = r2 * r2
    value = (T * r2 - q) / r4
    # ∇g = −2T w/r⁴ − 2 Z w/r⁴ + 4 q w/r⁶
    k = (4.0 * q / r2 - 2.0 * T) / r4
    return value, k * wx - 2.0 * zx / r4, k * wz - 2.0 * zz / r4


@njit(**JIT)
def _oracle(Z, m, cx, cz, rho, arena, tol, seed, stack):
    """``(h̄, best value, best x, best z)``: a certified upper bound ``h̄`` on
    ``max g(o) = tr(Z J(o))`` over the disc of radius ``rho`` about ``(cx, cz)`` within the arena,
    and the best point found (module docstring); ``seed (2,)`` a feasible start point,
    ``stack`` scratch ``(≥ 64 + 3·depth, 3)``."""
    T = Z[0] + Z[1] + Z[2]
    H2 = m[1] * m[1]
    best, _, _ = _g(Z, T, seed[0], seed[1], m)
    bx, bz = seed[0], seed[1]
    if rho <= 0.0:
        return best * (1.0 + 1e-12), best, bx, bz
    side = 4
    h0 = rho / side
    top = 0
    for i in range(side):
        for j in range(side):
            stack[top, 0] = cx - rho + (2 * i + 1) * h0
            stack[top, 1] = cz - rho + (2 * j + 1) * h0
            stack[top, 2] = h0
            top += 1
    upper = -np.inf
    floor = MIN_HALF * (1.0 + rho)
    while top > 0:
        top -= 1
        x, z, h = stack[top, 0], stack[top, 1], stack[top, 2]
        d = h * math.sqrt(2.0)
        dc = math.hypot(x - cx, z - cz)
        da = math.hypot(x, z)
        if dc > rho + d or da > arena + d:
            continue  # the square misses the reachable set
        v, gx, gz = _g(Z, T, x, z, m)
        if dc <= rho and da <= arena and v > best:
            best, bx, bz = v, x, z
        e = max(math.hypot(x - m[0], z - m[2]) - d, 0.0)
        r2 = e * e + H2  # r_min² over the square
        if not r2 > 0.0:
            u = np.inf
        else:
            first = 3.0 * T * d / (r2 * math.sqrt(r2))
            second = math.hypot(gx, gz) * d + 26.0 * T * d * d / (r2 * r2)
            u = v + min(first, second)
            u += 1e-12 * abs(u)
        if u <= best * (1.0 + tol) or h < floor or top + 4 > stack.shape[0]:
            upper = max(upper, u)
            continue
        half = 0.5 * h
        for sx in (-half, half):
            for sz in (-half, half):
                stack[top, 0], stack[top, 1], stack[top, 2] = x + sx, z + sz, half
                top += 1
    return max(upper, best * (1.0 + 1e-12)), best, bx, bz


# ---------------------------------------------------------------- one step


@njit(inline="always")
def _phi_slope(G, D, g, A, W, Z):
    """``tr (G + g D)⁻¹`` and its derivative ``−tr(A⁻² D)`` in ``g`` (``+inf``, ``+inf`` where
    ``A = G + g D`` is not positive definite)."""
    for i in range(6):
        A[i] = G[i] + g * D[i]
    t = _inverse(A, W)
    if not t < np.inf:
        return np.inf, np.inf
    _square(W, Z)
    slope = -(
        Z[0] * D[0] + Z[1] * D[1] + Z[2] * D[2] + 2.0 * (Z[3] * D[3] + Z[4] * D[4] + Z[5] * D[5])
    )
    return t, slope


@njit(**JIT)
def _step_row(targets, centres, radii, arena, tol, pts, J, lam, cnt, scores, stack):
    """``(L, relaxed)`` of one step: the certified lower bound ``L(Z)`` on ``tr G⁻¹`` over the
    reachable placements and the relaxation's value ``tr G⁻¹`` at the last iterate.

    ``targets (n, 3)`` the drone at each receiver's fix time, ``centres (n, 2)`` and
    ``radii (n,)`` the reachable discs (``(x, z)``, m); scratch: ``pts (n, K, 2)``,
    ``J (n, K, 6)``, ``lam``/``scores (n, K)``, ``cnt (n,)`` int, ``stack``."""
    n, K = pts.shape[0], pts.shape[1]
    G, W, Z = np.zeros(6), np.empty(6), np.empty(6)
    A, D, W2, Z2 = np.empty(6), np.empty(6), np.empty(6), np.empty(6)
    seed = np.empty(2)
    # initial atoms: the centre and RINGS × SPOKES points of each disc, pulled into the arena
    for k in range(n):
        c = 0
        pts[k, 0, 0], pts[k, 0, 1] = centres[k, 0], centres[k, 1]
        c += 1
        if radii[k] > 0.0:
            for i in range(RINGS):
                rr = radii[k] * (i + 1.0) / RINGS
                for j in range(SPOKES):
                    a = 2.0 * math.pi * (j + 0.5 * (i % 2)) / SPOKES
                    x = centres[k, 0] + rr * math.sin(a)
                    z = centres[k, 1] + rr * math.cos(a)
                    s = min(1.0, arena / max(math.hypot(x, z), 1e-300))
                    pts[k, c, 0], pts[k, c, 1] = x * s, z * s
                    c += 1
        cnt[k] = c
        for i in range(c):
            _atom(pts[k, i, 0], pts[k, i, 1], targets[k], J[k], i)
            lam[k, i] = 1.0 / c
            for q in range(6):
                G[q] += J[k, i, q] / c
    best = -np.inf
    relaxed = np.inf
    for _ in range(MAX_ROUNDS):
        # pairwise Frank–Wolfe on the atoms so far
        for _ in range(MAX_STEPS):
            relaxed = _inverse(G, W)
            if not relaxed < np.inf:
                break
            _square(W, Z)
            gap, pick, worth = 0.0, -1, 0.0
            i_fw, i_aw = 0, 0
            for k in range(n):
                top, low, mean, a_top, a_low = -np.inf, np.inf, 0.0, 0, -1
                for i in range(cnt[k]):
                    s = _dot(Z, J[k], i)
                    scores[k, i] = s
                    mean += lam[k, i] * s
                    if s > top:
                        top, a_top = s, i
                    if lam[k, i] > 0.0 and s < low:
                        low, a_low = s, i
                gap += top - mean
                if a_low >= 0 and top - low > worth:
                    worth, pick, i_fw, i_aw = top - low, k, a_top, a_low
            if gap <= 0.25 * tol * relaxed or pick < 0:
                break
            for q in range(6):
                D[q] = J[pick, i_fw, q] - J[pick, i_aw, q]
            g_max = lam[pick, i_aw]
            _, slope = _phi_slope(G, D, g_max, A, W2, Z2)
            if slope <= 0.0:
                g = g_max
            else:  # bisect the convex φ's slope
                lo, hi = 0.0, g_max
                for _ in range(50):
                    mid = 0.5 * (lo + hi)
                    _, slope = _phi_slope(G, D, mid, A, W2, Z2)
                    if slope <= 0.0:
                        lo = mid
                    else:
                        hi = mid
                g = lo
            if g <= 0.0:
                break
            for q in range(6):
                G[q] += g * D[q]
            lam[pick, i_fw] += g
            lam[pick, i_aw] = 0.0 if g >= g_max else lam[pick, i_aw] - g
        # the certificate at Z = G⁻² (regularised where G is singular: any Z ⪰ 0 will do)
        relaxed = _inverse(G, W)
        if not relaxed < np.inf:
            for i in range(6):
                A[i] = G[i]
            shift = 1e-9 * max(G[0] + G[1] + G[2], 1e-300)
            A[0] += shift
            A[1] += shift
            A[2] += shift
            if not _inverse(A, W) < np.inf:
                return -np.inf, np.inf
        _square(W, Z)
        half = W[0] + W[1] + W[2]  # tr Z^{1/2} = tr W (W ≻ 0)
        total = 0.0
        added = False
        for k in range(n):
            a = 0
            for i in range(cnt[k]):
                if _dot(Z, J[k], i) > _dot(Z, J[k], a):
                    a = i
            seed[0], seed[1] = pts[k, a, 0], pts[k, a, 1]
            h, v, bx, bz = _oracle(
                Z, targets[k], centres[k, 0], centres[k, 1], radii[k], arena, 0.25 * tol, seed,
                stack,
            )  # fmt: skip
            total += h
            if v > _dot(Z, J[k], a) and cnt[k] < K:
                c = cnt[k]
                pts[k, c, 0], pts[k, c, 1] = bx, bz
                _atom(bx, bz, targets[k], J[k], c)
                lam[k, c] = 0.0
                cnt[k] = c + 1
                added = True
        best = max(best, (2.0 * half - total) * (1.0 - DUAL_MARGIN))
        if relaxed - best <= tol * relaxed or not added:
            break
    return best, relaxed


@njit(**JIT)
def _path_kernel(targets, centres, radii, arena, tol, lower, relaxed):
    """``lower``/``relaxed (P,)`` of :func:`_step_row` for ``P`` steps: ``targets (P, n, 3)``,
    ``centres (P, n, 2)``, ``radii (P, n)``."""
    P, n = targets.shape[0], targets.shape[1]
    K = 1 + RINGS * SPOKES + MAX_ROUNDS
    pts, J = np.empty((n, K, 2)), np.empty((n, K, 6))
    lam, scores = np.empty((n, K)), np.empty((n, K))
    cnt = np.empty(n, np.int64)
    stack = np.empty((64 + 4 * 200, 3))
    for p in range(P):
        lower[p], relaxed[p] = _step_row(
            targets[p], centres[p], radii[p], arena, tol, pts, J, lam, cnt, scores, stack
        )


# ---------------------------------------------------------------- public functions


def reachable(
    params: PlacementParams, state: PlacementState, steps: int
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The reachable sets of the next ``steps`` steps from ``state``: ``(targets (B, steps, n,
    3), centres (B, n, 2), radii (B, steps, n))`` — the true drone at receiver ``k``'s fix time
    ``(t − 1)τ + d_k`` after ``state`` in step ``t`` (column ``t − 1``), and the disc
    ``‖(x, z) − centres[k]‖ ≤ radii[t − 1, k]`` (widened by ``RADIUS_MARGIN``) it can be in
    then, within the arena."""
    if steps < 1:
        raise ValueError(f"steps: must be >= 1, got {steps}")
    elapsed = np.arange(steps)[:, None] * params.period + params.delays_array[None]  # (steps, n)
    p0 = np.asarray(state.drone_position, dtype=np.float64)
    v = np.asarray(state.drone_velocity, dtype=np.float64)
    targets = p0[:, None, None] + v[:, None, None] * elapsed[None, :, :, None]
    centres = np.ascontiguousarray(np.asarray(state.receivers, dtype=np.float64)[..., [0, 2]])
    radii = params.max_speed * elapsed * (1.0 + RADIUS_MARGIN) + RADIUS_MARGIN
    radii = np.broadcast_to(radii, (p0.shape[0], steps, params.n_receivers))
    return targets, centres, np.ascontiguousarray(radii)


def trace_bound_path(
    params: PlacementParams, state: PlacementState, steps: int
) -> tuple[FloatArray, FloatArray]:
    """``(lower, relaxed)`` ``(B, steps)``: the certified lower bound ``L(Z)`` on ``tr G⁻¹`` of
    every placement reachable in each of the next ``steps`` steps from ``state``, and the convex
    relaxation's ``tr G⁻¹`` it certifies (``relaxed ≥ lower``, within ``TOLERANCE`` relative
    when the search converged) — module docstring."""
    targets, centres, radii = reachable(params, state, steps)
    B, n = centres.shape[0], params.n_receivers
    P = B * steps
    c = np.ascontiguousarray(np.broadcast_to(centres[:, None], (B, steps, n, 2)).reshape(P, n, 2))
    lower, relaxed = np.empty(P), np.empty(P)
    _path_kernel(
        np.ascontiguousarray(targets.reshape(P, n, 3)), c, radii.reshape(P, n),
        params.arena_radius * (1.0 + RADIUS_MARGIN), TOLERANCE, lower, relaxed,
    )  # fmt: skip
    return lower.reshape(B, steps), relaxed.reshape(B, steps)


def _reward_bound(params: PlacementParams, lower: FloatArray) -> FloatArray:
    """``clip(ln(σ_ref/σ_ang) − ½ ln L, −R, R)``, ``R`` where ``L ≤ 0`` or ``σ_ang = 0``."""
    R = params.reward_clip
    if params.sigma_ang == 0.0:
        return np.full(lower.shape, R)
    positive = lower > 0.0
    ln_l = np.log(np.where(positive, lower, 1.0))
    value = np.log(params.sigma_ref) - np.log(params.sigma_ang) - 0.5 * ln_l
    return np.where(positive, np.clip(value, -R, R), R)


def bound_path(params: PlacementParams, state: PlacementState, steps: int) -> FloatArray:
    """``(B, steps)`` the bound ``B_t`` of each of the next ``steps`` steps from ``state``:
    column ``t − 1`` bounds the reward of step ``t`` after ``state`` whatever the policy —
    ``B_t = clip(ln(σ_ref/σ_ang) − ½ ln L(Z), −R, R) ≥ max over the reachable placements``
    (module docstring)."""
    lower, _ = trace_bound_path(params, state, steps)
    return _reward_bound(params, lower)


def step_bound(params: PlacementParams, state: PlacementState) -> FloatArray:
    """``(B,)`` the largest reward any action taken in ``state`` can earn on this step, per
    scenario (receivers within ``max_speed · d_k`` of where they stand at their fix times)."""
    return bound_path(params, state, 1)[:, 0]


def episode_bound(
    params: PlacementParams, state: PlacementState, steps: int | None = None
) -> FloatArray:
    """``(B,)`` the bound of the return from ``state`` over ``steps`` steps (None: the
    registration's ``max_episode_steps``, 60 — from a reset state, the whole episode):
    ``Σ_t B_t`` summed in step order, as a return is. No policy's return from ``state`` can
    exceed it (module docstring)."""
    if steps is None:
        steps = int(gymnasium.spec("sensorgym/StereoPlacement-v0").max_episode_steps)
    values = bound_path(params, state, steps)
    out = np.zeros(values.shape[0])
    for t in range(steps):  # sequential, not np.sum's pairwise order
        out += values[:, t]
    return out
