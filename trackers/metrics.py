"""Multi-object tracking metrics: GOSPA, the distance a tracking user quotes for a set of
tracks against the set of true objects.

The generalised optimal sub-pattern assignment metric (Rahmathullah, García-Fernández and
Svensson, 2017) with cut-off ``c``, order ``p`` and ``α = 2`` between track positions
``X = {x_1 … x_k}`` and true positions ``Y = {y_1 … y_m}``:

``GOSPA = ( min_γ Σ_{(i,j)∈γ} d(x_i, y_j)^p + c^p/2 · (k + m − 2|γ|) )^{1/p}``

over the partial assignments ``γ`` with every assigned pair closer than ``c``: localisation
error of the assigned pairs, ``c^p/2`` per missed object and per false track. Cutting the
distances at ``c`` and assigning ``min(k, m)`` pairs gives the same minimum (a pair at ``c`` or
beyond costs ``c^p``, what leaving both unassigned costs), so it is one rectangular linear
assignment (:func:`scipy.optimize.linear_sum_assignment`). It is what Stone Soup's
``GOSPAMetric`` computes (checked in ``tests/train/test_tail.py``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import linear_sum_assignment


def gospa(tracks: ArrayLike, truths: ArrayLike, c: float, p: float = 2.0) -> float:
    """GOSPA (``α = 2``) between ``tracks (k, d)`` and ``truths (m, d)`` (Euclidean distance;
    either set may be empty), cut-off ``c > 0`` and order ``p ≥ 1``, in the units of the
    positions."""
    if not (c > 0.0 and np.isfinite(c)):
        raise ValueError(f"c: must be finite and > 0, got {c}")
    if not p >= 1.0:
        raise ValueError(f"p: must be >= 1, got {p}")
    x = np.asarray(tracks, dtype=np.float64)
    y = np.asarray(truths, dtype=np.float64)
    k, m = len(x), len(y)
    cp = c**p
    if k == 0 or m == 0:
        return float((cp / 2.0 * (k + m)) ** (1.0 / p))
    x, y = x.reshape(k, -1), y.reshape(m, -1)
    d = np.sqrt(((x[:, None, :] - y[None, :, :]) ** 2).sum(-1))
    cost = np.minimum(d, c) ** p
    rows, cols = linear_sum_assignment(cost)
    total = cost[rows, cols].sum() + cp / 2.0 * abs(k - m)
    return float(total ** (1.0 / p))
