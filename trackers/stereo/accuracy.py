"""Accuracy of stereo / multi-receiver location: closed forms and Fisher information (theory §3.4, §4).

Two noise models, and when each applies:

*Papers' model* (000, 003): the conjugation error ``e_k`` has i.i.d. components of variance
``σ_e²``. Then ``Q = σ_e² (AᵀA)⁻¹`` exactly (:class:`~.conjugation.ConjugationSolution`), and
for ranges only (000 eq. 12, 13 and the general-n Schur complement)::

    n = 2:  σ[r̂_1] = σ_e / sin γ                     γ = ∠(a_1, P_2 a_2)
    n = 3:  σ[r̂_1] = σ_e / √(sin²α + sin²β)
    any n:  σ[r̂_1] = σ_e / √(Σ_k sin²γ_k)

This model fits when the error really is isotropic in space (e.g. noise injected on the
position vectors, as paper 000's simulation does). It is *optimistic away from 90°* for real
sensors: angular errors are zero along each line of sight and grow with range.

*Angle-noise model* (realistic): each receiver's direction carries independent isotropic
angular noise ``σ_k`` (radians). To first order the error of ``a_k`` is ``δa_k ⊥ a_k`` with
covariance ``σ_k² (I − a_k a_kᵀ)``. Then

- the unweighted two-receiver LS range (000 eq. 8) has the exact first-order error
  ``σ[r̂_1] = σ √(r_2² + r_1² cos²γ) / sin γ`` (equal σ at both receivers; for ``γ = 90°`` it
  is ``r_2 σ``), see :func:`pair_range_sigma_angle_noise`;
- the Fisher information of the 3-D position ``M`` is
  ``I(M) = Σ_k (I − u_k u_kᵀ) / (σ_k² r_k²)`` (``u_k`` the world line of sight), and
  ``I(M)⁻¹`` is the Cramér–Rao bound that :func:`triangulate_ml` attains to first order.

Both optima are at orthogonal lines of sight for fixed ranges (theory §10.1 OC-1). All functions
take leading batch axes.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sensorgym.trackers.stereo import information
from sensorgym.trackers.validation import finite_array, unit_vectors

FloatArray = NDArray[np.float64]


def _check_angle(gamma: ArrayLike, name: str) -> FloatArray:
    g = finite_array(gamma, name)
    if np.any((g <= 0.0) | (g >= np.pi)):
        raise ValueError(f"{name}: angle between lines of sight must lie in (0, π) radians")
    return g


def _check_positive(x: ArrayLike, name: str) -> FloatArray:
    arr = finite_array(x, name)
    if np.any(arr <= 0.0):
        raise ValueError(f"{name}: must be positive")
    return arr


def los_angle(a1: ArrayLike, c2: ArrayLike) -> FloatArray:
    """Angle ``γ = ∠(a_1, c_2)`` between two unit lines of sight in one frame, radians.

    Computed as ``atan2(‖a_1 × c_2‖, a_1·c_2)``, accurate near 0 and π where ``arccos`` is not.
    """
    a1 = unit_vectors(a1, "a1")
    c2 = unit_vectors(c2, "c2")
    return np.arctan2(np.linalg.norm(np.cross(a1, c2), axis=-1), np.sum(a1 * c2, axis=-1))


def pair_covariance(gamma: ArrayLike, sigma_e: ArrayLike = 1.0) -> FloatArray:
    """``K_R = σ_e²/sin²γ · [[1, cos γ], [cos γ, 1]]`` of ``(r̂_1, r̂_2)`` (000 eq. 12), m²."""
    g = _check_angle(gamma, "gamma")
    s = _check_positive(sigma_e, "sigma_e")
    q = s**2 / np.sin(g) ** 2
    c = np.cos(g)
    return q[..., None, None] * np.stack(
        [np.stack([np.ones_like(c), c], -1), np.stack([c, np.ones_like(c)], -1)], -2
    )


def pair_range_sigma(gamma: ArrayLike, sigma_e: ArrayLike = 1.0) -> FloatArray:
    """``σ[r̂_1] = σ_e / sin γ`` (000 eq. 12, papers' i.i.d. model), metres."""
    return _check_positive(sigma_e, "sigma_e") / np.sin(_check_angle(gamma, "gamma"))


def triple_covariance(alpha: ArrayLike, beta: ArrayLike, sigma_e: ArrayLike = 1.0) -> FloatArray:
    """``K_R`` of ``(r̂_1, r̂_2, r̂_3)`` for n = 3 ranges only (000 eq. 13), m².

    ``σ_e²/(sin²α + sin²β) · [[1, cos α, cos β], [cos α, 1 + sin²β, cos α cos β],
    [cos β, cos α cos β, 1 + sin²α]]`` with ``α = ∠(a_1, c_2)``, ``β = ∠(a_1, c_3)``.
    """
    a = _check_angle(alpha, "alpha")
    b = _check_angle(beta, "beta")
    s = _check_positive(sigma_e, "sigma_e")
    ca, cb, sa2, sb2 = np.cos(a), np.cos(b), np.sin(a) ** 2, np.sin(b) ** 2
    ca, cb, sa2, sb2, s = np.broadcast_arrays(ca, cb, sa2, sb2, s)
    one = np.ones_like(ca)
    K = np.stack(
        [
            np.stack([one, ca, cb], -1),
            np.stack([ca, 1.0 + sb2, ca * cb], -1),
            np.stack([cb, ca * cb, 1.0 + sa2], -1),
        ],
        -2,
    )
    return (s**2 / (sa2 + sb2))[..., None, None] * K


def range_sigma_general(a1: ArrayLike, c: ArrayLike, sigma_e: ArrayLike = 1.0) -> FloatArray:
    """``σ[r̂_1] = σ_e / √(Σ_k sin²γ_k)`` for any n, ranges only (theory §3.4, Schur complement).

    ``a1 (..., 3)``; ``c (..., n−1, 3)`` lines of sight of receivers 2..n in frame 1.
    Returns ``inf`` when every line of sight is parallel to ``a_1`` (range unobservable).
    """
    a1 = unit_vectors(a1, "a1")
    c = unit_vectors(c, "c")
    cos = np.einsum("...j,...kj->...k", a1, c)
    total = np.sum(1.0 - cos**2, axis=-1)
    s = _check_positive(sigma_e, "sigma_e")
    with np.errstate(divide="ignore"):
        return s / np.sqrt(np.maximum(total, 0.0))


def pair_range_sigma_angle_noise(
    r1: ArrayLike, r2: ArrayLike, gamma: ArrayLike, sigma_ang: ArrayLike
) -> FloatArray:
    """First-order ``σ[r̂_1] = σ_ang √(r_2² + r_1² cos²γ) / sin γ`` of the LS pair (theory §4.1).

    Equal isotropic angular noise ``σ_ang`` (radians) on both directions; ranges in metres.
    At ``γ = 90°`` this is ``r_2 σ_ang``; it exceeds the papers' ``σ_e/sin γ`` with
    ``σ_e = r σ_ang`` away from 90°.
    """
    r1 = _check_positive(r1, "r1")
    r2 = _check_positive(r2, "r2")
    g = _check_angle(gamma, "gamma")
    s = _check_positive(sigma_ang, "sigma_ang")
    return s * np.sqrt(r2**2 + (r1 * np.cos(g)) ** 2) / np.sin(g)


def position_information(los: ArrayLike, ranges: ArrayLike, sigma_ang: ArrayLike) -> FloatArray:
    """Fisher information of the 3-D position, ``I(M) = Σ_k (I − u_k u_kᵀ)/(σ_k² r_k²)``, 1/m².

    ``los (..., n, 3)`` unit lines of sight ``u_k`` (any one common frame), ``ranges (..., n)``
    metres, ``sigma_ang (..., n)`` or scalar: isotropic angular noise per receiver, radians.
    """
    u = unit_vectors(los, "los")
    r = _check_positive(ranges, "ranges")
    s = _check_positive(sigma_ang, "sigma_ang")
    if u.ndim < 2:
        raise ValueError(f"los: expected shape (..., n, 3), got {u.shape}")
    return information.position_information(u, r, s)


def position_crlb(los: ArrayLike, ranges: ArrayLike, sigma_ang: ArrayLike) -> FloatArray:
    """Cramér–Rao bound ``I(M)⁻¹`` of the 3-D position, m².

    Needs at least two non-parallel lines of sight; raises ``ValueError`` where the
    information is singular (the position is unobservable along the common line of sight).
    """
    info = position_information(los, ranges, sigma_ang)
    if not np.all(information.observable(info)):
        raise ValueError("los: lines of sight are parallel; position information is singular")
    return np.linalg.inv(info)


def triangulate_ml(
    origins: ArrayLike, los: ArrayLike, sigma_ang: ArrayLike = 1.0, iterations: int = 2
) -> tuple[FloatArray, FloatArray]:
    """Position estimate under the angle-noise model, efficient to first order.

    Minimises ``Σ_k ‖(I − u_k u_kᵀ)(M − o_k)‖² / (σ_k² r_k²)``: the perpendicular miss of
    ``M`` from each line of sight, weighted by its Fisher information. Linear in ``M`` for
    fixed ranges, so it is solved in closed form; the ranges ``r_k`` start at 1 (unweighted
    midpoint) and are refreshed from the estimate ``iterations − 1`` times.

    ``origins (..., n, 3)`` receiver positions and ``los (..., n, 3)`` unit lines of sight in
    one common frame. Returns ``(M̂ (..., 3), covariance (..., 3, 3))`` with the covariance
    ``I(M̂)⁻¹`` at the final ranges. Raises ``ValueError`` for parallel lines of sight.
    """
    o = finite_array(origins, "origins", tail=(3,))
    u = unit_vectors(los, "los")
    if iterations < 1:
        raise ValueError("iterations: must be at least 1")
    M, info, ok = information.weighted_fix(o, u, sigma=sigma_ang, iterations=iterations)
    if not np.all(ok):
        raise ValueError("los: lines of sight are parallel; the position is unobservable")
    return M, np.linalg.inv(info)
