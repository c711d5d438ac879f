"""The readable reference of the StereoScanning reset and step: the spec of the compiled period.

The env (``sensorgym/StereoScanning-v0`` and its vector and PettingZoo doors) runs
:mod:`.simulation`, whose :func:`~.simulation.step` hands the period's draws to
:func:`.kernels.step_rows`: one numba pass per scenario through the same stages — sectors,
rasters, fixes, candidates, association, reward, the drones' motion and the new observation —
written for speed (scratch from one ``workspace()``, square-root-free pre-tests, closed-form
solves, the stages inlined). This module is the same period written to be read: numpy, one stage a
function, in the order of the equations of ``docs/theory.md`` — the sectors and rasters
(§6.1–6.3, §11.5), the candidates of paper 000's proposed algorithm (§3.3–3.5, §5.3, §13.6,
§13.13), the association over periods (§5.3, §11.5), the reward (§11.5) — each stage citing its
section, with the textbook symbols (``a_k``, ``c_k = P_k a_k``, ``b_k``, ``Δt_k``, ``A``, ``B``,
``X̂``, ``J``, ``Q``, ``κ_F``, ``σ_e``, ``M``, ``V``, ``ΔJ``, ``δ``, ``I``). The env never runs it.

Contract. :func:`reset`, :func:`start` and :func:`step` have the signatures and the contract of
their namesakes in :mod:`.simulation`: the same :class:`~.simulation.ScanningParams` and
:class:`~.simulation.ScanningState` (every field, the stale contents of freed table rows and
unused fix slots included), the same actions, the same random draws taken from the generator
in the same order and shapes (the scenario of :func:`.simulation.draw_scenario`; per period
the direction normals ``(B, n, m, 3)``, the apparent-position errors ``(B, m, 3)`` when
``σ_x > 0``, the false detections' counts ``(B, n)`` and places ``(B, n, max_clutter, 2)`` when
``clutter_rate > 0``). :func:`spaces`, :func:`observe`, :func:`observe_agents` and :func:`info`
only read a state, so they are :mod:`.simulation`'s own, re-exported: ``Core(reference,
params)`` runs.

Scope: the env's tracker, ``tracker="proposed"`` (paper 000's velocity-aware algorithm, the
default), for any ``n ≥ 3`` receivers, clutter, apparent-position noise and negative
information. The ``"alternative"`` and ``"algorithmic"`` trackers raise ``ValueError``: their
first continuation of a one-member track costs ``ΔJ = 0`` (theory §13.11, §5.5), so many
children tie in the cumulative index, and which of them the kernel confirms first is decided
by numba's ``np.argsort`` (an unstable quicksort above 15 entries), not by any rule a
reference could state. Under ``"proposed"`` every cost is a distance, ties have probability
zero, and the order below (stable) is the kernel's.

Rounding is all that should differ, and where:

* the candidates' 6×6 systems: the kernel eliminates ``V`` and solves the 3×3 range system by
  Cramer's rule (theory §3.5), this module takes the generic SVD path of
  :mod:`sensorgym.trackers.stereo.conjugation` (:func:`build_system`, :func:`solve_svd`); both
  are accurate to about ``κ_F ε``. Where the kernel's Cramer test finds the columns coplanar it
  sets ``κ_F = ∞``; the SVD's ``κ_F`` is then above ``1e10`` and ``cond_max`` drops the triple
  as well (so ``cond_max`` must stay below that, as its default ``1e7`` does);
* the joint fits over receivers 4 … n: the kernel solves the normal equations with
  ``r_2 … r_n`` eliminated (``κ_F² ε``), this module the SVD. The kernel keeps a joint fit only
  where ``κ_F ≤ NORMAL_EQUATIONS_COND = 1e4`` (beyond it the normal equations lose half the
  digits) as well as ``κ_F ≤ cond_max``: the reference applies the same two limits;
* the angles of the pixel-visit rule (numpy's ``arcsin``/``arctan2`` against the kernel's
  libm ``atan2`` or its polynomial) and a few sums in another order: these move a fix only if
  its angles lie within ulps of a pixel edge.

The kernel's pre-tests are left out because they decide nothing: the square-root-free bounds
on a gate (``(q s + m)² ≤ 2 (q² s² + m²)``, ``GATE_SLACK``) only skip what the gate itself
would refuse, and receivers 2–3 are pre-gated only for the pairs some fix of receiver 1 needs;
here every pair is gated and a triple is a candidate when its three pairs pass. So is the
kernel's fallback to the papers' ``σ`` for a triple whose exact covariance finds ``M``
singular: that is the test the triple's own solve already passed.

Each formula lives once: what the package holds in readable numpy is called, not copied — the
stacked conjugation system and its SVD solve (:func:`build_system`, :func:`solve_svd`), the
Jacobian of the 6×6 solution under angle noise (:func:`velocity_fix_jacobian`, theory §3.5:
the triple's exact covariance is ``J Σ Jᵀ``), the index combinations, the extrapolation
residual ``ΔJ`` and the greedy nearest matching of paper 000's tracker
(:mod:`sensorgym.trackers.stereo.association`), the drones' law of motion
(:class:`~sensorgym.envs.worlds.drones.Trajectories`), the receivers' frames
(:class:`~sensorgym.envs.worlds.scanning.ReceiverLayout`), the angles of a direction
(:func:`~sensorgym.trackers.geometry.angles_from_unit`, :func:`~sensorgym.trackers.geometry.
unit_from_angles`), the angular noise (:func:`sensorgym.envs.stereo_placement.reference.
noisy_directions`), the scenario draws (:func:`.simulation.draw_scenario`) and the observation
clip. Three primitives are the package's single compiled copies, called as such from numpy:
the raster's visit time and sector test (:func:`~sensorgym.envs.worlds.scanning_kernels.
raster_time`, :func:`~sensorgym.envs.worlds.scanning_kernels.in_sector`, theory §6.3) and the
clipped log-ratio reward (:func:`~sensorgym.trackers.stereo.information.log_ratio_reward`).

Paper 000's tracker in numpy (:mod:`sensorgym.trackers.stereo.period_tracking`) and this one
agree on the spatial step and the temporal index: on the same fixes of receivers 1–3, every
candidate here is one of :func:`~sensorgym.trackers.stereo.period_tracking.
proposed_candidates`'s triples with the same ``(M, V)`` (frame 1 there, the world here), and a
track is continued by ``ΔJ = ‖M − (M̂_s + V̂_s (t − t_s))‖``, :func:`association.
extrapolation_residual` itself. They differ by design: ``period_tracking`` runs a batch of ``N``
periods (groups of every candidate, a fixed gate ``δ`` from ``σ_x``, a beam, one selection at
the end), while the env runs online (theory §11.5) — triples pre-gated by their pairs, ``κ_F``
and the speed limit applied, gates from each candidate's and track's own covariance (and a
velocity gate), confirmed tracks served first, children confirmed after ``confirm_hits``
periods, births and misses, a table of fixed capacity — and extends paper 000 to ``n > 3``
receivers (§5.3). ``tests/envs/stereo_scanning/test_reference.py`` shows the agreement.

How it is checked: ``tests/envs/stereo_scanning/test_reference.py`` steps this module and
:mod:`.simulation` from the same states with the same draws over whole episodes with
autoresets, at the defaults and at settings that exercise more receivers (joint fits,
negative information), false detections, apparent-position noise and several close drones,
and compares every state field, the observations, rewards, terminations, infos and the
generators' states within stated tolerances.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sensorgym.envs.shells.contract import clip_observation
from sensorgym.envs.stereo_placement.reference import noisy_directions
from sensorgym.envs.stereo_scanning.kernels import CONFIRMED, EMPTY, GATE_FLOOR, TENTATIVE
from sensorgym.envs.stereo_scanning.simulation import (
    ScanningParams,
    ScanningState,
    draw_scenario,
    info,
    observe,
    observe_agents,
    spaces,
)
from sensorgym.envs.worlds.drones import Trajectories
from sensorgym.envs.worlds.scanning import ReceiverLayout
from sensorgym.envs.worlds.scanning_kernels import in_sector, raster_time
from sensorgym.trackers.geometry import angles_from_unit, unit_from_angles
from sensorgym.trackers.stereo import association
from sensorgym.trackers.stereo.conjugation import build_system, solve_svd, velocity_fix_jacobian
from sensorgym.trackers.stereo.conjugation_kernels import NORMAL_EQUATIONS_COND
from sensorgym.trackers.stereo.information import log_ratio_reward

__all__ = ["info", "observe", "observe_agents", "reset", "spaces", "start", "step"]

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
IntArray = NDArray[np.int64]

#: a drone is in the scene from its entry time on, to within this (s): entry times are whole
#: periods, the clock a sum of them
ENTRY_SLACK = 1e-9
#: observation floor of a standard deviation (and of the width range) before a logarithm or a
#: division
TINY = 1e-12
#: the raster's visit time and sector test (theory §6.3), elementwise over numpy arrays
_visit_time = np.vectorize(raster_time, otypes=[np.float64])
_in_sector = np.vectorize(in_sector, otypes=[np.bool_])


# --- the contract: reset and step ---------------------------------------------------------------


def reset(
    params: ScanningParams,
    rng: np.random.Generator,
    batch: int,
    like: ScanningState | None = None,
) -> ScanningState:
    """:func:`.simulation.reset`: ``batch`` fresh scenarios (:func:`.simulation.draw_scenario`,
    theory §11.5), then :func:`start`. Scenarios share nothing: ``like`` is unused."""
    if batch < 1:
        raise ValueError(f"batch: must be >= 1, got {batch}")
    return start(params, *draw_scenario(params, rng, batch))


def start(
    params: ScanningParams,
    drone_position: ArrayLike,
    drone_velocity: ArrayLike,
    drone_acceleration: ArrayLike,
    enter: ArrayLike,
) -> ScanningState:
    """:func:`.simulation.start`: scenarios from given drones ``(B, m, 3)`` (positions at their
    entry times ``enter (B, m)``) at ``t = 0`` with an empty track table (identities −1), no
    fixes (drone −1), zero sectors, no assignment (``σ = ∞``) and their observation."""
    _check_tracker(params)
    p, v, a, e = (np.array(x, dtype=np.float64) for x in (drone_position, drone_velocity,
                                                           drone_acceleration, enter))  # fmt: skip
    B, m = e.shape
    n, F, T = params.n_receivers, params.max_fixes, params.track_capacity
    track_int = np.zeros((B, T, 4), np.int64)
    track_int[..., 3] = -1
    state = ScanningState(
        t=np.zeros(B),
        drone_position=p,
        drone_velocity=v,
        drone_acceleration=a,
        enter=e,
        exited=np.zeros((B, m), bool),
        sectors=np.zeros((B, n, 3)),
        fixes=np.zeros((B, n, F, 4)),
        fix_count=np.zeros((B, n), np.int64),
        fix_drone=np.full((B, n, F), -1, np.int64),
        tracks=np.zeros((B, T, 19)),
        track_int=track_int,
        next_id=np.zeros(B, np.int64),
        assigned=np.full((B, m), -1, np.int64),
        drone_sigma=np.full((B, m), np.inf),
        parts=np.zeros((B, 6)),
        observation=np.empty((B, params.obs_dim), np.float32),  # derived below
    )
    return replace(state, observation=observation(params, state))


def step(
    params: ScanningParams, state: ScanningState, action: ArrayLike, rng: np.random.Generator
) -> tuple[ScanningState, FloatArray, BoolArray]:
    """:func:`.simulation.step`: one scan period ``τ`` under ``action (B, n, 3)`` (or
    ``(B, 3n)``), each entry clipped to ``[−1, 1]``: ``(state, reward (B,), terminated (B,))``.

    The period's noise is drawn first (a NaN or infinite action, which raises ``ValueError``,
    has consumed it, as in the kernel). Then, per scenario: the sectors (:func:`sectors_of`),
    the fixes (:func:`scan`), the candidates (:func:`candidates`), the association
    (:func:`associate`), the reward at the period end (:func:`score_period`), the drones' flight
    to it (:func:`fly_on`) and the new observation (:func:`observation`). Terminated once every
    drone has left the scene; the time limit is the shells'.
    """
    _check_tracker(params)
    B, n, m = state.batch_size, params.n_receivers, params.n_drones
    a = np.asarray(action, dtype=np.float64)
    if a.size != B * 3 * n:
        raise ValueError(f"action: expected {B * 3 * n} values (B, 3n), got shape {a.shape}")
    a = a.reshape(B, n, 3)
    # the draws, in this order: the directions' normals, the apparent-position errors (σ_x > 0),
    # the false detections' counts and places (clutter_rate > 0)
    normals = rng.standard_normal((B, n, m, 3))
    apparent = np.zeros((B, m, 3))
    if params.position_sigma > 0.0:
        apparent = params.position_sigma * rng.standard_normal((B, m, 3))
    clutter_count = np.zeros((B, n), np.int64)
    clutter_uv = np.zeros((B, n, 0, 2))
    if params.clutter_rate > 0.0 and params.max_clutter > 0:
        clutter_count = rng.poisson(params.clutter_rate, (B, n)).astype(np.int64)
        clutter_uv = rng.uniform(0.0, 1.0, (B, n, params.max_clutter, 2))
    if not np.all(np.isfinite(a)):
        raise ValueError("action: contains NaN or infinite values")
    # 1. the sectors; 2. the fixes of the drones present and the false detections
    sectors = sectors_of(params, a)
    sigma = fix_sigma(params, sectors[..., 2])
    present = in_scene(state)
    fixes = scan(params, state, sectors, sigma, present, normals, apparent, clutter_count,
                 clutter_uv)  # fmt: skip
    # 3. the tracker, scenario by scenario, on a copy of the table (rows change in place)
    tracks, track_int, next_id = state.tracks.copy(), state.track_int.copy(), state.next_id.copy()
    for i in range(B):
        found = candidates(params, fixes.scenario(i), sigma[i], sectors[i], state.t[i])
        table = Table(tracks[i], track_int[i])
        next_id[i] = associate(params, table, found, int(next_id[i]))
    # 4. the reward at the period end; 5. the drones fly on
    assigned, drone_sigma, parts, reward = score_period(params, state, tracks, track_int, present)
    position, velocity, exited = fly_on(params, state, present)
    new = ScanningState(
        t=state.t + params.period,
        drone_position=position,
        drone_velocity=velocity,
        drone_acceleration=state.drone_acceleration,
        enter=state.enter,
        exited=exited,
        sectors=sectors,
        fixes=np.concatenate([fixes.world, fixes.time[..., None]], axis=-1),
        fix_count=fixes.count,
        fix_drone=fixes.drone,
        tracks=tracks,
        track_int=track_int,
        next_id=next_id,
        assigned=assigned,
        drone_sigma=drone_sigma,
        parts=parts,
        observation=np.empty((B, params.obs_dim), np.float32),  # derived below
    )
    # 6. what the new state shows
    new = replace(new, observation=observation(params, new))
    return new, reward, np.all(exited, axis=1)


def _check_tracker(params: ScanningParams) -> None:
    if params.tracker != "proposed":
        raise ValueError(
            f"tracker: the reference covers 'proposed' only, got {params.tracker!r} (module "
            "docstring: the other trackers' ties in the cumulative index)"
        )


# --- 1. sectors and rasters (theory §6.1–6.3, §11.5) ------------------------------------------


def sectors_of(params: ScanningParams, action: FloatArray) -> FloatArray:
    """Each receiver's sector ``(φ_c, θ_c, w) (B, n, 3)`` of the action ``(B, n, 3)`` clipped to
    ``[−1, 1]`` (theory §11.5): centre ``a · regard/2`` in azimuth and elevation about the
    boresight, width ``w_min + (a + 1)/2 (w_max − w_min)``, rad (the inverse of
    :func:`.simulation.sector_action`)."""
    a = np.clip(action, -1.0, 1.0)
    half = 0.5 * params.field_of_regard
    lo, hi = params.sector_width
    return np.stack(
        [a[..., 0] * half, a[..., 1] * half, lo + 0.5 * (a[..., 2] + 1.0) * (hi - lo)], -1
    )


def fix_sigma(params: ScanningParams, width: FloatArray) -> FloatArray:
    """The angular noise of a fix from a sector of ``width``, ``σ_k = max(κ w, σ_min)`` rad
    (theory §11.5): the raster has a fixed pixel count, so a wider sector has coarser pixels."""
    return np.maximum(params.noise_per_width * width, params.sigma_ang_min)


def in_scene(state: ScanningState) -> BoolArray:
    """``(B, m)``: the drones in the scene through the period — entered by its start ``t_0``,
    not yet left (theory §11.5)."""
    return (state.enter <= state.t[:, None] + ENTRY_SLACK) & ~state.exited


def drone_paths(
    state: ScanningState, apparent: FloatArray | None = None, copies: int = 1
) -> Trajectories:
    """The drones' constant-acceleration paths ``p + v s + ½ a s²`` (``s`` from the period
    start; :class:`Trajectories`), flattened to ``(B·m·copies, 3)``, each drone ``copies``
    times in a row (one per receiver, each at its own time); ``apparent`` ``(B, m, 3)`` shifts
    every position by the period's shared apparent-position error ``σ_x`` (theory §4.1)."""
    p = state.drone_position if apparent is None else state.drone_position + apparent

    def rows(x: FloatArray) -> FloatArray:
        return np.repeat(x.reshape(-1, 3), copies, axis=0)

    return Trajectories(rows(p), rows(state.drone_velocity), rows(state.drone_acceleration))


