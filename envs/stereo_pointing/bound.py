"""A true upper bound on the ``sensorgym/StereoPointing-v0`` reward, per step and per episode.

**What the reward depends on.** Step ``t`` moves the drones to ``p_j' = p_j + v_j dt`` and the
boresights ``b_k`` by the action, then pays (:mod:`.simulation`, :mod:`.kernels`)

    r_t = (1/m) Σ_j f_j(K_j),   K_j = {k : u_kj · b_k ≥ cos fov, u_kj ≠ 0}

    f_j(K) = clip(ln(σ_ref / σ_pos(K)), −R, R),   σ_pos(K) = σ_ang √tr G_K⁻¹,
    G_K = Σ_{k∈K} (I − u_kj u_kjᵀ) / r_kj²

at the *true* lines of sight ``u_kj`` and ranges ``r_kj`` of the moved drones; ``σ_pos = ∞``
(so ``f_j = −R``) unless ``|K| ≥ 2`` and ``det G_K > CONDITION · (tr G_K)³`` (theory §4.3).
Neither the tracker, nor the noise draw, nor whether a drone was ever fixed enters: ``r_t`` is a
function of the true drone positions (which no action changes: drones fly straight lines) and
of the set ``S_k = {j : k ∈ K_j}`` of drones each receiver's cone holds.

**The relaxation.** Two drones in one cone of half-angle ``fov`` are at most ``2·fov`` apart
seen from its apex (the triangle inequality of angles on the sphere: ``∠(u_i, u_j) ≤ ∠(u_i, b)
+ ∠(b, u_j)``, and ``2·fov < π``). So every reachable ``S_k`` lies in the family

    𝓕_k = {S ⊆ drones : u_kj ≠ 0 for j ∈ S, u_ki · u_kj ≥ cos 2fov for i, j ∈ S}

(a cosine slack of ``COS_SLACK`` absorbs rounding). The bound drops everything else: the slew
limit, the elevation limit, the cone's need for one common centre (a superset for three or more
drones; exact for two), and the coupling between steps. Then

    B_t = max over S_k ∈ 𝓕_k of (1/m) Σ_j f_j({k : j ∈ S_k})  ≥  r_t   for every policy,

because the policy's ``(S_k)`` is one of the candidates and is scored by the same ``f_j``. No
monotonicity of ``f_j`` is needed for that, and none is assumed: ``f_j`` is *not* monotone in
general — adding a view adds information (``G`` grows in the Loewner order, so ``tr G⁻¹``
falls and the clipped log rises), but the conditioning test ``det G / (tr G)³`` can fall when a
very close receiver joins (never at the defaults' ranges). The search uses the monotone hull

    g_j(K) = max_{K' ⊆ K} f_j(K')

instead: ``Σ_j g_j(K_j)`` over choices in 𝓕 equals the maximum of ``Σ_j f_j`` over 𝓕, since 𝓕
is closed under taking subsets (shrink each ``S_k`` to the ``K'_j`` that attain ``g_j``). As
``g_j`` is monotone, each receiver need only take a *maximal* member of ``𝓕_k`` (a maximal clique
of the graph "within ``2·fov``" among the drones it can see), and the search is a branch and
bound over receivers with the bound ``Σ_j g_j(K_j ∪ {receivers still to choose})``.

Floating point: ``f_j`` is computed by the env's own compiled primitives on the same inputs
(bit for bit the env's per-drone reward for the same views), and rounding is monotone, so
``r_t ≤ B_t`` holds exactly in float64; the episode sums are taken in step order as a return is.

**The episode bound.** The drones' path does not depend on the policy, so the bound of an
episode is ``Σ_t B_t`` along the path from its first state: a number of the scenario alone,
known before the episode is played, which no policy's return can exceed.

**Cost.** Per scenario and step ``O(m n 2ⁿ)`` for the table of ``f_j`` and ``g_j`` over the
``2ⁿ`` receiver sets, ``O(n 2ᵐ m²)`` for the maximal cliques and at most ``m Π_k c_k`` for the
search, ``c_k ≤ 3^{m/3}`` the number of maximal cliques at receiver ``k`` (``m`` when all drones
are more than ``2·fov`` apart); the pruning cuts most of it.

The proof sketch in prose: theory §11.3.1.
"""

from __future__ import annotations

import math

import gymnasium
import numpy as np
from numba import njit
from numpy.typing import NDArray

