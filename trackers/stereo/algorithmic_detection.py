"""Paper 003, algorithmic approach: velocity-aware group track initiation, n = 2 (theory §5.5).

Period 1 (and every birth): each pair ``(a_1k, a_2j)`` is conjugated by least squares (003 eq.
6); ``J_1 = ‖M̂_1k − P_2 M̂_2j − b_2‖ ≤ α_1`` opens a group with index ``I = c_1 J_1``.

Periods i ≥ 2, for every group g and pair (k, j), all at once:

* 2.1 old-range positions ``M̂_1k = R_1(g) a_1k``, ``M̂_2j = R_2(g) a_2j``; velocities (9)
  ``V̂ = (M̂ − M_{i−1}(g))/τ``;
* 2.2 receiver 1's direction moved to ``t_2j``: ``M*_1k = M̂_1k + (t_2j − t_1k) V̂_1k``,
  ``a*_1k = M*/‖M*‖``; the pair ``(a*_1k, a_2j)`` re-conjugated (eq. 6); velocities (9) again
  with the refined positions;
* 2.3 ``J_1 = ‖M̂*_1k − P_2 M̂_2j − b_2‖`` and the proximity index
  ``J_2 = ‖M̂*_1k − M^э_1‖ + ‖M̂_2j − M^э_2‖`` with ``M^э = M_{i−1}(g) + τ V``;
* 3.4 (groups that already have a velocity) ``J_3 = ‖V̂_1 − V_1(g)‖ + ‖V̂_2 − V_2(g)‖``;
* ``J = c_1 J_1 + c_2 J_2 [+ c_3 J_3] ≤ α_i`` attaches the pair: ``I ← I + J``; velocities are
  stored as they come (first estimate) and then recursively averaged (3.5).

Decisions for the gaps (theory §13.28–13.35):

* gap 31 (``J_2 ≡ 0`` when read literally): the extrapolation ``M^э`` uses the velocity of step
  2.1 (before refinement) for a group's first continuation and the stored group velocity
  afterwards;
* gap 32: ``M̂*_1k`` refers to ``t_2j``; it is stored with ``T_1 = t_2j`` and ``τ_1`` of the
  refined velocity is ``t_2j − T_1(g)``;
* gap 34 (misses and births): a group with no accepted continuation records a miss and costs
  ``miss_cost`` (default: the gate α, the worst acceptable index); it is dropped after more
  than ``max_misses`` consecutive misses; pairs not absorbed by any continuation open new
  groups (period-1 operations) whose earlier periods count as misses;
* beam (003 remark): after each period at most ``beam`` (G_max) groups with the smallest
  cumulative index ``I`` are kept (003 ranks by the period index ``J``; we rank by ``I``, the
  quantity the final selection uses);
* selection (step 5): groups confirmed in at least ``min_confirmed`` periods, greedy by ``I``,
  each sharing at most π vectors with every group selected before (:func:`.association.select`).

Normalisers and gates default to the noise level (theory §13.6): ``c_1 = 1/σ_e``,
``c_2 = 1/(2√2 σ_p)``, ``c_3 = τ/(2√2 σ_p)`` put every term in units of its standard deviation,
and ``α_i = gate · (number of terms)``; a group's first continuation normalises ``J_2`` by
:attr:`AlgorithmicParams.c2_first`, which allows for the range change it contains.

Extension (off by default): 003's ``J_2``, ``J_3`` are isotropic norms, but a stereo position is
far less accurate along the line of sight than across it (≈ 20× for a 7.5 m baseline at
100 m). Giving ``sigma_transverse`` weights the across-LOS components by ``σ_p/σ_t``, which
stops cheap switches between objects a few metres apart (docs/reproduction/paper003.md).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sensorgym.trackers.stereo import association as assoc
from sensorgym.trackers.stereo.conjugation import solve_pair
from sensorgym.trackers.validation import check_fields, finite_array

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


@dataclass(frozen=True)
class AlgorithmicParams:
    """Normalisers, gates, beam and miss logic of the algorithmic detector (module docstring)."""

    sigma_e: float = 0.05
    """Std of the conjugation miss distance ``‖e_2‖`` of a true pair, m (≈ r σ_ang)."""
    sigma_position: float = 1.0
    """Std of each coordinate of a pair's position estimate, m (≈ r² σ_ang / baseline)."""
    period: float = 1.0
    """Scan period τ, s."""
    max_speed: float = 10.0
    """Largest plausible object speed, m/s."""
    max_delay: float = 0.1
    """Largest delay between the two receivers' fixes of one object, s."""
    gate: float = 4.0
    """Per-term gate in standard deviations (α_i = gate × number of terms)."""
    beam: int | None = 200
    """G_max: groups kept after each period (None: unbounded)."""
    max_shared: int = 1
    """π: vectors a selected group may share with each other selected group (003: e.g. 1)."""
    max_misses: int = 2
    """Consecutive missed periods after which a group is dropped."""
    min_confirmed: int = 2
    """Periods with a member a group needs to be selected."""
    sigma_transverse: float | None = None
    """Extension, not in 003: std of a position estimate across the line of sight, m. If given,
    J_2 and J_3 weight the components across each receiver's line of sight by
    ``σ_p/σ_transverse`` (a whitened norm: for close receivers the range error is far larger
    than the transverse one). None keeps the paper's isotropic norms."""
    miss_cost_override: float | None = None
    """Index added per missed period if given, else :attr:`alpha`."""

    def __post_init__(self) -> None:
        check_fields(self)  # every field of its annotated type: no bool for a count or a number
        if not (self.sigma_e > 0 and self.sigma_position > 0 and self.period > 0):
            raise ValueError("sigma_e, sigma_position and period must be positive")
        if not (self.max_speed >= 0 and self.max_delay >= 0 and self.gate > 0):
            raise ValueError("max_speed >= 0, max_delay >= 0 and gate > 0 required")
        if self.beam is not None and self.beam < 1:
            raise ValueError("beam: must be >= 1 or None")
        if self.sigma_transverse is not None and not self.sigma_transverse > 0:
            raise ValueError("sigma_transverse: must be positive or None")
        if self.max_shared < 0 or self.max_misses < 0 or self.min_confirmed < 1:
            raise ValueError("max_shared >= 0, max_misses >= 0, min_confirmed >= 1 required")

    @property
    def c(self) -> tuple[float, float, float]:
        """``(c_1, c_2, c_3)``: 1/m, 1/m, s/m (module docstring)."""
        s = 2.0 * np.sqrt(2.0) * self.sigma_position
        return 1.0 / self.sigma_e, 1.0 / s, self.period / s

    @property
    def transverse_gain(self) -> float:
        """``σ_p / σ_transverse`` (1 for the paper's isotropic index)."""
        if self.sigma_transverse is None:
            return 1.0
        return max(self.sigma_position / self.sigma_transverse, 1.0)

    @property
    def c2_first(self) -> float:
        """c_2 of a group's first continuation, 1/m: there ``J_2`` also carries the range change
        over one period (step 2.1 keeps the old range), up to ``2 v_max τ``, so its normaliser
        is ``1/(2√2 σ_p + 2 v_max τ / gate)`` — the largest range change costs at most one gate."""
        return 1.0 / (
            2.0 * np.sqrt(2.0) * self.sigma_position
            + 2.0 * self.max_speed * self.period / self.gate
        )

    @property
    def alpha1(self) -> float:
        """α_1, m: ``gate σ_e + v_max Δt_max`` (noise plus the miss opened by unmodelled motion)."""
        return self.gate * self.sigma_e + self.max_speed * self.max_delay

    @property
    def alpha(self) -> tuple[float, float]:
        """``(α_2, α_3)``: gates of the 2-term (first continuation) and 3-term indices."""
        return 2.0 * self.gate, 3.0 * self.gate

    @property
    def miss_cost(self) -> float:
        """Index added for a missed period."""
        return self.alpha[1] if self.miss_cost_override is None else self.miss_cost_override