def pixel_visit(
    params: ScanningParams,
    state: ScanningState,
    sectors: FloatArray,
    present: BoolArray,
    apparent: FloatArray,
) -> tuple[BoolArray, FloatArray, FloatArray]:
    """The pixel-visit rule (theory §6.3) for every receiver and drone: ``(seen (B, n, m),
    s (B, n, m), d (B, n, m, 3))``, the fix time ``s`` after the period start and the drone's
    offset ``d`` in the receiver's frame then.

    The fix time solves ``s = T_raster(φ(s), θ(s))`` by fixed-point iteration from the middle
    of the receiver's sweep, ``s ← offset_k + T_sweep/2``, at most ``pixel_iterations`` times:
    at each iterate the drone (its apparent position) is at ``d = R_kᵀ (p(s) − O_k)`` with angles
    ``φ = atan2(d_x, d_z)``, ``θ = asin(d_y/‖d‖)`` (theory §2.2). A drone outside the sector
    (or behind the receiver, ``d_z ≤ 0``) at an iterate is not fixed; one whose visit time
    repeats, ``T_raster = s``, is fixed at ``s``; one still moving after the last iterate is
    fixed where that iterate puts it if it is inside the sector then. (The world's numpy form
    for a boresight-centred raster, :func:`~sensorgym.envs.worlds.scanning.fix_times`, runs
    every iterate and judges the sector at the last one only: a drone crossing the sector's
    edge between iterates may be fixed there, never here.)"""
    B, n, m = sectors.shape[0], params.n_receivers, params.n_drones
    paths = drone_paths(state, apparent, copies=n)
    layout = ReceiverLayout(params.rotations, params.receivers)
    az, el, w = (x[:, :, None] for x in np.moveaxis(sectors, -1, 0))
    offset = params.offsets_array[None, :, None]
    lines, sweep = float(params.raster_lines), params.sweep_time

    def look(s: FloatArray) -> tuple[FloatArray, BoolArray, FloatArray]:
        # the drone at each receiver's iterate s (B, n, m) in that receiver's frame
        points = paths.position(s.transpose(0, 2, 1).reshape(-1)).reshape(B, m, n, 3)
        d = layout.to_local(points).transpose(0, 2, 1, 3)  # (B, n, m, 3)
        r = np.linalg.norm(d, axis=-1)
        with np.errstate(invalid="ignore", divide="ignore"):
            phi, theta = angles_from_unit(d / r[..., None], check=False)
        inside = (d[..., 2] > 0.0) & _in_sector(phi, theta, az, el, w, w)
        return d, inside, _visit_time(phi, theta, az, el, w, w, lines, lines, offset, sweep)

    s = np.broadcast_to(offset + 0.5 * sweep, (B, n, m)).copy()
    moving = np.broadcast_to(present[:, None, :], (B, n, m)).copy()
    seen = np.zeros((B, n, m), bool)
    d = np.zeros((B, n, m, 3))
    for _ in range(params.pixel_iterations):
        d_now, inside, s_new = look(s)
        moving &= inside  # out of the sector at an iterate: not fixed
        fixed = moving & (s_new == s)  # the visit time repeats: fixed at s
        seen |= fixed & (np.linalg.norm(d_now, axis=-1) > 0.0)
        d[fixed] = d_now[fixed]
        moving &= ~fixed
        s = np.where(moving, s_new, s)
    d_now, inside, _ = look(s)
    last = moving & inside & (np.linalg.norm(d_now, axis=-1) > 0.0)
    seen |= last
    d[last] = d_now[last]
    return seen, s, d


