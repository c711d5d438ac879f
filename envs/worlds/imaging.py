"""Simulated co-boresighted imaging channels watching one object (paper 004, theory §9.1, §9.4).

World model only: it imports no tracker. The tracker that sees these images,
:class:`sensorgym.trackers.fusion.tracker.FusionTracker`, is run in the loop (its matched model
and the closed-loop simulation) by :mod:`sensorgym.reproduce.experiments.paper004_closed_loop`.

One tracking plane. The object's line-of-sight angle λ (mrad) follows the Gauss–Markov law (1)
``λ_k = R_λ λ_{k−1} + σ_λ √(1 − R_λ²) ξ_k`` with ``σ_λ = θ₀`` (angles here, so the paper's
``σ_λ = θ₀ L`` is ``θ₀`` in angular units). Each channel ``n`` forms a 1-D image of ``J``
pixels across the plane, centred on the optical axis ``a_k``; the object is the paper's
rectangle of constant contrast on a uniform background (theory §9.4), of angular size ``g``,
blurred by a Gaussian point-spread function::

    s_m(x) = c_{n,m}/2 · [erf((x + g/2)/(√2 σ_psf)) − erf((x − g/2)/(√2 σ_psf))]
    y_j    = s_{ϑ_k}(x_j − (λ_k − a_k)) + n_j ,   n_j ~ N(0, σ_n²)               (2)

with view 0 the background (``c = 0``: invisible in that channel). The views of each channel
evolve by their own Markov chain ``π^{(n)}``, independently of the other channels.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.special import erf

from sensorgym.trackers.validation import finite_array

FloatArray = NDArray[np.float64]


def box_profile(x: ArrayLike, size: float, psf_std: float) -> tuple[FloatArray, FloatArray]:
    """Unit-contrast blurred rectangle of width ``size`` and its slope ``d/dx`` at ``x``."""
    x = np.asarray(x, dtype=np.float64)
    a = np.sqrt(2.0) * psf_std
    value = 0.5 * (erf((x + 0.5 * size) / a) - erf((x - 0.5 * size) / a))
    slope = (np.exp(-(((x + 0.5 * size) / a) ** 2)) - np.exp(-(((x - 0.5 * size) / a) ** 2))) / (
        np.sqrt(np.pi) * a
    )
    return value, slope


def _default_transition() -> FloatArray:
    return np.array([[0.8, 0.1, 0.1], [0.06, 0.9, 0.04], [0.06, 0.04, 0.9]])


@dataclass(frozen=True)
class ImagingScene:
    """Channels, object and motion of the paper 004 simulation (angles in mrad).

    The defaults are our "several weak channels" scenario: four channels with views
    {background, positive contrast, negative contrast}, each of matched-filter SNR ``q ≈ 3.3``
    (``P ≈ 0.82`` at ``F = 0.01``) and invisible (background) 23 % of the time in stationary
    regime, independently; θ₀ = 5 mrad and R_λ = 0.99 as in the paper's Fig. 2.
    """

    contrast: FloatArray = field(default_factory=lambda: np.array([[0.0, 1.5, -1.5]] * 4))
    """``c_{n,m}``: object contrast of view m in channel n, ``(N, M)``; column 0 (background)
    must be zero (intensity units)."""
    noise_std: FloatArray = field(default_factory=lambda: np.full(4, 1.0))
    """σ_n: pixel noise of each channel, ``(N,)`` (intensity units)."""
    transition: FloatArray = field(default_factory=lambda: np.stack([_default_transition()] * 4))
    """``π[n, μ, m]``: view transition probabilities per frame, row-stochastic ``(N, M, M)``."""
    object_size: float = 4.0
    """g: angular size of the object in the tracking plane (mrad)."""
    psf_std: float = 1.5
    """Standard deviation of the Gaussian blur (mrad)."""
    pixel_pitch: float = 0.5
    """Angular size of one pixel (mrad)."""
    pixels: int = 48
    """J: pixels per image (field of view ``J × pitch``)."""
    correlation: float = 0.99
    """R_λ of the line-of-sight motion (per frame)."""
    theta0: float = 5.0
    """θ₀ = σ_λ: RMS deviation of the line of sight without tracking (mrad)."""

    def __post_init__(self) -> None:
        c = finite_array(self.contrast, "contrast")
        sig = finite_array(self.noise_std, "noise_std")
        pi = finite_array(self.transition, "transition")
        if c.ndim != 2 or c.shape[1] < 2 or np.any(c[:, 0] != 0.0):
            raise ValueError("contrast: expected (N, M ≥ 2) with a zero background column 0")
        N, M = c.shape
        if sig.shape != (N,) or np.any(sig <= 0.0):
            raise ValueError(f"noise_std: expected {N} positive values")
        if pi.shape != (N, M, M) or np.any(pi < 0.0) or not np.allclose(pi.sum(-1), 1.0):
            raise ValueError(f"transition: expected row-stochastic matrices {(N, M, M)}")
        for name in ("object_size", "psf_std", "pixel_pitch", "theta0"):
            if not getattr(self, name) > 0.0:
                raise ValueError(f"{name}: must be positive")
        if self.pixels < 4:
            raise ValueError("pixels: need at least 4 pixels")
        if not 0.0 <= self.correlation < 1.0:
            raise ValueError("correlation: must lie in [0, 1)")

    @property
    def channels(self) -> int:
        return int(np.asarray(self.contrast).shape[0])

    @property
    def pixel_centres(self) -> FloatArray:
        """Angular positions ``x_j`` of the pixel centres relative to the axis (mrad)."""
        return (np.arange(self.pixels) - 0.5 * (self.pixels - 1)) * self.pixel_pitch

    @property
    def half_field(self) -> float:
        """Half the field of view (mrad)."""
        return 0.5 * self.pixels * self.pixel_pitch

    def templates(self, shift: ArrayLike = 0.0) -> tuple[FloatArray, FloatArray]:
        """Templates ``s_{n,m}(x_j − shift)`` and slopes, ``(..., N, M, J)`` for ``shift (...)``."""
        sh = finite_array(shift, "shift")
        x = self.pixel_centres - sh[..., None, None, None]
        value, slope = box_profile(x, self.object_size, self.psf_std)
        c = np.asarray(self.contrast)[..., None]
        return c * value, c * slope

    def detection_parameter(self) -> FloatArray:
        """Matched-filter SNR ``q_{n,m} = √(Σ_j s²)/σ_n`` of each view when centred, ``(N, M)``."""
        s, _ = self.templates()
        return np.sqrt(np.sum(s**2, axis=-1)) / np.asarray(self.noise_std)[:, None]

    def stationary_views(self) -> FloatArray:
        """Stationary distribution of each channel's view chain, ``(N, M)``."""
        out = []
        for pi in np.asarray(self.transition):
            w, v = np.linalg.eig(pi.T)
            p = np.real(v[:, np.argmin(np.abs(w - 1.0))])
            out.append(p / p.sum())
        return np.array(out)

    # -- simulation: the only place noise is drawn -------------------------------------------

    def initial_world(
        self, rng: np.random.Generator, batch_size: int
    ) -> tuple[FloatArray, NDArray[np.int64]]:
        """λ_0 = 0 (the operator designates the object on the axis) and visible initial views
        (uniform over the object views of each channel): ``(B,)``, ``(B, N)``."""
        M = np.asarray(self.contrast).shape[1]
        views = rng.integers(1, M, size=(batch_size, self.channels))
        return np.zeros(batch_size), views

    def step_world(
        self, rng: np.random.Generator, angle: FloatArray, views: NDArray[np.int64]
    ) -> tuple[FloatArray, NDArray[np.int64]]:
        """Advance λ by (1) and each channel's view by its Markov chain, one frame."""
        R = self.correlation
        # λ_k = R λ_{k−1} + σ_λ √(1 − R²) ξ_k
        new_angle = R * angle + self.theta0 * np.sqrt(1.0 - R * R) * rng.standard_normal(
            angle.shape
        )
        pi = np.asarray(self.transition)
        rows = pi[np.arange(self.channels)[None, :], views]  # (B, N, M)
        u = rng.uniform(size=views.shape)[..., None]
        new_views = np.minimum(np.sum(np.cumsum(rows, axis=-1) < u, axis=-1), rows.shape[-1] - 1)
        return new_angle, new_views

    def render(
        self,
        rng: np.random.Generator,
        angle: FloatArray,
        axis: FloatArray,
        views: NDArray[np.int64],
    ) -> FloatArray:
        """Images ``(B, N, J)`` of the object at λ seen with the optical axis at ``axis``, (2)."""
        s, _ = self.templates(angle - axis)  # (B, N, M, J)
        B, N = views.shape
        clean = s[np.arange(B)[:, None], np.arange(N)[None, :], views]  # (B, N, J)
        noise = rng.standard_normal(clean.shape) * np.asarray(self.noise_std)[None, :, None]
        return clean + noise
