"""Heuristic sector rules for ``sensorgym/StereoScanning-v0`` (theory §10.1 OC-1, §10.4 OC-4).

Each rule reads only the observation (the tracker's table of confirmed tracks and the last
sectors, :func:`sensorgym.envs.stereo_scanning.simulation.observe`) plus the env's params
(receiver layout, raster, noise per width), and implements SB3's ``predict``;
:class:`TruthSectors` also reads the simulator's true drones (a truth-informed rule, not a
fieldable policy, and not a bound on the return).

* :class:`FullSweep` — the papers' fixed sweep: every receiver scans its whole field of regard.
* :class:`CueFollowing` — sectors centred on the predicted tracks, just wide enough for them
  and their motion during the period; a search of two consecutive full sweeps every
  ``sweep_every`` periods (and a full sweep whenever there is no track) to find new drones;
  ``search="entry"`` searches with sectors on the region where drones enter instead.
* :class:`OrthogonalSectors` — OC-1: the tracks ranked by the papers' range-only score
  ``σ_e/√(Σ_k sin²γ_k)`` (lines of sight from receiver 1 against the others); each receiver's
  sector covers the best-ranked tracks that fit a narrow sector, the others wait for the sweeps.
* :class:`GreedyInformation` — per period, the common width (from a grid) and centres that
  maximise the expected reward ``Σ_tracks [covered ? ln(σ_ref/σ̂_pos(w)) : −R]`` with
  ``σ̂_pos = κ w r̄ √(σ[r̂_1]²/σ_e² + 2)`` (the env's covariance with the range-only closed form).
* :class:`TruthSectors` — the greedy choice on the true drones of the scene (truth-informed:
  what knowing the drones buys the greedy choice).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import NDArray

from sensorgym.agents.protocol import MemorylessRule, as_batch
from sensorgym.envs.stereo_scanning.simulation import (
    ScanningParams,
    local_angles,
    sector_action,
    split_observation,
)
from sensorgym.trackers.stereo.accuracy import range_sigma_general
from sensorgym.trackers.stereo.kernels import copy1, copy2

FloatArray = NDArray[np.float64]

#: angular margin added around the covered tracks on each side, rad
MARGIN = float(np.deg2rad(1.5))


def _full(params: ScanningParams, N: int) -> FloatArray:
    sectors = np.zeros((N, params.n_receivers, 3))
    sectors[..., 2] = params.sector_width[1]
    return sectors


def _cover(params: ScanningParams, angles: FloatArray, mask: NDArray[np.bool_]) -> FloatArray:
    """Sectors ``(n, 3)`` just covering the local angles ``(S, n, 3)`` of the masked points
    (plus :data:`MARGIN`); a full sweep where none is masked."""
    n = params.n_receivers
    if not mask.any():
        return _full(params, 1)[0]
    a = angles[mask]  # (S', n, 3)
    lo, hi = a[..., :2].min(axis=0), a[..., :2].max(axis=0)  # (n, 2)
    centre = 0.5 * (lo + hi)
    width = np.max(hi - lo, axis=-1) + 2 * MARGIN
    width = np.clip(width, *params.sector_width)
    out = np.empty((n, 3))
    out[:, :2] = centre
    out[:, 2] = width
    return out


def _motion_margin(params: ScanningParams, velocity: FloatArray, rng: FloatArray) -> FloatArray:
    """Angle (rad) a track may move during one period at its estimated speed, per receiver."""
    speed = np.linalg.norm(velocity, axis=-1)  # (S,)
    return speed[:, None] * params.period / np.maximum(rng, 1.0)


def _track_angles(params: ScanningParams, o: dict, i: int) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Local angles ``(S, n, 3)`` of scenario ``i``'s tracks predicted to mid-period."""
    mid = o["position"][i] + o["velocity"][i] * (0.5 * params.period)
    return local_angles(params, mid), o["valid"][i]


class FullSweep(MemorylessRule):
    """The papers' fixed sweep: every receiver scans the widest sector about its boresight."""

    def __init__(self, params: ScanningParams):
        self.params = params

    def act(self, obs: FloatArray) -> FloatArray:
        N = obs.shape[0]
        return sector_action(self.params, _full(self.params, N)).reshape(N, -1)


