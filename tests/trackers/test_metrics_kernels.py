"""The compiled GOSPA of a batch equals :func:`~sensorgym.trackers.metrics.gospa`, one scenario
at a time."""

from __future__ import annotations

import numpy as np
import pytest

from sensorgym.trackers.metrics import gospa
from sensorgym.trackers.metrics_kernels import gospa_batch


def test_the_batch_kernel_is_the_reference_on_every_scenario():
    rng = np.random.default_rng(20261203)
    B, K, M, c = 400, 7, 5, 4.0
    position = rng.normal(scale=3.0, size=(B, K, 3))
    velocity = rng.normal(size=(B, K, 3))
    lead = rng.uniform(0.0, 1.0, (B, K))
    truths = rng.normal(scale=3.0, size=(B, M, 3))
    # every mix of sizes: empty sides, more tracks than truths and fewer
    track_valid = rng.random((B, K)) < rng.uniform(0.0, 1.0, (B, 1))
    truth_valid = rng.random((B, M)) < rng.uniform(0.0, 1.0, (B, 1))
    position[~track_valid] = np.nan  # never read
    out = np.empty(B)
    gospa_batch(position, velocity, lead, track_valid, truths, truth_valid, c, out)
    for b in range(B):
        x = position[b] + lead[b][:, None] * velocity[b]
        want = gospa(x[track_valid[b]], truths[b, truth_valid[b]], c)
        assert out[b] == pytest.approx(want, rel=1e-12, abs=1e-12), b
    k, m = track_valid.sum(1), truth_valid.sum(1)
    assert np.any(k > m) and np.any(k < m) and np.any(k == 0) and np.any((k > 0) & (m > 0))
