"""The readable specification of StereoPointing's compiled reset and step, in plain numpy.

The envs (``sensorgym/StereoPointing-v0``, ``sensorgym/StereoPointingCrowded-v0`` and their
vector and PettingZoo doors) run :mod:`.simulation`, whose :func:`~.simulation.reset` and
:func:`~.simulation.step` hand their draws to the fused compiled loops of :mod:`.kernels` over
the primitives of :mod:`sensorgym.trackers.stereo.kernels`: fast (scalars in locals, one scratch
buffer, the observation written in the same pass) and hard to read (theory §11.3). This module
is the same reset and step written to be read: numpy over the batch, one stage a function, in
the order of the equations of ``docs/theory.md`` (§2.2, §4.1–§4.3, §10.3, §11.1, §11.3), each
stage citing its section, with the textbook symbols (``α_k``, ``ε_k``, ``b_k``, ``o_k``,
``u_kj``, ``r_kj``, ``z_kj``, ``Π``, ``G``, ``M``, ``F``, ``Q``, ``H``, ``R``, ``S``, ``K``,
``σ_pos``). The envs never run it.

It follows the simulation contract (:mod:`sensorgym.envs.shells.contract`) with the very
signatures of :mod:`.simulation`: :func:`reset`, :func:`start` and :func:`step` take the same
params (:class:`~.simulation.PointingParams`, the crowded env's
:class:`~.crowded.CrowdedPointingParams` too), return the same
:class:`~.simulation.PointingState` and take the same random draws from the Generator in the
same order and shapes; :func:`observe`, :func:`observe_agents` and :func:`info` compute what
the kernels write beside the state (the observation, the diagnostics) from its fields. With
:func:`spaces` (:mod:`.simulation`'s own) it is a complete simulation: ``Core(reference,
params)`` runs.

How it is checked: ``tests/envs/stereo_pointing/test_reference.py`` steps this module and
:mod:`.simulation` from the same state with the same draws over whole episodes with autoresets
(both envs' params, and settings that force the rare branches: random initial pointing, exact
fixes of a certain track, fixes behind a close pair of receivers; hand-made states for a drone,
a prediction and a cue on a receiver), and compares every state field,
the observations, rewards, terminations and infos within stated tolerances (rounding only: the
kernels solve the 3×3 systems by Gaussian elimination and take determinants by cofactors and
eigenvalues by Jacobi rotations, where this module calls LAPACK; numba may fuse and reorder
float operations), and the generators' states exactly.

Each formula lives once: the package's one copy of a convention is called, not copied — the
angles of §2.2 (:func:`~sensorgym.trackers.geometry.unit_from_angles` through
:func:`.simulation.boresights`, :func:`~sensorgym.trackers.geometry.angles_from_unit`), the
angle wrap (:func:`~sensorgym.trackers.geometry.wrap_angle`), the receivers' places
(:attr:`~.simulation.PointingParams.receiver_positions`), the scenario draws
(:func:`.simulation.draw_scenario`), the observation clip and the per-agent views
(:mod:`~sensorgym.envs.shells.contract`) and the tail-measure entries of the infos
(:func:`.simulation.tail_info`). The rest lives elsewhere only as compiled code (the drones'
starts, the cue, the slew, lines of sight, the cones, angular noise, the masked information, the
observability and in-front tests, the weighted fix, the constant-velocity Kalman filter, the
bound, the reward and the observation's blocks) and is written out below.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sensorgym.envs.shells.contract import clip_observation, with_agent_index
from sensorgym.envs.stereo_pointing.simulation import (
    PointingParams,
    PointingState,
    ScenarioDraws,
    boresights,
    draw_scenario,
    spaces,
    tail_info,
)
from sensorgym.trackers.geometry import angles_from_unit, wrap_angle
from sensorgym.trackers.stereo.information import CONDITION, MIN_FIX_RANGE, MIN_RANGE
from sensorgym.trackers.stereo.kalman import RCOND, CVTrack

__all__ = [
    "info",
    "observe",
    "observe_agents",
    "reset",
    "spaces",
    "start",
    "step",
]

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

#: floor of a standard deviation before its logarithm in the observation, m (``ln 0`` = −∞)
TINY_SIGMA = 1e-12

#: weighted least-squares passes of the fix: ranges 1, then the ranges of the first fix (§4.2)
FIX_ITERATIONS = 2


# --- the contract: reset, start and step ---------------------------------------------------------


def reset(
    params: PointingParams,
    rng: np.random.Generator,
    batch: int,
    like: PointingState | None = None,
) -> PointingState:
    """``batch`` fresh scenarios (:func:`.simulation.reset`; theory §11.3): the scenario draws
    (:func:`.simulation.draw_scenario`), the drones' straight lines from them
    (:func:`drone_starts`), then :func:`start_scenarios`, the gimbals on the cue when
    ``cued_start``. Scenarios share nothing: ``like`` is unused."""
    if batch < 1:
        raise ValueError(f"batch: must be >= 1, got {batch}")
    draws = draw_scenario(params, rng, batch)
    p, v = drone_starts(draws)
    return start_scenarios(
        params, p, v, draws.azimuth, draws.elevation, rng, cued=params.cued_start
    )


def start(
    params: PointingParams,
    drone_position: ArrayLike,
    drone_velocity: ArrayLike,
    azimuth: ArrayLike,
    elevation: ArrayLike,
    rng: np.random.Generator,
) -> PointingState:
    """:func:`.simulation.start`: scenarios from given drones ``(B, m, 3)`` and pointing
    ``(B, n)`` (not cued), the tracker on its cue (:func:`start_scenarios`). Unlike its
    namesake it does not check its inputs."""
    return start_scenarios(
        params,
        np.asarray(drone_position, dtype=np.float64),
        np.asarray(drone_velocity, dtype=np.float64),
        np.asarray(azimuth, dtype=np.float64),
        np.asarray(elevation, dtype=np.float64),
        rng,
        cued=False,
    )


def start_scenarios(
    params: PointingParams,
    p: FloatArray,
    v: FloatArray,
    azimuth: FloatArray,
    elevation: FloatArray,
    rng: np.random.Generator,
    cued: bool,
) -> PointingState:
    """The first state of every scenario (theory §11.3, the starting state): the cue's errors
    are drawn, position then velocity (``(B, m, 3)`` standard normals each); the tracker starts
    on the cue (:func:`cue_track`); the gimbals at the given pointing, wrapped and held within
    their elevation limit (:func:`hold_gimbals`), or, ``cued``, receiver ``k`` on drone
    ``k mod m``'s cued position (:func:`aim`). Nothing is seen or fixed yet (bound ``+∞``)."""
    B, n, m = p.shape[0], params.n_receivers, params.n_drones
    noise_p = rng.standard_normal(p.shape)
    noise_v = rng.standard_normal(v.shape)
    track = cue_track(params, p, v, noise_p, noise_v)
    az, el = hold_gimbals(params, azimuth, elevation)
    if cued:
        cue = track.position[:, np.arange(n) % m]  # (B, n, 3): drone k mod m for receiver k
        az, el = aim(params, cue, az, el)
    return PointingState(
        t=np.zeros(B),
        azimuth=az,
        elevation=el,
        drone_position=p,
        drone_velocity=v,
        track=track,
        seen=np.zeros((B, n, m), dtype=bool),
        fixed=np.zeros((B, m), dtype=bool),
        bound=np.full((B, m), np.inf),
    )


