"""One scan period of moving ground receivers and its velocity-aware conjugation fix (theory §3).

Within a period of length ``τ`` receiver ``k`` fixes the drone at its own delay ``d_k`` after
the period start (theory §6.4, §10.4 OC-4: scanning receivers fix at different times). Receivers
are vehicles: they move in a straight line during the period, so receiver ``k`` is at
``O_k(d_k)`` when it fixes the drone at ``M(d_k)``. The drone flies a straight line, so
``M(d_k) = M(d_1) + V (d_k − d_1)`` and the conjugation equations of theory §3.2 hold exactly
with the base vectors taken *at the fix times*::

    r_1 a_1 − r_k P_k a_k + V Δt_k − b_k = e_k ,   Δt_k = d_k − d_1 ,
    P_k = R_1ᵀ R_k ,   b_k = R_1ᵀ (O_k(d_k) − O_1(d_1))                        (theory §2.1)

solved for ``(r_1, …, r_n, V)`` by :func:`~sensorgym.trackers.stereo.conjugation.solve_conjugation`
(``order=1``; for n = 3 its compiled closed form). Each receiver's frame looks at the aim point
(the tracker's predicted drone position), so ``P_k ≠ I`` in general.

Covariance mapping. The solver's ``Q = σ_e² (AᵀA)⁻¹`` assumes i.i.d. errors of ``σ_e`` (m) on
every component of ``e_k`` (the papers' model). A direction error of ``σ_ang`` (rad) displaces
a point at range ``r`` by about ``r σ_ang`` across the line of sight, so we use
``σ_e = σ_ang · mean_k r̂_k`` with the *estimated* ranges (the tracker knows no truth). This is
the papers' model, not the angle-noise bound: it is what the tracker reports; the reward uses
the Cramér–Rao bound instead (:mod:`.stereo_placement_core`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from sensorgym.envs.worlds.scanning import ReceiverLayout
from sensorgym.envs.worlds.stereo_scene import perturb_directions
from sensorgym.trackers.geometry import look_at_rotation, unit_from_angles
from sensorgym.trackers.stereo.conjugation import solve_conjugation

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


@dataclass(frozen=True)
class ScanFix:
    """The conjugation tracker's output for one scan period, batched over scenarios ``B``."""

    position: FloatArray = field(repr=False)
    """(B, 3) estimated drone position at the period end, world frame, m."""
    velocity: FloatArray = field(repr=False)
    """(B, 3) estimated drone velocity, world frame, m/s."""
    range_sigma: FloatArray = field(repr=False)
    """(B, n) standard deviations of the ranges ``√diag(Q)[:n]``, m."""
    velocity_sigma: FloatArray = field(repr=False)
    """(B,) RMS velocity error ``√tr Q_VV``, m/s."""
    condition: FloatArray = field(repr=False)
    """(B,) Frobenius condition number ``κ_F`` of the conjugation matrix ``A`` (inf: singular)."""
    degenerate: BoolArray = field(repr=False)
    """(B,) True where the solver fell back to the pseudo-inverse (``used_pinv``)."""


@dataclass(frozen=True)
class ScanGeometry:
    """The true geometry of one scan period (ground truth: reward and rendering only)."""

    origins: FloatArray = field(repr=False)
    """(B, n, 3) receiver positions at their fix times, world frame, m."""
    los: FloatArray = field(repr=False)
    """(B, n, 3) true unit lines of sight at the fix times, world frame."""
    ranges: FloatArray = field(repr=False)
    """(B, n) true ranges at the fix times, m."""
    degenerate: BoolArray = field(repr=False)
    """(B,) True where the noise-free conjugation of this geometry needs the pseudo-inverse
    (coplanar or parallel lines of sight, equal delays): no noise draw can be trusted there."""


