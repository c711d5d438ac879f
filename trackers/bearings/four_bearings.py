"""Paper 002: the method of fictitious bearings (theory §7), ideal and block-smoothed variants.

The platform takes bearing 1 on detection, moves uniformly (the paper: along bearing 1) while
taking bearings 2 and 3 at equal intervals Δ, then turns perpendicular to bearing 2 and
speeds up; bearing 4 fixes the target (theory §7.3, §10.5 OC-5).

Geometry (theory §7.1–7.2). A is put on bearing 1 at an assumed distance D; line AE ⊥ bearing 1;
bearings 2 and 3 cut AE at B and E (signed offsets c₁ = AB, c₂ = AE along ``e`` = bearing 1
rotated 90° clockwise); ``α_k = atan2(u_k·u₁, u_k·e)``; then (paper eq. 1–3)::

    tan β = (c₂ sin α₂ sin α₁ − 2 c₁ sin α₁ sin α₂) / (2 c₁ sin α₁ cos α₂ − c₂ sin α₂ cos α₁)
    β = arctg(tan β),   Q = π − β,   d = cos Q e + sin Q u₁

and the fictitious track A B′ C′ (direction d) has AB′ = B′C′. Equivalent direct solve
(theory §7.3–7.4, recommended; exact for any *uniformly* moving platform, since M₃ − 2M₂ + M₁ = 0)::

    2 s₂ u₂ − s₃ u₃ = D u₁,   F₁ = D u₁,  F₂ = s₂ u₂,  W_f = (F₂ − F₁)/Δ

(F = fictitious target position relative to the platform). Had the platform kept its
initial velocity ``v_p0``, it would be at ``M_kᴹ = M₁ + v_p0 (t_k − t₁)`` and see the target in
direction ``F_k = F₁ + W_f (t_k − t₁)`` (the imaginary bearing). The true relative track is the
fictitious one scaled by λ, so bearing k (k ≥ 4) gives, with ``n_k ⊥ u_k``::

    λ F_k − ρ_k u_k = M_k − M_kᴹ   ⇒   λ = ((M_k − M_kᴹ)·n_k) / (F_k·n_k)

Course and speed use the moving-platform correction (theory §13.25; the paper's β is
the target course only for a stationary platform)::

    V = λ W_f + v_p0,     position at t₁: M₁ + λ D u₁,     range at t₁: λ D

Several post-turn bearings give λ by least squares, ``λ = Σ a_k b_k / Σ a_k²`` with
``a_k = F_k·n_k``, ``b_k = (M_k − M_kᴹ)·n_k`` (our reading of "intersect every real bearing
with its imaginary one", theory §7.3 step 9). Everything is batched over leading axes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sensorgym.trackers.bearings.models import STATE_DIM
from sensorgym.trackers.geometry import wrap_angle
from sensorgym.trackers.validation import finite_array

FloatArray = NDArray[np.float64]


def _unit(z: FloatArray) -> FloatArray:
    return np.stack([np.sin(z), np.cos(z)], axis=-1)


def _normal(u: FloatArray) -> FloatArray:
    """``u`` rotated 90° clockwise (North → East)."""
    return np.stack([u[..., 1], -u[..., 0]], axis=-1)


def _dot(a: FloatArray, b: FloatArray) -> FloatArray:
    return np.sum(a * b, axis=-1)


def tan_beta(c1: ArrayLike, c2: ArrayLike, alpha1: ArrayLike, alpha2: ArrayLike) -> FloatArray:
    """Paper 002 eq. (1): ``tan β`` from the signed offsets ``c₁, c₂`` (m) and angles ``α₁, α₂``."""
    c1, c2 = np.asarray(c1, float), np.asarray(c2, float)
    s1, s2 = np.sin(alpha1), np.sin(alpha2)
    k1, k2 = np.cos(alpha1), np.cos(alpha2)
    num = c2 * s2 * s1 - 2.0 * c1 * s1 * s2
    den = 2.0 * c1 * s1 * k2 - c2 * s2 * k1
    with np.errstate(divide="ignore"):
        return num / den


@dataclass(frozen=True)
class FictitiousTrack:
    """The paper's geometric construction from bearings 1–3 (absolute coordinates, m)."""

    A: FloatArray
    """Assumed object position on bearing 1 ``(..., 2)``."""
    B_prime: FloatArray
    """Fictitious track ∩ bearing 2 ``(..., 2)``."""
    C_prime: FloatArray
    """Fictitious track ∩ bearing 3 ``(..., 2)``."""
    c1: FloatArray
    """Signed offset AB along ``e`` (m)."""
    c2: FloatArray
    """Signed offset AE along ``e`` (m)."""
    alpha1: FloatArray
    """Angle from ``e`` to bearing 2 (rad)."""
    alpha2: FloatArray
    """Angle from ``e`` to bearing 3 (rad)."""
    beta: FloatArray
    """β = arctg(tan β) (rad), eq. (2)."""
    Q: FloatArray
    """Q = π − β (rad), eq. (3): CCW angle of the fictitious track from AE."""