def step(
    params: PointingParams, state: PointingState, action: ArrayLike, rng: np.random.Generator
) -> tuple[PointingState, FloatArray, BoolArray]:
    """One step of ``dt`` under the joint action ``(B, n, 2)`` (or ``(B, 2n)``)
    (:func:`.simulation.step`; theory §11.3): ``(state, reward (B,), terminated (B,))``.

    The measurement noise of every receiver–drone pair is drawn first, ``(B, n, m, 3)``
    standard normals (none when ``σ_ang = 0``), so that a NaN or infinite action, which raises
    ``ValueError``, has consumed it as in the kernel. Then the stages in order: the gimbals
    slew and the drones fly on; each receiver sees the drones in its cone and measures them;
    each drone seen by two receivers or more is fixed, and its track predicted and updated with
    a trusted fix; the bound of the true geometry and the reward. Nothing ends an episode here
    (the time limit is the shells').
    """
    n, m, B = params.n_receivers, params.n_drones, state.batch_size
    a = np.asarray(action, dtype=np.float64)
    if a.size != B * n * 2:
        raise ValueError(f"action: expected {B * n * 2} values (B, n, 2), got shape {a.shape}")
    a = a.reshape(B, n, 2)
    normals = rng.standard_normal((B, n, m, 3)) if params.sigma_ang > 0.0 else None
    if not np.all(np.isfinite(a)):
        raise ValueError("action: contains NaN or infinite values")
    o = params.receiver_positions  # o_k on the circle (theory §10.3, OC-3)
    # 1. the gimbals slew, the drones fly on
    az, el = slew(params, state.azimuth, state.elevation, a)
    p = fly(params, state.drone_position, state.drone_velocity)
    # 2. who sees which drone, and what each receiver measures
    u, r = lines_of_sight(o, p)
    seen = in_view(params, boresights(az, el), u)
    z = noisy_directions(u, normals, params.sigma_ang)
    # 3. the fix, trusted only in front of its receivers; each track predicted, then updated
    M, G, observable_fix = weighted_fix(o, z, seen)
    fixed = observable_fix & in_front(M, o, z, seen)
    predicted = kalman_predict(state.track, params.dt, params.process_noise)
    track = kalman_update(predicted, M, fix_covariance(params.sigma_ang, G, fixed), fixed)
    # 4. the bound of the true geometry of the receivers that see each drone, the reward
    bound = position_bound(params.sigma_ang, u, r, seen)
    new = PointingState(
        t=state.t + params.dt,
        azimuth=az,
        elevation=el,
        drone_position=p,
        drone_velocity=state.drone_velocity,
        track=track,
        seen=seen,
        fixed=fixed,
        bound=bound,
    )
    return new, reward(params, bound), np.zeros(B, dtype=bool)