@dataclass(frozen=True)
class _Groups:
    """Group arrays of 003's algorithmic approach (theory §5.5; one row per group)."""

    score: FloatArray  # I
    members: IntArray  # (G, N, 2): k_1i, j_2i
    M1: FloatArray  # (G, 3) frame 1
    M2: FloatArray  # (G, 3) frame 2
    R1: FloatArray
    R2: FloatArray
    V1: FloatArray  # (G, 3), NaN before the first continuation
    V2: FloatArray
    T1: FloatArray
    T2: FloatArray
    n_v: IntArray  # number of velocity estimates averaged
    misses: IntArray  # consecutive misses
    confirmed: IntArray  # periods with a member
    hist_M: FloatArray  # (G, N, 3) M_1i per period
    hist_V: FloatArray
    hist_T: FloatArray  # (G, N)

    def take(self, idx: IntArray) -> _Groups:
        return _Groups(*(getattr(self, f)[idx] for f in self.__dataclass_fields__))

    @staticmethod
    def concat(parts: Sequence[_Groups]) -> _Groups:
        return _Groups(
            *(np.concatenate([getattr(p, f) for p in parts]) for f in _Groups.__dataclass_fields__)
        )


def _births(
    f1: assoc.Fixes,
    f2: assoc.Fixes,
    pairs: IntArray,
    P2,
    b2,
    i: int,
    N: int,
    prm: AlgorithmicParams,
) -> _Groups:
    """Operations 1.1–1.3 for the given pairs in period ``i`` (earlier periods count as misses)."""
    a1, a2 = f1.directions[pairs[:, 0]], f2.directions[pairs[:, 1]]
    sol = solve_pair(a1, a2, P2, b2)
    # J_1 = ‖M̂_1k − P_2 M̂_2j − b_2‖ ≤ α_1
    J1 = sol.conjugation_error
    ok = (J1 <= prm.alpha1) & np.all(sol.ranges > 0, axis=-1) & ~sol.used_pinv
    p, sol_r, J1 = pairs[ok], sol.ranges[ok], J1[ok]
    G = p.shape[0]
    members = np.full((G, N, 2), -1, dtype=np.int64)
    members[:, i] = p
    M1 = sol_r[:, :1] * a1[ok]
    t1, t2 = f1.times[p[:, 0]], f2.times[p[:, 1]]
    hist_M = np.full((G, N, 3), np.nan)
    hist_M[:, i] = M1
    hist_T = np.full((G, N), np.nan)
    hist_T[:, i] = t1
    nan3 = np.full((G, 3), np.nan)
    zeros = np.zeros(G, dtype=np.int64)
    return _Groups(
        score=prm.c[0] * J1 + i * prm.miss_cost,
        members=members,
        M1=M1,
        M2=sol_r[:, 1:] * a2[ok],
        R1=sol_r[:, 0],
        R2=sol_r[:, 1],
        V1=nan3,
        V2=nan3.copy(),
        T1=t1,
        T2=t2,
        n_v=zeros,
        misses=zeros.copy(),
        confirmed=zeros + 1,
        hist_M=hist_M,
        hist_V=np.full((G, N, 3), np.nan),
        hist_T=hist_T,
    )