from sensorgym.envs.stereo_pointing.simulation import PointingParams, PointingState
from sensorgym.trackers.stereo.kernels import (
    JIT,
    count_views,
    line_of_sight,
    log_ratio_reward,
    observable,
    position_information,
    position_sigma,
)

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

__all__ = [
    "COS_SLACK",
    "bound_path",
    "episode_bound",
    "step_bound",
    "step_bound_views",
]

#: two drones count as fitting in one cone when ``u_i · u_j ≥ cos 2fov − COS_SLACK``: a slack far
#: above the rounding of either dot product (the env's cone test or this one) only widens 𝓕
COS_SLACK = 1e-9
#: the most receivers the table of ``2ⁿ`` receiver sets is built for (8 MB per drone)
MAX_RECEIVERS = 20
#: the most drones the ``2ᵐ`` candidate sets of a receiver are enumerated for
MAX_DRONES = 16


@njit(**JIT)
def _bound_row(
    receivers,
    settings,
    p,
    q,
    u,
    r,
    ones,
    mask,
    seeable,
    f,
    g,
    arg,
    cand,
    n_cand,
    rem,
    K,
    choice,
    scratch,
):
    """The bound ``B`` at the true drone positions ``p (m, 3)`` (after the step's move), each
    receiver holding at most ``q`` drones; returns ``(B, best K (m,) as receiver bit masks of
    the f-level sets that attain it)`` in ``K[n]`` (scratch arrays given by the caller)."""
    n, m = receivers.shape[0], p.shape[0]
    N = 1 << n
    s = settings[0]
    sigma_ang, sigma_ref, clip_r = s.sigma_ang, s.sigma_ref, s.reward_clip
    cos2 = math.cos(2.0 * s.fov) - COS_SLACK
    G, LU, inv = scratch[0], scratch[1], scratch[2]
    piv = np.empty(3, np.int64)
    # lines of sight u_kj and ranges r_kj; whether receiver k can see drone j at all (u ≠ 0:
    # a drone on a receiver has no direction from it and is never seen, cos fov > 0)
    for j in range(m):
        for k in range(n):
            r[j, k] = line_of_sight(receivers[k], p[j], u[j, k])
            seeable[j, k] = not (u[j, k, 0] == 0.0 and u[j, k, 1] == 0.0 and u[j, k, 2] == 0.0)
    # f_j(K) for every receiver set K, by the env's primitives; g_j(K) = max_{K' ⊆ K} f_j(K')
    for j in range(m):
        blind = 0  # the receivers that never see drone j
        for k in range(n):
            if not seeable[j, k]:
                blind |= 1 << k
        for S in range(N):
            if S & blind:
                f[j, S] = -np.inf
                continue
            views = 0
            for k in range(n):
                mask[k] = (S >> k) & 1 == 1
                views += 1 if mask[k] else 0
            if views < 2:
                # fewer than two views: σ_pos = ∞, f = −R (the test of §4.3 fails first)
                f[j, S] = log_ratio_reward(np.inf, sigma_ref, clip_r)
                continue
            # G = Σ_{k∈K} (I − u uᵀ)/r², σ_pos = σ √tr G⁻¹, f = clip(ln(σ_ref/σ_pos), −R, R)
            position_information(u[j], r[j], ones, mask, G)
            ok = observable(G, count_views(mask))
            sigma_pos = position_sigma(G, ok, sigma_ang, LU, piv, inv)
            f[j, S] = log_ratio_reward(sigma_pos, sigma_ref, clip_r)
        for S in range(N):
            g[j, S] = f[j, S]
            arg[j, S] = S
        for i in range(n):
            bit = 1 << i
            for S in range(N):
                if S & bit and g[j, S ^ bit] > g[j, S]:
                    g[j, S] = g[j, S ^ bit]
                    arg[j, S] = arg[j, S ^ bit]
    # candidates per receiver: the maximal drone sets of 𝓕_k holding at most q drones
    for k in range(n):
        n_cand[k] = 0
        for D in range(1 << m):
            size = 0
            fits = True
            for i in range(m):
                if (D >> i) & 1:
                    size += 1
                    fits = fits and seeable[i, k]
                    for j in range(i):
                        if (D >> j) & 1:
                            dot = u[i, k, 0] * u[j, k, 0] + u[i, k, 1] * u[j, k, 1]
                            fits = fits and dot + u[i, k, 2] * u[j, k, 2] >= cos2
            if not fits or size > q:
                continue
            maximal = True
            if size < q:
                for i in range(m):
                    if (D >> i) & 1 or not seeable[i, k]:
                        continue
                    joins = True
                    for j in range(m):
                        if (D >> j) & 1:
                            dot = u[i, k, 0] * u[j, k, 0] + u[i, k, 1] * u[j, k, 1]
                            joins = joins and dot + u[i, k, 2] * u[j, k, 2] >= cos2
                    if joins:
                        maximal = False
                        break
            if maximal:
                cand[k, n_cand[k]] = D
                n_cand[k] += 1
    # rem[i, j]: the receivers i … n − 1 that some candidate lets see drone j
    for j in range(m):
        rem[n, j] = 0
    for i in range(n - 1, -1, -1):
        for j in range(m):
            rem[i, j] = rem[i + 1, j]
        for a in range(n_cand[i]):
            for j in range(m):
                if (cand[i, a] >> j) & 1:
                    rem[i, j] |= 1 << i
    root = 0.0
    for j in range(m):
        root += g[j, rem[0, j]]
    # branch and bound over receivers: K[i, j] the receivers 0 … i − 1 chosen to see drone j
    best = -np.inf
    best_K = np.zeros(m, np.int64)
    for j in range(m):
        K[0, j] = 0
    level = 0
    choice[0] = -1
    while level >= 0:
        if level == n:
            # Σ_j g_j(K_j) in drone order, as the env sums its reward
            total = 0.0
            for j in range(m):
                total += g[j, K[n, j]]
            if total > best:
                best = total
                for j in range(m):
                    best_K[j] = K[n, j]
                if best >= root:  # the decoupled maximum: nothing can beat it
                    break
            level -= 1
            continue
        choice[level] += 1
        if choice[level] >= n_cand[level]:
            level -= 1
            continue
        if choice[level] == 0:
            # every leaf below has g_j(K_j) ≤ g_j(K_j ∪ rem_j) term by term (g monotone)
            ub = 0.0
            for j in range(m):
                ub += g[j, K[level, j] | rem[level, j]]
            if ub <= best:
                level -= 1
                continue
        D = cand[level, choice[level]]
        for j in range(m):
            K[level + 1, j] = K[level, j] | ((1 << level) if (D >> j) & 1 else 0)
        level += 1
        if level < n:
            choice[level] = -1
    for j in range(m):
        K[n, j] = arg[j, best_K[j]]
    return best / m