#: periods between the starts of two searches (tuned on seeds below 10000: flat from 8 to 16)
SWEEP_EVERY = 10
#: a ``sweep_every`` longer than any episode: the rule searches only at its start
NEVER = 10**9
#: consecutive full-sweep periods of one search: a drone found by a sweep opens a tentative
#: track, which dies unless the next period continues it, so a single sweep never confirms a
#: drone that the sectors on the known tracks do not happen to cover
SWEEP_PERIODS = 2


def entry_points(params: ScanningParams) -> FloatArray:
    """The 8 corners ``(8, 3)`` of the box where drones start or enter the scene (``±
    start_spread`` in X and Z, ``start_altitude`` in height), grown by one period of flight at
    the fastest speed, m (the scenario distribution is part of the params every rule sees)."""
    grow = params.drone_speed[1] * params.period
    xz = params.start_spread + grow
    lo, hi = params.start_altitude[0] - grow, params.start_altitude[1] + grow
    corners = [(x, y, z) for x in (-xz, xz) for y in (lo, hi) for z in (-xz, xz)]
    return np.asarray(corners, dtype=np.float64)


def entry_sectors(params: ScanningParams, o: dict, i: int) -> FloatArray:
    """Sectors ``(n, 3)`` covering the entry region (:func:`entry_points`) and scenario ``i``'s
    confirmed tracks: a search with finer fixes than the full sweep (53° wide by default)."""
    ang, valid = _track_angles(params, o, i)
    both = np.concatenate([local_angles(params, entry_points(params)), ang[valid]])
    return _cover(params, both, np.ones(both.shape[0], bool))


class _Periodic:
    """A rule with a period counter per env (SB3's ``state``): a search — ``sweep_periods``
    consecutive periods of full sweeps, or with ``search="entry"`` of :func:`entry_sectors` —
    every ``sweep_every`` periods, and a full sweep whenever it has no track."""

    params: ScanningParams
    sweep_every: int
    sweep_periods: int = SWEEP_PERIODS
    search: str = "sweep"

    def sectors(self, o: dict, i: int) -> FloatArray:
        raise NotImplementedError

    def predict(
        self,
        observation: NDArray[Any],
        state: Any = None,
        episode_start: NDArray[np.bool_] | None = None,
        deterministic: bool = True,
    ) -> tuple[NDArray[np.float32], NDArray[np.int64]]:
        obs, single = as_batch(observation, self.params.obs_dim)
        N = obs.shape[0]
        count = np.zeros(N, np.int64) if state is None else np.asarray(state, np.int64).copy()
        if count.shape != (N,):
            count = np.zeros(N, np.int64)
        if episode_start is not None:
            count[np.asarray(episode_start, bool).reshape(-1)[:N]] = 0
        o = split_observation(self.params, obs)
        sectors = _full(self.params, N)
        for i in range(N):
            searching = count[i] % self.sweep_every < self.sweep_periods
            if searching and self.search == "entry":
                sectors[i] = entry_sectors(self.params, o, i)
            elif o["valid"][i].any() and not searching:
                sectors[i] = self.sectors(o, i)
        count += 1
        action = sector_action(self.params, sectors).reshape(N, -1).astype(np.float32)
        return (action[0] if single else action), count


class CueFollowing(_Periodic):
    """Sectors centred on the predicted tracks, covering them and their motion in a period."""

    def __init__(self, params: ScanningParams, sweep_every: int = SWEEP_EVERY,
                 sweep_periods: int = SWEEP_PERIODS, search: str = "sweep"):  # fmt: skip
        if search not in ("sweep", "entry"):
            raise ValueError(f"search: 'sweep' or 'entry', got {search!r}")
        self.params = params
        self.sweep_every = sweep_every
        self.sweep_periods = sweep_periods
        self.search = search

    def sectors(self, o: dict, i: int) -> FloatArray:
        ang, valid = _track_angles(self.params, o, i)
        pad = _motion_margin(self.params, o["velocity"][i], ang[..., 2])
        wide = ang.copy()
        out = _cover(self.params, wide, valid)
        # widen by the largest motion of a covered track
        out[:, 2] = np.clip(out[:, 2] + 2 * pad[valid].max(axis=0), *self.params.sector_width)
        return out


def oc1_score(params: ScanningParams, points: FloatArray) -> FloatArray:
    """The papers' range-only OC-1 score ``1/√(Σ_k sin²γ_k)`` (``σ[r̂_1]/σ_e``, theory §3.4) of
    points ``(S, 3)``: lines of sight from receiver 1 against the others (lower is better)."""
    d = points[:, None, :] - params.receivers[None]
    u = d / np.maximum(np.linalg.norm(d, axis=-1, keepdims=True), 1e-9)
    return range_sigma_general(u[:, 0], u[:, 1:])


