"""Accuracy of the integrated tracking system: relative posterior variance (paper 004, theory §9.4).

With ``δ_k = d_k / σ_λ²`` the posterior variance relative to the prior ``σ_λ² = (θ₀ L)²`` and
``D̃_k = R_λ² δ_{k−1} + (1 − R_λ²)`` the relative variance of the extrapolated estimate, the
garbled eq. (11) is reconstructed in two forms (theory §9.4 [R], §13.36)::

    (11a) mixture:      δ_k = (1 − P)·D̃_k + P·D̃_k / (1 + z² D̃_k)   (object detected with prob. P)
    (11b) information:  δ_k = [ D̃_k⁻¹ + P z² ]⁻¹                     (information averaged over P)

where ``z`` is the generalised detection parameter, read as ``z² = q²/2`` (the print shows
"z … q … 2"; theory §13.36). The mixture form is the default. The stationary
solution ``δ_∞`` gives the tracking error ``Δ = θ₀ L √δ_∞`` (metres when ``θ₀`` is in rad and
``L`` in m) and, through eq. (12), the probability of holding the axis on the object.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sensorgym.trackers.validation import finite_array

FloatArray = NDArray[np.float64]
VarianceForm = Literal["mixture", "information"]


def generalised_detection_parameter_sq(q: ArrayLike) -> FloatArray:
    """``z² = q²/2``: the reading of the garbled definition under eq. (11) (theory §13.36)."""
    q = finite_array(q, "q")
    return 0.5 * q * q


def _check(P: ArrayLike, z2: ArrayLike, R: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
    P = finite_array(P, "P")
    z2 = finite_array(z2, "z2")
    R = finite_array(R, "R")
    if np.any((P < 0.0) | (P > 1.0)):
        raise ValueError("P: detection probability must lie in [0, 1]")
    if np.any(z2 < 0.0):
        raise ValueError("z2: squared detection parameter must be non-negative")
    if np.any((R < 0.0) | (R >= 1.0)):
        raise ValueError("R: correlation coefficient must lie in [0, 1)")
    return P, z2, R


def relative_variance_step(
    delta_prev: ArrayLike,
    P: ArrayLike,
    z2: ArrayLike,
    R: ArrayLike,
    form: VarianceForm = "mixture",
) -> FloatArray:
    """One step of recurrence (11): ``δ_{k−1} ↦ δ_k`` (all arguments broadcast together).

    ``delta_prev``: relative posterior variance at k−1 (≥ 0; 1 before lock-on);
    ``P``: detection probability of the integrated system, eq. (9)–(10);
    ``z2``: squared generalised detection parameter ``z²``; ``R``: correlation ``R_λ``.
    """
    d = finite_array(delta_prev, "delta_prev")
    if np.any(d < 0.0):
        raise ValueError("delta_prev: relative variance must be non-negative")
    P, z2, R = _check(P, z2, R)
    # D̃_k = R² δ_{k−1} + (1 − R²)
    D = R * R * d + (1.0 - R * R)
    if form == "mixture":
        # δ_k = (1 − P) D̃_k + P D̃_k / (1 + z² D̃_k)                                   (11a)
        return (1.0 - P) * D + P * D / (1.0 + z2 * D)
    if form == "information":
        # δ_k = [D̃_k⁻¹ + P z²]⁻¹                                                       (11b)
        return D / (1.0 + P * z2 * D)
    raise ValueError(f"form: expected 'mixture' or 'information', got {form!r}")


def relative_variance_history(
    P: ArrayLike,
    z2: ArrayLike,
    R: ArrayLike,
    steps: int,
    form: VarianceForm = "mixture",
    delta0: float = 1.0,
) -> FloatArray:
    """``δ_0, δ_1, …, δ_steps`` of recurrence (11), shape ``(steps + 1, *broadcast shape)``.

    ``delta0 = 1`` is the prior (no tracking yet: ``d_0 = σ_λ²``).
    """
    if steps < 0:
        raise ValueError("steps: must be non-negative")
    P, z2, R = _check(P, z2, R)
    d = np.broadcast_to(np.float64(delta0), np.broadcast_shapes(P.shape, z2.shape, R.shape))
    out = [d.copy()]
    for _ in range(steps):
        d = relative_variance_step(d, P, z2, R, form)
        out.append(d)
    return np.stack(out)


def stationary_relative_variance(
    P: ArrayLike, z2: ArrayLike, R: ArrayLike, form: VarianceForm = "mixture"
) -> FloatArray:
    """The fixed point ``δ_∞`` of recurrence (11) (the paper's "(9)" under eq. (12) means (11)).

    Closed form, no iteration. With ``c = 1 − R²`` substitute ``δ = (D − c)/R²`` into
    ``δ = f(D)`` and clear denominators to get ``A D² + B D + C = 0`` with ``C = −c``:

    * information (11b): ``A = P z²``, ``B = c − P z² c``;
    * mixture (11a): ``A = z² (1 − R²(1 − P))``, ``B = c − z² c``.

    ``A ≥ 0`` and ``C < 0``, so exactly one root is positive; it is evaluated in the form
    free of cancellation for the sign of ``B``. ``A = 0`` (no information) gives
    ``δ_∞ = 1``; ``R = 0`` gives ``D = 1`` and ``δ_∞ = f(1)``.
    """
    P, z2, R = _check(P, z2, R)
    P, z2, R = np.broadcast_arrays(P, z2, R)
    r2 = R * R
    c = 1.0 - r2
    if form == "information":
        # (D − c)(1 + P z² D) = R² D
        A = P * z2
        B = c - P * z2 * c
    elif form == "mixture":
        # (D − c)(1 + z² D) = R² [D + (1 − P) z² D²]
        A = z2 * (1.0 - r2 * (1.0 - P))
        B = c - z2 * c
    else:
        raise ValueError(f"form: expected 'mixture' or 'information', got {form!r}")
    C = -c
    # positive root of A D² + B D + C, in whichever form avoids cancellation:
    # D = −2C / (B + √(B² − 4AC)) for B ≥ 0 (equals 1 when A = 0), else (√(…) − B) / 2A
    root = np.sqrt(B * B - 4.0 * A * C)
    with np.errstate(divide="ignore", invalid="ignore"):
        D = np.where(B >= 0.0, (-2.0 * C) / (B + root), (root - B) / (2.0 * A))
    safe_r2 = np.where(r2 > 0.0, r2, 1.0)
    return np.where(r2 > 0.0, (D - c) / safe_r2, relative_variance_step(1.0, P, z2, R, form))


def steps_to_stationarity(
    P: ArrayLike,
    z2: ArrayLike,
    R: ArrayLike,
    form: VarianceForm = "mixture",
    tolerance: float = 0.05,
    delta0: float = 1.0,
    max_steps: int = 100_000,
) -> NDArray[np.int64]:
    """First step ``k`` with ``|δ_k − δ_∞| ≤ tolerance·δ_∞``, starting from ``δ_0 = delta0``.

    This is the "stationary δ is reached after 5…20 steps" of theory §9.4 (RT-15).
    Raises ``ValueError`` if it is not reached within ``max_steps``.
    """
    if tolerance <= 0.0:
        raise ValueError("tolerance: must be positive")
    P, z2, R = _check(P, z2, R)
    d_inf = stationary_relative_variance(P, z2, R, form)
    d = np.broadcast_to(np.float64(delta0), d_inf.shape).copy()
    k = np.zeros(d_inf.shape, dtype=np.int64)
    done = np.abs(d - d_inf) <= tolerance * d_inf
    for step in range(1, max_steps + 1):
        if np.all(done):
            return k
        d = relative_variance_step(d, P, z2, R, form)
        newly = ~done & (np.abs(d - d_inf) <= tolerance * d_inf)
        k = np.where(newly, step, k)
        done |= newly
    if not np.all(done):
        raise ValueError("steps_to_stationarity: not reached within max_steps")
    return k


def tracking_error(delta_inf: ArrayLike, theta0: ArrayLike, distance: ArrayLike) -> FloatArray:
    """``Δ = σ_λ √δ_∞ = θ₀ L √δ_∞`` (theory §9.4): RMS tracking error in the unit of ``L``.

    ``theta0``: RMS angular deviation of the line of sight without tracking (rad);
    ``distance``: observation range ``L``.
    """
    d = finite_array(delta_inf, "delta_inf")
    t = finite_array(theta0, "theta0")
    L = finite_array(distance, "distance")
    if np.any(d < 0.0) or np.any(t < 0.0) or np.any(L < 0.0):
        raise ValueError("delta_inf, theta0, distance: must be non-negative")
    return t * L * np.sqrt(d)