# --- the start: drones, cue and gimbals (theory §11.3, §2.2) --------------------------------------


def drone_starts(draws: ScenarioDraws) -> tuple[FloatArray, FloatArray]:
    """The drones' starts ``p`` and velocities ``v`` ``(B, m, 3)`` from the scenario draws
    (world frame of §2.2, ``Y`` up, angles from ``+Z`` towards ``+X``)::

        p = (d sin β, h, d cos β) ,   v = (s sin ψ, climb, s cos ψ)
    """
    d, beta, s, psi = draws.distance, draws.bearing, draws.speed, draws.heading
    p = np.stack([d * np.sin(beta), draws.height, d * np.cos(beta)], axis=-1)
    v = np.stack([s * np.sin(psi), draws.climb, s * np.cos(psi)], axis=-1)
    return p, v


def cue_track(
    params: PointingParams, p: FloatArray, v: FloatArray, noise_p: FloatArray, noise_v: FloatArray
) -> CVTrack:
    """The tracker on the external cue (theory §11.3): truth plus Gaussian errors of standard
    deviations ``cue_sigma = (σ_p, σ_v)`` from the standard normals ``noise_p``, ``noise_v``,
    with that covariance::

        x = (p + σ_p n_p, v + σ_v n_v) ,   P = diag(σ_p² I₃, σ_v² I₃)
    """
    sigma_p, sigma_v = params.cue_sigma
    x = np.concatenate([p + sigma_p * noise_p, v + sigma_v * noise_v], axis=-1)
    P = np.diag([sigma_p**2] * 3 + [sigma_v**2] * 3)
    return CVTrack(x, np.broadcast_to(P, (*x.shape, 6)).copy())