def _norm(d: FloatArray, u: FloatArray, k: float) -> FloatArray:
    """``‖d‖`` (003), or with ``k > 1`` ``√((d·u)² + k²‖d − (d·u)u‖²)``: the components across
    the line of sight ``u`` weighted by ``k = σ_p/σ_t`` (:attr:`AlgorithmicParams.transverse_gain`)."""
    if k == 1.0:
        return np.linalg.norm(d, axis=-1)
    along = np.sum(d * u, axis=-1)
    across2 = np.maximum(np.sum(d * d, axis=-1) - along**2, 0.0)
    return np.sqrt(along**2 + k * k * across2)


def _continue(
    g: _Groups,
    f1: assoc.Fixes,
    f2: assoc.Fixes,
    pairs: IntArray,
    P2,
    b2,
    i: int,
    prm: AlgorithmicParams,
) -> tuple[_Groups, IntArray, IntArray]:
    """Steps 2.1–2.5 / 3.1–3.5 for every (group, pair) at once; returns the continued groups,
    their parent rows and the pairs they absorbed."""
    c1, c2, c3 = prm.c
    a1 = f1.directions[pairs[:, 0]][None]  # (1, C, 3)
    a2 = f2.directions[pairs[:, 1]][None]
    t1 = f1.times[pairs[:, 0]][None]  # (1, C)
    t2 = f2.times[pairs[:, 1]][None]
    # 2.1: M̂_1k = R_1(g) a_1k, M̂_2j = R_2(g) a_2j; V̂ = (M̂ − M_{i−1}(g))/τ   (9)
    M1h = g.R1[:, None, None] * a1
    M2h = g.R2[:, None, None] * a2
    tau1 = t1 - g.T1[:, None]
    tau2 = t2 - g.T2[:, None]
    V1h = (M1h - g.M1[:, None]) / tau1[..., None]
    V2h = (M2h - g.M2[:, None]) / tau2[..., None]
    # 2.2: M*_1k = M̂_1k + (t_2j − t_1k) V̂_1k ; a*_1k = M*/‖M*‖
    Ms = M1h + (t2 - t1)[..., None] * V1h
    a_star = Ms / np.linalg.norm(Ms, axis=-1, keepdims=True)
    sol = solve_pair(a_star, np.broadcast_to(a2, a_star.shape), P2, b2)
    M1s = sol.ranges[..., :1] * a_star
    M2r = sol.ranges[..., 1:] * a2
    # refined velocities (9); M̂*_1k refers to t_2j (gap 32)
    tau1s = t2 - g.T1[:, None]
    V1r = (M1s - g.M1[:, None]) / tau1s[..., None]
    V2r = (M2r - g.M2[:, None]) / tau2[..., None]
    # 2.3: J_1 with motion; J_2 against the extrapolated group positions (gap 31)
    J1 = sol.conjugation_error
    first = g.n_v == 0
    V1p = np.where(first[:, None, None], V1h, g.V1[:, None])
    V2p = np.where(first[:, None, None], V2h, g.V2[:, None])
    E1 = g.M1[:, None] + tau1s[..., None] * V1p
    E2 = g.M2[:, None] + tau2[..., None] * V2p
    k = prm.transverse_gain
    J2 = _norm(M1s - E1, a_star, k) + _norm(M2r - E2, a2, k)
    # 3.4: J_3 = ‖ΔV_1‖ + ‖ΔV_2‖ for groups that already carry a velocity
    with np.errstate(invalid="ignore"):
        J3 = _norm(V1r - g.V1[:, None], a_star, k) + _norm(V2r - g.V2[:, None], a2, k)
        J = c1 * J1 + np.where(first[:, None], prm.c2_first * J2, c2 * J2 + c3 * J3)
    alpha = np.where(first, prm.alpha[0], prm.alpha[1])[:, None]
    speed_ok = np.linalg.norm(V1r, axis=-1) <= prm.max_speed
    valid = np.all(sol.ranges > 0, axis=-1) & ~sol.used_pinv & speed_ok & (J <= alpha)
    J = np.where(valid, J, np.inf)
    # 2.4–2.6: gate, cumulative index, beam
    gi, ci, score = assoc.extend(g.score, J, np.inf, prm.beam)
    new = g.take(gi)
    # 3.5: first velocity as estimated, then recursively averaged
    n_v = new.n_v
    V1n, V2n = V1r[gi, ci], V2r[gi, ci]
    w = 1.0 / (n_v + 1.0)
    V1 = np.where((n_v == 0)[:, None], V1n, new.V1 + (V1n - new.V1) * w[:, None])
    V2 = np.where((n_v == 0)[:, None], V2n, new.V2 + (V2n - new.V2) * w[:, None])
    members = new.members.copy()
    members[:, i] = pairs[ci]
    hist_M, hist_V, hist_T = new.hist_M.copy(), new.hist_V.copy(), new.hist_T.copy()
    T = t2[0, ci]
    hist_M[:, i], hist_V[:, i], hist_T[:, i] = M1s[gi, ci], V1, T
    out = _Groups(
        score=score,
        members=members,
        M1=M1s[gi, ci],
        M2=M2r[gi, ci],
        R1=sol.ranges[gi, ci, 0],
        R2=sol.ranges[gi, ci, 1],
        V1=V1,
        V2=V2,
        T1=T,
        T2=T,
        n_v=n_v + 1,
        misses=np.zeros_like(n_v),
        confirmed=new.confirmed + 1,
        hist_M=hist_M,
        hist_V=hist_V,
        hist_T=hist_T,
    )
    return out, gi, ci


