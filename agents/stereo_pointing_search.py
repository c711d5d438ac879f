"""Find a drone that only one receiver sees: search along that receiver's line of sight
(``sensorgym/StereoPointing-v0``, the ``plan-search`` rule).

A drone is fixed, and its track updated, only when two receivers see it at once. When the cue
puts a drone just outside one of its two receivers' fields of view, the other one sees it, the
track is never corrected, its error grows, and the receivers sent to it keep aiming at a
prediction that is metres off: the drone is never fixed for the whole episode (a few episodes
of the rules before this one, each among their worst, most of the spread of their returns).
One sighting already says much: the drone lies inside the seeing receiver's cone, near its
boresight ray (the epipolar constraint of stereo, theory §4.4). :func:`search_aims` sends the
other receivers assigned to a *lost* drone (track RMS above ``lost_rms``) that exactly one
receiver saw on the last step to the point of that ray nearest the prediction, swept along the
ray from step to step (range is what one sighting leaves open) and, from sweep to sweep, across
it (the drone may sit anywhere in the seeing receiver's cone, up to ``fov · ρ`` off the ray).
The seeing receiver itself, if it is sent to that drone, holds its line of sight (``anchor``):
slewing onto the prediction, which is metres off, would carry the drone out of its cone before
the others find it. Measured on the tuning seeds (``research/stereo_pointing/pointing_search.py``,
``research/stereo_pointing/results/pointing_search.json``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from sensorgym.agents.stereo_pointing import RuleView
from sensorgym.envs.stereo_pointing.simulation import PointingParams, boresights

#: nearest range along the seeing receiver's ray searched, m
MIN_SEARCH_RANGE = 5.0


@dataclass(frozen=True)
class EpipolarSearch:
    """Where the receivers sent to a lost drone look. The default is the best of the settings
    measured on tuning seeds 500 and 600 and confirmed on 700 and 800 (paired, 512 episodes
    each: first the range sweep alone over ``plan-fix-first``, then the anchor and the sweep
    across the ray over that, which also leave fewer drones never fixed;
    ``research/stereo_pointing/results/pointing_search.json``)."""

    lost_rms: float = 4.0
    """Track RMS position error ``σ̂`` above which a drone counts as lost, m (a fixed track has
    centimetres; one without a fix grows by metres per second); ``inf`` never searches."""
    width: float = 1.0
    """Sweep step along the ray, in units of ``fov ·`` the mean range from the receivers to the
    ray's point nearest the prediction (about the span of one field of view)."""
    sweep: tuple[int, ...] = (0, 1, -1)
    """Offsets along the ray, in sweep steps, visited in turn on consecutive episode steps."""
    across: tuple[float, ...] = (0.0, 0.7, -0.7)
    """Offsets across the ray, in units of the seeing receiver's cone radius there (``fov ·
    ρ``), along ``b × d`` (``b`` the ray, ``d`` the searching receiver's line of sight to the
    point: out of their common plane, where a shift along the ray does not reach). Each is
    held for one whole sweep along the ray, then the next: the drone seen at the edge of the
    one cone is found by the other receivers' narrower one."""
    anchor: bool = True
    """The seeing receiver, when it is sent to the lost drone, aims at its own ray's point
    nearest the prediction, advanced by the estimated velocity over one step, not at the
    prediction itself (metres off): slewing there would carry the drone out of its cone before
    the others find it."""

    def __post_init__(self) -> None:
        if not self.lost_rms >= 0.0:  # NaN fails too; inf never searches
            raise ValueError(f"lost_rms: must be >= 0 (inf: never), got {self.lost_rms!r}")
        if not (np.isfinite(self.width) and self.width >= 0.0):
            raise ValueError(f"width: must be finite and >= 0, got {self.width!r}")
        if not self.sweep or not all(isinstance(s, int | np.integer) for s in self.sweep):
            raise ValueError(f"sweep: must be a non-empty tuple of integers, got {self.sweep!r}")
        if not self.across or not all(np.isfinite(a) for a in self.across):
            raise ValueError(
                f"across: must be a non-empty tuple of finite numbers, got {self.across!r}"
            )
        if not isinstance(self.anchor, bool | np.bool_):
            raise ValueError(f"anchor: must be a bool, got {self.anchor!r}")


