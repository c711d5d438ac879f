"""Baselines for the paper 001 angle predictor (theory §8.9, §13.21).

Both share the interface of :class:`~sensorgym.trackers.angles.prediction.ABCPredictor`
(``initial_state(B)``, ``update(state, θ, ϕ, mask)``, ``predict(state, k)``), are pure and
batched over a leading track axis.

* :class:`LineFitPredictor` — the same range-free straight-line model as the A-B-C predictor,
  but fitted by least squares to **all** ``N + 1`` samples of the window instead of three
  (theory §13.21). With ``j = −N…0`` the frame offset from the latest sample C, the
  conditional horizontal trajectory ``(X_C + j δ_X, Y_C + j δ_Y)`` must lie on every measured
  azimuth ray: ``(X_C + j δ_X) cos θ_j − (Y_C + j δ_Y) sin θ_j = 0``. These ``N + 1`` homogeneous
  equations in ``p = (X_C, Y_C, δ_X, δ_Y)`` are solved in the total-least-squares sense
  (right singular vector of the smallest singular value); the sign is chosen so that C lies
  on the measured ray of θ_C. Heights follow from ``Z_j = h_j tan ϕ_j`` (``h_j`` the horizontal
  range of sample j on the fitted line) by an ordinary least-squares line ``Z_C + j δ_Z``.
  Exact for noise-free uniform rectilinear motion.
* :class:`AngleKalmanPredictor` — a constant-velocity Kalman filter run independently on θ and
  ϕ (the paper's "low-order polynomial of past angles" approach, theory §8.1 (a)), with wrapped
  azimuth residuals. Not exact for rectilinear motion: the angles of a straight path are not
  linear in time, so its error grows with the horizon.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sensorgym.trackers.angles.prediction import measurement_arrays, push_window
from sensorgym.trackers.geometry import unit_from_zup_angles, wrap_angle, zup_angles_from_unit
from sensorgym.trackers.validation import check_fields, finite_array

FloatArray = NDArray[np.float64]


def _horizon(steps: ArrayLike) -> FloatArray:
    k = finite_array(steps, "steps")
    if np.any(k < 0.0):
        raise ValueError("steps: prediction horizon must be non-negative")
    return k


@dataclass(frozen=True)
class WindowState:
    """Sliding windows of the last ``N + 1`` measured angles, oldest first (rad)."""

    azimuth_window: FloatArray
    """Measured azimuths θ, ``(B, N + 1)`` (rad)."""
    elevation_window: FloatArray
    """Measured elevations ϕ, ``(B, N + 1)`` (rad)."""
    count: NDArray[np.int64]
    """Frames in the window since the last (re)start of the warm-up, ``(B,)``."""

    def __post_init__(self) -> None:
        if self.azimuth_window.shape != self.elevation_window.shape or (
            self.azimuth_window.shape[0] != self.count.shape[0]
        ):
            raise ValueError("WindowState: window and count shapes disagree")

    @property
    def ready(self) -> NDArray[np.bool_]:
        """True where the window is full, ``(B,)``."""
        return self.count >= self.azimuth_window.shape[1]


@dataclass(frozen=True)
class LineFitPredictor:
    """Least-squares fit of the range-free straight trajectory to all N + 1 samples."""

    window: int = 50
    """N: the window holds the last N + 1 samples (≥ 2)."""

    def __post_init__(self) -> None:
        check_fields(self)  # every field of its annotated type: no bool for a count or a number
        if self.window < 2:
            raise ValueError(f"window: N must be ≥ 2, got {self.window}")

    def initial_state(self, batch_size: int) -> WindowState:
        if batch_size < 1:
            raise ValueError("batch_size: must be ≥ 1")
        W = self.window + 1
        return WindowState(
            np.zeros((batch_size, W)), np.zeros((batch_size, W)), np.zeros(batch_size, np.int64)
        )

    def update(
        self,
        state: WindowState,
        azimuth: ArrayLike,
        elevation: ArrayLike,
        mask: ArrayLike | None = None,
    ) -> WindowState:
        """Advance one frame: append the measured angles ``(B,)`` where ``mask`` (default:
        everywhere). Elsewhere the image is lost: a full window coasts (the fitted line's
        1-frame-ahead angles are appended), a window still filling restarts its warm-up."""
        if state.azimuth_window.shape[1] != self.window + 1:
            raise ValueError("state: window length does not match this predictor's N")
        az, el, m = measurement_arrays(azimuth, elevation, state.count.shape[0], mask)
        if np.all(m):
            coast_az, coast_el = az, el
        else:
            coast_az, coast_el = (a[:, 0] for a in self.predict(state, np.array([1.0])))
        push = m | state.ready
        return WindowState(
            push_window(state.azimuth_window, np.where(m, az, coast_az), push),
            push_window(state.elevation_window, np.where(m, el, coast_el), push),
            np.where(push, state.count + 1, 0),
        )

    def fit(self, state: WindowState) -> tuple[FloatArray, FloatArray]:
        """Conditional point C and per-frame increment, each ``(B, 3)`` (conditional metres)."""
        th, ph = state.azimuth_window, state.elevation_window
        N = self.window
        j = np.arange(-N, 1, dtype=np.float64) / N  # offsets scaled to [−1, 0] for conditioning
        c, s = np.cos(th), np.sin(th)
        # rows [cos θ_j, −sin θ_j, j cos θ_j, −j sin θ_j] · (X_C, Y_C, N δ_X, N δ_Y) = 0
        M = np.stack([c, -s, j * c, -j * s], axis=-1)
        p = np.linalg.svd(M)[2][:, -1, :]
        # C on the measured ray of θ_C, not the opposite one: (X_C, Y_C)·(sin θ_C, cos θ_C) > 0
        sign = np.where(p[:, 0] * s[:, -1] + p[:, 1] * c[:, -1] < 0.0, -1.0, 1.0)
        p = p * sign[:, None]
        X = p[:, :1] + j * p[:, 2:3]
        Y = p[:, 1:2] + j * p[:, 3:4]
        # Z_j = h_j tan ϕ_j, fitted by Z_C + j δ_Z (ordinary least squares)
        Z = np.hypot(X, Y) * np.tan(ph)
        jm = j.mean()
        slope = ((j - jm) * (Z - Z.mean(axis=1, keepdims=True))).sum(axis=1) / ((j - jm) ** 2).sum()
        Z_C = Z.mean(axis=1) - slope * jm
        anchor = np.stack([p[:, 0], p[:, 1], Z_C], axis=-1)
        delta = np.stack([p[:, 2], p[:, 3], slope], axis=-1) / N
        return anchor, delta

    def predict(self, state: WindowState, steps: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Predicted θ, ϕ ``(B, *k.shape)`` k frames after the current one (rad).

        Tracks whose window is not yet full hold their latest measurement.
        """
        k = _horizon(steps)
        extra = (None,) * k.ndim
        anchor, delta = self.fit(state)
        pos = anchor[(slice(None), *extra)] + k[..., None] * delta[(slice(None), *extra)]
        hold = unit_from_zup_angles(state.azimuth_window[:, -1], state.elevation_window[:, -1])
        ready = state.ready[(slice(None), *extra, None)]
        return zup_angles_from_unit(np.where(ready, pos, hold[(slice(None), *extra)]))


