"""Compiled GOSPA over a batch of scenarios: the per-step form of :func:`.metrics.gospa`.

:func:`.metrics.gospa` (one scenario, scipy's ``linear_sum_assignment``) is the readable
reference; here the same minimum is found for every scenario of a batch in one compiled pass,
so an env can report it every step (StereoScanning's ``info``) without a Python loop over
scenarios. The assignment is the Hungarian method in its shortest-augmenting-path form
(Kuhn 1955, Munkres 1957; potentials ``u``, ``v``), exact for a rectangular cost matrix with
at most as many rows as columns, ``O(n² m)``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

_JIT = {"cache": True, "nogil": True, "error_model": "numpy", "boundscheck": False}


@njit(**_JIT)
def _min_assignment(a, n, m, u, v, p, way, minv, used):
    """The least ``Σ a[i, σ(i)]`` over injective ``σ`` from the ``n`` rows into the ``m ≥ n``
    columns of ``a[:n, :m]``; ``u (n+1)``, ``v, p, way, minv (m+1)`` and ``used (m+1)`` are
    scratch (1-based: index 0 is the virtual start column)."""
    u[: n + 1] = 0.0
    v[: m + 1] = 0.0
    p[: m + 1] = 0
    way[: m + 1] = 0
    for i in range(1, n + 1):
        # grow a shortest augmenting path from row i over the reduced costs a − u − v
        p[0] = i
        j0 = 0
        minv[: m + 1] = np.inf
        used[: m + 1] = False
        while True:
            used[j0] = True
            i0 = p[j0]
            delta = np.inf
            j1 = 0
            for j in range(1, m + 1):
                if not used[j]:
                    cur = a[i0 - 1, j - 1] - u[i0] - v[j]
                    if cur < minv[j]:
                        minv[j] = cur
                        way[j] = j0
                    if minv[j] < delta:
                        delta = minv[j]
                        j1 = j
            for j in range(m + 1):
                if used[j]:
                    u[p[j]] += delta
                    v[j] -= delta
                else:
                    minv[j] -= delta
            j0 = j1
            if p[j0] == 0:
                break
        while True:  # flip the path's assignments
            j1 = way[j0]
            p[j0] = p[j1]
            j0 = j1
            if j0 == 0:
                break
    total = 0.0
    for j in range(1, m + 1):
        if p[j] != 0:
            total += a[p[j] - 1, j - 1]
    return total


@njit(**_JIT)
def gospa_batch(position, velocity, lead, track_valid, truths, truth_valid, c, out):
    """``out[b]``: GOSPA (``p = 2``, ``α = 2``, cut-off ``c``) of scenario ``b`` between its
    valid tracks (``track_valid (B, K)``), each at ``x_i = position + lead · velocity``
    (``(B, K, d)``, ``(B, K, d)``, ``(B, K)``: a constant-velocity prediction to the time of
    the truth; ``lead`` 0 for tracks already there), and the rows of ``truths (B, M, d)``
    where ``truth_valid (B, M)``:

        GOSPA² = min over assignments Σ min(‖x_i − y_j‖, c)² + c²/2 · |k − m|

    (the ``min(k, m)`` pairs of a rectangular assignment on the cut distances; theory and
    reference: :func:`.metrics.gospa`). Invalid rows are never read."""
    B, K, d = position.shape
    M = truths.shape[1]
    size = max(K, M)
    a = np.empty((size, size))
    u = np.empty(size + 1)
    v = np.empty(size + 1)
    p = np.empty(size + 1, np.int64)
    way = np.empty(size + 1, np.int64)
    minv = np.empty(size + 1)
    used = np.empty(size + 1, np.bool_)
    rows = np.empty(K, np.int64)
    cols = np.empty(M, np.int64)
    c2 = c * c
    for b in range(B):
        k = 0
        for i in range(K):
            if track_valid[b, i]:
                rows[k] = i
                k += 1
        m = 0
        for j in range(M):
            if truth_valid[b, j]:
                cols[m] = j
                m += 1
        total = 0.5 * c2 * abs(k - m)
        if k > 0 and m > 0:
            # the smaller set indexes the rows: the solver needs rows ≤ columns
            flip = k > m
            n_r, n_c = (m, k) if flip else (k, m)
            for r in range(n_r):
                for q in range(n_c):
                    i, j = (rows[q], cols[r]) if flip else (rows[r], cols[q])
                    dist2 = 0.0
                    for e in range(d):
                        x = position[b, i, e] + lead[b, i] * velocity[b, i, e]
                        diff = x - truths[b, j, e]
                        dist2 += diff * diff
                    a[r, q] = min(dist2, c2)
            total += _min_assignment(a, n_r, n_c, u, v, p, way, minv, used)
        out[b] = np.sqrt(total)