def search_aims(
    params: PointingParams,
    view: RuleView,
    target: NDArray[np.int64],
    t: NDArray[np.int64],
    search: EpipolarSearch,
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Search points ``(N, n, 3)`` and which receivers take them ``(N, n)`` at episode steps
    ``t (N,)``. Drone ``j`` is searched for when its track RMS exceeds ``lost_rms`` and exactly
    one receiver ``k*`` saw it on the last step; the line of sight of ``k*`` is the ray ``o +
    ρ b``, and ``ρ = b · (x̂ − o)`` (at least :data:`MIN_SEARCH_RANGE`) is the range of its point
    nearest the prediction ``x̂``. Every other receiver ``k`` sent to ``j`` (``target[:, k]``)
    aims at that point shifted along the ray by ``sweep[t mod L] · width · fov · r̄`` (``r̄``
    the receivers' mean range to it, ``L = len(sweep)``) and across it by ``across[(t div L)
    mod len(across)] · fov · ρ`` along the unit ``b × d`` (``d`` from ``k`` to the shifted
    point; not at all where ``b × d`` vanishes, ``k`` on the ray); ``k*`` itself, if sent to
    ``j`` and with ``anchor``, aims at the nearest point plus ``v̂ · dt``."""
    N, n = target.shape[0], params.n_receivers
    if target.shape != (N, n) or t.shape != (N,):
        raise ValueError(
            f"target, t: expected shapes {(N, n)} and ({N},), got {target.shape}, {t.shape}"
        )
    rows, receivers = np.arange(N)[:, None], np.arange(n)[None]
    seen = view.seen > 0.0  # (N, n, m)
    lost = (seen.sum(axis=1) == 1) & (view.sigma > search.lost_rms)  # (N, m)
    # the seeing receiver's boresight ray, per drone
    k_star = np.argmax(seen, axis=1)  # (N, m)
    origin = params._receivers[k_star]  # (N, m, 3)
    ray = boresights(view.azimuth, view.elevation)[rows, k_star]  # (N, m, 3)
    rho = np.einsum("nmc,nmc->nm", ray, view.position - origin)
    reach = np.maximum(rho, MIN_SEARCH_RANGE)  # range of the nearest point searched
    nearest = origin + reach[..., None] * ray
    mean_range = np.linalg.norm(nearest[:, :, None] - params._receivers, axis=-1).mean(axis=-1)
    shift = np.asarray(search.sweep)[t % len(search.sweep)][:, None] * search.width * params.fov
    swept = origin + np.maximum(rho + shift * mean_range, MIN_SEARCH_RANGE)[..., None] * ray
    # per receiver, about the drone it is sent to
    is_star = k_star[rows, target] == receivers  # (N, n)
    sent_lost = lost[rows, target]
    points = swept[rows, target]  # (N, n, 3)
    across = np.asarray(search.across, dtype=np.float64)
    if np.any(across):
        # out of the plane of the ray b and the searching receiver's line of sight d
        cycle = (t // len(search.sweep)) % len(across)
        d = points - params._receivers[None]
        e = np.cross(ray[rows, target], d)
        size = np.linalg.norm(e, axis=-1, keepdims=True)  # |d| sin of the angle between b, d
        turned = size > 1e-9 * np.linalg.norm(d, axis=-1, keepdims=True)
        e = np.where(turned, e / np.where(turned, size, 1.0), 0.0)  # 0: k on the ray
        radius = params.fov * reach[rows, target]
        points = points + (across[cycle][:, None] * radius)[..., None] * e
    searching = sent_lost & ~is_star
    if search.anchor:
        held = (nearest + view.velocity * params.dt)[rows, target]
        points = np.where(is_star[..., None], held, points)
        searching = sent_lost
    return points, searching
