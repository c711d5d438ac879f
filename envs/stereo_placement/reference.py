"""The readable specification of StereoPlacement's compiled step, in plain numpy.

The env runs :func:`.kernels.period_rows`: one fused numba pass per step over the scenarios,
fast and hard to read (theory §11.4, "Implementation"). This module is the same step written
to be read: the equations of docs/theory.md in order, one stage a function, each stage citing
the section it implements, with the textbook symbols (``O_k``, ``M``, ``u_k``, ``R_k``,
``a_k``, ``P_k``, ``b_k``, ``A``, ``B``, ``X``, ``Q``, ``κ_F``, ``G``, ``σ_pos``). The env never
runs it.

:func:`reset`, :func:`start` and :func:`step` have the signatures and the contract of their
namesakes in :mod:`.simulation` (the functions there that call the kernel; :func:`in_arena`
and :func:`los_angles` too): the same params, state (:class:`.simulation.PlacementState`),
actions and random draws, consumed in the same order, so that from the same state and a
generator in the same state they return the same scenarios to rounding.
``tests/envs/stereo_placement/test_reference.py`` checks that over whole episodes with autoresets, field
by field, within stated tolerances.

Rounding is all that should differ. The kernel solves the conjugation system of ``n = 3``
receivers by Cramer's rule and of more by the normal equations; the reference always takes
the generic SVD path of :mod:`sensorgym.trackers.stereo.conjugation` (which the kernel also
takes where ``κ_F`` is large). Both are accurate to about ``κ_F ε`` (the normal equations to
``κ_F² ε``), hence the test's tolerances.

Each formula lives once: what the package already holds in readable numpy is called, not
copied — the stacked system and its least-squares / pseudo-inverse solve
(:func:`~sensorgym.trackers.stereo.conjugation.build_system` and its SVD solver), the noise
draws (:func:`.scan.draw_normals`), the angle between two lines of sight
(:func:`~sensorgym.trackers.stereo.accuracy.los_angle`), the observation clip
(:func:`~sensorgym.envs.shells.contract.clip_observation`) and the diagnostics
(:func:`.simulation.info` reads them off the state). The rest lives elsewhere only as
compiled primitives (look-at frames, angular noise, the Fisher information, its bound and the
reward) and is written out below.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sensorgym.envs.shells.contract import clip_observation
from sensorgym.envs.stereo_placement.scan import ScanFix, ScanGeometry, draw_normals
from sensorgym.envs.stereo_placement.simulation import (
    PlacementParams,
    PlacementState,
    draw_cue,
    draw_scenario,
)
from sensorgym.trackers.stereo.accuracy import los_angle
from sensorgym.trackers.stereo.conjugation import DEFAULT_COND_MAX, build_system, solve_svd
from sensorgym.trackers.stereo.information import CONDITION, MIN_RANGE

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

#: world up (theory §2.2: ``Y`` up); the receivers' frames keep their ``Y`` axis towards it
UP = np.array([0.0, 1.0, 0.0])

#: observation floor of a standard deviation before its logarithm, m (``ln 0`` would be −∞)
TINY_SIGMA = 1e-12

#: observation ceiling of ``κ_F`` before its logarithm (``log10 ∞`` would be ∞)
HUGE_CONDITION = 1e300


# ------------------------------------------- step 1: the vehicles drive, the drone flies on


def in_arena(params: PlacementParams, positions: ArrayLike, margin: float = 0.0) -> FloatArray:
    """Ground positions ``(..., 3)`` pulled radially back onto the permitted disc (radius
    ``arena_radius − margin``) where outside it (theory §11.4): ``o ← o · min(1, ρ_max/ρ)``,
    ``ρ = √(x² + z²)`` (floored at 1e-12 m)."""
    o = np.asarray(positions, dtype=np.float64)
    rho = np.maximum(np.hypot(o[..., 0], o[..., 2]), 1e-12)
    return o * np.minimum(1.0, (params.arena_radius - margin) / rho)[..., None]


def drive(params: PlacementParams, receivers: FloatArray, action: FloatArray) -> FloatArray:
    """Receivers ``(B, n, 3)`` after one period at the velocities of ``action (B, n, 2)``
    (theory §11.4, step 1; ``simulation`` module docstring).

    Each component is clipped to ``[−1, 1]``, the speed capped:
    ``v_k = v_max (a_x, 0, a_z) / max(‖a‖, 1)``; the receiver drives straight for ``τ``,
    ``o_k ← o_k + τ v_k``, and is held in the disc.
    """
    a = np.clip(action, -1.0, 1.0)
    s = np.maximum(np.linalg.norm(a, axis=-1), 1.0)
    v_x = params.max_speed * (a[..., 0] / s)
    v_z = params.max_speed * (a[..., 1] / s)
    v = np.stack([v_x, np.zeros_like(v_x), v_z], axis=-1)
    return in_arena(params, receivers + params.period * v)


def fly(params: PlacementParams, drone: FloatArray, velocity: FloatArray) -> FloatArray:
    """The drone after one period of its straight level line (theory §11.4): ``M ← M + τ V``."""
    return drone + params.period * velocity


# --------------------------------------------------- step 2: the scan period and the tracker


def geometry_at_fix_times(
    params: PlacementParams,
    start: FloatArray,
    end: FloatArray,
    drone_end: FloatArray,
    drone_velocity: FloatArray,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The true geometry of the period at each receiver's fix time ``d_k`` (theory §6.4):
    ``(O_k(d_k) (B, n, 3), u_k (B, n, 3), r_k (B, n))``.

    Receivers drive straight from ``start`` to ``end`` over ``τ``:
    ``O_k(d_k) = O_k(0) + (O_k(τ) − O_k(0)) d_k/τ``; the drone flies straight and is at
    ``M(τ) = drone_end``: ``M(d_k) = M(τ) − V (τ − d_k)``; ``u_k = (M(d_k) − O_k)/r_k``,
    ``r_k = ‖M(d_k) − O_k‖``.
    """
    tau, d = params.period, params.delays_array
    origins = start + (end - start) * (d / tau)[None, :, None]
    drone_at_fix = drone_end[:, None, :] - drone_velocity[:, None, :] * (tau - d)[None, :, None]
    sight = drone_at_fix - origins
    ranges = np.linalg.norm(sight, axis=-1)
    if not np.all(ranges > MIN_RANGE):
        raise ValueError("scan: a receiver sits on the drone (no line of sight)")
    return origins, sight / ranges[..., None], ranges


