"""Static stereo scenes: receivers at world poses looking at one point (theory §2.1, §3.2).

The smallest world the conjugation trackers can watch: a :class:`~.scanning.ReceiverLayout`
(the same receiver poses the scanning world uses) of ``n`` receivers with local→world
rotations ``R_k`` (000/003 frame: ``Y`` up, ``Z`` boresight) and world origins ``o_k``, and a
point target. It produces what the receivers measure (unit vectors in their own frames) and
the relative poses ``P_k, b_k`` the trackers need, keeping the truth (ranges, positions)
apart. Noise is added by :func:`perturb_directions` / :func:`perturb_positions` with an
explicit generator.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sensorgym.envs.worlds.scanning import ReceiverLayout
from sensorgym.trackers.geometry import look_at_rotation
from sensorgym.trackers.geometry_kernels import perturb_batch
from sensorgym.trackers.kernel_args import kernel_array
from sensorgym.trackers.validation import finite_array, unit_vectors

FloatArray = NDArray[np.float64]

_Z = np.array([0.0, 0.0, 1.0])


@dataclass(frozen=True)
class StereoScene:
    """A receiver layout and one point target, batched over leading axes ``...``."""

    layout: ReceiverLayout
    """Receiver world poses ``R_k``, ``o_k`` (``(..., n, 3, 3)``, ``(..., n, 3)``)."""
    target: FloatArray
    """``(..., 3)`` target position in the world frame, metres."""

    def __post_init__(self) -> None:
        finite_array(self.target, "target", tail=(3,))
        if np.any(self.ranges == 0.0):
            raise ValueError("target: coincides with a receiver origin")

    @property
    def origins(self) -> FloatArray:
        """``(..., n, 3)`` receiver positions ``o_k`` in the world frame, metres."""
        return self.layout.positions

    @property
    def rotations(self) -> FloatArray:
        """``(..., n, 3, 3)`` local→world rotations ``R_k`` (columns: receiver axes)."""
        return self.layout.rotations

    @property
    def ranges(self) -> FloatArray:
        """``(..., n)`` true slant ranges ``r_k``, metres."""
        return np.linalg.norm(self.target[..., None, :] - self.origins, axis=-1)

    @property
    def world_los(self) -> FloatArray:
        """``(..., n, 3)`` unit lines of sight in the world frame."""
        d = self.target[..., None, :] - self.origins
        return d / np.linalg.norm(d, axis=-1, keepdims=True)

    @property
    def directions(self) -> FloatArray:
        """``(..., n, 3)`` unit vectors ``a_k`` each receiver measures in its own frame."""
        local = self.layout.to_local(self.target[..., None, :])
        return local / np.linalg.norm(local, axis=-1, keepdims=True)

    @property
    def relative_poses(self) -> tuple[FloatArray, FloatArray]:
        """``P (..., n−1, 3, 3)`` and ``b (..., n−1, 3)`` of receivers 2..n w.r.t. receiver 1."""
        return self.layout.relative


def receivers_around(
    target: ArrayLike,
    directions: ArrayLike,
    ranges: ArrayLike,
    boresight_offset: ArrayLike = (0.0, 0.0, 0.0),
) -> StereoScene:
    """Place receivers at ``o_k = T − r_k d_k`` so that they see ``target`` along ``d_k``.

    ``directions (..., n, 3)`` world unit vectors from each receiver to the target,
    ``ranges (..., n)`` metres. Each receiver's boresight points at ``T + boresight_offset``
    (world metres), so the measured ``a_k`` are off-axis unless the offset is zero.
    """
    T = finite_array(target, "target", tail=(3,))
    d = unit_vectors(directions, "directions")
    r = finite_array(ranges, "ranges")
    if np.any(r <= 0.0):
        raise ValueError("ranges: must be positive")
    origins = T[..., None, :] - r[..., None] * d
    aim = T[..., None, :] + finite_array(boresight_offset, "boresight_offset", tail=(3,))
    layout = ReceiverLayout(look_at_rotation(origins, aim), origins)
    return StereoScene(layout, np.broadcast_to(T, (*origins.shape[:-2], 3)))


def pair_scene(
    gamma: ArrayLike,
    r1: ArrayLike = 150.0,
    r2: ArrayLike = 120.0,
    elevation: float = 0.3,
    boresight_offset: ArrayLike = (2.0, -1.0, 1.5),
) -> StereoScene:
    """Two receivers whose lines of sight to a target at height 50 m meet at exactly ``γ`` (radians).

    Both lines of sight lie in the plane spanned by ``e = (0, sin ε, cos ε)`` (``ε`` the
    ``elevation``, radians) and the world ``X`` axis: ``d_1 = e``, ``d_2 = cos γ e + sin γ X``.
    """
    g = finite_array(gamma, "gamma")
    e = np.array([0.0, np.sin(elevation), np.cos(elevation)])
    x = np.array([1.0, 0.0, 0.0])
    d1 = np.broadcast_to(e, (*g.shape, 3))
    d2 = np.cos(g)[..., None] * e + np.sin(g)[..., None] * x
    zero = np.zeros_like(g)
    r = np.stack(
        np.broadcast_arrays(np.asarray(r1, float) + zero, np.asarray(r2, float) + zero), -1
    )
    target = np.broadcast_to(np.array([0.0, 50.0, 0.0]), (*g.shape, 3))
    return receivers_around(target, np.stack([d1, d2], -2), r, boresight_offset)


def perturb_directions(a: ArrayLike, sigma_ang: ArrayLike, rng: np.random.Generator) -> FloatArray:
    """Isotropic angular noise: rotate each unit vector by a Gaussian tilt of σ radians per axis.

    The perturbation ``δ ~ N(0, σ²(I − a aᵀ))`` is drawn perpendicular to ``a`` and the sum
    renormalised, so the error has standard deviation ``σ`` in each of the two directions
    across the line of sight and none along it.

    A zero vector (a point at the receiver: no direction to measure) is returned as the zero
    vector; its draws are still taken, so the other vectors and the generator's stream do not
    depend on it. Any other vector must have unit length.
    """
    arr = finite_array(a, "a", tail=(3,), check=False)  # unit_vectors reports NaN
    zero = np.all(arr == 0.0, axis=-1)
    if np.any(zero):  # check the others, keep the zeros
        a = np.where(zero[..., None], 0.0, unit_vectors(np.where(zero[..., None], _Z, arr), "a"))
    else:
        a = unit_vectors(arr, "a")
    s = finite_array(sigma_ang, "sigma_ang")
    if np.any(s < 0.0):
        raise ValueError("sigma_ang: must be non-negative")
    z = rng.standard_normal(a.shape)
    # δ = (I − a aᵀ) z σ,  (a + δ)/‖a + δ‖  (geometry_kernels.perturbed_direction3; zeros stay)
    sig = np.broadcast_to(s, np.broadcast_shapes(s.shape, a.shape[:-1]))
    shape = (*sig.shape, 3)
    flat_a, flat_z = (kernel_array(x, shape).reshape(-1, 3) for x in (a, z))
    out = np.empty(flat_a.shape)
    perturb_batch(flat_a, flat_z, np.ascontiguousarray(sig, dtype=np.float64).reshape(-1), out)
    return out.reshape(shape)


def perturb_positions(M: ArrayLike, sigma: ArrayLike, rng: np.random.Generator) -> FloatArray:
    """Papers' model: i.i.d. ``N(0, σ²)`` on every coordinate of the position vectors (theory §4.1)."""
    M = finite_array(M, "M", tail=(3,))
    s = finite_array(sigma, "sigma")
    if np.any(s < 0.0):
        raise ValueError("sigma: must be non-negative")
    return M + rng.standard_normal(M.shape) * np.asarray(s)[..., None]