@dataclass(frozen=True)
class KalmanAngleState:
    """Batched constant-velocity filter state per angle (index 0: θ, 1: ϕ)."""

    mean: FloatArray
    """``(B, 2, 2)``: for each angle, (angle (rad), rate (rad/frame))."""
    covariance: FloatArray
    """``(B, 2, 2, 2)``: 2×2 covariance of each angle's (angle, rate)."""
    count: NDArray[np.int64]
    """Number of measurements received, ``(B,)``."""

    def __post_init__(self) -> None:
        B = self.count.shape[0]
        if self.mean.shape != (B, 2, 2) or self.covariance.shape != (B, 2, 2, 2):
            raise ValueError("KalmanAngleState: mean/covariance shapes do not match the batch")


@dataclass(frozen=True)
class AngleKalmanPredictor:
    """Constant-velocity Kalman filter on azimuth and elevation, one frame per step.

    Model per angle: ``x = (angle, rate)``, ``F = [[1, 1], [0, 1]]``, white-noise acceleration
    ``Q = q [[1/3, 1/2], [1/2, 1]]`` (continuous-time spectral density q over one frame),
    ``H = [1, 0]``, ``R = σ²``.
    """

    measurement_std: float = float(np.deg2rad(0.001))
    """σ of each measured angle (rad); default the paper's 0.001°."""
    accel_psd: float = 1e-11
    """q: spectral density of the angular acceleration (rad²/frame³); the default suits the
    theory §8.7 example, whose angular accelerations are ≈ 1e-6 rad/frame²."""
    initial_rate_std: float = 1e-2
    """Prior standard deviation of the angular rate at the first measurement (rad/frame)."""

    def __post_init__(self) -> None:
        for name in ("measurement_std", "accel_psd", "initial_rate_std"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0.0):
                raise ValueError(f"{name}: must be finite and positive, got {v}")

    @property
    def transition(self) -> FloatArray:
        """F: constant-velocity transition over one frame."""
        return np.array([[1.0, 1.0], [0.0, 1.0]])

    @property
    def process_noise(self) -> FloatArray:
        """Q = q [[1/3, 1/2], [1/2, 1]]."""
        return self.accel_psd * np.array([[1.0 / 3.0, 0.5], [0.5, 1.0]])

    def initial_state(self, batch_size: int) -> KalmanAngleState:
        if batch_size < 1:
            raise ValueError("batch_size: must be ≥ 1")
        return KalmanAngleState(
            np.zeros((batch_size, 2, 2)),
            np.zeros((batch_size, 2, 2, 2)),
            np.zeros(batch_size, np.int64),
        )

    def update(
        self,
        state: KalmanAngleState,
        azimuth: ArrayLike,
        elevation: ArrayLike,
        mask: ArrayLike | None = None,
    ) -> KalmanAngleState:
        """Advance one frame: predict, then correct with the measured angles where ``mask``.

        Where ``mask`` is False the image is lost and only the time update runs (the track
        coasts at its estimated rates); a track with no measurement yet stays empty.
        """
        B = state.count.shape[0]
        az, el, m = measurement_arrays(azimuth, elevation, B, mask)
        z = np.stack([az, el], axis=-1)  # (B, 2)
        F, Q, r = self.transition, self.process_noise, self.measurement_std**2
        # x⁻ = F x,  P⁻ = F P Fᵀ + Q
        x = state.mean @ F.T
        x[:, 0, 0] = wrap_angle(x[:, 0, 0])
        P = F @ state.covariance @ F.T + Q
        # ν = z − H x⁻ (azimuth residual wrapped),  S = H P⁻ Hᵀ + R,  K = P⁻ Hᵀ S⁻¹
        nu = z - x[..., 0]
        nu[:, 0] = wrap_angle(nu[:, 0])
        S = P[..., 0, 0] + r
        K = P[..., :, 0] / S[..., None]
        # x = x⁻ + K ν,  P = (I − K H) P⁻
        x_new = x + K * nu[..., None]
        x_new[:, 0, 0] = wrap_angle(x_new[:, 0, 0])
        P_new = P - K[..., :, None] * P[..., None, 0, :]
        P_new = 0.5 * (P_new + np.swapaxes(P_new, -1, -2))
        # first measurement: x = (z, 0), P = diag(σ², σ_rate²)
        first = state.count == 0
        x_new = np.where(first[:, None, None], np.stack([z, np.zeros_like(z)], axis=-1), x_new)
        P0 = np.diag([r, self.initial_rate_std**2])
        P_new = np.where(first[:, None, None, None], P0, P_new)
        # lost image: time update only; nothing to coast before the first measurement
        coast = ~m & ~first
        return KalmanAngleState(
            np.where(m[:, None, None], x_new, np.where(coast[:, None, None], x, state.mean)),
            np.where(
                m[:, None, None, None],
                P_new,
                np.where(coast[:, None, None, None], P, state.covariance),
            ),
            state.count + m,
        )

    def predict(self, state: KalmanAngleState, steps: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """θ, ϕ ``(B, *k.shape)`` k frames after the current one: ``angle + rate·k`` (rad)."""
        k = _horizon(steps)
        extra = (None,) * k.ndim
        angle = state.mean[..., 0][(slice(None), *extra)]
        rate = state.mean[..., 1][(slice(None), *extra)]
        out = angle + k[..., None] * rate
        return wrap_angle(out[..., 0]), out[..., 1]
