"""Multi-channel fused angle tracker with weighted discriminators (paper 004, theory §9.1–9.3).

``N`` co-boresighted imaging channels watch one object; one tracking plane is treated, with the
continuous parameter λ (deviation of the line of sight from the optical axis). Each channel n
has a discrete Markov chain of object views ``ϑ_m^{(n)}``, ``m = 0..M−1``; **view 0 is the
background** (the object is not visible in that channel, ``s ≡ 0``). λ is Gauss–Markov::

    (1)  λ_k = R_λ λ_{k−1} + σ_λ √(1 − R_λ²) ξ_k
    (2)  y_{jk}^{(n)} = s_j^{(n)}(λ_k, ϑ_k^{(n)}) + n_{jk}^{(n)} ,   n^{(n)} ~ N(0, σ_n²) white

Closed loop (Fig. 1): before frame k the axis is pointed at the extrapolated estimate
``λ_k^э = R_λ λ̂_{k−1}`` (:meth:`FusionTracker.command`), so the images arrive centred on
``λ_k^э`` and the tracker needs the templates and their slopes at zero shift only. One step
(:meth:`FusionTracker.update`, theory §9.2 reconstructions, §13.36–13.41 choices):

* extrapolation: ``D_k = R_λ² d_{k−1} + d₀``, ``d₀ = (1 − R_λ²) σ_λ²``;
* per channel and view, the log-likelihood ratio with its energy term (theory §13.37)
  ``Π = σ⁻² Σ_j y_j s_j − ½ σ⁻² Σ_j s_j²``, its derivative (the discriminator output)
  ``Π′ = σ⁻² Σ_j (y_j − s_j) ∂s_j/∂λ = −σ⁻² Σ_j (y_j − s_j) s′_j`` and the Fisher information
  ``I = σ⁻² Σ_j s′_j²`` (theory §13.38); background: ``Π = Π′ = I = 0``;
* (3) view posteriors: ``P_k(ϑ_m) ∝ exp{Π_m}·g_m·Σ_μ π(ϑ_m | ϑ_μ) P_{k−1}(ϑ_μ)`` — detection
  likelihood × transition prediction — where ``g_m = (1 + D_k I_m)^{-1/2}
  exp{½ D_k Π′_m² / (1 + D_k I_m)}`` is the Gaussian factor of integrating the quadratic LLR
  expansion over the extrapolated density (the illegible factor of (3); switchable);
* (5) ``d_k = [D_k⁻¹ + Σ_n Σ_m P_k(ϑ_m^{(n)}) I_n(ϑ_m^{(n)})]⁻¹``;
* (4) ``λ̂_k = λ_k^э + d_k Σ_n Σ_m P_k(ϑ_m^{(n)}) Π′_n(ϑ_m^{(n)})``: the weighted sum of the
  discriminator outputs. For one channel and a certain view the gain ``d_k`` equals the
  paper's ``D_k(ϑ) = D_k / (1 + D_k I)``; for several channels the common gain ``d_k`` counts
  each channel's information once (summing per-channel ``D_k(ϑ^{(n)})`` would over-count it);
* (7), optional (``gain="stationary"``): the block diagram's simplified estimator with a constant
  gain, the stationary ``d`` with all channels seeing the object;
* loop opening (theory §9.3): when the object posterior ``1 − P_k(background)`` of **every** channel is
  below ``open_threshold`` the loop opens, ``λ̂_k = λ_k^э`` and ``d_k = D_k`` (coasting).

Everything is batched over a leading scenario axis ``B`` and deterministic.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sensorgym.trackers.fusion.variance import stationary_relative_variance
from sensorgym.trackers.validation import finite_array

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class FusionModel:
    """What the tracker knows about the channels and the motion (shapes: N channels, M views,
    J pixels per image). Build one matched to a simulated world with
    ``sensorgym.reproduce.experiments.paper004_closed_loop.matched_model(scene)``.

    All channels share M and J. A channel with fewer views is padded with unreachable views
    (zero template, zero transition probability into them): their posterior is zero from the
    first update on. Images of different sizes are padded with pixels where every template is
    zero (they add nothing to Π, Π′ or I).
    """

    templates: FloatArray
    """``s_{n,m,j}`` reference images at zero shift, ``(N, M, J)`` (intensity); view 0 must be
    the background (all zeros)."""
    template_slopes: FloatArray
    """``∂s_{n,m}(x_j)/∂x`` at zero shift, ``(N, M, J)`` (intensity per unit of λ)."""
    noise_std: FloatArray
    """σ_n of each channel's pixel noise, ``(N,)`` (intensity)."""
    transition: FloatArray
    """``π[n, μ, m] = P(ϑ_k = m | ϑ_{k−1} = μ)``, row-stochastic, ``(N, M, M)``."""
    correlation: float = 0.99
    """R_λ: correlation of λ between adjacent frames, in [0, 1)."""
    prior_std: float = 5.0
    """σ_λ: prior (untracked) standard deviation of λ (unit of λ, e.g. mrad)."""
    open_threshold: float = 1e-3
    """The loop opens when every channel's object posterior is below this value."""
    gaussian_factor: bool = True
    """Include the Gaussian marginalisation factor ``g_m`` in (3)."""
    gain: Literal["posterior", "stationary"] = "posterior"
    """``"posterior"``: gain ``d_k`` of (4)–(5). ``"stationary"``: the simplified estimator (7)
    of the block diagram, with the constant gain :attr:`stationary_gain` (theory §13.39)."""

    def __post_init__(self) -> None:
        s = finite_array(self.templates, "templates")
        ds = finite_array(self.template_slopes, "template_slopes")
        sig = finite_array(self.noise_std, "noise_std")
        pi = finite_array(self.transition, "transition")
        if s.ndim != 3 or ds.shape != s.shape:
            raise ValueError("templates, template_slopes: expected equal shapes (N, M, J)")
        N, M, _ = s.shape
        if M < 2:
            raise ValueError("templates: need the background view 0 and at least one object view")
        if np.any(s[:, 0] != 0.0) or np.any(ds[:, 0] != 0.0):
            raise ValueError("templates: view 0 is the background and must be all zeros")
        if sig.shape != (N,) or np.any(sig <= 0.0):
            raise ValueError(f"noise_std: expected {N} positive values")
        if pi.shape != (N, M, M) or np.any(pi < 0.0) or not np.allclose(pi.sum(-1), 1.0):
            raise ValueError(f"transition: expected row-stochastic matrices of shape {(N, M, M)}")
        if not 0.0 <= self.correlation < 1.0:
            raise ValueError("correlation: R_λ must lie in [0, 1)")
        if not (np.isfinite(self.prior_std) and self.prior_std > 0.0):
            raise ValueError("prior_std: σ_λ must be positive")
        if not 0.0 <= self.open_threshold < 1.0:
            raise ValueError("open_threshold: must lie in [0, 1)")
        if self.gain not in ("posterior", "stationary"):
            raise ValueError(f"gain: expected 'posterior' or 'stationary', got {self.gain!r}")

    @property
    def channels(self) -> int:
        return int(self.templates.shape[0])

    @property
    def views(self) -> int:
        return int(self.templates.shape[1])

    @property
    def transition_variance(self) -> float:
        """``d₀ = (1 − R_λ²) σ_λ²``, the variance of the transition density."""
        return (1.0 - self.correlation**2) * self.prior_std**2

    @property
    def fisher_information(self) -> FloatArray:
        """``I_n(ϑ_m) = σ_n⁻² Σ_j s′²``, ``(N, M)`` (per unit of λ²)."""
        return np.sum(self.template_slopes**2, axis=-1) / self.noise_std[:, None] ** 2

    @property
    def detection_parameter(self) -> FloatArray:
        """``q_n(ϑ_m) = √(Σ_j s²)/σ_n``: the matched-filter SNR of each view, ``(N, M)``."""
        return np.sqrt(np.sum(self.templates**2, axis=-1)) / self.noise_std[:, None]

    @property
    def stationary_gain(self) -> float:
        """γ of (7): the stationary posterior variance with every channel seeing the object in
        its most informative view, the fixed point of ``d = [(R² d + d₀)⁻¹ + Σ_n max_m I_n]⁻¹``
        (recurrence (11b) with P = 1, ``z² = σ_λ² Σ_n max_m I_n``), in the unit of λ²."""
        z2 = self.prior_std**2 * float(np.sum(np.max(self.fisher_information, axis=1)))
        delta = stationary_relative_variance(1.0, z2, self.correlation, "information")
        return float(delta) * self.prior_std**2

    def select_channels(self, channels: ArrayLike) -> FusionModel:
        """The model restricted to some channels (e.g. one, for single-channel trackers)."""
        idx = np.atleast_1d(np.asarray(channels, dtype=np.int64))
        return replace(
            self,
            templates=self.templates[idx],
            template_slopes=self.template_slopes[idx],
            noise_std=self.noise_std[idx],
            transition=self.transition[idx],
        )