@njit(**JIT)
def _bound_path_kernel(receivers, settings, position, velocity, steps, q, values, views):
    """``values (B, steps)``: the bound of each of the next ``steps`` steps from drones at
    ``position``/``velocity (B, m, 3)``, moved as the env moves them (``p ← p + v dt``);
    ``views (B, n, m)``: the attaining views of the first step."""
    B, m, n = position.shape[0], position.shape[1], receivers.shape[0]
    N = 1 << n
    dt = settings[0].dt
    p = np.empty((m, 3))
    u, r = np.empty((m, n, 3)), np.empty((m, n))
    ones = np.ones(n)
    mask = np.empty(n, dtype=np.bool_)
    seeable = np.empty((m, n), dtype=np.bool_)
    f, g = np.empty((m, N)), np.empty((m, N))
    arg = np.empty((m, N), np.int64)
    cand = np.empty((n, 1 << m), np.int64)
    n_cand = np.empty(n, np.int64)
    rem = np.empty((n + 1, m), np.int64)
    K = np.empty((n + 1, m), np.int64)
    choice = np.empty(n + 1, np.int64)
    scratch = np.empty((3, 3, 3))
    for b in range(B):
        for j in range(m):
            for i in range(3):
                p[j, i] = position[b, j, i]
        for t in range(steps):
            # the env's move, the same expression (kernels.step_kernel)
            for j in range(m):
                for i in range(3):
                    p[j, i] = p[j, i] + velocity[b, j, i] * dt
            values[b, t] = _bound_row(
                receivers, settings, p, q, u, r, ones, mask, seeable, f, g, arg, cand, n_cand, rem, K,
                choice, scratch,
            )  # fmt: skip
            if t == 0:
                for k in range(n):
                    for j in range(m):
                        views[b, k, j] = (K[n, j] >> k) & 1 == 1