@dataclass(frozen=True)
class PeriodFixes:
    """The period's fixes of every receiver: rows ``< count`` are used (the state's
    ``fixes``, ``fix_count`` and ``fix_drone``)."""

    local: FloatArray
    """(B, n, F, 3) measured unit directions ``a_k`` in each receiver's frame."""
    world: FloatArray
    """(B, n, F, 3) the same in the world, ``R_k a_k``."""
    time: FloatArray
    """(B, n, F) fix times, s."""
    count: IntArray
    """(B, n) fixes per receiver: the drones it fixed, in drone order, then its false ones."""
    drone: IntArray
    """(B, n, F) the drone of each fix, −1 for a false one; the unused slots hold 0 (the
    kernel's scratch value after a step; −1 after a reset)."""

    def scenario(self, i: int) -> PeriodFixes:
        """Scenario ``i``'s fixes (a leading axis of one)."""
        return PeriodFixes(*(x[i : i + 1] for x in (self.local, self.world, self.time,
                                                    self.count, self.drone)))  # fmt: skip


def scan(
    params: ScanningParams,
    state: ScanningState,
    sectors: FloatArray,
    sigma: FloatArray,
    present: BoolArray,
    normals: FloatArray,
    apparent: FloatArray,
    clutter_count: IntArray,
    clutter_uv: FloatArray,
) -> PeriodFixes:
    """Every receiver's fixes of the period (theory §6.1–6.3, §11.5): each drone present that
    the pixel-visit rule fixes (:func:`pixel_visit`), its direction ``u = d/‖d‖`` with isotropic
    angular noise ``σ_k`` from its normals (:func:`noisy_directions`, theory §4.1, in the
    receiver's frame; none where ``σ_k = 0``) at ``t_0 + s``; then ``min(count, max_clutter)``
    false detections uniform in the sector (:func:`false_detections`)."""
    B, n, F = sectors.shape[0], params.n_receivers, params.max_fixes
    seen, s, d = pixel_visit(params, state, sectors, present, apparent)
    with np.errstate(invalid="ignore", divide="ignore"):  # unseen rows: d may be zero
        u = d / np.linalg.norm(d, axis=-1, keepdims=True)
    u = noisy_directions(np.where(seen[..., None], u, 0.0), normals, sigma[..., None])
    clutter_dir, clutter_time = false_detections(params, sectors, clutter_uv)
    local, time = np.zeros((B, n, F, 3)), np.zeros((B, n, F))
    count, drone = np.zeros((B, n), np.int64), np.zeros((B, n, F), np.int64)
    for i in range(B):
        for k in range(n):
            j = np.flatnonzero(seen[i, k])
            q = min(int(clutter_count[i, k]), clutter_uv.shape[2])
            c = j.size
            local[i, k, :c], time[i, k, :c], drone[i, k, :c] = u[i, k, j], s[i, k, j], j
            local[i, k, c : c + q] = clutter_dir[i, k, :q]
            time[i, k, c : c + q] = clutter_time[i, k, :q]
            drone[i, k, c : c + q] = -1
            count[i, k] = c + q
            time[i, k, : c + q] += state.t[i]
    world = np.einsum("kij,bkfj->bkfi", params.rotations, local)
    return PeriodFixes(local, world, time, count, drone)


