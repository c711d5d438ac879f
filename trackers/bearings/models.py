"""Bearings-only target motion analysis: state, motion model and measurement model.

Shared by every bearings estimator (``bearings_*``) and by the platform world
(:mod:`sensorgym.envs.worlds.platform`).

Conventions (fixed for all of sensorgym's 2-D bearings code)
-------------------------------------------------------------
* Plane coordinates ``x`` = East, ``y`` = North, metres; time in seconds.
* Target state ``x = (x, y, ẋ, ẏ)`` — absolute position (m) and velocity (m/s). The platform
  trajectory is known, so the absolute state is as good as the relative one and is what
  the environments need.
* Bearing: absolute, from North clockwise, radians::

      β = atan2(x_t − x_p, y_t − y_p)                                (theory §2.5)

  Residuals are wrapped with :func:`sensorgym.trackers.geometry.wrap_angle`.
* Motion: nearly constant velocity with continuous white-noise acceleration of intensity
  ``q̃`` (m²/s³) per axis (Bar-Shalom, Li & Kirubarajan 2001, §6.2.2)::

      F(T) = [[I, T I], [0, I]],   Q(T) = q̃ [[T³/3 I, T²/2 I], [T²/2 I, T I]]

Everything accepts leading batch axes (scenarios, filter-bank members, candidates).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sensorgym.trackers.bearings import kernels
from sensorgym.trackers.geometry import wrap_angle
from sensorgym.trackers.validation import finite_array

FloatArray = NDArray[np.float64]

#: One international knot in m/s.
KNOT = 1852.0 / 3600.0
#: State dimension (x, y, ẋ, ẏ).
STATE_DIM = 4


@dataclass(frozen=True)
class BearingsGaussian:
    """Gaussian estimate of the target state, batched over leading axes."""

    x: FloatArray
    """Mean ``(..., 4)``: East, North position (m) and velocity (m/s)."""
    P: FloatArray
    """Covariance ``(..., 4, 4)`` in m², m²/s, m²/s²."""
    t: float
    """Time (s) the estimate refers to."""

    def __post_init__(self) -> None:
        x = finite_array(self.x, "x", tail=(STATE_DIM,))
        P = finite_array(self.P, "P", tail=(STATE_DIM, STATE_DIM))
        if P.shape[:-2] != x.shape[:-1]:
            raise ValueError(f"P: batch shape {P.shape[:-2]} does not match x {x.shape[:-1]}")
        object.__setattr__(self, "x", x)
        object.__setattr__(self, "P", P)
        object.__setattr__(self, "t", float(self.t))

    @classmethod
    def trusted(cls, x: FloatArray, P: FloatArray, t: float) -> BearingsGaussian:
        """An estimate from arrays a compiled kernel has just written, without the checks of
        the constructor (hot paths only). Nothing is checked: ``x``, ``P`` must be float64 of
        matching shapes and finite, which a kernel's outputs are by construction when its
        inputs passed the public functions' checks; anything else belongs to the constructor."""
        obj = object.__new__(cls)
        obj.__dict__.update(x=x, P=P, t=float(t))
        return obj

    @property
    def position(self) -> FloatArray:
        """Estimated position ``(..., 2)`` (m)."""
        return self.x[..., :2]

    @property
    def velocity(self) -> FloatArray:
        """Estimated velocity ``(..., 2)`` (m/s)."""
        return self.x[..., 2:]


def cv_transition(T: ArrayLike) -> FloatArray:
    """Constant-velocity transition ``F(T) = [[I, T I], [0, I]]``; ``T`` (s) may be batched."""
    T = np.asarray(T, dtype=np.float64)
    F = np.broadcast_to(np.eye(STATE_DIM), (*T.shape, STATE_DIM, STATE_DIM)).copy()
    F[..., 0, 2] = T
    F[..., 1, 3] = T
    return F


def _interval(T: ArrayLike) -> FloatArray:
    T = np.asarray(T, dtype=np.float64)
    if not np.all(np.isfinite(T)) or np.any(T < 0.0):
        raise ValueError(f"T: the time step must be finite and >= 0 (process noise), got {T}")
    return T


def _check_q_tilde(q_tilde: float) -> None:
    if not np.isfinite(q_tilde) or q_tilde < 0.0:
        raise ValueError(f"q_tilde: must be finite and >= 0, got {q_tilde}")


def cwna_covariance(T: ArrayLike, q_tilde: float) -> FloatArray:
    """Process noise ``Q(T) = q̃ [[T³/3 I, T²/2 I], [T²/2 I, T I]]`` (m², m²/s, m²/s²).

    ``T`` must be finite and ``>= 0`` (a negative step would give a negative variance):
    ``ValueError`` naming ``T`` otherwise.
    """
    _check_q_tilde(q_tilde)
    T = _interval(T)
    Q = np.zeros((*T.shape, STATE_DIM, STATE_DIM))
    for i in range(2):
        Q[..., i, i] = T**3 / 3.0
        Q[..., i, i + 2] = Q[..., i + 2, i] = T**2 / 2.0
        Q[..., i + 2, i + 2] = T
    return q_tilde * Q