def hold_gimbals(
    params: PointingParams, azimuth: FloatArray, elevation: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Gimbal angles as the gimbal holds them: ``α ← wrap(α)`` into ``[−π, π)``,
    ``ε ← clip(ε, −ε_max, ε_max)``."""
    lim = params.max_elevation
    return wrap_angle(azimuth), np.clip(elevation, -lim, lim)


def aim(
    params: PointingParams, points: FloatArray, azimuth: FloatArray, elevation: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Azimuths and elevations ``(B, n)`` that put receiver ``k`` on ``points[:, k] (B, n, 3)``
    (:func:`.simulation.aim_at`): the angles of §2.2 of the line of sight ``u_k`` from ``o_k``,
    ``α = atan2(u_x, u_z)``, ``ε = arcsin u_y`` held within ``±ε_max``; where the point lies on
    the receiver (``u_k = 0``, no direction) the receiver keeps ``azimuth``/``elevation``."""
    o = params.receiver_positions
    u, _ = lines_of_sight(o, points, pairwise=True)
    az, el = angles_from_unit(u, check=False)
    no_direction = ~np.any(u != 0.0, axis=-1)
    az = np.where(no_direction, azimuth, az)
    el = np.where(no_direction, elevation, el)
    return az, np.clip(el, -params.max_elevation, params.max_elevation)


# --- step 1: the gimbals slew, the drones fly on (theory §11.3) -----------------------------------


def slew(
    params: PointingParams, azimuth: FloatArray, elevation: FloatArray, action: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """The gimbals after one step under ``action (B, n, 2)``, each entry clipped to
    ``[−1, 1]`` (theory §11.3)::

        α_k ← wrap(α_k + a_k,0 · ω dt) ,   ε_k ← clip(ε_k + a_k,1 · ω dt, −ε_max, ε_max)

    with ``ω = slew_rate``."""
    a = np.clip(action, -1.0, 1.0)
    step_angle = params.slew_rate * params.dt
    lim = params.max_elevation
    az = wrap_angle(azimuth + a[..., 0] * step_angle)
    el = np.clip(elevation + a[..., 1] * step_angle, -lim, lim)
    return az, el


def fly(params: PointingParams, position: FloatArray, velocity: FloatArray) -> FloatArray:
    """The drones one step on along their straight lines: ``p_j ← p_j + v_j dt``."""
    return position + velocity * params.dt


# --- step 2: lines of sight, the cones and the measurements (theory §4.1, §4.3, §11.3) ---------


def lines_of_sight(
    receivers: FloatArray, points: FloatArray, pairwise: bool = False
) -> tuple[FloatArray, FloatArray]:
    """Unit lines of sight and ranges from the receivers ``o_k (n, 3)`` (theory §4.2)::

        u_kj = (p_j − o_k) / r_kj ,   r_kj = ‖p_j − o_k‖

    to every point of ``points (B, m, 3)``: ``u (B, n, m, 3)``, ``r (B, n, m)``; ``pairwise``:
    receiver ``k`` to ``points[:, k] (B, n, 3)`` only, ``u (B, n, 3)``, ``r (B, n)``. Within
    ``MIN_RANGE`` of a receiver there is no direction: ``u = 0`` (theory §4.3)."""
    o = receivers if pairwise else receivers[:, None, :]  # (n, 3) or (n, 1, 3)
    d = (points if pairwise else points[:, None, :, :]) - o
    r = np.sqrt(np.sum(d * d, axis=-1))
    has_direction = r > MIN_RANGE
    u = np.where(has_direction[..., None], d / np.where(has_direction, r, 1.0)[..., None], 0.0)
    return u, r


def in_view(params: PointingParams, boresight: FloatArray, u: FloatArray) -> BoolArray:
    """Which receiver sees which drone ``(B, n, m)`` (theory §11.3): the line of sight lies in
    the cone of half-angle ``fov`` around the boresight ``b_k (B, n, 3)``,
    ``u_kj · b_k ≥ cos fov`` (a zero ``u_kj``, a drone on the receiver, is never seen)."""
    return np.sum(u * boresight[:, :, None, :], axis=-1) >= np.cos(params.fov)


def noisy_directions(u: FloatArray, normals: FloatArray | None, sigma_ang: float) -> FloatArray:
    """The directions the receivers measure (theory §4.1, angle-noise model): every line of
    sight, seen or not, with isotropic angular noise from the standard normals ``n_kj``::

        z_kj = (u_kj + δ_kj) / ‖u_kj + δ_kj‖ ,   δ_kj = σ_ang (I − u_kj u_kjᵀ) n_kj

    (the error lies across the line of sight, ``σ_ang`` in each of the two directions); a zero
    ``u_kj`` (no direction) is measured as zero. Noise-free (``σ_ang = 0``, no draws):
    ``z = u``."""
    if normals is None:
        return u
    along = np.sum(normals * u, axis=-1, keepdims=True)
    v = u + (normals - along * u) * sigma_ang
    no_direction = ~np.any(u != 0.0, axis=-1, keepdims=True)
    norm = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.where(no_direction, 0.0, v / np.where(no_direction, 1.0, norm))


# --- step 3: the fix and the tracker (theory §4.2, §4.3, §11.3) ---------------------------------


def projections(u: FloatArray) -> FloatArray:
    """``Π = I − u uᵀ`` ``(..., 3, 3)`` of unit vectors ``u (..., 3)``: the part of a vector
    across the line of sight ``u``."""
    return np.eye(3) - u[..., :, None] * u[..., None, :]


def weights(r: FloatArray, seen: BoolArray) -> FloatArray:
    """Each line of sight's weight ``w_kj = s_kj / r_kj²`` ``(B, n, m)`` (theory §4.2, with the
    noise ``σ_ang`` factored out): ``s_kj = 1`` where receiver ``k`` sees drone ``j``, else 0;
    ranges floored at ``MIN_RANGE`` (a receiver on the point)."""
    return seen / np.maximum(r, MIN_RANGE) ** 2


def information(u: FloatArray, r: FloatArray, seen: BoolArray) -> FloatArray:
    """The geometric part of each drone's Fisher information ``(B, m, 3, 3)``, 1/m² (theory
    §4.2; ``I(M) = G/σ_ang²``)::

        G_j = Σ_k w_kj (I − u_kj u_kjᵀ) ,   w_kj = s_kj / r_kj²  (:func:`weights`)

    over the receivers ``k`` that see drone ``j``; ``u (B, n, m, 3)``, ``r``/``seen
    (B, n, m)``."""
    return np.sum(weights(r, seen)[..., None, None] * projections(u), axis=1)


def observable(G: FloatArray, seen: BoolArray) -> BoolArray:
    """The observability test of theory §4.3 ``(B, m)``: at least two views and
    ``det G > CONDITION · (tr G)³`` (``CONDITION = 1e-12``; scale free)."""
    views = np.sum(seen, axis=1)
    trace = np.trace(G, axis1=-2, axis2=-1)
    return (views >= 2) & (np.linalg.det(G) > CONDITION * trace**3)


def weighted_fix(
    receivers: FloatArray, z: FloatArray, seen: BoolArray
) -> tuple[FloatArray, FloatArray, BoolArray]:
    """Each drone's position fix ``M (B, m, 3)``, its information ``G`` at its own ranges and
    whether it is observable (theory §4.2, §4.3): the minimum of the information-weighted
    perpendicular misses ``Σ_k s_k ‖Π_k (M − o_k)‖² / r_k²`` over the measured lines of sight
    ``z_k``, ``Π_k = I − z_k z_kᵀ``. For fixed ranges it solves the normal equations::

        G M = Σ_k s_k Π_k o_k / r_k² ,   G = Σ_k s_k Π_k / r_k²

    with the ranges ``r_k = 1`` first (the unweighted midpoint), then ``r_k = ‖M − o_k‖`` of
    that fix (:func:`weights` floors them): ``FIX_ITERATIONS`` passes. Where a pass's ``G``
    fails the test of :func:`observable`, ``M = 0``. The fix is observable where the last
    pass's ``G`` and ``G`` at the fix's own ranges (returned) both pass.
    """
    o = receivers[:, None, :]  # o_k, (n, 1, 3)
    r = np.ones(seen.shape)
    for _ in range(FIX_ITERATIONS):
        G = information(z, r, seen)
        ok = observable(G, seen)
        Pi_o = o - z * np.sum(z * o, axis=-1, keepdims=True)  # Π_k o_k
        rhs = np.sum(weights(r, seen)[..., None] * Pi_o, axis=1)  # Σ_k s_k Π_k o_k / r_k²
        # M = G⁻¹ rhs where observable (the identity stands in elsewhere)
        G_safe = np.where(ok[..., None, None], G, np.eye(3))
        M = np.where(ok[..., None], np.linalg.solve(G_safe, rhs[..., None])[..., 0], 0.0)
        r = np.linalg.norm(M[:, None] - o, axis=-1)
    G = information(z, r, seen)
    return M, G, ok & observable(G, seen)


def in_front(M: FloatArray, receivers: FloatArray, z: FloatArray, seen: BoolArray) -> BoolArray:
    """Whether each fix ``M (B, m, 3)`` lies in front of every receiver that sees it (theory
    §4.3): ``z_k · (M − o_k) > MIN_FIX_RANGE`` (1 cm) along the measured line of sight. Noisy,
    near-parallel lines of sight from nearby receivers cross on or behind them, where the
    information at the fix's own tiny ranges looks regular."""
    ahead = np.sum(z * (M[:, None] - receivers[:, None, :]), axis=-1)  # (B, n, m)
    return np.all(~seen | (ahead > MIN_FIX_RANGE), axis=1)


def fix_covariance(sigma_ang: float, G: FloatArray, fixed: BoolArray) -> FloatArray:
    """The fix's covariance ``R = σ_ang² G⁻¹`` ``(B, m, 3, 3)`` at its own ranges (theory
    §4.2, §11.3: the Cramér–Rao bound the weighted fix attains to first order); zero where the
    drone is not fixed (unused there)."""
    G_safe = np.where(fixed[..., None, None], G, np.eye(3))
    return np.where(fixed[..., None, None], sigma_ang**2 * np.linalg.inv(G_safe), 0.0)


def cv_model(dt: float, q: float) -> tuple[FloatArray, FloatArray]:
    """The constant-velocity model of the tracker (theory §11.3; Bar-Shalom, Li and
    Kirubarajan 2001, white-noise acceleration of spectral density ``q``), state
    ``x = (p, v)``::

        F = [[I, dt I], [0, I]] ,   Q = q [[dt³/3 I, dt²/2 I], [dt²/2 I, dt I]]
    """
    I3 = np.eye(3)
    F = np.block([[I3, dt * I3], [np.zeros((3, 3)), I3]])
    Q = q * np.block([[dt**3 / 3.0 * I3, dt**2 / 2.0 * I3], [dt**2 / 2.0 * I3, dt * I3]])
    return F, Q


def kalman_predict(track: CVTrack, dt: float, q: float) -> CVTrack:
    """The Kalman prediction ``dt`` ahead: ``x⁻ = F x``, ``P⁻ = F P Fᵀ + Q`` (:func:`cv_model`)."""
    F, Q = cv_model(dt, q)
    return CVTrack(track.x @ F.T, F @ track.P @ F.T + Q)


def innovation_singular(S: FloatArray) -> BoolArray:
    """Whether the innovation covariance ``S (..., 3, 3)`` is singular to working precision
    (:mod:`sensorgym.trackers.stereo.kalman`): its smallest eigenvalue
    ``λ_min ≤ RCOND · max|λ|`` (``RCOND = 1e-13``). Exact fixes (``σ_ang = 0``, ``R = 0``) of a
    certain track (``q = 0``) make it so."""
    lam = np.linalg.eigvalsh(S)  # ascending
    return lam[..., 0] <= RCOND * np.max(np.abs(lam), axis=-1)


def kalman_gain(P: FloatArray, S: FloatArray) -> FloatArray:
    """The gain ``K (..., 6, 3)`` of the position fix (:mod:`sensorgym.trackers.stereo.kalman`,
    theory §11.3) for the predicted covariance ``P (..., 6, 6)`` and the innovation covariance
    ``S (..., 3, 3)``: ``K = P Hᵀ S⁻¹``, solved as ``Kᵀ = S⁻¹ H P`` (``P`` and ``S``
    symmetric). Where ``S`` is singular (:func:`innovation_singular`) the pseudo-inverse gain
    instead::

        K = P Hᵀ S⁺ + [N; 0] ,   S⁺ = V diag(1/λ_i kept) Vᵀ ,   N = I − S S⁺ = V diag(dropped) Vᵀ

    with ``S = V diag(λ) Vᵀ`` and the eigenvalues ``λ_i > RCOND · max|λ|`` kept: on the null
    space of ``S`` (prediction and fix both claim to be exact) the fix is taken as it is.

    Both are solved for ``S`` and ``H P`` divided by ``c = max_ij |S_ij|`` (``K`` is unchanged:
    ``P Hᵀ S⁻¹ = (P Hᵀ/c)(S/c)⁻¹``). Exact fixes of a certain track drive ``P`` towards zero,
    through the subnormal numbers, where ``1/S_ii`` (which LAPACK's solvers may form) overflows.
    """
    singular = innovation_singular(S)
    c = np.max(np.abs(S), axis=(-2, -1))
    c = np.where(c > 0.0, c, 1.0)[..., None, None]  # S = 0: singular, nothing to scale
    S_c, HP_c = S / c, P[..., :3, :] / c  # H P, H = [I 0]
    K = np.empty((*P.shape[:-1], 3))
    regular = ~singular
    K[regular] = np.swapaxes(np.linalg.solve(S_c[regular], HP_c[regular]), -1, -2)
    lam, V = np.linalg.eigh(S_c[singular])
    keep = lam > RCOND * np.max(np.abs(lam), axis=-1, keepdims=True)
    inverse = np.where(keep, 1.0 / np.where(keep, lam, 1.0), 0.0)
    S_plus = (V * inverse[..., None, :]) @ np.swapaxes(V, -1, -2)
    N = (V * ~keep[..., None, :]) @ np.swapaxes(V, -1, -2)
    K[singular] = np.swapaxes(HP_c[singular], -1, -2) @ S_plus
    K[singular, :3] += N
    return K


def kalman_update(predicted: CVTrack, M: FloatArray, R: FloatArray, fixed: BoolArray) -> CVTrack:
    """The Kalman update of each predicted track with its fix ``M`` of covariance ``R`` where
    ``fixed`` (theory §11.3; elsewhere the track only predicts)::

        S = H P Hᵀ + R ,   K (:func:`kalman_gain`) ,   x ← x + K (M − H x) ,
        P ← P − K S Kᵀ , symmetrised: P ← (P + Pᵀ)/2

    with ``H = [I 0]`` (the fix measures the position)."""
    H = np.hstack([np.eye(3), np.zeros((3, 3))])
    x, P = predicted.x, predicted.P
    S = H @ P @ H.T + R
    K = kalman_gain(P, S)
    innovation = M - x @ H.T
    x_fixed = x + np.einsum("...ij,...j->...i", K, innovation)
    P_fixed = P - K @ S @ np.swapaxes(K, -1, -2)
    P_fixed = 0.5 * (P_fixed + np.swapaxes(P_fixed, -1, -2))
    return CVTrack(
        np.where(fixed[..., None], x_fixed, x), np.where(fixed[..., None, None], P_fixed, P)
    )


# --- step 4: the bound and the reward (theory §4.2, §4.3, §11.1, §11.3) -------------------------


def position_bound(sigma_ang: float, u: FloatArray, r: FloatArray, seen: BoolArray) -> FloatArray:
    """The Cramér–Rao position RMS of each drone ``σ_pos (B, m)``, m, at the true lines of
    sight ``u`` and ranges ``r`` of the receivers that see it now (theory §4.2, §11.3)::

        σ_pos = √tr I(M)⁻¹ = σ_ang √tr G⁻¹ ,   G = Σ_k s_k (I − u_k u_kᵀ) / r_k²

    (:func:`information`), ``+∞`` where the position is not observable (:func:`observable`:
    fewer than two views, or parallel lines of sight)."""
    G = information(u, r, seen)
    ok = observable(G, seen)
    G_inv = np.linalg.inv(np.where(ok[..., None, None], G, np.eye(3)))
    trace = np.maximum(np.trace(G_inv, axis1=-2, axis2=-1), 0.0)
    return np.where(ok, sigma_ang * np.sqrt(trace), np.inf)


def reward(params: PointingParams, bound: FloatArray) -> FloatArray:
    """The mean over the drones of ``clip(ln(σ_ref/σ_pos), −R, R)`` ``(B,)`` (theory §11.1,
    §11.3): ``−R`` for a drone without an observable position (``σ_pos = ∞``), ``+R`` for an
    exact one (``σ_pos = 0``, noise-free)."""
    R = params.reward_clip
    with np.errstate(divide="ignore"):  # ln 0 = −∞: the exact fix, clipped to +R
        log_ratio = np.clip(np.log(params.sigma_ref) - np.log(bound), -R, R)
    return np.mean(np.where(np.isfinite(bound), log_ratio, -R), axis=1)


# --- what the agents see, and the diagnostics -----------------------------------------------------


def pointing_offsets(
    azimuth: FloatArray, elevation: FloatArray, u: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """World-angle offsets ``(Δα, Δε)`` ``(B, n, m)`` of the directions ``u (B, n, m, 3)`` from
    each boresight ``(α_k, ε_k)`` (:func:`.simulation.pointing_offsets`):
    ``Δα = wrap(α_u − α_k)``, ``Δε = ε_u − ε_k`` with ``(α_u, ε_u)`` the angles of §2.2 of
    ``u``; a zero ``u`` (the point on the receiver, no direction) reads as ``(0, 0)``."""
    az_u, el_u = angles_from_unit(u, check=False)
    no_direction = ~np.any(u != 0.0, axis=-1)
    d_az = np.where(no_direction, 0.0, wrap_angle(az_u - azimuth[..., None]))
    d_el = np.where(no_direction, 0.0, el_u - elevation[..., None])
    return d_az, d_el


def observe(params: PointingParams, state: PointingState) -> NDArray[np.float32]:
    """The agent's observation ``(B, obs_dim)`` (the block table of :func:`.simulation.observe`):
    own gimbals and the tracker's prediction for the next step, no truth; clipped to
    ``±OBS_CLIP``, float32. ``L = length_scale``, ``V = velocity_scale``, ``p̂_j``, ``v̂_j``,
    ``P_j`` the predicted track (:func:`kalman_predict`)."""
    B, n, m = state.batch_size, params.n_receivers, params.n_drones
    az, el = state.azimuth, state.elevation
    predicted = kalman_predict(state.track, params.dt, params.process_noise)
    p_hat, v_hat, P = predicted.position, predicted.velocity, predicted.P
    # gimbals (n, 3): sin α_k, cos α_k, ε_k / (π/2)
    gimbals = np.stack([np.sin(az), np.cos(az), el / (np.pi / 2)], axis=-1)
    # pairs (n, m, 3): the offsets of p̂_j from boresight k in half-angles, and whether k saw j
    u, _ = lines_of_sight(params.receiver_positions, p_hat)
    d_az, d_el = pointing_offsets(az, el, u)
    pairs = np.stack([d_az / params.fov, d_el / params.fov, state.seen.astype(np.float64)], -1)
    # drones (m, 8): p̂/L, ln(σ̂/σ_ref), v̂/V, ln(σ̂_v · 1 s/σ_ref); σ̂ = √tr P_pp, σ̂_v = √tr P_vv
    sigma_p = predicted.position_sigma
    sigma_v = np.sqrt(np.maximum(np.trace(P[..., 3:, 3:], axis1=-2, axis2=-1), 0.0))
    drones = np.concatenate(
        [
            p_hat / params.length_scale,
            np.log(np.maximum(sigma_p, TINY_SIGMA) / params.sigma_ref)[..., None],
            v_hat / params.velocity_scale,
            np.log(np.maximum(sigma_v, TINY_SIGMA) / params.sigma_ref)[..., None],
        ],
        axis=-1,
    )
    blocks = [gimbals.reshape(B, 3 * n), pairs.reshape(B, 3 * n * m), drones.reshape(B, 8 * m)]
    return clip_observation(np.concatenate(blocks, axis=-1))


def observe_agents(params: PointingParams, state: PointingState) -> NDArray[np.float32]:
    """Per-receiver views ``(B, n, obs_dim + n)``: :func:`observe` and a one-hot of the
    receiver's index (:func:`~sensorgym.envs.shells.contract.with_agent_index`)."""
    return with_agent_index(observe(params, state), params.n_receivers)


def info(params: PointingParams, state: PointingState) -> dict[str, FloatArray]:
    """Diagnostics (:func:`.simulation.info`; ground truth included, never observed): the mean
    position error of the tracks ``mean_j ‖p̂_j − p_j‖`` (m), the number of drones fixed and of
    receiver–drone views, then the tail measures' entries (:func:`.simulation.tail_info`)."""
    error = np.linalg.norm(state.track.position - state.drone_position, axis=-1)
    return {
        "position_error": np.mean(error, axis=1),
        "drones_fixed": np.sum(state.fixed, axis=1).astype(np.float64),
        "views": np.sum(state.seen, axis=(1, 2)).astype(np.float64),
        **tail_info(state),
    }