def boresight_rotations(origins: FloatArray, aim: FloatArray, max_elevation: float) -> FloatArray:
    """Local→world rotations ``(B, n, 3, 3)`` of receivers at ``origins (B, n, 3)`` looking at
    ``aim (B, 3)``, the boresight elevation held within ``±max_elevation`` (rad) so that the
    frame's roll (``Y`` towards world up) stays defined even right under the aim point."""
    d = aim[:, None, :] - origins
    horizontal = np.hypot(d[..., 0], d[..., 2])
    azimuth = np.arctan2(d[..., 0], d[..., 2])  # atan2(0, 0) = 0: any azimuth is fine there
    elevation = np.clip(np.arctan2(d[..., 1], horizontal), -max_elevation, max_elevation)
    return look_at_rotation(origins, origins + unit_from_angles(azimuth, elevation))


def scan(
    delays: FloatArray,
    period: float,
    sigma_ang: float,
    max_elevation: float,
    start: FloatArray,
    end: FloatArray,
    drone_end: FloatArray,
    drone_velocity: FloatArray,
    aim: FloatArray,
    rng: np.random.Generator,
) -> tuple[ScanFix, ScanGeometry]:
    """Simulate one period and solve its conjugation system.

    ``delays (n,)`` fix times after the period start, s; ``period`` ``τ``, s; ``sigma_ang`` rad;
    receivers move linearly from ``start`` to ``end`` ``(B, n, 3)`` over the period; the drone
    is at ``drone_end (B, 3)`` at the period end with ``drone_velocity (B, 3)``; ``aim (B, 3)``
    is where the receivers' frames look. Draws ``B·n·3`` normals from ``rng`` when
    ``sigma_ang > 0`` (none otherwise).
    """
    d = np.asarray(delays, dtype=np.float64)
    # O_k(d_k): receivers drive straight from start to end during the period
    origins = start + (end - start) * (d / period)[None, :, None]
    # M(d_k) = M(τ) − V (τ − d_k)
    targets = drone_end[:, None, :] - drone_velocity[:, None, :] * (period - d)[None, :, None]
    offset = targets - origins
    ranges = np.linalg.norm(offset, axis=-1)
    los = offset / np.maximum(ranges, 1e-9)[..., None]
    layout = ReceiverLayout(boresight_rotations(origins, aim, max_elevation), origins)
    P, b = layout.relative
    measured = perturb_directions(los, sigma_ang, rng) if sigma_ang > 0.0 else los
    # a_k = R_kᵀ z_k: each receiver reports the direction in its own frame
    local = np.einsum("bkji,bkj->bki", layout.rotations, measured)
    # σ_e = 1 here; Q is rescaled below by σ_e² = (σ_ang · mean r̂)² (module docstring)
    sol = solve_conjugation(local[:, 0], local[:, 1:], P, b, d[1:] - d[0], order=1)
    if sigma_ang > 0.0:  # the same system without noise: is the geometry itself degenerate?
        exact = np.einsum("bkji,bkj->bki", layout.rotations, los)
        true = solve_conjugation(exact[:, 0], exact[:, 1:], P, b, d[1:] - d[0], order=1)
    else:
        true = sol
    n = d.shape[0]
    sigma_e = sigma_ang * np.mean(np.abs(sol.ranges), axis=-1)
    Q = sigma_e[:, None, None] ** 2 * sol.covariance
    diag = np.maximum(np.diagonal(Q, axis1=-2, axis2=-1), 0.0)
    R1 = layout.rotations[:, 0]
    # frame 1 → world: M = O_1(d_1) + R_1 M̂_1, V = R_1 V̂_1; then on to the period end
    velocity = np.einsum("bij,bj->bi", R1, sol.velocity)
    position = origins[:, 0] + np.einsum("bij,bj->bi", R1, sol.position)
    position = position + velocity * (period - d[0])
    fix = ScanFix(
        position=position,
        velocity=velocity,
        range_sigma=np.sqrt(diag[:, :n]),
        velocity_sigma=np.sqrt(diag[:, n : n + 3].sum(axis=-1)),
        condition=np.asarray(sol.condition, dtype=np.float64),
        degenerate=np.asarray(sol.used_pinv, dtype=bool),
    )
    geometry = ScanGeometry(origins, los, ranges, np.asarray(true.used_pinv, dtype=bool))
    return fix, geometry
