"""Paper 003, algebraic approach: motion parameters from one scan period (theory §5.4).

*Single object.* Each period the n direction vectors (fixed at different times by scanning
receivers) are conjugated with the velocity term (003 eq. 2, 4, 6) or power-weighted (eq. 7):
``M̂_1 = r̂_1 a_1`` and ``V̂_1`` at ``t_1`` in frame 1. :func:`algebraic_single`.

*Several objects* (n = 4; the text says "n = 3" but uses four vectors, gap 30). Every index
combination ``(j1, j2, j3, j4)`` is split into the overlapping subgroups ``{1, 2, 3}`` and
``{1, 2, 4}``; each is solved for position and velocity and extrapolated to the end of the
period ``T``; the index (8) ``I_j = ‖M^э_{1j} − M^э_{2j}‖``,
``M^э_{kj} = r̂_{1kj} a_{1j} + V̂_{1kj} (T − t_{1j})``, rejects the group when ``I_j > γ``
and the non-intersecting groups with the smallest ``I_j`` are the objects.
:func:`algebraic_multi`. (003 writes ``τ − t_{1j}``, presuming the period starts at 0; we use
the absolute end time ``T``.)

*Economical variant* (n = 2, N = 2, constant motion). A group ``{a_1(1), a_2(1), a_1(2),
a_2(2)}`` is split into ``{a_1(1); a_2(1), a_2(2)}`` and ``{a_1(2); a_2(2), a_2(1)}``; each is
three vectors solved like three receivers (receiver 2 twice, same ``P_2, b_2``, different
times; a negative delay for ``a_2(1)`` in the second) and the (8)-type index extrapolates to
the end of the second period. :func:`economical`.

All combinations of a period are solved in one batched call of the conjugation core; the
selection is the shared :func:`~sensorgym.trackers.stereo.association.select`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sensorgym.trackers.stereo import association as assoc
from sensorgym.trackers.stereo.conjugation import ConjugationSolution, solve_conjugation
from sensorgym.trackers.validation import finite_array

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class AlgebraicParams:
    """Gate γ of the multi-object algebraic index (8), solver options (theory §5.4, §13.6)."""

    position_sigma: float = 0.3
    """Std of each coordinate of a subgroup's position estimate, m."""
    velocity_sigma: float = 0.1
    """Std of each coordinate of a subgroup's velocity estimate, m/s."""
    horizon: float = 20.0
    """Largest extrapolation time ``T − t_1``, s (the period τ)."""
    gate_probability: float = 0.999
    """Probability that a true group passes γ."""
    weighted: bool = False
    """Weight each receiver pair's equations by w_1 w_k (003 eq. 7)."""
    cond_max: float = 1e7
    """Condition number above which the core takes the pseudo-inverse branch."""
    gamma_override: float | None = None
    """γ in m if given, else :attr:`gamma`."""

    def __post_init__(self) -> None:
        if not (self.position_sigma > 0 and self.velocity_sigma >= 0 and self.horizon >= 0):
            raise ValueError("position_sigma > 0, velocity_sigma >= 0, horizon >= 0 required")
        if not 0.0 < self.gate_probability < 1.0:
            raise ValueError("gate_probability: must lie in (0, 1)")

    @property
    def gamma(self) -> float:
        """γ, m: ``q_{3D}(√2 · √(σ_p² + σ_v² h²))`` — two independent extrapolated estimates."""
        if self.gamma_override is not None:
            return self.gamma_override
        s = np.sqrt(2.0 * (self.position_sigma**2 + (self.velocity_sigma * self.horizon) ** 2))
        return assoc.norm_quantile(s, self.gate_probability)


def _solve(
    a1: FloatArray,
    ak: FloatArray,
    P: FloatArray,
    b: FloatArray,
    dt: FloatArray,
    w: FloatArray | None,
    order: int,
    cond_max: float,
) -> ConjugationSolution:
    """One batched core call; equal or zero delays (close receivers, one raster line) make the
    velocity system singular and take the core's pseudo-inverse branch (flagged)."""
    return solve_conjugation(a1, ak, P, b, dt, order=order, weights=w, cond_max=cond_max)


def algebraic_single(
    fixes: Sequence[assoc.Fixes],
    P: ArrayLike,
    b: ArrayLike,
    *,
    order: int = 1,
    weighted: bool = False,
    cond_max: float = 1e7,
) -> ConjugationSolution:
    """One object, one period: conjugate the first fix of every receiver (003 eq. 4, 6–7).

    ``order`` 1 estimates ``(r, V)`` (6 parameters for n = 3); 0 ignores the motion (the
    "3 parameters" of 003 variant 2); 2 adds the acceleration (n ≥ 5).
    """
    n = len(fixes)
    P = finite_array(P, "P", tail=(n - 1, 3, 3))
    b = finite_array(b, "b", tail=(n - 1, 3))
    if any(f.times.shape[0] < 1 for f in fixes):
        raise ValueError("fixes: every receiver needs at least one fix")
    a1 = fixes[0].directions[0]
    ak = np.stack([f.directions[0] for f in fixes[1:]])
    dt = np.array([f.times[0] for f in fixes[1:]]) - fixes[0].times[0]
    w = np.array([f.powers[0] for f in fixes]) if weighted else None
    return _solve(a1, ak, P, b, dt, w, order, cond_max)