def boresight_rotations(origins: FloatArray, aim: FloatArray, max_elevation: float) -> FloatArray:
    """Local→world rotations ``R_k (B, n, 3, 3)`` (columns: the receiver's ``X``, ``Y``, ``Z``
    axes) of receivers at ``origins`` looking at ``aim (B, 3)`` (theory §6.4, §2.2).

    The boresight points at the aim with its elevation held within ``±max_elevation``:
    ``φ = atan2(d_x, d_z)``, ``θ = clip(atan2(d_y, √(d_x² + d_z²)), ±θ_max)``, ``d = aim − O_k``,
    ``Z = (cos θ sin φ, sin θ, cos θ cos φ)`` (000 eq. 2); ``Y`` is world up made orthogonal to
    ``Z``, ``Y = (up − (up·Z) Z)/‖·‖``, and ``X = Y × Z`` (the 000/003 receiver frame).
    """
    d = aim[:, None, :] - origins
    azimuth = np.arctan2(d[..., 0], d[..., 2])
    elevation = np.arctan2(d[..., 1], np.hypot(d[..., 0], d[..., 2]))
    elevation = np.clip(elevation, -max_elevation, max_elevation)
    Z = np.stack(
        [
            np.cos(elevation) * np.sin(azimuth),
            np.sin(elevation),
            np.cos(elevation) * np.cos(azimuth),
        ],
        axis=-1,
    )
    Y = UP - (Z @ UP)[..., None] * Z
    Y /= np.linalg.norm(Y, axis=-1, keepdims=True)
    X = np.cross(Y, Z)
    return np.stack([X, Y, Z], axis=-1)