@dataclass(frozen=True)
class FusionState:
    """Batched tracker state (leading axis B)."""

    estimate: FloatArray
    """λ̂_k, ``(B,)`` (unit of λ)."""
    variance: FloatArray
    """d_k, posterior variance of λ̂_k, ``(B,)``."""
    view_posterior: FloatArray
    """``P_k(ϑ_m^{(n)})``, ``(B, N, M)``; index 0 is the background."""
    loop_open: NDArray[np.bool_]
    """True where the last step coasted because no channel saw the object, ``(B,)``."""

    def __post_init__(self) -> None:
        B = self.estimate.shape[0]
        if (
            self.variance.shape != (B,)
            or self.view_posterior.ndim != 3
            or self.view_posterior.shape[0] != B
            or self.loop_open.shape != (B,)
        ):
            raise ValueError("FusionState: field shapes do not share the batch axis")

    @property
    def object_probability(self) -> FloatArray:
        """``1 − P_k(background)`` per channel, ``(B, N)``: posterior detection probability."""
        return 1.0 - self.view_posterior[..., 0]


@dataclass(frozen=True)
class FusionTracker:
    """Pure fused tracker: ``update(state, images) -> state``, ``command(state) -> λ^э``."""

    model: FusionModel

    def initial_state(
        self, batch_size: int, estimate: ArrayLike = 0.0, variance: float | None = None
    ) -> FusionState:
        """State at lock-on: the object designated at ``estimate`` (default 0, the axis) with
        variance ``variance`` (default σ_λ²); uniform view prior ``1/M`` (theory §9.1)."""
        if batch_size < 1:
            raise ValueError("batch_size: must be ≥ 1")
        var = self.model.prior_std**2 if variance is None else float(variance)
        if not (np.isfinite(var) and var > 0.0):
            raise ValueError("variance: must be positive")
        M, N = self.model.views, self.model.channels
        return FusionState(
            estimate=np.broadcast_to(finite_array(estimate, "estimate"), (batch_size,)).copy(),
            variance=np.full(batch_size, var),
            view_posterior=np.full((batch_size, N, M), 1.0 / M),
            loop_open=np.zeros(batch_size, dtype=bool),
        )

    def command(self, state: FusionState) -> FloatArray:
        """Axis command for the next frame: the extrapolated estimate ``λ^э = R_λ λ̂``, ``(B,)``."""
        return self.model.correlation * state.estimate

    def update(self, state: FusionState, images: ArrayLike) -> FusionState:
        """One frame: ``images (B, N, J)`` taken with the axis at :meth:`command` (state)."""
        mdl = self.model
        B = state.estimate.shape[0]
        y = finite_array(images, "images", tail=mdl.templates.shape[::2])
        if y.shape[0] != B or y.ndim != 3:
            raise ValueError(f"images: expected shape {(B, *mdl.templates.shape[::2])}")
        if state.view_posterior.shape[1:] != mdl.templates.shape[:2]:
            raise ValueError("state: view posteriors do not match the model's channels and views")
        s, ds = mdl.templates, mdl.template_slopes
        inv_var = 1.0 / mdl.noise_std**2  # (N,)
        R = mdl.correlation
        # λ^э = R_λ λ̂_{k−1};  D_k = R_λ² d_{k−1} + d₀
        lam_e = R * state.estimate
        D = R * R * state.variance + mdl.transition_variance
        # Π = σ⁻² Σ y s − ½ σ⁻² Σ s²                                   (LLR, theory §9.2, §13.37)
        Pi = inv_var[:, None] * (np.einsum("bnj,nmj->bnm", y, s) - 0.5 * np.sum(s * s, axis=-1))
        # Π′ = −σ⁻² Σ (y − s) s′   (the image is s(x − (λ − λ^э)))     (discriminator output)
        dPi = -inv_var[:, None] * (np.einsum("bnj,nmj->bnm", y, ds) - np.sum(s * ds, axis=-1))
        info = mdl.fisher_information[None]  # I = σ⁻² Σ s′²,  (1, N, M)
        log_like = Pi
        if mdl.gaussian_factor:
            # g = (1 + D I)^{-1/2} exp{½ D Π′² / (1 + D I)}
            DI = 1.0 + D[:, None, None] * info
            log_like = log_like - 0.5 * np.log(DI) + 0.5 * D[:, None, None] * dPi**2 / DI
        # (3) P_k(ϑ_m) ∝ exp{…} Σ_μ π(ϑ_m | ϑ_μ) P_{k−1}(ϑ_μ)
        predicted = np.einsum("bnu,num->bnm", state.view_posterior, mdl.transition)
        with np.errstate(divide="ignore"):
            log_post = log_like + np.log(predicted)
        log_post -= np.max(log_post, axis=-1, keepdims=True)
        post = np.exp(log_post)
        post /= np.sum(post, axis=-1, keepdims=True)
        # (5) d_k = [D_k⁻¹ + Σ_n Σ_m P I]⁻¹
        d = 1.0 / (1.0 / D + np.sum(post * info, axis=(1, 2)))
        # (4) λ̂_k = λ^э + d_k Σ_n Σ_m P Π′   or   (7) λ̂_k = λ^э + γ Σ_n Σ_m P Π′
        gain = d if mdl.gain == "posterior" else mdl.stationary_gain
        lam = lam_e + gain * np.sum(post * dPi, axis=(1, 2))
        # theory §9.3: the loop opens when no channel holds the object
        open_loop = np.all(1.0 - post[..., 0] < mdl.open_threshold, axis=-1)
        return FusionState(
            estimate=np.where(open_loop, lam_e, lam),
            variance=np.where(open_loop, D, d),
            view_posterior=post,
            loop_open=open_loop,
        )
