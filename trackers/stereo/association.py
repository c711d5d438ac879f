"""Grouping, gating, beam and final selection shared by every stereo tracker (theory §5).

Papers 000 and 003 detect objects the same way: candidates (pairs or triples of direction
vectors, one per receiver) are formed each period; groups of candidates across periods are
grown by attaching the candidates whose index passes a gate; groups are kept sorted by their
cumulative index; after the last period the groups with the smallest index that share (almost)
no direction vectors are selected, and their number is the estimate m̂ (theory §13.7).
This module holds that machinery once; the trackers only compute their indices.

Members. A group's members are stored as an integer array ``(N, S)``: for every period and
every *slot* (a receiver), the index of the fix it uses in that receiver's list, −1 where it
has none (a missed period, or a period before the group was born). Two groups share a vector
when they use the same fix of the same receiver in the same period.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from numpy.typing import NDArray
from scipy.stats import chi2

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


def combinations(counts: Sequence[int]) -> IntArray:
    """All index tuples ``(j_1, …, j_n)``, ``j_k < counts[k]``, as a ``(Π counts, n)`` array.

    Lexicographic order (the last receiver's index varies fastest); empty when any count is 0.
    """
    counts = [int(c) for c in counts]
    if any(c < 0 for c in counts):
        raise ValueError(f"counts: must be non-negative, got {counts}")
    if not counts:
        return np.zeros((1, 0), dtype=np.int64)
    grids = np.meshgrid(*[np.arange(c) for c in counts], indexing="ij")
    return np.stack([g.reshape(-1) for g in grids], axis=-1).astype(np.int64)


def norm_quantile(sigma: float, probability: float = 0.999, dof: int = 3) -> float:
    """``q`` with ``P(‖x‖ ≤ q) = probability`` for ``x ~ N(0, σ² I_dof)`` (chi quantile × σ).

    The 99.9 % point for 3-D is 4.03 σ (theory §13.6).
    """
    if not (sigma >= 0.0 and 0.0 < probability < 1.0 and dof >= 1):
        raise ValueError("norm_quantile: need sigma >= 0, 0 < probability < 1, dof >= 1")
    return float(sigma * np.sqrt(chi2.ppf(probability, dof)))


def extend(
    parent_score: FloatArray,
    step_cost: FloatArray,
    threshold: float = np.inf,
    beam: int | None = None,
) -> tuple[IntArray, IntArray, FloatArray]:
    """Attach candidates to groups: gate the step cost, sort by cumulative score, keep a beam.

    ``parent_score (G,)`` cumulative indices of the existing groups; ``step_cost (G, C)`` the
    index of attaching candidate ``c`` to group ``g`` (``inf`` or NaN = impossible). A pair is
    accepted when ``step_cost ≤ threshold`` (000 ``ΔJ ≤ δ``; 003 ``J_kj ≤ α_i``). The accepted
    extensions are returned as ``(parent, candidate, score)`` sorted by the new cumulative
    score ``I = I_parent + J`` (ties by parent, then candidate), truncated to ``beam`` groups
    (003's G_max remark; None keeps all).
    """
    step_cost = np.asarray(step_cost, dtype=np.float64)
    parent_score = np.asarray(parent_score, dtype=np.float64)
    if step_cost.ndim != 2 or parent_score.shape != step_cost.shape[:1]:
        raise ValueError(
            f"step_cost/parent_score: expected (G, C) and (G,), got {step_cost.shape}, "
            f"{parent_score.shape}"
        )
    ok = step_cost <= threshold  # NaN and inf fail the gate
    g, c = np.nonzero(ok)
    score = parent_score[g] + step_cost[g, c]
    if beam is not None and score.shape[0] > beam:
        keep = np.argpartition(score, beam - 1)[:beam]
        g, c, score = g[keep], c[keep], score[keep]
    order = np.lexsort((c, g, score))
    return g[order].astype(np.int64), c[order].astype(np.int64), score[order]


def prune(score: FloatArray, beam: int | None) -> IntArray:
    """Indices of the ``beam`` smallest scores, ascending (all when ``beam`` is None)."""
    score = np.asarray(score, dtype=np.float64)
    order = np.argsort(score, kind="stable")
    return order if beam is None else order[:beam]


def shared_vectors(members: IntArray) -> IntArray:
    """``(G, G)`` number of vectors two groups share (members ``(G, N, S)``, −1 = none)."""
    members = np.asarray(members)
    if members.ndim != 3:
        raise ValueError(f"members: expected shape (G, N, S), got {members.shape}")
    flat = members.reshape(members.shape[0], -1)
    same = (flat[:, None, :] == flat[None, :, :]) & (flat[:, None, :] >= 0)
    return same.sum(axis=-1)


def select(
    members: IntArray,
    score: FloatArray,
    max_shared: int = 0,
    eligible: NDArray[np.bool_] | None = None,
    max_objects: int | None = None,
) -> IntArray:
    """Greedy final selection (000 temporal step 5, 003 step 5, theory §13.7).

    Walk the groups in ascending ``score``; accept a group when it shares at most
    ``max_shared`` vectors (the papers' π) with **every** group accepted so far. Groups with
    ``eligible`` False (e.g. unconfirmed, or index above a cap) are skipped. Returns the indices
    of the accepted groups in acceptance order; their number is m̂.
    """
    members = np.asarray(members)
    score = np.asarray(score, dtype=np.float64)
    if members.ndim != 3 or score.shape != members.shape[:1]:
        raise ValueError(
            f"members/score: expected (G, N, S) and (G,), got {members.shape}, {score.shape}"
        )
    if max_shared < 0:
        raise ValueError("max_shared: must be non-negative")
    if eligible is None:
        eligible = np.ones(score.shape, dtype=bool)
    idx = np.flatnonzero(eligible & np.isfinite(score))
    idx = idx[np.argsort(score[idx], kind="stable")]
    flat = members[idx].reshape(idx.size, members.shape[1] * members.shape[2])
    accepted: list[int] = []
    blocked = np.zeros(idx.size, dtype=bool)
    while max_objects is None or len(accepted) < max_objects:
        free = np.flatnonzero(~blocked)
        if free.size == 0:
            break
        pos = int(free[0])
        accepted.append(pos)
        blocked[pos] = True
        # a group conflicts with the accepted one when it shares more than π vectors
        shared = np.sum((flat == flat[pos]) & (flat >= 0), axis=1)
        blocked |= shared > max_shared
    return idx[np.asarray(accepted, dtype=np.int64)]


def extrapolation_residual(
    M: FloatArray, V: FloatArray, t_ref: FloatArray, positions: FloatArray, times: FloatArray
) -> FloatArray:
    """``ΔJ (G, J)``: distance of each new candidate from each group's straight-line prediction.

    ``M̂^Э = M̂_s + V̂_s (t(i, j) − t_s)``, ``ΔJ = ‖M(i, j) − M̂^Э‖`` (000 temporal steps 3–4);
    ``M, V (G, 3)`` and ``t_ref (G,)`` per group, ``positions (J, 3)`` and ``times (J,)`` per
    candidate.
    """
    dt = times[None, :] - t_ref[:, None]
    pred = M[:, None, :] + V[:, None, :] * dt[..., None]
    return np.linalg.norm(positions[None, :, :] - pred, axis=-1)


def match_tracks(distance: FloatArray, gate: float) -> IntArray:
    """Identify simulated and found objects by proximity (000 "Pr_m", theory §5.6, gap §13.15).

    ``distance (m, K)``: distance between true object ``i`` and estimate ``k`` at the same
    instant. Greedy nearest pairs (globally smallest distance first), one-to-one, only within
    ``gate`` metres. Returns ``(m,)``: the estimate matched to each true object, −1 = none.
    """
    d = np.asarray(distance, dtype=np.float64)
    if d.ndim != 2:
        raise ValueError(f"distance: expected shape (m, K), got {d.shape}")
    assign = np.full(d.shape[0], -1, dtype=np.int64)
    used = np.zeros(d.shape[1], dtype=bool)
    for flat in np.argsort(d, axis=None, kind="stable"):
        i, k = np.unravel_index(flat, d.shape)
        if not d[i, k] <= gate:
            break
        if assign[i] < 0 and not used[k]:
            assign[i], used[k] = k, True
    return assign


class Fixes(Protocol):
    """One receiver's report for one period, as the trackers read it (see ``sensorgym.envs.worlds.stereo``)."""

    directions: FloatArray
    """(m_k, 3) unit direction vectors in the receiver's own frame."""
    times: FloatArray
    """(m_k,) formation times, s."""
    powers: FloatArray
    """(m_k,) normalised received powers."""


@dataclass(frozen=True)
class Detection:
    """Objects found by a stereo tracker: m̂ selected groups and their per-period estimates."""

    members: IntArray = field(repr=False)
    """(m̂, N, S) fix index per period and receiver slot of every selected group, −1 = none."""
    score: FloatArray = field(repr=False)
    """(m̂,) cumulative index of each selected group (ascending)."""
    positions: FloatArray = field(repr=False)
    """(m̂, N, 3) position estimates in frame 1 per period, m (NaN where the group has none)."""
    velocities: FloatArray = field(repr=False)
    """(m̂, N, 3) velocity estimates in frame 1 per period, m/s (NaN where unknown)."""
    times: FloatArray = field(repr=False)
    """(m̂, N) time each position estimate refers to, s (NaN where none)."""
    groups_kept: int = 0
    """Number of groups alive after the last period (before selection)."""

    @property
    def m_hat(self) -> int:
        """Estimated number of objects m̂."""
        return int(self.score.shape[0])

    @classmethod
    def select_from(
        cls,
        members: IntArray,
        score: FloatArray,
        positions: FloatArray,
        velocities: FloatArray,
        times: FloatArray,
        max_shared: int,
        eligible: NDArray[np.bool_] | None = None,
    ) -> Detection:
        """The groups :func:`select` accepts out of all alive groups, as a detection."""
        chosen = select(members, score, max_shared, eligible)
        return cls(
            members[chosen],
            score[chosen],
            positions[chosen],
            velocities[chosen],
            times[chosen],
            groups_kept=int(score.shape[0]),
        )

    def latest(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        """``(position (m̂, 3), velocity (m̂, 3), time (m̂,))`` of each group's latest estimate."""
        have = np.isfinite(self.times)
        last = self.times.shape[1] - 1 - np.argmax(have[:, ::-1], axis=1)
        rows = np.arange(self.m_hat)
        return self.positions[rows, last], self.velocities[rows, last], self.times[rows, last]


def per_period(value: FloatArray, i: int, static_ndim: int) -> FloatArray:
    """Period ``i``'s receiver pose: ``value`` is static (``static_ndim`` dims) or has one more,
    leading axis over periods (receivers moved or re-pointed between periods)."""
    if value.ndim == static_ndim + 1:
        return value[i]
    if value.ndim != static_ndim:
        raise ValueError(
            f"pose: expected {static_ndim} dims or a leading period axis, got {value.shape}"
        )
    return value