def noisy_directions(los: FloatArray, normals: FloatArray, sigma_ang: ArrayLike) -> FloatArray:
    """The directions the receivers fix (theory §4.1, angle-noise model):
    ``z_k = (u_k + δ_k)/‖u_k + δ_k‖``, ``δ_k = σ_ang (I − u_k u_kᵀ) n_k`` with ``n_k`` the
    standard normal draws ``normals (..., 3)`` (the error lies across the line of sight), in
    whatever frame ``los (..., 3)`` is given. ``σ_ang`` is one value or one per direction
    (broadcast against ``los[..., 0]``); noise-free (``σ_ang = 0``): ``z_k = u_k``."""
    sigma = np.asarray(sigma_ang, dtype=np.float64)
    if not np.any(sigma > 0.0):
        return los
    along = np.sum(normals * los, axis=-1, keepdims=True)
    z = los + (normals - along * los) * sigma[..., None]
    return np.where(sigma[..., None] > 0.0, z / np.linalg.norm(z, axis=-1, keepdims=True), los)


def own_frame(R: FloatArray, directions: FloatArray) -> FloatArray:
    """What each receiver reports: its world direction ``z_k`` in its own frame,
    ``a_k = R_kᵀ z_k`` (theory §2.1: ``R_k`` local→world)."""
    return np.einsum("bkji,bkj->bki", R, directions)


