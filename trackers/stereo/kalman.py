"""A 3-D constant-velocity Kalman filter fed by multi-receiver position fixes (batched).

The tracker of the receiver-pointing environments (theory §4.2, §10.1 OC-1). Each step, for each
object, the receivers that see it give unit lines of sight ``u_k`` from their origins ``o_k``;
the *measurement model* (:func:`~sensorgym.trackers.stereo.information.weighted_fix`) turns
them into one position fix, the *updater* fuses the fix into a constant-velocity track, the
*predictor* carries the track when fewer than two receivers see it.

Position fix (angle-noise model, :mod:`.information`): with isotropic angular noise ``σ``
on every direction, the Fisher information of the position ``M`` is
``I(M) = Σ_k s_k (I − u_k u_kᵀ) / (σ² r_k²)`` (``s_k`` = 1 if receiver ``k`` sees the object)
and the weighted least-squares fix ``(Σ_k s_k Π_k / r_k²) M = Σ_k s_k Π_k o_k / r_k²`` attains
``I(M)⁻¹`` to first order (:func:`~.information.weighted_fix`). The
geometry part ``G = Σ_k s_k Π_k / r_k²`` is kept apart from ``σ²`` so that ``σ = 0``
(noise-free measurements) gives the exact intersection and a zero covariance.

Constant-velocity model (white-noise acceleration of spectral density ``q``, m²/s³), state
``x = (p, v)`` in world metres and m/s::

    F = [[I, dt I], [0, I]],   Q = q [[dt³/3 I, dt²/2 I], [dt²/2 I, dt I]]
    z = H x + w,  H = [I 0],   w ~ N(0, R),   R = σ² G⁻¹

Singular innovation covariance. The update solves ``S = H P Hᵀ + R`` for the gain. Exact fixes
(``σ = 0``, so ``R = 0``) together with no process noise (``q = 0``) make ``S`` singular — after
a few fixes the track is certain and ``S = 0``. Where ``S`` is singular to working precision
(:func:`singular_innovation`: an eigenvalue ``λ ≤ RCOND · max|λ|``, or none positive) the update
uses the pseudo-inverse gain instead of ``S⁻¹``: ``K = P Hᵀ S⁺`` on the range of ``S`` and, on its
null space ``N = I − S S⁺`` (directions in which both the prediction and the fix claim to be
exact), the fix itself, ``K_p += N``. ``S = 0`` therefore gives the fix as the position and
leaves the velocity and its covariance unchanged; ``σ = 0`` with a regular ``S = P_pp`` gives
``K_p = I``, the fix again (to round-off). Regular ``S`` is solved by LU with partial pivoting
(:func:`~.kernels.lu3`).

Every function takes leading batch axes. Each formula is written once, as a compiled primitive
of :mod:`.kernels` (``cv_predict``, ``cv_update``, ``singular_innovation``, ``pseudo_gain``); the
functions here broadcast, flatten the batch and loop over it in compiled code.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sensorgym.trackers.kernel_args import kernel_array
from sensorgym.trackers.stereo import kernels
from sensorgym.trackers.stereo.kernels import RCOND, SCREEN
from sensorgym.trackers.validation import finite_array

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

__all__ = [
    "RCOND",
    "SCREEN",
    "CVTrack",
    "cv_predict",
    "cv_prior",
    "cv_update",
    "singular_innovation",
]


@dataclass(frozen=True)
class CVTrack:
    """Gaussian constant-velocity track: mean ``x (..., 6)`` = (p, v) and covariance ``P``."""

    x: FloatArray
    """(..., 6) position (m) and velocity (m/s), world frame."""
    P: FloatArray
    """(..., 6, 6) covariance (m², m²/s, m²/s²)."""

    def __post_init__(self) -> None:
        if self.x.shape[-1:] != (6,) or self.P.shape != (*self.x.shape, 6):
            raise ValueError(
                f"x/P: expected (..., 6) and (..., 6, 6), got {self.x.shape}, {self.P.shape}"
            )

    @property
    def position(self) -> FloatArray:
        """(..., 3) estimated position, m."""
        return self.x[..., :3]

    @property
    def velocity(self) -> FloatArray:
        """(..., 3) estimated velocity, m/s."""
        return self.x[..., 3:]

    @property
    def position_sigma(self) -> FloatArray:
        """(...) position RMS ``√tr P_pp``, m."""
        return np.sqrt(np.maximum(np.trace(self.P[..., :3, :3], axis1=-2, axis2=-1), 0.0))


def cv_prior(position: ArrayLike, velocity: ArrayLike, sigma_p: float, sigma_v: float) -> CVTrack:
    """Track started from a cue: mean ``(position, velocity)``, covariance ``diag(σ_p², σ_v²)``."""
    p = finite_array(position, "position", tail=(3,))
    v = finite_array(velocity, "velocity", tail=(3,))
    if p.shape != v.shape:
        raise ValueError(f"position/velocity: shapes differ, {p.shape} vs {v.shape}")
    if not (sigma_p > 0.0 and sigma_v > 0.0):
        raise ValueError(f"sigma_p/sigma_v: must be positive, got {sigma_p}, {sigma_v}")
    x, P = np.empty((*p.shape[:-1], 6)), np.empty((*p.shape[:-1], 6, 6))
    # x = (p, v),  P = diag(σ_p² I, σ_v² I)  (kernels.cv_prior)
    kernels.cv_prior_batch(
        np.ascontiguousarray(p).reshape(-1, 3),
        np.ascontiguousarray(v).reshape(-1, 3),
        float(sigma_p),
        float(sigma_v),
        x.reshape(-1, 6),
        P.reshape(-1, 6, 6),
    )
    return CVTrack(x, P)


def cv_predict(track: CVTrack, dt: float, q: float) -> CVTrack:
    """Predictor: ``x⁻ = F x``, ``P⁻ = F P Fᵀ + Q`` over ``dt`` seconds (``q`` in m²/s³)."""
    # F = [[I, dt I], [0, I]],  Q = q [[dt³/3 I, dt²/2 I], [dt²/2 I, dt I]]  (kernels.cv_predict)
    x = np.ascontiguousarray(track.x, dtype=np.float64)
    P = np.ascontiguousarray(track.P, dtype=np.float64)
    x_out, P_out = np.empty_like(x), np.empty_like(P)
    kernels.cv_predict_batch(
        x.reshape(-1, 6),
        P.reshape(-1, 6, 6),
        float(dt),
        float(q),
        x_out.reshape(-1, 6),
        P_out.reshape(-1, 6, 6),
    )
    return CVTrack(x_out, P_out)


def singular_innovation(S: ArrayLike) -> BoolArray:
    """Where the symmetric ``S (..., 3, 3)`` is singular to working precision ``(...)``: its
    smallest eigenvalue ``λ_min ≤ RCOND · max|λ|`` (so also ``S = 0`` and indefinite ``S``).

    Only candidates are decomposed: a matrix that is not positive definite has a leading
    principal minor ``≤ 0`` (Sylvester's criterion), and a positive-definite one with
    ``λ_min ≤ RCOND · λ_max`` has ``det S ≤ RCOND · ‖S‖³``; so every singular ``S`` has a leading
    minor of order ``k`` at most ``SCREEN · ‖S‖^k`` (``SCREEN > RCOND``, ``‖·‖`` Frobenius).
    """
    S = np.ascontiguousarray(S, dtype=np.float64)
    out = np.empty(S.shape[:-2], dtype=bool)
    kernels.singular_innovation_batch(S.reshape(-1, 3, 3), out.reshape(-1))
    return out


def cv_update(track: CVTrack, z: ArrayLike, R: ArrayLike, mask: ArrayLike) -> CVTrack:
    """Updater with a position fix ``z (..., 3)`` of covariance ``R (..., 3, 3)`` where ``mask``.

    Tracks where ``mask`` is False are returned unchanged (no fix: predict only). Where the
    innovation covariance ``S`` is singular (exact fixes and an exact track, see the module
    docstring) the pseudo-inverse gain is used and the fix is taken in the null space of ``S``.
    """
    z = np.asarray(z, dtype=np.float64)
    R = np.asarray(R, dtype=np.float64)
    m = np.asarray(mask, dtype=bool)
    batch = np.broadcast_shapes(track.x.shape[:-1], z.shape[:-1], R.shape[:-2], m.shape)
    x = kernel_array(track.x, (*batch, 6))
    P = kernel_array(track.P, (*batch, 6, 6))
    x_out, P_out = np.empty_like(x), np.empty_like(P)
    kernels.cv_update_batch(
        x.reshape(-1, 6),
        P.reshape(-1, 6, 6),
        kernel_array(z, (*batch, 3)).reshape(-1, 3),
        kernel_array(R, (*batch, 3, 3)).reshape(-1, 3, 3),
        kernel_array(m, batch, bool).reshape(-1),
        x_out.reshape(-1, 6),
        P_out.reshape(-1, 6, 6),
    )
    return CVTrack(x_out, P_out)
