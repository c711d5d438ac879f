"""Heuristic pointing rules for ``sensorgym/StereoPointing-v0`` (theory §10.1 OC-1, §10.2 OC-2).

Each rule reads only the observation (own gimbal angles and the tracker's predictions, see
:func:`sensorgym.envs.stereo_pointing.simulation.observe`) plus the fixed receiver layout from the
env's params, and implements SB3's ``predict``, so
``stable_baselines3.common.evaluation.evaluate_policy`` scores it like a trained model. The
assignment rules enumerate every map of receivers to drones (``m^n`` of them) and slew each
receiver straight at the predicted position of its drone; the scores of all candidates are the
compiled :func:`~sensorgym.trackers.stereo.kernels.assignment_orthogonality_batch` and
:func:`~sensorgym.trackers.stereo.kernels.assignment_log_det_batch`, the lines of sight and
pointing offsets the env's compiled ones.
"""

from __future__ import annotations

import itertools
from abc import abstractmethod
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sensorgym.agents.protocol import MemorylessRule, as_batch
from sensorgym.envs.stereo_pointing.simulation import (
    PointingParams,
    lines_of_sight,
    pointing_offsets,
    split_observation,
)
from sensorgym.trackers.stereo import kernels
from sensorgym.trackers.stereo.information import MIN_RANGE

FloatArray = NDArray[np.float64]

#: the assignment rules refuse layouts with more candidate assignments than this
MAX_ASSIGNMENTS = 4096


@dataclass(frozen=True)
class _View:
    """What a rule knows at one step: decoded observation and the geometry it implies."""

    azimuth: FloatArray
    """(N, n) boresight azimuths, rad."""
    elevation: FloatArray
    """(N, n) boresight elevations, rad."""
    seen: FloatArray
    """(N, n, m) 1.0 where receiver k saw drone j on the last step."""
    position: FloatArray
    """(N, m, 3) predicted drone positions, m."""
    sigma: FloatArray
    """(N, m) predicted position RMS, m."""
    los: FloatArray
    """(N, n, m, 3) unit lines of sight from the receivers to the predicted positions."""
    ranges: FloatArray
    """(N, n, m) ranges to the predicted positions, m (inf: predicted on the receiver)."""


def _view(params: PointingParams, obs: FloatArray) -> _View:
    """Decode ``obs``. A drone predicted on a receiver (the zero line of sight, which that
    receiver never sees) is at infinite range from it: it adds no information there and is
    never the nearest."""
    gimbals, pairs, drones = split_observation(params, obs)
    position = drones[..., :3] * params.length_scale
    los, r = lines_of_sight(params, position)
    return _View(
        azimuth=np.arctan2(gimbals[..., 0], gimbals[..., 1]),
        elevation=gimbals[..., 2] * (np.pi / 2),
        seen=pairs[..., 2],
        position=position,
        sigma=np.exp(drones[..., 3]) * params.sigma_ref,
        los=los,
        ranges=np.where(r > MIN_RANGE, np.maximum(r, MIN_RANGE), np.inf),
    )


def _slew_to(params: PointingParams, view: _View, target: NDArray[np.int64]) -> FloatArray:
    """Normalised actions ``(N, 2n)`` that slew receiver ``k`` at drone ``target[:, k]``."""
    offsets = pointing_offsets(params, view.azimuth, view.elevation, view.position)
    off = np.take_along_axis(offsets, target[:, :, None, None], axis=2)[:, :, 0]  # (N, n, 2)
    # the gimbal stops at its elevation limit
    lim = params.max_elevation
    d_el = np.clip(view.elevation + off[..., 1], -lim, lim) - view.elevation
    step = max(params.slew_rate * params.dt, 1e-12)
    action = np.stack([off[..., 0], d_el], -1) / step
    return np.clip(action, -1.0, 1.0).reshape(off.shape[0], -1)


def _assignments(params: PointingParams) -> NDArray[np.int64]:
    """Every map of the ``n`` receivers to the ``m`` drones, ``(m^n, n)``."""
    n, m = params.n_receivers, params.n_drones
    if m**n > MAX_ASSIGNMENTS:
        raise ValueError(f"params: {m}^{n} receiver-to-drone assignments exceed {MAX_ASSIGNMENTS}")
    return np.array(list(itertools.product(range(m), repeat=n)), dtype=np.int64)


def _keep_bonus(view: _View, cand: NDArray[np.int64], bonus: float) -> FloatArray:
    """``bonus`` times the number of receivers each candidate leaves on a drone they see
    ``(N, C)``: hysteresis, so that near-ties do not make receivers slew back and forth."""
    n = cand.shape[1]
    kept = view.seen[:, np.arange(n)[None, :], cand]  # (N, C, n)
    return bonus * kept.sum(axis=-1)