class OrthogonalSectors(_Periodic):
    """OC-1: narrow sectors on the tracks whose lines of sight are nearest orthogonal."""

    def __init__(self, params: ScanningParams, max_width: float = float(np.deg2rad(20.0)),
                 sweep_every: int = SWEEP_EVERY, sweep_periods: int = SWEEP_PERIODS):  # fmt: skip
        self.params = params
        self.max_width = max_width
        self.sweep_every = sweep_every
        self.sweep_periods = sweep_periods

    def sectors(self, o: dict, i: int) -> FloatArray:
        ang, valid = _track_angles(self.params, o, i)
        idx = np.flatnonzero(valid)
        score = oc1_score(self.params, o["position"][i][idx])
        # by score, the tracks whose covering sectors stay within max_width (the best always)
        S, n = valid.shape[0], self.params.n_receivers
        lo, hi = np.empty((1, n, 2)), np.empty((1, n, 2))
        pad_max, chosen = np.empty((1, n)), np.empty((1, S), np.bool_)
        _greedy_cover(np.ascontiguousarray(ang[..., :2]), np.zeros((S, n)),
                      idx[np.argsort(score)], np.array([self.max_width]), MARGIN,
                      *self.params.sector_width, 0.0, True, lo, hi, pad_max, chosen)  # fmt: skip
        chosen = chosen[0]
        out = _cover(self.params, ang, chosen)
        pad = _motion_margin(self.params, o["velocity"][i], ang[..., 2])
        out[:, 2] = np.clip(out[:, 2] + 2 * pad[chosen].max(axis=0), *self.params.sector_width)
        return out


@njit(cache=True, nogil=True)
def _greedy_cover(ang, pad, order, widths, margin, lo_w, hi_w, tol, take_first, lo, hi, pad_max,
                  chosen):  # fmt: skip
    """For every width ``w`` of ``widths (W,)``: walk the points in ``order``, taking a point
    when every receiver's covering sector of the points taken so far and it (their angular
    extent ``[lo, hi]`` from ``ang (S, n, 2)``, plus ``2 margin``, clipped to ``[lo_w, hi_w]``)
    widened by twice their largest motion ``pad (S, n)`` fits ``w + tol`` (or, with
    ``take_first``, when it is the first point taken). Writes the extent
    ``lo, hi (W, n, 2)``, the largest motion ``pad_max (W, n)`` and ``chosen (W, S)`` (what
    :func:`_cover` of the chosen points gives, without building it per trial)."""
    n = ang.shape[1]
    t_lo, t_hi, t_pad = np.empty((n, 2)), np.empty((n, 2)), np.empty(n)
    for w in range(widths.shape[0]):
        lo[w] = np.inf
        hi[w] = -np.inf
        pad_max[w] = -np.inf
        chosen[w] = False
        first = take_first
        for q in order:
            fits = True
            for k in range(n):
                width = -np.inf
                for x in range(2):
                    t_lo[k, x] = min(lo[w, k, x], ang[q, k, x])
                    t_hi[k, x] = max(hi[w, k, x], ang[q, k, x])
                    width = max(width, t_hi[k, x] - t_lo[k, x])
                cover = min(max(width + 2 * margin, lo_w), hi_w)
                t_pad[k] = max(pad_max[w, k], pad[q, k])
                if not (first or cover + 2 * t_pad[k] <= widths[w] + tol):
                    fits = False
                    break
            if fits:
                # element-wise copies: slice assignments from arrays compile numba's
                # shape-error message (seconds of cold start)
                copy2(t_lo, lo[w])
                copy2(t_hi, hi[w])
                copy1(t_pad, pad_max[w])
                chosen[w, q] = True
                first = False