def paper_construction(M: ArrayLike, z: ArrayLike, D: ArrayLike) -> FictitiousTrack:
    """Eq. (1)–(3) construction from platform positions ``M`` ``(..., 3, 2)`` and bearings ``z``
    ``(..., 3)`` (rad), with the assumed distance ``D`` (m). Signs as in theory §7.2."""
    M = finite_array(M, "M", tail=(3, 2))
    z = finite_array(z, "z", tail=(3,))
    D = finite_array(D, "D")
    u = _unit(z)
    u1 = u[..., 0, :]
    e = _normal(u1)
    A = M[..., 0, :] + D[..., None] * u1

    def cut_AE(Mk: FloatArray, uk: FloatArray) -> FloatArray:
        # M_k + s u_k = A + c e  →  c = ((M_k − A) × u_k) / (e × u_k)
        cross = lambda a, b: a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]  # noqa: E731
        return cross(Mk - A, uk) / cross(e, uk)

    c1 = cut_AE(M[..., 1, :], u[..., 1, :])
    c2 = cut_AE(M[..., 2, :], u[..., 2, :])
    a1 = np.arctan2(_dot(u[..., 1, :], u1), _dot(u[..., 1, :], e))
    a2 = np.arctan2(_dot(u[..., 2, :], u1), _dot(u[..., 2, :], e))
    beta = np.arctan(tan_beta(c1, c2, a1, a2))
    Q = np.pi - beta
    d = np.cos(Q)[..., None] * e + np.sin(Q)[..., None] * u1

    def along(Mk: FloatArray, uk: FloatArray) -> FloatArray:
        # A + s d = M_k + r u_k  →  s = ((M_k − A) × u_k) / (d × u_k)
        cross = lambda a, b: a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]  # noqa: E731
        return A + (cross(Mk - A, uk) / cross(d, uk))[..., None] * d

    B_prime = along(M[..., 1, :], u[..., 1, :])
    C_prime = along(M[..., 2, :], u[..., 2, :])
    return FictitiousTrack(A, B_prime, C_prime, c1, c2, a1, a2, beta, Q)


