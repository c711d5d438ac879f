"""Heuristic placement rules for ``sensorgym/StereoPlacement-v0`` (theory §10.1 OC-1, §10.3 OC-3).

Each rule reads only the observation (own positions and the conjugation tracker's estimate,
see :func:`sensorgym.envs.stereo_placement.simulation.observe`) plus the env's params (speed limit,
permitted disc, noise), and implements SB3's ``predict``, so
``stable_baselines3.common.evaluation.evaluate_policy`` scores it like a trained model.
"""

from __future__ import annotations

import functools
import itertools
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sensorgym.agents.protocol import MemorylessRule, as_batch
from sensorgym.envs.stereo_placement import kernels
from sensorgym.envs.stereo_placement.simulation import PlacementParams, split_observation

FloatArray = NDArray[np.float64]

#: GreedyPlacement refuses layouts with more joint candidate moves than this
MAX_CANDIDATES = 10_000


def _drive_to(params: PlacementParams, receivers: FloatArray, goal: FloatArray) -> FloatArray:
    """Normalised actions ``(N, 2n)`` driving receivers ``(N, n, 3)`` straight at ``goal``
    ``(N, n, 3)``: full speed when farther than one period's drive, else exactly onto it."""
    d = (goal - receivers)[..., [0, 2]] / (params.max_speed * params.period)
    norm = np.linalg.norm(d, axis=-1, keepdims=True)
    return (d / np.maximum(norm, 1.0)).reshape(d.shape[0], -1)


@dataclass(frozen=True)
class HoldPosition(MemorylessRule):
    """Never drive: the receivers stay clustered where they start (the baseline to beat)."""

    params: PlacementParams = field(default_factory=PlacementParams)
    """Env settings (observation layout, action size)."""

    def act(self, obs: FloatArray) -> FloatArray:
        """Actions ``(N, action size)`` for observations ``(N, obs_dim)``."""
        return np.zeros((obs.shape[0], 2 * self.params.n_receivers))


@dataclass(frozen=True)
class CirclePlacement(MemorylessRule):
    """Drive the receivers onto a circle around the estimated drone's ground point, spaced
    ``360°/n`` apart, of radius ``ρ = √2 ĥ`` with ``ĥ`` the estimated altitude (theory §10.3 OC-3
    "on a circle, not clustered", OC-1 "near-orthogonal lines of sight").

    Why ``√2 ĥ``: from ``n = 3`` receivers at 120° on a circle of radius ``ρ`` the lines of
    sight to a point at height ``h`` above its centre meet at ``cos γ = (h² − ρ²/2)/(h² + ρ²)``,
    zero — all three mutually orthogonal — at ``ρ = √2 h``. That maximises
    ``|det[a_1, P_2 a_2, P_3 a_3]|`` (= 1), the conditioning of the velocity-aware conjugation
    (OC-3: non-coplanar lines of sight). The angle-noise CRLB alone, at fixed altitude, would
    prefer a smaller circle, ``ρ ≈ 0.69 h`` (ranges shrink faster than the angles degrade,
    OC-1's fixed-baseline caveat; ``σ_pos`` 23 % lower there): :class:`GreedyPlacement`
    follows the bound instead. The circle leads the drone by one period of its estimated
    velocity; the slot assignment (which receiver goes where, and the circle's phase) is the
    one that minimises the longest drive; slots outside the permitted disc are pulled inside.
    """

    params: PlacementParams = field(default_factory=PlacementParams)
    """Env settings (speed limit, permitted disc, observation layout)."""
    radius_factor: float = float(np.sqrt(2.0))
    """``ρ / ĥ``; √2 gives mutually orthogonal lines of sight for n = 3."""

    @functools.cached_property
    def _perms(self) -> NDArray[np.int64]:
        """Every assignment of receivers to slots ``(n!, n)``: the slot of receiver ``k``."""
        return np.array(list(itertools.permutations(range(self.params.n_receivers))))

    def targets(self, observation: NDArray[Any]) -> FloatArray:
        """The slot ``(N, n, 3)`` each receiver is driven to (the search is compiled:
        :func:`sensorgym.envs.stereo_placement.kernels.circle_search`)."""
        obs, _ = as_batch(observation, self.params.obs_dim)
        view = split_observation(self.params, obs)
        o, p, v = view["receivers"], view["position"], view["velocity"]
        centre = p + self.params.period * v
        centre[:, 1] = 0.0
        rho = self.radius_factor * np.maximum(p[:, 1], 1.0)  # (N,)
        goal = np.empty_like(o)
        kernels.circle_search(o, centre, rho, self._perms, self.params.arena_radius, 1.0, goal)
        return goal

    def act(self, obs: FloatArray) -> FloatArray:
        """Actions ``(N, action size)`` for observations ``(N, obs_dim)``."""
        view = split_observation(self.params, obs)
        return _drive_to(self.params, view["receivers"], self.targets(obs))


@dataclass(frozen=True)
class GreedyPlacement(MemorylessRule):
    """Move every receiver by the one-step candidate (stay, or full speed in one of
    ``headings`` directions) whose joint placement maximises ``ln det I`` of the predicted
    position information at the estimated drone position one period ahead,
    ``I = Σ_k (I − u_k u_kᵀ)/(σ_ang² r_k²)`` (one-step D-optimal placement, theory §10.1 OC-1)."""

    params: PlacementParams = field(default_factory=PlacementParams)
    """Env settings (speed limit, permitted disc, observation layout)."""
    headings: int = 8
    """Number of full-speed headings per receiver (plus standing still)."""

    def __post_init__(self) -> None:
        if self.headings < 1:
            raise ValueError(f"headings: need at least 1, got {self.headings}")
        if (self.headings + 1) ** self.params.n_receivers > MAX_CANDIDATES:
            raise ValueError(f"headings: (headings + 1)^n exceeds {MAX_CANDIDATES} candidates")

    @property
    def moves(self) -> FloatArray:
        """Normalised per-receiver moves ``(headings + 1, 2)``: standing still first."""
        angle = 2.0 * np.pi * np.arange(self.headings) / self.headings
        return np.concatenate([np.zeros((1, 2)), np.stack([np.sin(angle), np.cos(angle)], -1)])

    @functools.cached_property
    def _candidates(self) -> tuple[FloatArray, NDArray[np.int64], FloatArray]:
        """``(shifts (M, 3), joint (C, n), actions (C, 2n))``: each move's displacement over one
        period, the joint candidates as move indices, and their normalised actions."""
        moves = self.moves
        joint = np.array(list(itertools.product(range(len(moves)), repeat=self.params.n_receivers)))
        step = self.params.max_speed * self.params.period * moves
        shifts = np.stack([step[:, 0], np.zeros(len(moves)), step[:, 1]], -1)
        return shifts, joint, moves[joint].reshape(len(joint), -1)

    def act(self, obs: FloatArray) -> FloatArray:
        """Actions ``(N, action size)`` for observations ``(N, obs_dim)`` (the search is
        compiled: :func:`sensorgym.envs.stereo_placement.kernels.greedy_search`)."""
        view = split_observation(self.params, obs)
        o, p, v = view["receivers"], view["position"], view["velocity"]
        shifts, joint, actions = self._candidates
        target = p + self.params.period * v
        best = np.empty(obs.shape[0], np.int64)
        kernels.greedy_search(o, target, shifts, joint, self.params.arena_radius, best)
        return actions[best]
