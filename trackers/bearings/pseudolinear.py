"""Pseudo-linear estimator (PLE) for bearings-only target motion analysis, batched.

A bearing ``z_k`` from platform position ``p_k`` says the target lies on a line; with the
deterministic state ``x₀ = (x, y, ẋ, ẏ)`` at ``t₀`` and ``Δt_k = t_k − t₀`` (Lingren & Gong 1978;
Aidala & Nardone 1982)::

    a_kᵀ x₀ = b_k,   a_k = (cos z_k, −sin z_k, Δt_k cos z_k, −Δt_k sin z_k),
                     b_k = p_{k,x} cos z_k − p_{k,y} sin z_k

The equation error is ``r_k sin(β_k − z_k) ≈ −r_k η_k`` (η the bearing noise), so the weighted
estimate uses ``w_k = 1/(σ² r̂_k²)`` with ranges from the previous iterate (``iterations`` ≥ 1;
0 gives the unweighted PLE). The PLE is biased (noise sits in ``a_k``; Nardone, Lindgren &
Gong 1984), which is why it serves as the initialiser of :mod:`bearings_ml`. Its returned
covariance ``(Aᵀ W A)⁻¹`` is first-order and ignores that bias.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sensorgym.trackers.bearings.models import STATE_DIM, BearingsGaussian, bearing_sequence

FloatArray = NDArray[np.float64]


def pseudolinear_estimate(
    z: ArrayLike,
    times: ArrayLike,
    platform_positions: ArrayLike,
    sigma: float,
    t_ref: float,
    iterations: int = 2,
) -> BearingsGaussian:
    """Weighted pseudo-linear estimate of the state at ``t_ref`` from bearings ``z`` ``(..., K)``.

    ``times`` ``(K,)`` (s), ``platform_positions`` ``(..., K, 2)`` (m). Raises ``ValueError`` when
    the system is rank deficient for some scenario (fewer than 4 bearings, or no platform
    manoeuvre: the range is then unobservable).
    """
    z, times, p = bearing_sequence(z, times, platform_positions)
    K = times.shape[0]
    if K < STATE_DIM:
        raise ValueError(f"z: need at least {STATE_DIM} bearings, got {K}")
    if not np.isfinite(sigma) or sigma <= 0.0:
        raise ValueError(f"sigma: must be positive, got {sigma}")
    dt = times - float(t_ref)
    c, s = np.cos(z), np.sin(z)
    A = np.stack([c, -s, dt * c, -dt * s], axis=-1)  # (..., K, 4)
    b = p[..., 0] * c - p[..., 1] * s
    w = np.ones_like(z)
    for it in range(iterations + 1):
        # x̂ = (Aᵀ W A)⁻¹ Aᵀ W b
        AtW = np.swapaxes(A, -1, -2) * w[..., None, :]
        N = AtW @ A
        scale = np.sqrt(np.diagonal(N, axis1=-2, axis2=-1))
        Ns = N / (scale[..., :, None] * scale[..., None, :])
        if np.any(np.linalg.cond(Ns) > 1e12):
            raise ValueError("z: pseudo-linear system is rank deficient (no platform manoeuvre?)")
        x = np.linalg.solve(N, np.einsum("...ik,...k->...i", AtW, b)[..., None])[..., 0]
        if it == iterations:
            break
        # w_k = 1/(σ² r̂_k²), ranges from the current iterate
        pos = x[..., None, :2] + dt[:, None] * x[..., None, 2:]
        r2 = np.sum((pos - p) ** 2, axis=-1)
        w = 1.0 / (sigma**2 * np.maximum(r2, 1.0))
    if iterations == 0:
        pos = x[..., None, :2] + dt[:, None] * x[..., None, 2:]
        w = 1.0 / (sigma**2 * np.maximum(np.sum((pos - p) ** 2, axis=-1), 1.0))
        N = (np.swapaxes(A, -1, -2) * w[..., None, :]) @ A
    P = np.linalg.inv(N)
    return BearingsGaussian(x, 0.5 * (P + np.swapaxes(P, -1, -2)), t_ref)