def cwna_covariance_factor(T: ArrayLike, q_tilde: float) -> FloatArray:
    """Lower-triangular square root ``G`` of :func:`cwna_covariance`, ``G Gᵀ = Q(T)``, in closed
    form: per axis ``√q̃ [[√(T³/3), 0], [(√3/2) √T, √T / 2]]`` (rows position, velocity)."""
    _check_q_tilde(q_tilde)
    T = _interval(T)
    G = np.zeros((*T.shape, STATE_DIM, STATE_DIM))
    for i in range(2):
        G[..., i, i] = np.sqrt(T**3 / 3.0)
        G[..., i + 2, i] = 0.5 * np.sqrt(3.0 * T)
        G[..., i + 2, i + 2] = 0.5 * np.sqrt(T)
    return np.sqrt(q_tilde) * G


#: the compiled bearing of one target from one platform, ``bearing_scalar(tx, ty, px, py)``
#: (:func:`.kernels.bearing`, the measurement model's one copy; worlds and kernels call it)
bearing_scalar = kernels.bearing


def bearing(target_position: ArrayLike, platform_position: ArrayLike) -> FloatArray:
    """Absolute bearing ``β = atan2(Δx, Δy)`` (rad, from North clockwise) of the target.

    Both positions are ``(..., 2)`` (East, North) in metres, broadcast together. A target on
    top of the platform has no bearing and raises ``ValueError``.
    """
    d = finite_array(target_position, "target_position", tail=(2,)) - finite_array(
        platform_position, "platform_position", tail=(2,)
    )
    if np.any(np.hypot(d[..., 0], d[..., 1]) == 0.0):
        raise ValueError("target_position: coincides with the platform, bearing undefined")
    t, p = np.broadcast_arrays(
        np.asarray(target_position, np.float64), np.asarray(platform_position, np.float64)
    )
    out = np.empty(d.shape[:-1])
    # β = atan2(Δx, Δy)  (compiled: kernels.bearing, the one copy)
    kernels.bearing_batch(
        np.ascontiguousarray(t).reshape(-1, 2),
        np.ascontiguousarray(p).reshape(-1, 2),
        out.reshape(-1),
    )
    return out


def bearing_jacobian(target_state: ArrayLike, platform_position: ArrayLike) -> FloatArray:
    """Row ``H = ∂β/∂x = (Δy, −Δx, 0, 0)/r²`` (``(..., 4)``, rad/m) at the target state."""
    x = finite_array(target_state, "target_state", tail=(STATE_DIM,))
    p = finite_array(platform_position, "platform_position", tail=(2,))
    dx = x[..., 0] - p[..., 0]
    dy = x[..., 1] - p[..., 1]
    r2 = dx * dx + dy * dy
    if np.any(r2 == 0.0):
        raise ValueError("target_state: position coincides with the platform")
    zero = np.zeros_like(r2)
    return np.stack([dy / r2, -dx / r2, zero, zero], axis=-1)


def bearing_residual(
    z: ArrayLike, target_state: ArrayLike, platform_position: ArrayLike
) -> FloatArray:
    """Wrapped innovation ``ν = wrap(z − β(x))`` (rad)."""
    x = finite_array(target_state, "target_state", tail=(STATE_DIM,))
    z = finite_array(z, "z")
    return wrap_angle(z - bearing(x[..., :2], platform_position))


def predict(state: BearingsGaussian, t: float, q_tilde: float) -> BearingsGaussian:
    """Kalman prediction to time ``t`` (exact for the linear CV/CWNA model)::

        x⁻ = F x,   P⁻ = F P Fᵀ + Q        with F = F(t − t₀), Q = Q(t − t₀)

    A filter runs forward: ``t`` before the estimate's own time ``t₀`` (which would give a
    negative process-noise variance) or not finite raises ``ValueError`` naming ``t``.
    """
    t = float(t)
    if not np.isfinite(t) or t < state.t:
        raise ValueError(
            f"t: prediction time {t} must be finite and not before the estimate's time {state.t}"
        )
    T = t - state.t
    _check_q_tilde(q_tilde)
    _interval(T)
    x = np.array(state.x, dtype=np.float64)
    P = np.array(np.broadcast_to(state.P, (*x.shape, STATE_DIM)), dtype=np.float64)
    # x⁻ = F x,  P⁻ = F P Fᵀ + Q  (compiled: kernels.cv_predict)
    kernels.cv_predict_batch(
        x.reshape(-1, STATE_DIM), P.reshape(-1, STATE_DIM, STATE_DIM), T, float(q_tilde)
    )
    return BearingsGaussian(x, P, t)


def bearing_sequence(
    z: ArrayLike, times: ArrayLike, platform_positions: ArrayLike
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Checked bearings ``z (..., K)`` (rad), ``times (K,)`` (s), ``platform_positions (..., K, 2)`` (m).

    Raises ``ValueError`` naming the arguments when the sample counts disagree.
    """
    z = finite_array(z, "z")
    times = finite_array(times, "times")
    p = finite_array(platform_positions, "platform_positions", tail=(2,))
    K = times.shape[0] if times.ndim == 1 else -1
    if K < 0 or z.shape[-1:] != (K,) or p.shape[-2] != K:
        raise ValueError(
            f"z (..., K), times (K,), platform_positions (..., K, 2): got {z.shape}, "
            f"{times.shape}, {p.shape}"
        )
    return z, times, p