def _check(params: PointingParams, max_drones_per_receiver: int | None) -> int:
    """The cap ``q`` on the drones one receiver holds (``m`` for none), sizes checked."""
    n, m = params.n_receivers, params.n_drones
    if n > MAX_RECEIVERS or m > MAX_DRONES:
        raise ValueError(
            f"params: the bound enumerates 2^n receiver sets and 2^m drone sets; needs"
            f" n_receivers <= {MAX_RECEIVERS} and n_drones <= {MAX_DRONES}, got {n} and {m}"
        )
    if max_drones_per_receiver is None:
        return m
    if int(max_drones_per_receiver) < 1:
        raise ValueError(f"max_drones_per_receiver: must be >= 1, got {max_drones_per_receiver}")
    return min(int(max_drones_per_receiver), m)


def bound_path(
    params: PointingParams,
    state: PointingState,
    steps: int,
    *,
    max_drones_per_receiver: int | None = None,
) -> FloatArray:
    """``(B, steps)`` the bound ``B_t`` of each of the next ``steps`` steps from ``state``:
    column ``t`` bounds the reward of the action taken in the ``t``-th state from this one,
    whatever the policy (the drones' path does not depend on it; module docstring).

    ``max_drones_per_receiver``: None for the bound; ``q`` restricts every receiver to at most
    ``q`` drones — with ``q = 1`` (each receiver on one drone) a diagnostic of what seeing two
    drones at once is worth, *not* an upper bound on the env's reward.
    """
    if steps < 0:
        raise ValueError(f"steps: must be >= 0, got {steps}")
    q = _check(params, max_drones_per_receiver)
    p = np.ascontiguousarray(state.drone_position, dtype=np.float64)
    v = np.ascontiguousarray(state.drone_velocity, dtype=np.float64)
    B = p.shape[0]
    values = np.empty((B, steps))
    views = np.zeros((B, params.n_receivers, params.n_drones), dtype=bool)
    _bound_path_kernel(params._receivers, params.kernel_settings, p, v, steps, q, values, views)
    return values


def step_bound(
    params: PointingParams, state: PointingState, *, max_drones_per_receiver: int | None = None
) -> FloatArray:
    """``(B,)`` the largest reward any action taken in ``state`` can earn on this step, per
    scenario: ``B_t = max_{S_k ∈ 𝓕_k} (1/m) Σ_j f_j({k : j ∈ S_k})`` at the drones moved by
    ``dt`` (module docstring: the relaxation and why no action exceeds it).
    ``max_drones_per_receiver`` as in :func:`bound_path`."""
    return step_bound_views(params, state, max_drones_per_receiver=max_drones_per_receiver)[0]


def step_bound_views(
    params: PointingParams, state: PointingState, *, max_drones_per_receiver: int | None = None
) -> tuple[FloatArray, BoolArray]:
    """:func:`step_bound` and views ``(B, n, m)`` that attain it: receiver ``k`` seeing exactly
    the drones ``j`` with ``views[:, k, j]`` scores ``(1/m) Σ_j f_j`` equal to the bound, bit for
    bit. Each receiver's drones lie within ``2·fov`` of each other (for two drones, or one,
    a pointing that shows the receiver exactly these exists unless another drone lies in the
    way)."""
    q = _check(params, max_drones_per_receiver)
    p = np.ascontiguousarray(state.drone_position, dtype=np.float64)
    v = np.ascontiguousarray(state.drone_velocity, dtype=np.float64)
    B = p.shape[0]
    values = np.empty((B, 1))
    views = np.zeros((B, params.n_receivers, params.n_drones), dtype=bool)
    _bound_path_kernel(params._receivers, params.kernel_settings, p, v, 1, q, values, views)
    return values[:, 0], views


def episode_bound(
    params: PointingParams,
    state: PointingState,
    steps: int | None = None,
    *,
    max_drones_per_receiver: int | None = None,
) -> FloatArray:
    """``(B,)`` the bound of the return from ``state`` over ``steps`` steps (None: the
    registration's ``max_episode_steps``, 150 — from a reset state, the whole episode):
    ``Σ_t B_t`` summed in step order, as a return is. No policy's return from ``state`` can
    exceed it (module docstring). ``max_drones_per_receiver`` as in :func:`bound_path`."""
    if steps is None:
        steps = int(gymnasium.spec("sensorgym/StereoPointing-v0").max_episode_steps)
    values = bound_path(params, state, steps, max_drones_per_receiver=max_drones_per_receiver)
    out = np.zeros(values.shape[0])
    for t in range(steps):  # sequential, not np.sum's pairwise order
        out += values[:, t]
    return out
