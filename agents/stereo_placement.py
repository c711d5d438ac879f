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

#: GreedyPlacement's exhaustive search takes layouts with at most this many joint candidate
#: moves (a reference for the coordinate-wise search at small sizes)
MAX_CANDIDATES = 10_000

#: ``solver="auto"`` searches exhaustively up to this many joint moves, coordinate-wise beyond:
#: the 729 of the registered 3 receivers at 8 headings; the 6561 of 4 receivers take longer
#: than the 1 ms a decision may take, the coordinate-wise search far less (decision times:
#: ``benchmarks/results/scaling.json``, the scaling table of README.md)
AUTO_EXHAUSTIVE = 1_000

#: CirclePlacement tries every assignment of receivers to slots up to this many receivers
#: (``n!`` of them); beyond, the rotations of the receivers' order around the circle
MAX_PERMUTED = 6

#: the joint-move searches of GreedyPlacement
SOLVERS = ("auto", "exhaustive", "coordinate")


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
    one that minimises the longest drive — over every assignment up to ``MAX_PERMUTED``
    receivers, beyond over the ``n`` rotations of the receivers' own order of bearing around
    the centre (``n!`` assignments would not fit: 40320 at n = 8); slots outside the
    permitted disc are pulled inside.
    """

    params: PlacementParams = field(default_factory=PlacementParams)
    """Env settings (speed limit, permitted disc, observation layout)."""
    radius_factor: float = float(np.sqrt(2.0))
    """``ρ / ĥ``; √2 gives mutually orthogonal lines of sight for n = 3."""

    @functools.cached_property
    def _perms(self) -> NDArray[np.int64]:
        """Every assignment of receivers to slots ``(n!, n)``: the slot of receiver ``k``
        (none beyond ``MAX_PERMUTED`` receivers: the search then rotates their order)."""
        n = self.params.n_receivers
        if n > MAX_PERMUTED:
            return np.zeros((0, n), np.int64)
        return np.array(list(itertools.permutations(range(n))))

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
        cyclic = self.params.n_receivers > MAX_PERMUTED
        kernels.circle_search(
            o, centre, rho, self._perms, self.params.arena_radius, 1.0, goal, cyclic
        )
        return goal

    def act(self, obs: FloatArray) -> FloatArray:
        """Actions ``(N, action size)`` for observations ``(N, obs_dim)``."""
        view = split_observation(self.params, obs)
        return _drive_to(self.params, view["receivers"], self.targets(obs))


@dataclass(frozen=True)
class GreedyPlacement(MemorylessRule):
    """Move every receiver by the candidate (stay, or full speed in one of ``headings``
    directions) whose joint placement maximises the env's own reward predicted from the
    estimate: ``clip(ln(σ_ref/σ_pos), −R, R)`` with ``σ_pos = σ_ang √tr I⁻¹``,
    ``I = Σ_k (I − u_k u_kᵀ)/r_k²`` (theory §10.1 OC-1) of the lines of sight from the
    receivers at the end of their moves to the estimated drone one period ahead, ``p̂ + τ v̂``.
    (Until issue 13 it maximised ``ln det I`` instead, D-optimal where the reward is
    A-optimal, and scored lower.)

    ``horizon = 1`` is the one-step greedy rule; ``horizon = H > 1`` scores the sum of the
    next ``H`` periods' rewards with every receiver keeping its move (an open-loop lookahead
    over straight drives: it sees that the drone flies on, the one-step rule does not; on the
    tracker's noisy estimate it scores no better for H = 2–5).

    The search over joint moves (``solver``): ``"exhaustive"`` scores all ``(headings + 1)^n``
    of them (:func:`~sensorgym.envs.stereo_placement.kernels.plan_search`), exponential in the
    number of receivers; ``"coordinate"`` is coordinate-wise improvement
    (:func:`~sensorgym.envs.stereo_placement.kernels.coordinate_search`, the same score):
    start from every receiver's best move with the others standing still, then re-optimise
    one receiver's move at a time, the others fixed, sweeping until no receiver improves or
    after ``max_sweeps`` — ``O(sweeps · n · (headings + 1) · n)`` per scenario, a local optimum
    never worse than its start; ``"auto"`` is exhaustive while ``(headings + 1)^n ≤
    AUTO_EXHAUSTIVE`` (n ≤ 3 at 8 headings: the registered 3 receivers search as before),
    coordinate-wise beyond."""

    params: PlacementParams = field(default_factory=PlacementParams)
    """Env settings (speed limit, permitted disc, delays, noise, reward)."""
    headings: int = 8
    """Number of full-speed headings per receiver (plus standing still)."""
    horizon: int = 1
    """Periods the candidate moves are scored over (1: one-step greedy)."""
    solver: str = "auto"
    """Search over the joint moves: ``"exhaustive"``, ``"coordinate"`` (coordinate-wise
    improvement) or ``"auto"`` (exhaustive up to ``AUTO_EXHAUSTIVE`` joint moves)."""
    max_sweeps: int = 8
    """Coordinate-wise search: most sweeps over the receivers after the start."""

    def __post_init__(self) -> None:
        if self.headings < 1:
            raise ValueError(f"headings: need at least 1, got {self.headings}")
        if self.solver not in SOLVERS:
            raise ValueError(f"solver: must be one of {SOLVERS}, got {self.solver!r}")
        if self.solver == "exhaustive" and self.candidates > MAX_CANDIDATES:
            raise ValueError(
                f"headings: (headings + 1)^n = {self.candidates} exceeds {MAX_CANDIDATES} "
                'candidates for the exhaustive search (solver="coordinate" or "auto" scales)'
            )
        if self.horizon < 1:
            raise ValueError(f"horizon: need at least 1 period, got {self.horizon}")
        if self.max_sweeps < 1:
            raise ValueError(f"max_sweeps: need at least 1, got {self.max_sweeps}")

    @property
    def candidates(self) -> int:
        """Number of joint moves ``(headings + 1)^n``."""
        return (self.headings + 1) ** self.params.n_receivers

    @property
    def exhaustive(self) -> bool:
        """Whether :meth:`plan` scores every joint move (else coordinate-wise)."""
        if self.solver == "auto":
            return self.candidates <= AUTO_EXHAUSTIVE
        return self.solver == "exhaustive"

    @property
    def moves(self) -> FloatArray:
        """Normalised per-receiver moves ``(headings + 1, 2)``: standing still first."""
        angle = 2.0 * np.pi * np.arange(self.headings) / self.headings
        return np.concatenate([np.zeros((1, 2)), np.stack([np.sin(angle), np.cos(angle)], -1)])

    @functools.cached_property
    def _shifts(self) -> FloatArray:
        """Each move's displacement over one period ``(M, 3)``."""
        step = self.params.max_speed * self.params.period * self.moves
        return np.stack([step[:, 0], np.zeros(len(step)), step[:, 1]], -1)

    @functools.cached_property
    def _joint(self) -> NDArray[np.int64]:
        """The exhaustive search's joint candidates ``(C, n)`` as move indices."""
        M = self.headings + 1
        return np.array(list(itertools.product(range(M), repeat=self.params.n_receivers)))

    def search(
        self, receivers: FloatArray, position: FloatArray, velocity: FloatArray, solver: str
    ) -> tuple[NDArray[np.int64], FloatArray, FloatArray]:
        """The joint move of ``solver`` (``"exhaustive"`` or ``"coordinate"``) for receivers
        ``(N, n, 3)`` and a drone at ``position``, ``velocity`` ``(N, 3)``: ``(moves (N, n)``
        indices into :attr:`moves`, ``value (N,)`` its predicted score, ``start (N,)`` the
        score the search started from``)`` (the exhaustive search's start: its optimum). The
        searches are compiled: :func:`~sensorgym.envs.stereo_placement.kernels.plan_search`,
        :func:`~sensorgym.envs.stereo_placement.kernels.coordinate_search`."""
        p = self.params
        N = receivers.shape[0]
        scalars = (p.period, p.sigma_ang, p.sigma_ref, p.reward_clip, p.arena_radius)
        arrays = tuple(np.ascontiguousarray(x, np.float64) for x in (receivers, position, velocity))
        value = np.empty(N)
        if solver == "exhaustive":
            if self.candidates > MAX_CANDIDATES:
                raise ValueError(f"solver: {self.candidates} joint moves exceed {MAX_CANDIDATES}")
            best = np.empty(N, np.int64)
            kernels.plan_search(
                *arrays, self._shifts, self._joint, scalars, self.horizon, best, value
            )
            return self._joint[best], value, value
        if solver != "coordinate":
            raise ValueError(f"solver: must be 'exhaustive' or 'coordinate', got {solver!r}")
        moves, start = np.empty((N, p.n_receivers), np.int64), np.empty(N)
        kernels.coordinate_search(
            *arrays, self._shifts, scalars, self.horizon, self.max_sweeps, moves, value, start
        )
        return moves, value, start

    def plan(self, receivers: FloatArray, position: FloatArray, velocity: FloatArray) -> FloatArray:
        """Actions ``(N, 2n)`` for receivers ``(N, n, 3)`` and a drone at ``position``,
        ``velocity`` ``(N, 3)``: the joint move of the rule's search."""
        solver = "exhaustive" if self.exhaustive else "coordinate"
        moves, _, _ = self.search(receivers, position, velocity, solver)
        return self.moves[moves].reshape(moves.shape[0], -1)

    def act(self, obs: FloatArray) -> FloatArray:
        """Actions ``(N, action size)`` for observations ``(N, obs_dim)``: :meth:`plan` on
        the tracker's estimate."""
        view = split_observation(self.params, obs)
        return self.plan(view["receivers"], view["position"], view["velocity"])


@dataclass(frozen=True)
class TruthGreedyPlacement(GreedyPlacement):
    """:class:`GreedyPlacement` planned on the TRUE drone position and velocity (read from the
    simulator): a truth-informed planner, not a fieldable rule — what knowing the truth buys
    this search, not a bound on the return; the teacher a trained policy imitates before RL
    (it sees only the observation)."""

    state_fn: Any = None
    """Returns the simulator's current state (:class:`PlacementState`)."""

    def act(self, obs: FloatArray) -> FloatArray:
        """Actions ``(N, action size)``: :meth:`plan` on the simulator's truth."""
        state = self.state_fn()
        if state.batch_size != obs.shape[0]:
            raise ValueError(f"observation: batch {obs.shape[0]}, simulator {state.batch_size}")
        return self.plan(state.receivers, state.drone_position, state.drone_velocity)