def _subgroup_index(
    a1: FloatArray,
    t1: FloatArray,
    sols: tuple[ConjugationSolution, ConjugationSolution],
    t_end: float,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(8): ``I = ‖M^э_1 − M^э_2‖``, ``M^э_k = r̂_{1k} a_1 + V̂_k (T − t_1)``; I, mean state."""
    h = (t_end - t1)[:, None]
    ext = [s.ranges[:, :1] * a1 + s.velocity * h for s in sols]
    index = np.linalg.norm(ext[0] - ext[1], axis=-1)
    pos = 0.5 * (sols[0].position + sols[1].position)
    vel = 0.5 * (sols[0].velocity + sols[1].velocity)
    return index, pos, vel


def _detection(members: NDArray, index: FloatArray, pos, vel, t, keep, chosen) -> assoc.Detection:
    """Selected groups; ``pos, vel (C, N, 3)`` and ``t (C, N)`` are per-period estimates."""
    sel = np.flatnonzero(keep)[chosen]
    return assoc.Detection(
        members[sel], index[sel], pos[sel], vel[sel], t[sel], groups_kept=int(keep.sum())
    )


def algebraic_multi(
    fixes: Sequence[assoc.Fixes],
    P: ArrayLike,
    b: ArrayLike,
    t_end: float,
    params: AlgebraicParams = AlgebraicParams(),
) -> assoc.Detection:
    """Several objects, one period, n = 4 receivers: subgroups {1,2,3}, {1,2,4} and index (8)."""
    if len(fixes) != 4:
        raise ValueError(
            f"fixes: the multi-object algebraic scheme needs 4 receivers, got {len(fixes)}"
        )
    P = finite_array(P, "P", tail=(3, 3, 3))
    b = finite_array(b, "b", tail=(3, 3))
    C = assoc.combinations([f.times.shape[0] for f in fixes])
    a = [fixes[k].directions[C[:, k]] for k in range(4)]
    t = [fixes[k].times[C[:, k]] for k in range(4)]
    w = [fixes[k].powers[C[:, k]] for k in range(4)]
    sols = []
    for other in (2, 3):  # subgroups {1, 2, 3} and {1, 2, 4}
        ks = (1, other)
        sols.append(
            _solve(
                a[0],
                np.stack([a[k] for k in ks], axis=1),
                P[[k - 1 for k in ks]],
                b[[k - 1 for k in ks]],
                np.stack([t[k] - t[0] for k in ks], axis=1),
                np.stack([w[0]] + [w[k] for k in ks], axis=1) if params.weighted else None,
                1,
                params.cond_max,
            )
        )
    index, pos, vel = _subgroup_index(a[0], t[0], (sols[0], sols[1]), t_end)
    # I_j ≤ γ (003, theory §5.4), ranges in front of the receivers
    keep = (
        (index <= params.gamma)
        & np.all(sols[0].ranges > 0, axis=-1)
        & np.all(sols[1].ranges > 0, axis=-1)
    )
    members = C[:, None, :]
    chosen = assoc.select(members[keep], index[keep], 0)
    return _detection(members, index, pos[:, None], vel[:, None], t[0][:, None], keep, chosen)


def economical(
    periods: Sequence[Sequence[assoc.Fixes]],
    P2: ArrayLike,
    b2: ArrayLike,
    t_end: float,
    params: AlgebraicParams = AlgebraicParams(),
) -> assoc.Detection:
    """Economical algebraic variant: n = 2 receivers over N = 2 periods (003, theory §5.4).

    Period ``i``'s position/velocity is subgroup ``i``'s estimate at receiver 1's fix time
    ``t_1(i)``; ``t_end`` is the end of the second period.
    """
    if len(periods) != 2 or any(len(p) != 2 for p in periods):
        raise ValueError("periods: the economical variant takes 2 periods of 2 receivers")
    P2 = finite_array(P2, "P2", tail=(3, 3))
    b2 = finite_array(b2, "b2", tail=(3,))
    (f11, f21), (f12, f22) = periods
    C = assoc.combinations(
        [f11.times.shape[0], f21.times.shape[0], f12.times.shape[0], f22.times.shape[0]]
    )
    a11, a21, a12, a22 = (f.directions[C[:, k]] for k, f in enumerate((f11, f21, f12, f22)))
    t11, t21, t12, t22 = (f.times[C[:, k]] for k, f in enumerate((f11, f21, f12, f22)))
    PP = np.stack([P2, P2])
    bb = np.stack([b2, b2])
    # subgroup 1: {a_1(1); a_2(1), a_2(2)}, subgroup 2: {a_1(2); a_2(2), a_2(1)}
    s1 = _solve(
        a11,
        np.stack([a21, a22], 1),
        PP,
        bb,
        np.stack([t21 - t11, t22 - t11], 1),
        None,
        1,
        params.cond_max,
    )
    s2 = _solve(
        a12,
        np.stack([a22, a21], 1),
        PP,
        bb,
        np.stack([t22 - t12, t21 - t12], 1),
        None,
        1,
        params.cond_max,
    )
    h1, h2 = (t_end - t11)[:, None], (t_end - t12)[:, None]
    # (8)-type index at the end of the second period
    e1 = s1.ranges[:, :1] * a11 + s1.velocity * h1
    e2 = s2.ranges[:, :1] * a12 + s2.velocity * h2
    index = np.linalg.norm(e1 - e2, axis=-1)
    # period i's estimate is subgroup i's, at its reference time t_1(i): the position is
    # well determined there, the velocity (from one receiver's two vectors) much less
    pos = np.stack([s1.position, s2.position], axis=1)
    vel = np.stack([s1.velocity, s2.velocity], axis=1)
    t = np.stack([t11, t12], axis=1)
    keep = (index <= params.gamma) & np.all(s1.ranges > 0, -1) & np.all(s2.ranges > 0, -1)
    members = np.stack([C[:, :2], C[:, 2:]], axis=1)
    chosen = assoc.select(members[keep], index[keep], 0)
    return _detection(members, index, pos, vel, t, keep, chosen)