class _AssignAndSlew(MemorylessRule):
    """Rules that pick a drone per receiver (``choose``) and slew to it."""

    params: PointingParams

    @abstractmethod
    def choose(self, view: _View) -> NDArray[np.int64]:
        """Drone index per receiver ``(N, n)``."""

    def assign(self, observation: NDArray[Any]) -> NDArray[np.int64]:
        """The drone each receiver is sent to, ``(n,)`` or ``(n_envs, n)``."""
        obs, single = as_batch(observation, self.params.obs_dim)
        choice = self.choose(_view(self.params, obs))
        return choice[0] if single else choice

    def act(self, obs: FloatArray) -> FloatArray:
        """Actions ``(N, action size)`` for observations ``(N, obs_dim)``."""
        view = _view(self.params, obs)
        return _slew_to(self.params, view, self.choose(view))


@dataclass(frozen=True)
class HoldStill(MemorylessRule):
    """Never slew: the receivers keep their starting directions (the baseline to beat)."""

    params: PointingParams = field(default_factory=PointingParams)
    """Env settings (observation layout, action size)."""

    def act(self, obs: FloatArray) -> FloatArray:
        """Actions ``(N, action size)`` for observations ``(N, obs_dim)``."""
        return np.zeros((obs.shape[0], 2 * self.params.n_receivers))


@dataclass(frozen=True)
class TrackNearest(_AssignAndSlew):
    """Each receiver slews to the drone whose predicted position is nearest to it (the naive
    rule OC-1 improves on: nearby receivers end up on one drone with near-parallel sight lines)."""

    params: PointingParams = field(default_factory=PointingParams)
    """Env settings (receiver layout, slew limit, observation layout)."""

    def choose(self, view: _View) -> NDArray[np.int64]:
        """Drone index per receiver ``(N, n)``."""
        return np.argmin(view.ranges, axis=-1)


@dataclass(frozen=True)
class OrthogonalPairs(_AssignAndSlew):
    """Assign receivers to drones so that each drone's lines of sight are closest to orthogonal
    (theory §10.1 OC-1): minimise ``Σ_j ln score_j`` with ``score_j = σ / √(Σ_{k∈S_j} sin²γ_k)``,
    ``γ_k`` the angle between receiver ``k``'s line of sight and the reference receiver's
    (the member of ``S_j`` that gives the best score); fewer than two receivers: infinite.

    The papers' score ignores ranges (their i.i.d. conjugation-error model); it ranks the
    geometry of the crossing only.
    """

    params: PointingParams = field(default_factory=PointingParams)
    """Env settings (receiver layout, slew limit, observation layout)."""
    keep_bonus: float = 0.05
    """Objective bonus per receiver left on a drone it sees (hysteresis against flapping)."""

    def choose(self, view: _View) -> NDArray[np.int64]:
        """Drone index per receiver ``(N, n)``."""
        cand = _assignments(self.params)  # (C, n)
        objective = np.empty((view.los.shape[0], cand.shape[0]))
        # Σ_j ½ ln max_{k∈S_j} Σ_{l∈S_j} sin²γ_kl, compiled
        kernels.assignment_orthogonality_batch(view.los, cand, objective)
        objective += _keep_bonus(view, cand, self.keep_bonus)
        return cand[np.argmax(objective, axis=-1)]


@dataclass(frozen=True)
class GreedyPointing(_AssignAndSlew):
    """Choose the assignment that maximises ``Σ_j ln det I_j`` of the position information the
    assigned receivers would give at the predicted positions (one-step D-optimal sensor
    selection, theory §10.1–10.2 OC-1/OC-2): ``I_j = Σ_{k∈S_j} (I − u_k u_kᵀ)/(σ_ang² r_k²)``.

    A drone given fewer than two receivers gets no fix (its ``I_j`` is singular, and the env's
    reward for it is ``−R``); it scores ``−no_fix_cost`` instead of ``−∞``, so that when there
    are too few receivers for all drones the rule still fixes as many as it can. Unlike
    :class:`OrthogonalPairs` the score counts ranges (the angle-noise model of the reward).
    """

    params: PointingParams = field(default_factory=PointingParams)
    """Env settings (receiver layout, noise, slew limit, observation layout)."""
    keep_bonus: float = 0.05
    """Objective bonus per receiver left on a drone it sees (hysteresis against flapping)."""
    no_fix_cost: float = 1e3
    """Score of a drone left without a pair of receivers (ln det units)."""

    def choose(self, view: _View) -> NDArray[np.int64]:
        """Drone index per receiver ``(N, n)``."""
        cand = _assignments(self.params)
        objective = np.empty((view.los.shape[0], cand.shape[0]))
        # Σ_j ln det I_j of the receivers each candidate assigns to drone j, compiled
        kernels.assignment_log_det_batch(
            view.los,
            view.ranges,
            max(self.params.sigma_ang, 1e-9),
            cand,
            float(self.no_fix_cost),
            objective,
        )
        objective += _keep_bonus(view, cand, self.keep_bonus)
        return cand[np.argmax(objective, axis=-1)]
