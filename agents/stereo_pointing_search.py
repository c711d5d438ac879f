"""Find a drone that only one receiver sees: search along that receiver's line of sight
(``sensorgym/StereoPointing-v0``, the ``plan-search`` rule).

A drone is fixed, and its track updated, only when two receivers see it at once. When the cue
puts a drone just outside one of its two receivers' fields of view, the other one sees it, the
track is never corrected, its error grows, and the receivers sent to it keep aiming at a
prediction that is metres off: the drone is never fixed for the whole episode (about 2 % of the
episodes of the rules before this one, each about −400, most of the spread of their returns).
One sighting already says much: the drone lies inside the seeing receiver's cone, near its
boresight ray (the epipolar constraint of stereo, theory §4.4). :func:`search_aims` sends the
other receivers assigned to a *lost* drone (track RMS above ``lost_rms``) that exactly one
receiver saw on the last step to the point of that ray nearest the prediction, swept along the
ray from step to step (range is what one sighting leaves open). Measured on the tuning seeds
(``benchmarks/pointing_search.py``, ``benchmarks/results/pointing_search.json``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from sensorgym.agents.stereo_pointing import _View
from sensorgym.envs.stereo_pointing.simulation import PointingParams, boresights

#: nearest range along the seeing receiver's ray searched, m
MIN_SEARCH_RANGE = 5.0


@dataclass(frozen=True)
class EpipolarSearch:
    """Where the receivers sent to a lost drone look. The default is the best of the four
    settings measured on tuning seeds 500 and 600 (``benchmarks/results/pointing_search.json``:
    +4.5 and +5.5 over ``plan-fix-first``, paired, 512 episodes each)."""

    lost_rms: float = 4.0
    """Track RMS position error ``σ̂`` above which a drone counts as lost, m (a fixed track has
    centimetres; one without a fix grows by metres per second); ``inf`` never searches."""
    width: float = 1.0
    """Sweep step along the ray, in units of ``fov ·`` the mean range from the receivers to the
    ray's point nearest the prediction (about the span of one field of view)."""
    sweep: tuple[int, ...] = (0, 1, -1, 2, -2, 3, -3)
    """Offsets along the ray, in sweep steps, visited in turn on consecutive episode steps."""

    def __post_init__(self) -> None:
        if not self.lost_rms >= 0.0:  # NaN fails too; inf never searches
            raise ValueError(f"lost_rms: must be >= 0 (inf: never), got {self.lost_rms!r}")
        if not (np.isfinite(self.width) and self.width >= 0.0):
            raise ValueError(f"width: must be finite and >= 0, got {self.width!r}")
        if not self.sweep or not all(isinstance(s, int | np.integer) for s in self.sweep):
            raise ValueError(f"sweep: must be a non-empty tuple of integers, got {self.sweep!r}")


def search_aims(
    params: PointingParams,
    view: _View,
    target: NDArray[np.int64],
    t: NDArray[np.int64],
    search: EpipolarSearch,
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Search points ``(N, n, 3)`` and which receivers search ``(N, n)`` at episode steps ``t
    (N,)``: receiver ``k`` sent to drone ``j = target[:, k]`` searches when ``j``'s track RMS
    exceeds ``lost_rms``, exactly one receiver ``k*`` saw ``j`` on the last step and ``k`` is not
    that one. Its point lies on ``k*``'s boresight ray ``o + ρ b``, at the range ``ρ = b · (x̂ −
    o)`` of the ray's point nearest the prediction ``x̂`` (at least :data:`MIN_SEARCH_RANGE`),
    shifted by ``sweep[t mod len] · width · fov · r̄`` (``r̄`` the receivers' mean range to
    that point)."""
    N, n = target.shape[0], params.n_receivers
    if target.shape != (N, n) or t.shape != (N,):
        raise ValueError(
            f"target, t: expected shapes {(N, n)} and ({N},), got {target.shape}, {t.shape}"
        )
    rows = np.arange(N)[:, None]
    seen = view.seen > 0.0  # (N, n, m)
    single = seen.sum(axis=1) == 1  # (N, m)
    lost = view.sigma > search.lost_rms  # (N, m)
    # the seeing receiver's boresight ray, per drone
    k_star = np.argmax(seen, axis=1)  # (N, m)
    origin = params._receivers[k_star]  # (N, m, 3)
    ray = boresights(view.azimuth, view.elevation)[rows, k_star]  # (N, m, 3)
    rho = np.einsum("nmc,nmc->nm", ray, view.position - origin)
    nearest = origin + np.maximum(rho, MIN_SEARCH_RANGE)[..., None] * ray
    mean_range = np.linalg.norm(nearest[:, :, None] - params._receivers, axis=-1).mean(axis=-1)
    shift = np.asarray(search.sweep)[t % len(search.sweep)][:, None] * search.width * params.fov
    points = origin + np.maximum(rho + shift * mean_range, MIN_SEARCH_RANGE)[..., None] * ray
    searching = (lost & single)[rows, target] & ~seen[rows, np.arange(n)[None], target]
    return points[rows, target], searching