def fictitious_relative_track(z: ArrayLike, D: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Direct solve ``2 s₂ u₂ − s₃ u₃ = D u₁``; returns ``F₁ = D u₁`` and ``F₂ − F₁`` ``(..., 2)``.

    ``z`` ``(..., 3)``: bearings 1–3 (rad). Raises ``ValueError`` if bearings 2 and 3 are
    parallel (no bearing change: the course is undetermined).
    """
    z = finite_array(z, "z", tail=(3,))
    D = finite_array(D, "D")
    u = _unit(z)
    A = np.stack([2.0 * u[..., 1, :], -u[..., 2, :]], axis=-1)  # columns 2u₂, −u₃
    det = np.linalg.det(A)
    if np.any(np.abs(det) < 1e-12):
        raise ValueError("z: bearings 2 and 3 are parallel; the fictitious track is undefined")
    F1 = D[..., None] * u[..., 0, :]
    s = np.linalg.solve(A, F1[..., None])[..., 0]
    F2 = s[..., 0:1] * u[..., 1, :]
    return F1, F2 - F1


@dataclass(frozen=True)
class FictitiousFix:
    """Target track from the fictitious-bearing method (deterministic, no covariance)."""

    t_ref: float
    """Reference time (s) of :attr:`position`."""
    position: FloatArray
    """Target position at ``t_ref`` ``(..., 2)`` (m)."""
    velocity: FloatArray
    """Target velocity ``(..., 2)`` (m/s), moving-platform corrected."""
    scale: FloatArray
    """λ: true over fictitious relative track ``(...,)``; the range at ``t_ref`` is ``λ D``."""

    def position_at(self, t: float) -> FloatArray:
        """Predicted position ``(..., 2)`` at time ``t`` (s)."""
        return self.position + (float(t) - self.t_ref) * self.velocity

    def state_at(self, t: float) -> FloatArray:
        """State ``(x, y, ẋ, ẏ)`` ``(..., 4)`` at time ``t`` (s)."""
        return np.concatenate([self.position_at(t), self.velocity], axis=-1)


def fictitious_bearing_fix(
    times: ArrayLike,
    platform_positions: ArrayLike,
    z: ArrayLike,
    D: ArrayLike,
    *,
    equal_tolerance: float = 1e-6,
) -> FictitiousFix:
    """Fix from bearings 1–3 (course) and bearings 4… (scale), theory §7.3.

    ``times`` ``(K,)`` with ``K ≥ 4`` and ``t₂ − t₁ = t₃ − t₂``; ``platform_positions``
    ``(..., K, 2)``: the platform must move uniformly through bearings 1–3 (``v_p0 = (M₂ − M₁)/Δ``);
    ``z`` ``(..., K)`` bearings (rad); ``D`` assumed distance (m). Bearings 4…K each give λ; with
    K > 4 the least-squares λ is used. Position refers to ``t₁``.
    """
    times = finite_array(times, "times")
    M = finite_array(platform_positions, "platform_positions", tail=(2,))
    z = finite_array(z, "z")
    K = times.shape[0]
    if K < 4 or z.shape[-1] != K or M.shape[-2] != K:
        raise ValueError(f"need K >= 4 bearings with matching positions; got {z.shape}, {M.shape}")
    delta = times[1] - times[0]
    if delta <= 0.0 or abs((times[2] - times[1]) - delta) > equal_tolerance * delta:
        raise ValueError("times: bearings 1-3 must be taken at equal positive intervals")
    # the construction is exact only for a uniformly moving platform: M₃ − 2M₂ + M₁ = 0
    second = np.linalg.norm(M[..., 2, :] - 2.0 * M[..., 1, :] + M[..., 0, :], axis=-1)
    span = np.linalg.norm(M[..., 2, :] - M[..., 0, :], axis=-1)
    if np.any(second > 1e-6 * span + 1e-6):
        raise ValueError("platform_positions: the platform must move uniformly over bearings 1-3")
    F1, dF = fictitious_relative_track(z[..., :3], D)
    W = dF / delta
    vp0 = (M[..., 1, :] - M[..., 0, :]) / delta
    tau = times[3:] - times[0]  # (K−3,)
    Fk = F1[..., None, :] + tau[:, None] * W[..., None, :]
    MkM = M[..., :1, :] + tau[:, None] * vp0[..., None, :]
    n = _normal(_unit(z[..., 3:]))
    a = _dot(Fk, n)
    b = _dot(M[..., 3:, :] - MkM, n)
    den = np.sum(a * a, axis=-1)
    if np.any(den < 1e-12 * np.maximum(np.sum(Fk * Fk, axis=(-1, -2)), 1e-300)):
        raise ValueError(
            "z: the post-turn bearings coincide with their imaginary bearings; the range is "
            "unobservable (turn and speed up, theory §10.5 OC-5)"
        )
    lam = np.sum(a * b, axis=-1) / den
    if np.any(np.abs(lam) < 1e-9):
        raise ValueError(
            "platform_positions: no displacement across the bearings after the turn; "
            "the range is unobservable (turn and speed up, theory §10.5 OC-5)"
        )
    return FictitiousFix(
        t_ref=float(times[0]),
        position=M[..., 0, :] + lam[..., None] * F1,
        velocity=lam[..., None] * W + vp0,
        scale=lam,
    )


def literal_refinement(
    preliminary: FictitiousFix,
    times: ArrayLike,
    platform_positions: ArrayLike,
    z: ArrayLike,
) -> FictitiousFix:
    """The paper's refinement read literally (theory §7.5 step 7; gap §13.26).

    Bearings 4–6 (taken after the turn, platform uniform again) are "projected onto a new
    line A_nE_n" with A_n at the preliminary position on bearing 4; the fictitious track from
    bearings 4–6 then gives the course with the scale fixed by the preliminary range
    (``λ = 1``): ``V = W_n + v_p1``, position at t₄ = ``M₄ + D_n u₄``. ``times`` ``(3,)``,
    ``platform_positions`` ``(..., 3, 2)``, ``z`` ``(..., 3)`` are bearings 4–6.
    """
    times = finite_array(times, "times", tail=(3,))
    M = finite_array(platform_positions, "platform_positions", tail=(3, 2))
    z = finite_array(z, "z", tail=(3,))
    delta = times[1] - times[0]
    if delta <= 0.0 or abs((times[2] - times[1]) - delta) > 1e-6 * delta:
        raise ValueError("times: bearings 4-6 must be taken at equal positive intervals")
    rel = preliminary.position_at(times[0]) - M[..., 0, :]
    D_n = np.maximum(_dot(rel, _unit(z[..., 0])), 1.0)
    F1, dF = fictitious_relative_track(z, D_n)
    vp1 = (M[..., 1, :] - M[..., 0, :]) / delta
    return FictitiousFix(
        t_ref=float(times[0]),
        position=M[..., 0, :] + F1,
        velocity=dF / delta + vp1,
        scale=np.ones_like(D_n),
    )


def block_base_bearings(
    times: ArrayLike, z: ArrayLike, block_size: int, degree: int = 1
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Base bearings by polynomial smoothing over consecutive blocks (theory §7.5 steps 2–4).

    Each block of ``block_size`` samples (causal: only the block's own samples) is fitted by
    least squares with a polynomial of ``degree`` in time, and the fit is evaluated at the
    block's last sample time. Bearings are unwrapped about each block's first sample before
    fitting. Returns base times ``(M,)``, base bearings ``(..., M)`` (rad) and the
    noise gain ``g`` ``(M,)``: the base bearing's standard deviation is ``g σ`` for iid noise σ.
    """
    times = finite_array(times, "times")
    z = finite_array(z, "z")
    if z.shape[-1] != times.shape[0]:
        raise ValueError(f"z: last axis must match times ({times.shape[0]}), got {z.shape}")
    if block_size < degree + 1:
        raise ValueError(f"block_size {block_size} too small for degree {degree}")
    n_blocks = times.shape[0] // block_size
    if n_blocks == 0:
        raise ValueError("times: fewer samples than one block")
    tb = times[: n_blocks * block_size].reshape(n_blocks, block_size)
    zb = z[..., : n_blocks * block_size].reshape(*z.shape[:-1], n_blocks, block_size)
    t_end = tb[:, -1]
    scale = np.maximum(tb[:, -1] - tb[:, 0], 1e-9)
    s = (tb - t_end[:, None]) / scale[:, None]  # in [−1, 0], end at 0
    V = s[..., None] ** np.arange(degree + 1)  # (M, n, d+1)
    pinv = np.linalg.pinv(V)  # (M, d+1, n)
    z0 = zb[..., :1]
    zu = z0 + wrap_angle(zb - z0)
    coef = np.einsum("mdn,...mn->...md", pinv, zu)
    base = wrap_angle(coef[..., 0])  # polynomial at s = 0 (block end)
    gain = np.sqrt(np.sum(pinv[:, 0, :] ** 2, axis=-1))
    return t_end, base, gain


def state_error(estimate: ArrayLike, truth: ArrayLike) -> dict[str, FloatArray]:
    """Position (m), speed (m/s) and course (rad) errors of ``(…, 4)`` states."""
    x = finite_array(estimate, "estimate", tail=(STATE_DIM,))
    y = finite_array(truth, "truth", tail=(STATE_DIM,))
    return {
        "position": np.hypot(x[..., 0] - y[..., 0], x[..., 1] - y[..., 1]),
        "speed": np.hypot(x[..., 2], x[..., 3]) - np.hypot(y[..., 2], y[..., 3]),
        "course": wrap_angle(np.arctan2(x[..., 2], x[..., 3]) - np.arctan2(y[..., 2], y[..., 3])),
    }
