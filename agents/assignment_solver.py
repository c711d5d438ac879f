"""Solvers of the receiver-to-drone assignment problems the pointing rules pose.

An assignment ``a`` sends each of ``n`` receivers to one of ``m`` drones. The rules' objectives
are separable over drones, ``F(a) = Σ_j V_j(S_j)`` with ``S_j = {k : a_k = j}``, plus a bonus
``Σ_k β[k, a_k]`` per receiver (hysteresis). Two ways to maximise ``F``:

* **exhaustive**: score every one of the ``m^n`` assignments (:func:`assignments`) and take the
  best — exact, refused above ``MAX_ASSIGNMENTS``;
* **greedy**, polynomial: a start from :func:`sequential_greedy`, then :func:`improve`,
  coordinate-wise ascent: re-assign one receiver at a time, the move that raises ``F`` most,
  while ``F`` rises. The result is a local optimum — no single receiver can move to a better
  drone — never above the exhaustive optimum. Each step costs ``O(n m)`` drone scores at the
  start and ``O(n)`` per move (only the two drones a move touches are re-scored).

Sequential greedy (the *locally greedy* heuristic of Fisher, Nemhauser & Wolsey 1978) takes
the receivers in order and gives each the drone of largest marginal value given those before
it. Assigning each receiver to one drone is a partition-matroid constraint on the
(receiver, drone) pairs; for a normalised, monotone, submodular ``F`` — such as the
information gain ``Σ_j ln det(λ_j I + I_j(S_j)) − ln det(λ_j I)`` over a regular prior
``λ_j I`` (:data:`~sensorgym.trackers.stereo.kernels.GAIN`) — its value is at least half the
optimum. (The ``1 − 1/e`` bound is that of a cardinality constraint, choosing any ``K``
pairs, not of an assignment.) The rules' own objectives are not submodular: a drone seen by
one receiver has no fix, and its value jumps only with the second; the ascent from the greedy
start fixes what it can (a lone receiver joins another to make a pair).

``solver`` (a field of every assignment rule): ``"auto"`` is exhaustive up to
``MAX_ASSIGNMENTS`` candidates and greedy beyond, ``"exhaustive"`` always (refused above),
``"greedy"`` always (to compare with the exhaustive one at small sizes).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from sensorgym.envs.shells.rows import run_rows
from sensorgym.trackers.kernel_args import kernel_array
from sensorgym.trackers.stereo import kernels

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

#: the exhaustive solver refuses layouts with more candidate assignments than this
MAX_ASSIGNMENTS = 4096
#: the solvers of the assignment rules' ``solver`` field
SOLVERS = ("auto", "exhaustive", "greedy")
#: a move is made only if it raises the objective by more than this (round-off of the
#: marginals must not make receivers cycle)
MIN_RISE = 1e-9


def check_solver(solver: str) -> None:
    """``ValueError`` unless ``solver`` is one of :data:`SOLVERS`."""
    if solver not in SOLVERS:
        raise ValueError(f"solver: expected one of {SOLVERS}, got {solver!r}")


def exhaustive(solver: str, n: int, m: int, auto_limit: int = MAX_ASSIGNMENTS) -> bool:
    """Whether ``solver`` searches all ``m^n`` assignments of ``n`` receivers to ``m`` drones
    (``"auto"``: when there are at most ``auto_limit``, by default ``MAX_ASSIGNMENTS``; a rule
    whose every candidate costs much passes a lower one)."""
    check_solver(solver)
    return solver == "exhaustive" or (solver == "auto" and m**n <= min(auto_limit, MAX_ASSIGNMENTS))


def assignments(n: int, m: int) -> IntArray:
    """Every map of the ``n`` receivers to the ``m`` drones, ``(m^n, n)``, in lexicographic
    order; ``ValueError`` above ``MAX_ASSIGNMENTS``."""
    if m**n > MAX_ASSIGNMENTS:
        raise ValueError(
            f"params: {m}^{n} receiver-to-drone assignments exceed {MAX_ASSIGNMENTS}"
            " (use solver='greedy' or 'auto')"
        )
    return np.array(list(itertools.product(range(m), repeat=n)), dtype=np.int64)


@dataclass(frozen=True)
class SeparableObjective:
    """``F(a) = Σ_j V_j(S_j)`` of a batch of ``B`` scenarios, ``V_j`` the compiled
    :func:`~sensorgym.trackers.stereo.kernels.drone_score` of ``kind`` summed over ``S``
    steps (one for the one-step rules, the planning grid for the planners)."""

    kind: int
    """:data:`~sensorgym.trackers.stereo.kernels.LOG_DET`, ``GAIN``, ``REWARD`` or
    ``ORTHOGONALITY``."""
    u: FloatArray
    """(B, S, n, m, 3) unit lines of sight from the receivers to the drones on each step."""
    w: FloatArray
    """(B, S, n, m) information weights ``1/(σ r)²`` (unused by ORTHOGONALITY)."""
    ready: NDArray[np.bool_]
    """(B, S, n, m) whether receiver ``k`` counts for drone ``j`` on step ``s``."""
    prior: FloatArray
    """(B, m) prior information ``λ_j`` per drone (GAIN; 0 for the others)."""
    weight: FloatArray
    """(B, S) weight of each step."""
    consts: FloatArray
    """``(no_fix,)`` for LOG_DET, ``(σ_ref, R)`` for REWARD."""

    @property
    def shape(self) -> tuple[int, int, int]:
        """``(B, n, m)``: scenarios, receivers, drones."""
        B, _, n, m = self.w.shape
        return B, n, m

    @property
    def arrays(self) -> tuple:
        """The objective as the compiled kernels take it: ``(kind, u, w, ready, prior,
        weight, consts)``, C-contiguous."""
        fields = (self.u, self.w, self.ready, self.prior, self.weight, self.consts)
        return (self.kind, *(np.ascontiguousarray(a) for a in fields))

    def marginals(
        self, assign: IntArray, scenarios: IntArray, rows: IntArray, cols: IntArray
    ) -> FloatArray:
        """``(len(scenarios), len(rows), cols.shape[1])`` marginal values ``V_j(S ∪ {k}) −
        V_j(S)`` of receivers ``rows`` on drones ``cols`` (per row of ``scenarios``), ``S``
        drone ``j``'s receivers other than ``k`` under ``assign (len(scenarios), n)``
        (:func:`~sensorgym.trackers.stereo.kernels.assignment_marginals_batch`)."""
        out = np.empty((len(scenarios), len(rows), cols.shape[1]))
        a = np.ascontiguousarray(assign, dtype=np.int64)
        b = np.ascontiguousarray(scenarios, dtype=np.int64)
        k = np.ascontiguousarray(rows, dtype=np.int64)
        j = np.ascontiguousarray(cols, dtype=np.int64)
        data = self.arrays
        # rows of the batch split over threads (the kernel releases the GIL)
        run_rows(
            len(b),
            lambda lo, hi: kernels.assignment_marginals_batch(
                *data, a[lo:hi], b[lo:hi], k, j[lo:hi], out[lo:hi]
            ),
        )
        return out

    def gains(self, assign: IntArray, scenarios: IntArray | None = None) -> FloatArray:
        """``F(a) − F(∅)`` ``(len(scenarios),)`` of full assignments ``assign`` (one per row of
        ``scenarios``, default every scenario): the marginals of the receivers added one by
        one (they telescope)."""
        n = self.shape[1]
        rows = np.arange(len(assign)) if scenarios is None else np.asarray(scenarios)
        partial = np.full_like(assign, -1)
        total = np.zeros(len(assign))
        for k in range(n):
            value = self.marginals(partial, rows, np.array([k]), assign[:, k : k + 1])
            total += value[:, 0, 0]
            partial[:, k] = assign[:, k]
        return total


def _bonus(objective: SeparableObjective, bonus: FloatArray | None) -> FloatArray:
    """``bonus (B, n, m)`` as the kernels take it (zeros for none)."""
    if bonus is None:
        return np.zeros(objective.shape)
    return kernel_array(bonus, objective.shape)


def sequential_greedy(
    objective: SeparableObjective,
    bonus: FloatArray | None = None,
    start: IntArray | None = None,
) -> IntArray:
    """The locally greedy assignment ``(B, n)``: receivers in index order, each to the drone of
    largest marginal value (plus ``bonus (B, n, m)``) given the receivers assigned before it;
    ties go to the lowest drone index. Receivers with a drone in ``start (B, n)`` keep it (−1:
    to assign; default all). At most ``n m`` drone scores per scenario (compiled:
    :func:`~sensorgym.trackers.stereo.kernels.assignment_greedy_batch`)."""
    B, n, _ = objective.shape
    assign = np.full((B, n), -1, dtype=np.int64)
    if start is not None:
        assign[:] = start
    data, beta = objective.arrays, _bonus(objective, bonus)
    run_rows(B, lambda lo, hi: kernels.assignment_greedy_batch(*data, beta, lo, hi, assign))
    return assign


def _ascend(
    objective: SeparableObjective,
    starts: list[IntArray],
    bonus: FloatArray | None,
    max_moves: int | None,
) -> IntArray:
    """The compiled ascent of :func:`improve` from every start, the best end per scenario
    (:func:`~sensorgym.trackers.stereo.kernels.assignment_ascent_batch`)."""
    B, n, m = objective.shape
    first = np.stack([np.asarray(s, dtype=np.int64) for s in starts])  # (T, B, n)
    moves = n * m if max_moves is None else int(max_moves)
    data, beta = objective.arrays, _bonus(objective, bonus)
    out = np.empty((B, n), dtype=np.int64)
    run_rows(
        B,
        lambda lo, hi: kernels.assignment_ascent_batch(
            *data, first, beta, moves, MIN_RISE, lo, hi, out
        ),
    )
    return out


def improve(
    objective: SeparableObjective,
    start: IntArray,
    bonus: FloatArray | None = None,
    max_moves: int | None = None,
) -> IntArray:
    """Coordinate-wise ascent of ``F(a) + Σ_k bonus[k, a_k]`` from ``start (B, n)``: in every
    scenario, while some receiver can move to another drone and raise the objective by more
    than ``MIN_RISE``, make the move that raises it most (the first, receiver-major, on
    ties). Every move raises the objective, so no assignment repeats; ``max_moves`` (default
    ``n · m``) bounds the moves per scenario. Returns a local optimum ``(B, n)`` (unless
    stopped by ``max_moves``). One compiled pass per scenario
    (:func:`~sensorgym.trackers.stereo.kernels.assignment_ascent_batch`): the marginals of
    every receiver on every drone once, then only the two drones a move touches."""
    return _ascend(objective, [start], bonus, max_moves)


def best_of(
    objective: SeparableObjective, starts: list[IntArray], bonus: FloatArray | None = None
) -> IntArray:
    """:func:`improve` from each of ``starts``; per scenario the result of the highest
    objective ``F(a)`` (plus bonus), the first on ties (within ``MIN_RISE`` per start). The
    ascents of one scenario share the drones' scores: a drone's receiver set met by an
    earlier ascent is not scored again."""
    return _ascend(objective, starts, bonus, None)
