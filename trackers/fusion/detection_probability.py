"""Detection probability and detection parameter of an imaging channel (paper 004, theory §9.4).

Paper 004 writes the detection probability of a rectangle of constant contrast on a uniform
background with the Laplace function ``Φ₀(x) = (2π)^{-1/2} ∫₀ˣ exp(−t²/2) dt``::

    (9)  P_n = 0.5 + Φ₀( q_n − Φ₀⁻¹(0.5 − F) )
    (13) q_N = Φ₀⁻¹(0.5 − F_N) + Φ₀⁻¹(P_N − 0.5)

Because ``Φ₀(x) = Φ(x) − ½`` with ``Φ`` the standard normal CDF, (9) is
``P = Φ(q − z_{1−F})`` with ``z_{1−F} = Φ⁻¹(1 − F)``, and (13) is its inverse
``q = z_{1−F} + Φ⁻¹(P)`` (theory §9.4 [R,V]). Both are evaluated with ``scipy.stats.norm``
(``isf``/``sf`` keep full precision for small ``F`` and for ``P`` close to one).

The detection parameter of ``N`` channels observed together is eq. (10); the paper's print is
garbled between the root-sum-square ``q = √(Σ q_n²)`` (the matched-filter SNR of independent
channels, our default) and the plain sum ``Σ q_n`` (theory §13.36), so both are offered.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.stats import norm

from sensorgym.trackers.validation import finite_array

FloatArray = NDArray[np.float64]
CombineRule = Literal["rss", "sum"]


def _probability(value: ArrayLike, name: str, *, open_interval: bool) -> FloatArray:
    p = finite_array(value, name)
    bad = (p <= 0.0) | (p >= 1.0) if open_interval else (p < 0.0) | (p > 1.0)
    if np.any(bad):
        interval = "(0, 1)" if open_interval else "[0, 1]"
        raise ValueError(f"{name}: probabilities must lie in {interval}")
    return p


def detection_threshold(false_alarm: ArrayLike) -> FloatArray:
    """``z_{1−F} = Φ⁻¹(1 − F) = Φ₀⁻¹(0.5 − F)``: the normalised threshold for false-alarm rate F."""
    F = _probability(false_alarm, "false_alarm", open_interval=True)
    return norm.isf(F)


def detection_probability(q: ArrayLike, false_alarm: ArrayLike) -> FloatArray:
    """Eq. (9): ``P = 0.5 + Φ₀(q − Φ₀⁻¹(0.5 − F)) = Φ(q − z_{1−F})``.

    ``q``: detection parameter (signal-to-noise ratio, dimensionless); ``false_alarm``: F in
    (0, 1). Broadcast together. ``detection_probability(3, 0.01) = 0.7497`` (RT-14).
    """
    q = finite_array(q, "q")
    return norm.cdf(q - detection_threshold(false_alarm))


def detection_parameter(probability: ArrayLike, false_alarm: ArrayLike) -> FloatArray:
    """Eq. (13), the inverse of (9): ``q = Φ₀⁻¹(0.5 − F) + Φ₀⁻¹(P − 0.5) = z_{1−F} + Φ⁻¹(P)``.

    ``probability`` P and ``false_alarm`` F both in the open interval (0, 1).
    """
    P = _probability(probability, "probability", open_interval=True)
    # q = z_{1−F} + Φ⁻¹(P)
    return detection_threshold(false_alarm) + norm.ppf(P)


def combined_detection_parameter(
    q_channels: ArrayLike, *, axis: int = -1, rule: CombineRule = "rss"
) -> FloatArray:
    """Eq. (10): detection parameter of the integrated system from the per-channel ``q_n``.

    ``rule="rss"`` gives ``q = √(Σ_n q_n²)`` (default, the SNR of a matched filter over
    independent channels); ``rule="sum"`` gives the alternative reading ``q = Σ_n q_n``.
    ``q_channels`` must be non-negative; the sum runs over ``axis``.
    """
    q = finite_array(q_channels, "q_channels")
    if np.any(q < 0.0):
        raise ValueError("q_channels: detection parameters must be non-negative")
    if rule == "rss":
        # q = √(Σ_n q_n²)
        return np.sqrt(np.sum(q * q, axis=axis))
    if rule == "sum":
        # q = Σ_n q_n
        return np.sum(q, axis=axis)
    raise ValueError(f"rule: expected 'rss' or 'sum', got {rule!r}")


def axis_holding_probability(size_g: ArrayLike, size_v: ArrayLike, sigma: ArrayLike) -> FloatArray:
    """Eq. (12): ``P_c = [2Φ₀(g/(2σ_∞))]·[2Φ₀(v/(2σ_∞))]``, with ``2Φ₀(x) = 2Φ(x) − 1``.

    Probability that the optical axis stays inside the visible projection of angular size
    ``g × v`` when the stationary tracking error has standard deviation ``sigma`` (same
    angular unit) in each plane. ``sigma`` must be positive.
    """
    g = finite_array(size_g, "size_g")
    v = finite_array(size_v, "size_v")
    s = finite_array(sigma, "sigma")
    if np.any(g < 0.0) or np.any(v < 0.0):
        raise ValueError("size_g, size_v: angular sizes must be non-negative")
    if np.any(s <= 0.0):
        raise ValueError("sigma: tracking error must be positive")

    def two_phi0(x: FloatArray) -> FloatArray:
        # 2Φ₀(x) = Φ(x) − Φ(−x), computed without cancellation
        return 1.0 - 2.0 * norm.sf(x)

    # P_c = [2Φ₀(g/2σ)]·[2Φ₀(v/2σ)]
    return two_phi0(g / (2.0 * s)) * two_phi0(v / (2.0 * s))