def false_detections(
    params: ScanningParams, sectors: FloatArray, uv: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """False detections uniform in each sector (theory §11.5) from the uniform draws
    ``uv (B, n, c, 2)``: local directions ``(B, n, c, 3)`` at ``φ = φ_c + (u − ½) w``,
    ``θ = θ_c + (v − ½) w`` (000 eq. 2) and their visit times after the period start
    ``(B, n, c)`` (theory §6.3)."""
    az, el, w = (x[:, :, None] for x in np.moveaxis(sectors, -1, 0))
    phi = az + (uv[..., 0] - 0.5) * w
    theta = el + (uv[..., 1] - 0.5) * w
    lines, offset = float(params.raster_lines), params.offsets_array[None, :, None]
    when = _visit_time(phi, theta, az, el, w, w, lines, lines, offset, params.sweep_time)
    return unit_from_angles(phi, theta), np.asarray(when, dtype=np.float64).reshape(phi.shape)


# --- 2. candidates: paper 000's proposed spatial step (theory §3.3–3.5, §5.3, §13.6, §13.13) ---


@dataclass(frozen=True)
class PeriodCandidates:
    """One scenario's candidates that passed every check, in the order of their triples."""

    members: IntArray
    """(C, n) the fix of each receiver, −1 where none joined (receivers 4 … n)."""
    position: FloatArray
    """(C, 3) ``M`` in the world at ``time``, m."""
    velocity: FloatArray
    """(C, 3) ``V`` in the world, m/s."""
    time: FloatArray
    """(C,) ``t_1``: the time of receiver 1's fix, s."""
    sigma: FloatArray
    """(C, 2) ``(σ_pos, σ_vel)``, m and m/s."""


def frame1_poses(params: ScanningParams) -> tuple[FloatArray, FloatArray]:
    """``P_k (n, 3, 3)`` and ``b_k (n, 3)`` of every receiver in receiver 1's frame (theory §2.1;
    ``P_1 = I``, ``b_1 = 0``): ``c_k = P_k a_k`` is receiver ``k``'s direction there."""
    P, b = params.relative
    return np.concatenate([np.eye(3)[None], P]), np.concatenate([np.zeros((1, 3)), b])


def pair_gate(
    params: ScanningParams, fixes: PeriodFixes, sigma: FloatArray, h: int, k: int
) -> BoolArray:
    """``(F_h, F_k)``: the pairs of fixes of receivers ``h < k`` that pass the pre-gate of the
    triples (theory §11.5 step 1): their least-squares ranges (000 eq. 7–9, in frame 1)::

        r_h c_h − r_k c_k − (b_k − b_h) = e ,   J = ‖e‖²

    both positive and ``J ≤ ε_J = (q √2 σ_e + v_max |Δt|)²`` (theory §13.6), ``σ_e² = σ_x² +
    ((σ_h r̂_h)² + (σ_k r̂_k)²)/2``, ``Δt = t_k − t_h``: noise plus the largest miss the
    unmodelled motion opens between the rays. No ``κ_F`` test: a true triple's pairs pass."""
    P, b = frame1_poses(params)
    pairs = association.combinations(fixes.count[0, [h, k]])
    c_h = fixes.local[0, h, pairs[:, 0]] @ P[h].T
    c_k = fixes.local[0, k, pairs[:, 1]] @ P[k].T
    A, B = build_system(c_h, c_k[:, None], (b[k] - b[h])[None, None], None, order=0)
    r, J, _, _, _ = solve_svd(A, B, None, 1.0, np.inf)
    dt = fixes.time[0, k, pairs[:, 1]] - fixes.time[0, h, pairs[:, 0]]
    sigma_e = np.sqrt(params.position_sigma**2 + 0.5 * ((sigma[h] * r[:, 0]) ** 2
                                                        + (sigma[k] * r[:, 1]) ** 2))  # fmt: skip
    eps = params.gate_q * np.sqrt(2.0) * sigma_e + params.max_speed * np.abs(dt)
    passes = (r[:, 0] > 0.0) & (r[:, 1] > 0.0) & (J <= eps * eps)
    return passes.reshape(fixes.count[0, h], fixes.count[0, k])


def triple_covariance_sigmas(
    params: ScanningParams,
    a1: FloatArray,
    ak: FloatArray,
    dt: FloatArray,
    sigma: FloatArray,
) -> FloatArray:
    """``(σ_pos, σ_vel) (C, 2)`` of triples: the square roots of the traces of the position and
    velocity blocks of the exact first-order covariance of the 6×6 solution under the angle
    noise (theory §3.5, §11.5 step 2)::

        C = J Σ Jᵀ + σ_x² diag(I₃, 0) ,   Σ = diag(σ_k² (I − u_k u_kᵀ)) ,  u = (a_1, c_2, c_3)

    with ``J`` the Jacobian of ``(M̂_1, V̂)`` in the direction errors
    (:func:`velocity_fix_jacobian`). Frame 1: the traces are the world's."""
    P, b = frame1_poses(params)
    J = velocity_fix_jacobian(a1, ak, P[1:3], b[1:3], dt, cond_max=params.cond_max,
                              check_inputs=False)  # fmt: skip
    u = np.concatenate([a1[:, None], np.einsum("kij,ckj->cki", P[1:3], ak)], axis=1)  # (C, 3, 3)
    Sigma = np.zeros((a1.shape[0], 9, 9))
    for k in range(3):
        across = np.eye(3) - u[:, k, :, None] * u[:, k, None, :]
        Sigma[:, 3 * k : 3 * k + 3, 3 * k : 3 * k + 3] = sigma[k] ** 2 * across
    C = J @ Sigma @ np.swapaxes(J, -1, -2)
    C[:, :3, :3] += params.position_sigma**2 * np.eye(3)
    position_var = np.trace(C[:, :3, :3], axis1=-2, axis2=-1)
    velocity_var = np.trace(C[:, 3:, 3:], axis1=-2, axis2=-1)
    return np.sqrt(np.maximum(np.stack([position_var, velocity_var], -1), 0.0))


def papers_sigmas(
    params: ScanningParams, sigma: FloatArray, ranges: FloatArray, Q: FloatArray
) -> tuple[float, float, float]:
    """``(σ_e, σ_pos, σ_vel)`` of a joint fit of ``n'`` receivers by the papers' model (theory
    §13.4, §11.5 step 2): ``Q = (AᵀA)⁻¹`` of ``X = (r_1 … r_n', V)``, ``σ_e² = σ_x² +
    (1/n') Σ_k (σ_k r̂_k)²``, ``σ_pos = σ_e √(Q_11 + 2)`` (the range error along receiver 1's
    line of sight, ``σ_e`` across it on each axis), ``σ_vel = σ_e √tr Q_VV``."""
    nu = ranges.shape[0]
    sigma_e = np.sqrt(params.position_sigma**2 + np.mean((sigma * np.abs(ranges)) ** 2))
    sp = sigma_e * np.sqrt(max(Q[0, 0], 0.0) + 2.0)
    sv = sigma_e * np.sqrt(max(np.trace(Q[nu:, nu:]), 0.0))
    return float(sigma_e), float(sp), float(sv)


def candidates(
    params: ScanningParams,
    fixes: PeriodFixes,
    sigma: FloatArray,
    sectors: FloatArray,
    t0: float,
) -> PeriodCandidates:
    """One scenario's candidates (theory §5.3 spatial step, §11.5 steps 1–2, §13.13).

    Every triple ``(j_1, j_2, j_3)`` of fixes of receivers 1–3 whose three pairs pass
    :func:`pair_gate` is solved by the velocity-aware system (theory §3.3; 000 eq. 10–11,
    003 eq. 4), ``Δt_k = t_k − t_1``::

        r_1 a_1 − r_k c_k + V Δt_k − b_k = e_k   (k = 2, 3) ,   X̂ = (AᵀA)⁻¹ AᵀB

    and kept where ``κ_F ≤ cond_max`` and every range is positive (theory §13.13); its ``σ_pos``,
    ``σ_vel`` are those of the exact covariance (:func:`triple_covariance_sigmas`), its
    position ``M = O_1 + R_1 r̂_1 a_1`` and velocity ``R_1 V̂`` in the world at ``t_1``. A triple
    whose speed exceeds ``max_speed`` by more than ``q σ_vel`` is dropped; with ``n > 3``
    receivers 4 … n join it and it may be re-solved over all of them (:func:`join_receivers`);
    last, a candidate faster than ``max_speed`` is dropped."""
    n = params.n_receivers
    P, b = frame1_poses(params)
    O1, R1 = params.receivers[0], params.rotations[0]
    g12, g13, g23 = (pair_gate(params, fixes, sigma, h, k) for h, k in ((0, 1), (0, 2), (1, 2)))
    triples = association.combinations(fixes.count[0, :3])
    j1, j2, j3 = triples.T
    triples = triples[g12[j1, j2] & g13[j1, j3] & g23[j2, j3]]
    empty = PeriodCandidates(np.zeros((0, n), np.int64), np.zeros((0, 3)), np.zeros((0, 3)),
                             np.zeros(0), np.zeros((0, 2)))  # fmt: skip
    if triples.shape[0] == 0:
        return empty
    a1 = fixes.local[0, 0, triples[:, 0]]
    ak = np.stack([fixes.local[0, 1, triples[:, 1]], fixes.local[0, 2, triples[:, 2]]], 1)
    t1 = fixes.time[0, 0, triples[:, 0]]
    dt = (
        np.stack([fixes.time[0, 1, triples[:, 1]], fixes.time[0, 2, triples[:, 2]]], 1)
        - t1[:, None]
    )
    A, B = build_system(a1, np.einsum("kij,ckj->cki", P[1:3], ak), b[None, 1:3], dt, order=1)
    X, _, _, kappa, _ = solve_svd(A, B, None, 1.0, params.cond_max)
    ok = (kappa <= params.cond_max) & np.all(X[:, :3] > 0.0, axis=1)
    if not ok.any():
        return empty
    triples, a1, ak, t1, dt, X = triples[ok], a1[ok], ak[ok], t1[ok], dt[ok], X[ok]
    sig = triple_covariance_sigmas(params, a1, ak, dt, sigma[:3])
    M = O1 + (X[:, :1] * a1) @ R1.T
    V = X[:, 3:6] @ R1.T
    members = np.full((triples.shape[0], n), -1, np.int64)
    members[:, :3] = triples
    keep = np.linalg.norm(V, axis=1) - params.gate_q * sig[:, 1] <= params.max_speed
    for c in np.flatnonzero(keep):
        if n > 3:
            kept = join_receivers(params, fixes, sigma, sectors, t0, members[c], M[c], V[c],
                                  t1[c], sig[c])  # fmt: skip
            if kept is None:
                keep[c] = False
                continue
            members[c], M[c], V[c], sig[c] = kept
        keep[c] = np.linalg.norm(V[c]) <= params.max_speed
    return PeriodCandidates(members[keep], M[keep], V[keep], t1[keep], sig[keep])


def nearest_fix(
    params: ScanningParams,
    fixes: PeriodFixes,
    k: int,
    sigma_k: float,
    M: FloatArray,
    V: FloatArray,
    t1: float,
    sig: FloatArray,
) -> int:
    """The fix of receiver ``k`` (≥ 4) that joins a triple (theory §5.3, more than three
    receivers), −1 for none: the one whose line of sight passes nearest the triple's prediction
    ``p = M + V s`` at its time (``s = t − t_1``), the miss ``e = ‖d − (d·u) u‖`` (``d = p − O_k``,
    ``u`` the measured world direction, in front: ``d·u > 0``) within
    ``max(q √(σ_pos² + (σ_vel s)² + (σ_k d·u)²) + ½ a_max s², δ_0)`` (first of equal misses)."""
    count = fixes.count[0, k]
    s = fixes.time[0, k, :count] - t1
    d = M + V * s[:, None] - params.receivers[k]
    u = fixes.world[0, k, :count]
    along = np.sum(d * u, axis=1)
    miss2 = np.maximum(np.sum(d * d, axis=1) - along**2, 0.0)
    spread = np.sqrt(sig[0] ** 2 + (sig[1] * s) ** 2 + (sigma_k * along) ** 2)
    gate = np.maximum(params.gate_q * spread + 0.5 * params.max_acceleration * s**2, GATE_FLOOR)
    passes = (along > 0.0) & (miss2 <= gate**2)
    if not passes.any():
        return -1
    return int(np.argmin(np.where(passes, miss2, np.inf)))


def surely_seen(
    params: ScanningParams,
    k: int,
    sector: FloatArray,
    t0: float,
    M: FloatArray,
    V: FloatArray,
    t1: float,
    sig: FloatArray,
) -> bool:
    """Negative information (theory §5.3): whether the triple's prediction ``d = M + V s − O_k``
    at the middle of receiver ``k``'s sweep (``s`` from ``t_1``) lies inside ``k``'s sector by
    more than ``μ = q √(σ_pos² + (σ_vel s)²) + ‖V‖ T_sweep/2 + ½ a_max s² + δ_0``, on the cone
    inside the sector — axis ``ĉ`` the sector's centre, half-angle
    ``ρ = min(w/2, asin(cos θ_c sin(w/2)))``: ``∠(d, ĉ) ≤ ρ − m``, ``m = asin(μ/‖d‖)``, tested
    on cosines (``cos ∠(d, ĉ) ≥ cos ρ cos m + sin ρ sin m``, where ``sin m < sin ρ``)."""
    az, el, w = sector
    axis = params.rotations[k] @ unit_from_angles(az, el)
    rho = min(0.5 * w, np.arcsin(np.cos(el) * np.sin(0.5 * w)))
    half_sweep = 0.5 * params.sweep_time
    s = t0 + params.offsets_array[k] + half_sweep - t1
    d = M + V * s - params.receivers[k]
    dist = np.linalg.norm(d)
    mu = (params.gate_q * np.sqrt(sig[0] ** 2 + (sig[1] * s) ** 2)
          + np.linalg.norm(V) * half_sweep + 0.5 * params.max_acceleration * s * s + GATE_FLOOR)  # fmt: skip
    with np.errstate(divide="ignore"):
        sin_m = mu / dist
    if not sin_m < np.sin(rho):
        return False
    cos_m = np.sqrt(1.0 - sin_m * sin_m)
    return bool(d @ axis >= dist * (np.cos(rho) * cos_m + np.sin(rho) * sin_m))


def join_receivers(
    params: ScanningParams,
    fixes: PeriodFixes,
    sigma: FloatArray,
    sectors: FloatArray,
    t0: float,
    members: IntArray,
    M: FloatArray,
    V: FloatArray,
    t1: float,
    sig: FloatArray,
) -> tuple[IntArray, FloatArray, FloatArray, FloatArray] | None:
    """Receivers 4 … n join a triple (theory §5.3, more than three receivers): each adds its
    :func:`nearest_fix`. Where none of receiver ``k``'s fixes joins although the prediction is
    :func:`surely_seen` in its sector, ``k`` speaks against the triple; at ``ghost_misses``
    such receivers (``> 0``) the triple is a ghost: ``None``, dropped. With fixes joined, the
    candidate is re-solved by least squares over all its ``n'`` receivers (theory §3.3)::

        X̂ = (AᵀA)⁻¹ AᵀB ,   J = ‖A X̂ − B‖² ,   Q = (AᵀA)⁻¹ ,   X = (r_1 … r_n', V)

    kept where ``κ_F ≤ min(cond_max, NORMAL_EQUATIONS_COND)``, every range is positive and the
    speed ``≤ max_speed`` (else the triple stands and the joined fixes are released), with the
    papers' ``σ_pos``, ``σ_vel`` (:func:`papers_sigmas`); a kept fit must pass the χ² test
    ``J ≤ σ_e² χ²_{2n'−6} + Σ_k (½ a_max Δt_k² + δ_0)²`` (``fit_false_alarm``), else ``None``.
    Returns ``(members, M, V, (σ_pos, σ_vel))``."""
    n = params.n_receivers
    members = members.copy()
    misses = 0
    for k in range(3, n):
        members[k] = nearest_fix(params, fixes, k, sigma[k], M, V, t1, sig)
        if members[k] < 0 and params.ghost_misses > 0:
            misses += surely_seen(params, k, sectors[k], t0, M, V, t1, sig)
    if params.ghost_misses > 0 and misses >= params.ghost_misses:
        return None
    used = np.flatnonzero(members >= 0)
    if used.size == 3:
        return members, M, V, sig
    # the joint system of receivers 1 and k ∈ used[1:] (in receiver order)
    P, b = frame1_poses(params)
    rest = used[1:]
    a1 = fixes.local[0, 0, members[0]]
    c = np.einsum("kij,kj->ki", P[rest], fixes.local[0, rest, members[rest]])
    dt = fixes.time[0, rest, members[rest]] - t1
    A, B = build_system(a1, c, b[rest], dt, order=1)
    X, J, Q, kappa, _ = solve_svd(A, B, None, 1.0, params.cond_max)
    nu = used.size
    R1 = params.rotations[0]
    V_fit = R1 @ X[nu:]
    limit = min(params.cond_max, NORMAL_EQUATIONS_COND)
    if not (kappa <= limit and np.all(X[:nu] > 0.0) and np.linalg.norm(V_fit) <= params.max_speed):
        members[3:] = -1
        return members, M, V, sig
    sigma_e, sp, sv = papers_sigmas(params, sigma[used], X[:nu], Q)
    # χ² on 3 (n' − 1) − (n' + 3) = 2n' − 6 degrees of freedom, plus the unmodelled drift
    drift = np.sum((0.5 * params.max_acceleration * dt**2 + GATE_FLOOR) ** 2)
    if J > sigma_e**2 * params.fit_thresholds[nu - 4] + drift:
        return None
    M_fit = params.receivers[0] + R1 @ (X[0] * a1)
    return members, M_fit, V_fit, np.array([sp, sv])


# --- 3. association over periods (theory §5.3 temporal step, §11.5 step 3) --------------------


class Table:
    """One scenario's track table (theory §11.5), as views of its rows in the state's arrays
    (writing a view writes the state): a freed row keeps its last values until reused."""

    def __init__(self, tracks: FloatArray, track_int: IntArray) -> None:
        self.rows = tracks
        """(T, 19) the float columns, as :attr:`.simulation.ScanningState.tracks`."""
        self.ints = track_int
        """(T, 4) the integer columns."""
        self.M, self.V = tracks[:, 0:3], tracks[:, 3:6]  # M̂ at t_s, V̂ (world)
        self.t = tracks[:, 6]  # t_s: the time of the latest member
        self.sigma = tracks[:, 7:9]  # σ_pos, σ_vel
        self.score = tracks[:, 9]  # cumulative index I = Σ ΔJ
        self.sums = tracks[:, 10:19]  # the alternative's line-fit sums (0 here)
        self.hits, self.misses = track_int[:, 0], track_int[:, 1]
        self.status, self.ident = track_int[:, 2], track_int[:, 3]

    def free_row(self) -> int:
        """The first empty row, −1 when the table is full."""
        empty = np.flatnonzero(self.status == EMPTY)
        return int(empty[0]) if empty.size else -1

    def extend(self, q: int, found: PeriodCandidates, c: int, cost: float) -> None:
        """Row ``q`` takes candidate ``c`` (000 proposed step 3): ``I ← I + ΔJ``, one more
        member, no miss, and the latest spatial estimate ``(M, V)`` with its time and ``σ``s."""
        self.score[q] += cost
        self.hits[q] += 1
        self.misses[q] = 0
        self.M[q], self.V[q] = found.position[c], found.velocity[c]
        self.t[q] = found.time[c]
        self.sigma[q] = found.sigma[c]


def continuation_costs(params: ScanningParams, table: Table, found: PeriodCandidates) -> FloatArray:
    """``ΔJ (T, C)`` of continuing each track with each candidate, ``inf`` where it may not
    (theory §11.5 step 3; 000 proposed steps 2–3 and :func:`association.extrapolation_residual`)::

        ΔJ = ‖M − (M̂_s + V̂_s Δ)‖ ≤ δ = max(q s + ½ a_max Δ², δ_0) ,   Δ = t − t_s > 0
        s² = (σ_pos,c² + σ_pos,s² + (σ_vel,s Δ)²)/3
        ‖V − V̂_s‖ ≤ max(q √((σ_vel,c² + σ_vel,s²)/3) + a_max Δ, δ_0)   (003's J_3, §5.5)

    for every track in the table (tentative or confirmed)."""
    q_, a_max = params.gate_q, params.max_acceleration
    dJ = association.extrapolation_residual(table.M, table.V, table.t, found.position, found.time)
    lead = found.time[None, :] - table.t[:, None]  # Δ
    sp_c, sv_c = found.sigma[None, :, 0], found.sigma[None, :, 1]
    sp_s, sv_s = table.sigma[:, None, 0], table.sigma[:, None, 1]
    spread = np.sqrt((sp_c**2 + sp_s**2 + (sv_s * lead) ** 2) / 3.0)
    gate = np.maximum(q_ * spread + 0.5 * a_max * lead**2, GATE_FLOOR)
    dv = np.linalg.norm(found.velocity[None, :, :] - table.V[:, None, :], axis=-1)
    dv_gate = np.maximum(q_ * np.sqrt((sv_c**2 + sv_s**2) / 3.0) + a_max * lead, GATE_FLOOR)
    live = (table.status != EMPTY)[:, None]
    ok = live & (lead > 0.0) & (dv <= dv_gate) & (dJ <= gate)
    return np.where(ok, dJ, np.inf)


def associate(params: ScanningParams, table: Table, found: PeriodCandidates, next_id: int) -> int:
    """The period's association (theory §11.5 step 3, §5.3; π = 0: no two tracks taken this
    period share a direction vector), in place on ``table``; returns the next identity.

    1. Confirmed tracks take, greedily in ascending ``ΔJ`` over all passing (track, candidate)
       pairs (:func:`continuation_costs`), a candidate sharing no fix with one already taken.
    2. Every tentative track (paper 000's group) grows a child for each passing continuation
       sharing no fix with those taken; the children, in ascending cumulative index
       ``I = I_parent + ΔJ``, replace their parents in the first free rows, each unless it
       shares a fix with one taken by now; a child holding ``confirm_hits`` members is
       confirmed (a new identity) and its fixes are taken.
    3. A confirmed track without a continuation coasts, and is dropped after more than
       ``max_misses`` such periods.
    4. Every candidate neither taken nor sharing a taken fix opens a tentative track (confirmed
       at once if ``confirm_hits ≤ 1``) in the first free row, in candidate order, while rows
       last."""
    n, F = params.n_receivers, params.max_fixes
    cost = continuation_costs(params, table, found)
    rows, cands = np.nonzero(np.isfinite(cost))  # (track, candidate) in table order
    order = np.argsort(cost[rows, cands], kind="stable")
    pairs = [(int(q), int(c)) for q, c in zip(rows[order], cands[order], strict=True)]
    taken_fix = np.zeros((n, F), bool)  # (receiver, fix) taken this period
    continued = np.zeros(table.status.shape[0], bool)
    taken = np.zeros(found.time.shape[0], bool)

    def shares(c: int) -> bool:
        k = np.flatnonzero(found.members[c] >= 0)
        return bool(np.any(taken_fix[k, found.members[c, k]]))

    def take(c: int) -> None:
        k = np.flatnonzero(found.members[c] >= 0)
        taken_fix[k, found.members[c, k]] = True

    # 1. confirmed tracks, greedy by ΔJ
    for q, c in pairs:
        if table.status[q] != CONFIRMED or continued[q] or shares(c):
            continue
        continued[q], taken[c] = True, True
        take(c)
        table.extend(q, found, c, cost[q, c])
    # 2. tentative tracks: their children, in ascending cumulative index
    children = [(q, c) for q, c in pairs if table.status[q] == TENTATIVE and not shares(c)]
    index = np.array([table.score[q] + cost[q, c] for q, c in children])
    parents = {q: (table.rows[q].copy(), table.hits[q]) for q, _ in children}
    table.status[table.status == TENTATIVE] = EMPTY
    for e in np.argsort(index, kind="stable"):
        q, c = children[e]
        if shares(c):
            continue
        slot = table.free_row()
        if slot < 0:
            break
        table.rows[slot], table.hits[slot] = parents[q]  # the parent's columns, then its child
        table.misses[slot] = 0
        table.extend(slot, found, c, cost[q, c])
        taken[c], continued[slot] = True, True
        if table.hits[slot] >= params.confirm_hits:
            table.status[slot], table.ident[slot] = CONFIRMED, next_id
            next_id += 1
            take(c)
        else:
            table.status[slot] = TENTATIVE
    # 3. confirmed tracks without a continuation coast
    coasting = (table.status == CONFIRMED) & ~continued
    table.misses[coasting] += 1
    table.status[coasting & (table.misses > params.max_misses)] = EMPTY
    # 4. births
    for c in range(found.time.shape[0]):
        if taken[c] or shares(c):
            continue
        slot = table.free_row()
        if slot < 0:
            break
        table.hits[slot], table.misses[slot] = 0, 0
        table.score[slot], table.sums[slot] = 0.0, 0.0
        table.extend(slot, found, c, 0.0)
        if params.confirm_hits <= 1:
            table.status[slot], table.ident[slot] = CONFIRMED, next_id
            next_id += 1
        else:
            table.status[slot] = TENTATIVE
    return next_id


# --- 4. reward at the period end, 5. the drones fly on (theory §11.5) --------------------------


def score_period(
    params: ScanningParams,
    state: ScanningState,
    tracks: FloatArray,
    track_int: IntArray,
    present: BoolArray,
) -> tuple[IntArray, FloatArray, FloatArray, FloatArray]:
    """The reward of the period (theory §11.5): ``(assigned (B, m), σ (B, m), parts (B, 6),
    reward (B,))``.

    Each confirmed track is compared with the drones present at its own time if a candidate
    continued it this period (``t_s ≥ t_0``), else at the period end ``t_0 + τ``, where its
    prediction ``M̂ + V̂ (t − t_s)`` carries ``σ_pos(t)² = σ_pos² + (σ_vel (t − t_s))²``. Tracks
    and drones are matched greedily, nearest first, one-to-one, within ``truth_gate``
    (:func:`association.match_tracks`). A present drone scores ``clip(ln(σ_ref/σ_pos), −R, R)``
    with its track, ``−R`` without; the reward is their mean (0 with no drone present) less
    ``false_track_penalty`` per confirmed track matched to no drone. ``parts``: drones present,
    drones tracked, false tracks, the mean per-drone reward, the mean ``σ_pos`` of the tracked
    drones (0 if none), confirmed tracks."""
    B, m, T = present.shape[0], params.n_drones, params.track_capacity
    R = params.reward_clip
    t0, t_end = state.t, state.t + params.period
    assigned, drone_sigma = np.full((B, m), -1, np.int64), np.full((B, m), np.inf)
    parts, reward = np.zeros((B, 6)), np.zeros(B)
    for i in range(B):
        table = Table(tracks[i], track_int[i])
        confirmed = np.flatnonzero(table.status == CONFIRMED)
        when = np.where(table.t >= t0[i], table.t, t_end[i])  # the time each track is judged at
        lead = when - table.t
        distance = np.full((m, T), np.inf)
        paths = Trajectories(state.drone_position[i], state.drone_velocity[i],
                             state.drone_acceleration[i])  # fmt: skip
        for q in confirmed:
            truth = paths.position(when[q] - t0[i])
            d = np.linalg.norm(table.M[q] + table.V[q] * lead[q] - truth, axis=1)
            distance[:, q] = np.where(present[i], d, np.inf)
        assigned[i] = association.match_tracks(distance, params.truth_gate)
        tracked = assigned[i] >= 0
        q = assigned[i, tracked]
        drone_sigma[i, tracked] = np.sqrt(
            table.sigma[q, 0] ** 2 + (table.sigma[q, 1] * lead[q]) ** 2
        )
        per_drone = np.where(tracked, log_ratio_reward(drone_sigma[i], params.sigma_ref, R), -R)
        n_present, found = int(present[i].sum()), int(tracked.sum())
        mean = float(per_drone[present[i]].mean()) if n_present else 0.0
        n_false = int(np.sum(~np.isin(confirmed, q)))
        reward[i] = mean - params.false_track_penalty * n_false
        mean_sigma = float(drone_sigma[i, tracked].mean()) if found else 0.0
        parts[i] = (n_present, found, n_false, mean, mean_sigma, confirmed.size)
    return assigned, drone_sigma, parts, reward


def fly_on(
    params: ScanningParams, state: ScanningState, present: BoolArray
) -> tuple[FloatArray, FloatArray, BoolArray]:
    """The drones at the period end (theory §11.5): those present fly their constant-acceleration
    paths for ``τ`` (:class:`Trajectories`: ``p + v τ + ½ a τ²``, ``v + a τ``), the others wait
    (not yet entered) or are gone; a drone beyond ``±scene_half_width`` in X or Z, below
    ``scene_floor`` or above ``scene_height`` has left for good. ``(position, velocity, exited)``."""
    paths = drone_paths(state)
    shape = state.drone_position.shape
    moved = paths.position(params.period).reshape(shape)
    sped = paths.velocity_at(params.period).reshape(shape)
    position = np.where(present[..., None], moved, state.drone_position)
    velocity = np.where(present[..., None], sped, state.drone_velocity)
    half, floor, ceiling = params.scene_half_width, params.scene_floor, params.scene_height
    outside = ((np.abs(position[..., 0]) > half) | (np.abs(position[..., 2]) > half)
               | (position[..., 1] < floor) | (position[..., 1] > ceiling))  # fmt: skip
    return position, velocity, state.exited | (present & outside)


# --- 6. the observation ---------------------------------------------------------------------------


def observation(params: ScanningParams, state: ScanningState) -> NDArray[np.float32]:
    """The observation of ``state`` ``(B, obs_dim)`` (the table of :func:`.simulation.observe`):
    the first ``track_slots`` confirmed tracks in table order — ``1``, ``(p̂ − c)/L``, ``v̂/S``,
    ``ln(σ_pos(t)/σ_ref)``, ``ln(σ_vel τ/σ_ref)``, ``Δ/τ``, members/10, with ``Δ = t − t_s``,
    ``p̂ = M̂ + V̂ Δ`` and ``σ_pos(t)² = σ_pos² + (σ_vel Δ)²`` (deviations floored at 1e-12 m) —
    then per receiver its sector (centre ``/(regard/2)``, width mapped to ``[−1, 1]``) and its
    fixes over ``max_fixes``; clipped to ``±OBS_CLIP``, float32."""
    B, S, n = state.batch_size, params.track_slots, params.n_receivers
    L, speed, ref, tau = params.length_scale, params.speed_scale, params.sigma_ref, params.period
    rows = np.zeros((B, S, 11))
    for i in range(B):
        table = Table(state.tracks[i], state.track_int[i])
        shown = np.flatnonzero(table.status == CONFIRMED)[:S]
        lead = state.t[i] - table.t[shown]
        sp = np.sqrt(table.sigma[shown, 0] ** 2 + (table.sigma[shown, 1] * lead) ** 2)
        rows[i, : shown.size] = np.column_stack([
            np.ones(shown.size),
            (table.M[shown] + table.V[shown] * lead[:, None] - params.centre) / L,
            table.V[shown] / speed,
            np.log(np.maximum(sp, TINY) / ref),
            np.log(np.maximum(table.sigma[shown, 1] * tau, TINY) / ref),
            lead / tau,
            table.hits[shown] / 10.0,
        ])  # fmt: skip
    lo, hi = params.sector_width
    half = 0.5 * params.field_of_regard
    receivers = np.stack([
        state.sectors[..., 0] / half,
        state.sectors[..., 1] / half,
        2.0 * (state.sectors[..., 2] - lo) / max(hi - lo, TINY) - 1.0,
        state.fix_count / params.max_fixes,
    ], -1)  # fmt: skip
    return clip_observation(np.concatenate([rows.reshape(B, -1), receivers.reshape(B, 4 * n)], 1))