def conjugation_system(
    params: PlacementParams, R: FloatArray, origins: FloatArray, a: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """``A (B, 3(n−1), n+3)`` and ``B (B, 3(n−1))`` of the period's velocity-aware conjugation
    equations (theory §6.4, §3.2–3.3)::

        r_1 a_1 − r_k P_k a_k + V Δt_k − b_k = e_k ,   Δt_k = d_k − d_1 ,   k = 2..n

    ``a (B, n, 3)`` are the receivers' reports in their own frames (:func:`own_frame`); the
    relative poses at the fix times are ``P_k = R_1ᵀ R_k`` and ``b_k = R_1ᵀ (O_k − O_1)``
    (theory §2.1), so ``c_k = P_k a_k`` is direction ``k`` in frame 1. Unknowns
    ``X = (r_1 … r_n, V)``, ``V`` in frame 1 (:func:`build_system`, order 1).
    """
    R1 = R[:, :1]
    P = np.swapaxes(R1, -1, -2) @ R[:, 1:]  # P_k = R_1ᵀ R_k
    b = np.einsum("bkji,bkj->bki", R1, origins[:, 1:] - origins[:, :1])  # b_k = R_1ᵀ (O_k − O_1)
    c = np.einsum("bkij,bkj->bki", P, a[:, 1:])  # c_k = P_k a_k
    d = params.delays_array
    return build_system(a[:, 0], c, b, d[1:] - d[0], order=1)


def least_squares(
    A: FloatArray, B: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray, BoolArray]:
    """``(X̂, (AᵀA)⁻¹, κ_F, used_pinv)`` of ``A X − B = E`` (theory §3.3, 003 eq. 5–6)::

        X̂ = (AᵀA)⁻¹ AᵀB ,   Q = σ_e² (AᵀA)⁻¹ (here σ_e = 1) ,   κ_F = √(tr(AᵀA) · tr((AᵀA)⁻¹))

    and, where ``κ_F > cond_max`` (theory §13.14), the pseudo-inverse ``X̂ = A⁺B`` with singular
    values below ``s_max/cond_max`` dropped, flagged ``used_pinv`` (000 eq. 11). The solver's
    generic SVD path (:mod:`sensorgym.trackers.stereo.conjugation`) computes exactly this.
    """
    X, _, Q, kappa, used_pinv = solve_svd(A, B, None, 1.0, DEFAULT_COND_MAX)
    return X, Q, kappa, used_pinv


def fix_in_world(
    params: PlacementParams,
    R: FloatArray,
    origins: FloatArray,
    a1: FloatArray,
    X: FloatArray,
    Q: FloatArray,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """The tracker's fix in the world at the period end and its reported accuracy:
    ``(position (B, 3), velocity (B, 3), range σ (B, n), velocity σ (B,))``.

    Position and velocity (theory §6.4, §13.5): ``M̂_1 = r̂_1 a_1`` and ``V̂`` in frame 1 go to
    the world, ``V = R_1 V̂``, ``M(d_1) = O_1(d_1) + R_1 M̂_1``, and on to the period end,
    ``M(τ) = M(d_1) + V (τ − d_1)``.

    Covariance mapping (theory §13.4, :mod:`.scan`): the papers' ``Q = σ_e² (AᵀA)⁻¹`` with
    ``σ_e = σ_ang · mean_k |r̂_k|`` from the estimated ranges; ``σ[r̂_k] = √Q_kk`` and
    ``σ_V = √tr Q_VV`` (negative round-off on the diagonal counts as 0).
    """
    n, d = params.n_receivers, params.delays_array
    sigma_e = params.sigma_ang * np.mean(np.abs(X[:, :n]), axis=-1)
    variances = np.maximum(sigma_e[:, None] ** 2 * np.diagonal(Q, axis1=-2, axis2=-1), 0.0)
    range_sigma = np.sqrt(variances[:, :n])
    velocity_sigma = np.sqrt(np.sum(variances[:, n:], axis=-1))
    R1 = R[:, 0]
    M1 = X[:, :1] * a1  # M̂_1 = r̂_1 a_1, frame 1
    velocity = np.einsum("bij,bj->bi", R1, X[:, n:])  # V = R_1 V̂
    at_fix = origins[:, 0] + np.einsum("bij,bj->bi", R1, M1)  # M(d_1)
    position = at_fix + velocity * (params.period - d[0])  # M(τ)
    return position, velocity, range_sigma, velocity_sigma


def tracker_estimate(
    params: PlacementParams,
    position: FloatArray,
    velocity: FloatArray,
    degenerate: BoolArray,
    previous: FloatArray,
) -> FloatArray:
    """The tracker's estimate ``(p̂, v̂) (B, 6)`` at the period end (theory §11.4): the fix, but
    where the solve was degenerate (the pseudo-inverse fallback) the fix is not trusted and
    the previous estimate coasts by ``τ``: ``p̂ ← p̂ + τ v̂``, ``v̂`` kept."""
    p, v = previous[:, :3], previous[:, 3:]
    coasted = np.concatenate([p + params.period * v, v], axis=-1)
    fixed = np.concatenate([position, velocity], axis=-1)
    return np.where(degenerate[:, None], coasted, fixed)


# ------------------------------------------------------------- step 3: the bound and reward


def position_bound(los: FloatArray, ranges: FloatArray, sigma_ang: float) -> FloatArray:
    """Cramér–Rao position RMS ``σ_pos (B,)`` of the period's true geometry, m (theory §4.2,
    §4.3, §11.4)::

        G = Σ_k (I − u_k u_kᵀ) / r_k² ,   σ_pos = σ_ang √tr G⁻¹

    (ranges floored at ``MIN_RANGE``), ``+∞`` where ``G`` fails the observability test
    ``det G > 1e-12 (tr G)³`` (every receiver sees the drone: n ≥ 2 views).
    """
    r = np.maximum(ranges, MIN_RANGE)
    projections = np.eye(3) - los[..., :, None] * los[..., None, :]  # Π_k = I − u_k u_kᵀ
    G = np.sum(projections / (r**2)[..., None, None], axis=1)
    observable = np.linalg.det(G) > CONDITION * np.trace(G, axis1=-2, axis2=-1) ** 3
    # G⁻¹ where observable (the identity stands in elsewhere, whose bound is then +∞)
    G_inv = np.linalg.inv(np.where(observable[:, None, None], G, np.eye(3)))
    trace = np.maximum(np.trace(G_inv, axis1=-2, axis2=-1), 0.0)
    return np.where(observable, sigma_ang * np.sqrt(trace), np.inf)


def reward(params: PlacementParams, bound: FloatArray, degenerate: BoolArray) -> FloatArray:
    """``clip(ln(σ_ref/σ_pos), −R, R)`` (theory §11.1, §11.4): ``+R`` for an exact fix
    (``σ_pos = 0``), ``−R`` where the position is unobservable (``σ_pos = ∞``) and where the
    conjugation is degenerate (``degenerate``: the tracker's solve or the noise-free solve of
    the true geometry took the pseudo-inverse)."""
    R = params.reward_clip
    with np.errstate(divide="ignore"):  # ln 0 = −∞: the exact fix, clipped to +R
        log_ratio = np.clip(np.log(params.sigma_ref) - np.log(bound), -R, R)
    return np.where(degenerate | ~np.isfinite(bound), -R, log_ratio)


# ------------------------------------------------------ the observation and the diagnostics


def los_angles(params: PlacementParams, receivers: FloatArray, point: FloatArray) -> FloatArray:
    """Angles ``γ_kl (B, n(n−1)/2)`` between the lines of sight from receivers ``(B, n, 3)``
    to ``point (B, 3)``, pairs in :attr:`PlacementParams.pairs` order, rad (theory §10.1:
    ``γ = atan2(‖u_k × u_l‖, u_k·u_l)``, :func:`los_angle`)."""
    sight = point[:, None, :] - receivers
    u = sight / np.linalg.norm(sight, axis=-1, keepdims=True)
    k, l = params.pairs_array.T
    return los_angle(u[:, k], u[:, l])


def observation(
    params: PlacementParams, receivers: FloatArray, estimate: FloatArray, fix: ScanFix
) -> NDArray[np.float32]:
    """The agent's observation ``(B, obs_dim)`` (the block table of :func:`.simulation.observe`):
    own positions and the tracker, no truth; ``L = length_scale``, ``S = speed_scale``."""
    B, L = receivers.shape[0], params.length_scale
    p_hat, v_hat = estimate[:, :3], estimate[:, 3:]
    ground = receivers[..., [0, 2]]  # (x_k, z_k)
    blocks = [
        (ground / L).reshape(B, -1),  # own (x, z) / L
        ((ground - p_hat[:, None, [0, 2]]) / L).reshape(B, -1),  # receiver from ĝ
        p_hat / L,
        v_hat / params.speed_scale,
        np.log(np.maximum(fix.range_sigma, TINY_SIGMA) / params.sigma_ref),  # ln(σ[r̂_k]/σ_ref)
        # ln(σ_V / (σ_ref/τ))
        np.log(np.maximum(fix.velocity_sigma, TINY_SIGMA) * params.period / params.sigma_ref)[
            :, None
        ],
        np.log10(np.minimum(fix.condition, HUGE_CONDITION))[:, None],  # log10 κ_F
        los_angles(params, receivers, p_hat) / (np.pi / 2),  # γ_kl / (π/2) to p̂
        fix.degenerate.astype(np.float64)[:, None],
    ]
    return clip_observation(np.concatenate(blocks, axis=-1))


def diagnostics(
    params: PlacementParams, receivers: FloatArray, estimate: FloatArray, drone: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Ground truth for ``info`` (never observed): the estimate's error ``‖p̂ − p‖`` and the
    smallest angle between the receivers' lines of sight to the drone."""
    error = np.linalg.norm(estimate[:, :3] - drone, axis=-1)
    return error, np.min(los_angles(params, receivers, drone), axis=-1)


# ------------------------------------------------------------------------- one scan period


def scan_period(
    params: PlacementParams,
    t: FloatArray,
    start: FloatArray,
    end: FloatArray,
    drone_end: FloatArray,
    drone_velocity: FloatArray,
    previous: FloatArray,
    normals: FloatArray,
) -> tuple[PlacementState, FloatArray]:
    """One scan period ending at ``t`` (theory §6.4, §11.4): the receivers drive from ``start``
    to ``end``, the drone ends at ``drone_end``; the frames look at the ``previous (B, 6)``
    estimate coasted to mid-period; ``normals (B, n, 3)`` are the period's noise draws.
    Returns ``(state, reward)`` (the kernel's ``period_rows`` after the drive)."""
    sigma_ang = params.sigma_ang
    origins, los, ranges = geometry_at_fix_times(params, start, end, drone_end, drone_velocity)
    aim = previous[:, :3] + 0.5 * params.period * previous[:, 3:]
    R = boresight_rotations(origins, aim, params.max_boresight_elevation)
    z = noisy_directions(los, normals, sigma_ang)
    a = own_frame(R, z)
    X, Q, kappa, degenerate = least_squares(*conjugation_system(params, R, origins, a))
    # the same system without noise: is the true geometry itself degenerate (theory §11.4)?
    if sigma_ang > 0.0:
        exact = own_frame(R, los)
        degenerate_true = least_squares(*conjugation_system(params, R, origins, exact))[3]
    else:
        degenerate_true = degenerate
    position, velocity, range_sigma, velocity_sigma = fix_in_world(
        params, R, origins, a[:, 0], X, Q
    )
    fix = ScanFix(position, velocity, range_sigma, velocity_sigma, kappa, degenerate)
    estimate = tracker_estimate(params, position, velocity, degenerate, previous)
    bound = position_bound(los, ranges, sigma_ang)
    error, min_angle = diagnostics(params, end, estimate, drone_end)
    state = PlacementState(
        t=t,
        receivers=end,
        drone_position=drone_end,
        drone_velocity=drone_velocity,
        fix=fix,
        estimate=estimate,
        geometry=ScanGeometry(origins, los, ranges, degenerate_true),
        bound=bound,
        observation=observation(params, end, estimate, fix),
        position_error=error,
        min_los_angle=min_angle,
    )
    return state, reward(params, bound, degenerate | degenerate_true)


# ------------------------------------------------------------------ the contract's functions


def start(
    params: PlacementParams,
    receivers: ArrayLike,
    drone_position: ArrayLike,
    drone_velocity: ArrayLike,
    rng: np.random.Generator,
) -> PlacementState:
    """:func:`.simulation.start`: receivers ``(B, n, 3)`` put on the ground (``y = 0``) and in
    the disc, drone ``(B, 3)``. The tracker's first estimate is the external cue (truth plus
    Gaussian errors ``cue_sigma``, drawn position then velocity) carried back to ``t = −τ``;
    its first fix is one period of the receivers standing still, ending at ``t = 0``."""
    o = in_arena(params, np.asarray(receivers, dtype=np.float64) * np.array([1.0, 0.0, 1.0]))
    p = np.asarray(drone_position, dtype=np.float64)
    v = np.asarray(drone_velocity, dtype=np.float64)
    B = p.shape[0]
    before = draw_cue(params, p, v, rng)
    normals = draw_normals(rng, B, params.n_receivers, params.sigma_ang)
    state, _ = scan_period(params, np.zeros(B), o, o, p, v, before, normals)
    return state


def reset(
    params: PlacementParams,
    rng: np.random.Generator,
    batch: int,
    like: PlacementState | None = None,
) -> PlacementState:
    """:func:`.simulation.reset`: ``batch`` fresh scenarios, drawn in its order — receivers
    uniform in the disc of ``cluster_radius`` (radius ``ρ_c √U``, bearing), then the drone's
    distance, bearing, height, speed and heading (a straight level line) — then
    :func:`start`. ``like`` is unused (scenarios share nothing)."""
    o, p, v = draw_scenario(params, rng, batch)
    return start(params, o, p, v, rng)


def step(
    params: PlacementParams, state: PlacementState, action: ArrayLike, rng: np.random.Generator
) -> tuple[PlacementState, FloatArray, BoolArray]:
    """:func:`.simulation.step`: one scan period under ``action (B, n, 2)`` (or ``(B, 2n)``).

    The period's noise is drawn first (so a NaN or infinite action, which raises
    ``ValueError``, has consumed it, as in the kernel); the receivers drive (:func:`drive`),
    the drone flies on (:func:`fly`), and the period is scanned (:func:`scan_period`).
    Returns ``(state, reward (B,), terminated (B,))``; nothing ends an episode here (theory
    §11.4: the time limit is the shells').
    """
    B, n = state.batch_size, params.n_receivers
    a = np.asarray(action, dtype=np.float64)
    if a.size != B * 2 * n:
        raise ValueError(f"action: expected {B * 2 * n} values (B, 2n), got shape {a.shape}")
    a = a.reshape(B, n, 2)
    normals = draw_normals(rng, B, n, params.sigma_ang)
    if not np.all(np.isfinite(a)):
        raise ValueError("action: contains NaN or infinite values")
    end = drive(params, state.receivers, a)
    drone_end = fly(params, state.drone_position, state.drone_velocity)
    new, r = scan_period(
        params, state.t + params.period, state.receivers, end, drone_end, state.drone_velocity,
        state.estimate, normals,
    )  # fmt: skip
    return new, r, np.zeros(B, dtype=bool)