def detect_algorithmic(
    periods: Sequence[Sequence[assoc.Fixes]],
    P2: ArrayLike,
    b2: ArrayLike,
    params: AlgorithmicParams = AlgorithmicParams(),
) -> assoc.Detection:
    """Paper 003's algorithmic detector over ``N ≥ 1`` periods of two receivers (theory §5.5).

    ``P2 (3, 3)``, ``b2 (3,)`` relative pose of receiver 2 (or per period with a leading ``N``).
    Returns the m̂ selected groups with their member indices and frame-1 positions per period.
    """
    N = len(periods)
    if N < 1:
        raise ValueError("periods: need at least one period")
    P2 = finite_array(P2, "P2", tail=(3, 3))
    b2 = finite_array(b2, "b2", tail=(3,))
    groups: _Groups | None = None
    for i, fixes in enumerate(periods):
        if len(fixes) != 2:
            raise ValueError(f"periods[{i}]: expected fixes of 2 receivers, got {len(fixes)}")
        f1, f2 = fixes
        Pi, bi = assoc.per_period(P2, i, 2), assoc.per_period(b2, i, 1)
        pairs = assoc.combinations([f1.times.shape[0], f2.times.shape[0]])
        absorbed = np.zeros(pairs.shape[0], dtype=bool)
        parts = []
        if groups is not None and groups.score.shape[0] and pairs.shape[0]:
            cont, gi, ci = _continue(groups, f1, f2, pairs, Pi, bi, i, params)
            parts.append(cont)
            absorbed[ci] = True
            # step 4: unconfirmed groups record a miss; dropped after max_misses in a row
            missed = np.setdiff1d(np.arange(groups.score.shape[0]), gi)
        else:
            missed = np.arange(0 if groups is None else groups.score.shape[0])
        if groups is not None and missed.size:
            m = groups.take(missed)
            keep = m.misses < params.max_misses
            m = m.take(np.flatnonzero(keep))
            parts.append(
                _Groups(
                    **{
                        **{f: getattr(m, f) for f in _Groups.__dataclass_fields__},
                        "score": m.score + params.miss_cost,
                        "misses": m.misses + 1,
                    }
                )
            )
        # births: pairs not absorbed by any continuation (step 4), period-1 operations (step 1)
        if pairs.shape[0]:
            parts.append(_births(f1, f2, pairs[~absorbed], Pi, bi, i, N, params))
        if not parts:
            continue
        groups = _Groups.concat(parts)
        groups = groups.take(assoc.prune(groups.score, params.beam))
    if groups is None or groups.score.shape[0] == 0:
        e = np.zeros(0)
        return assoc.Detection(
            np.zeros((0, N, 2), dtype=np.int64),
            e,
            np.zeros((0, N, 3)),
            np.zeros((0, N, 3)),
            np.zeros((0, N)),
        )
    # step 5: greedy selection, at most π shared vectors, confirmed groups only
    return assoc.Detection.select_from(
        groups.members,
        groups.score,
        groups.hist_M,
        groups.hist_V,
        groups.hist_T,
        params.max_shared,
        eligible=groups.confirmed >= params.min_confirmed,
    )