def greedy_sectors(
    params: ScanningParams, points: FloatArray, velocity: FloatArray, widths: FloatArray
) -> FloatArray:
    """Sectors ``(n, 3)`` maximising ``Σ_points [covered ? ln(σ_ref/σ̂(w)) : −R]`` over a grid of
    common maximum widths: for each, the points are taken greedily by OC-1 score while every
    receiver's covering sector fits the width (module docstring).

    The greedy walk runs compiled on the running angular extent of each width's chosen set
    (:func:`_greedy_cover`: the ``min``/``max`` that :func:`_cover` takes, so the same
    sectors), ``O(W S n)`` for ``W`` widths and ``S`` points; the value of every width's choice
    is one array expression."""
    if points.shape[0] == 0:
        return _full(params, 1)[0]
    widths = np.asarray(widths, dtype=np.float64)
    W, S, n = widths.shape[0], points.shape[0], params.n_receivers
    lo_w, hi_w = params.sector_width
    mid = points + velocity * (0.5 * params.period)
    ang = local_angles(params, mid)
    pad = _motion_margin(params, velocity, ang[..., 2])
    rel = oc1_score(params, points)
    lo, hi = np.empty((W, n, 2)), np.empty((W, n, 2))
    pad_max, chosen = np.empty((W, n)), np.empty((W, S), np.bool_)
    _greedy_cover(np.ascontiguousarray(ang[..., :2]), pad, np.argsort(rel), widths, MARGIN,
                  lo_w, hi_w, 1e-12, False, lo, hi, pad_max, chosen)  # fmt: skip
    some = chosen.any(axis=1)
    if not some.any():
        return _full(params, 1)[0]
    lo, hi, pad_max, chosen = lo[some], hi[some], pad_max[some], chosen[some]
    sec = np.empty((lo.shape[0], n, 3))
    sec[..., :2] = 0.5 * (lo + hi)
    cover = np.clip(np.max(hi - lo, axis=-1) + 2 * MARGIN, lo_w, hi_w)
    sec[..., 2] = np.clip(cover + 2 * pad_max, lo_w, hi_w)
    sig = np.maximum(params.noise_per_width * sec[..., 2], params.sigma_ang_min)  # (W', n)
    r = ang[..., 2]  # (S, n)
    sigma_e = np.sqrt(params.position_sigma**2 + np.mean((sig[:, None] * r) ** 2, axis=-1))
    sigma_pos = sigma_e * np.sqrt(rel**2 + 2.0)
    with np.errstate(divide="ignore"):
        gain = np.clip(np.log(params.sigma_ref / sigma_pos), -params.reward_clip,
                       params.reward_clip)  # fmt: skip
    value = np.sum(np.where(chosen, gain, -params.reward_clip), axis=1)
    return sec[int(np.argmax(value))]


class GreedyInformation(_Periodic):
    """Per period, the sector width and centres with the best expected covariance reward."""

    def __init__(self, params: ScanningParams, n_widths: int = 8, sweep_every: int = SWEEP_EVERY,
                 sweep_periods: int = SWEEP_PERIODS):  # fmt: skip
        self.params = params
        self.widths = np.geomspace(*params.sector_width, n_widths)
        self.sweep_every = sweep_every
        self.sweep_periods = sweep_periods

    def sectors(self, o: dict, i: int) -> FloatArray:
        valid = o["valid"][i]
        return greedy_sectors(
            self.params, o["position"][i][valid], o["velocity"][i][valid], self.widths
        )


class TruthSectors(MemorylessRule):
    """The greedy choice on the true drones present (reads ``simulator_state``): a
    truth-informed rule, not fieldable and not a bound on the return."""

    def __init__(self, state_fn: Callable[[], Any], params: ScanningParams, n_widths: int = 8):
        self.state_fn = state_fn
        self.params = params
        self.widths = np.geomspace(*params.sector_width, n_widths)

    def act(self, obs: FloatArray) -> FloatArray:
        s = self.state_fn()
        N = obs.shape[0]
        if s.batch_size != N:
            raise ValueError(f"observation: {N} envs, but the simulator holds {s.batch_size}")
        out = np.empty((N, self.params.n_receivers, 3))
        for i in range(N):
            present = (s.enter[i] <= s.t[i] + 1e-9) & ~s.exited[i]
            out[i] = greedy_sectors(
                self.params, s.drone_position[i][present], s.drone_velocity[i][present],
                self.widths,
            )  # fmt: skip
        return sector_action(self.params, out).reshape(N, -1)


__all__ = [
    "NEVER",
    "SWEEP_EVERY",
    "SWEEP_PERIODS",
    "CueFollowing",
    "FullSweep",
    "GreedyInformation",
    "OrthogonalSectors",
    "TruthSectors",
    "entry_points",
    "entry_sectors",
    "greedy_sectors",
    "oc1_score",
]
