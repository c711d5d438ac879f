"""Kernel inputs in one form (trackers/kernel_args.py): one compiled signature per kernel."""

from __future__ import annotations

import numpy as np

from sensorgym.trackers.kernel_args import kernel_array
from sensorgym.trackers.stereo import kernels
from sensorgym.trackers.stereo.information import position_information, weighted_fix


def test_kernel_array_is_c_ordered_writable_and_copies_only_when_it_must():
    a = np.arange(12.0).reshape(3, 4)
    assert kernel_array(a, (3, 4)) is a  # already the form: no copy
    for odd in (
        np.broadcast_to(a, (3, 4)),  # read-only view, nothing broadcast
        np.asfortranarray(a),
        a[:, ::2].repeat(2, axis=1),
        np.arange(4.0),  # broadcast
    ):
        out = kernel_array(odd, (3, 4))
        assert out.shape == (3, 4) and out.flags.c_contiguous and out.flags.writeable
        np.testing.assert_array_equal(out, np.broadcast_to(odd, (3, 4)))
    mask = kernel_array(True, (2, 3), bool)
    assert mask.dtype == bool and mask.all() and mask.flags.writeable


def test_public_functions_compile_one_signature_whatever_the_inputs_layout():
    rng = np.random.default_rng(0)
    origins = rng.normal(0.0, 50.0, (6, 3, 3))
    target = rng.normal(0.0, 50.0, (6, 1, 3)) + np.array([0.0, 0.0, 200.0])
    d = target - origins
    ranges = np.linalg.norm(d, axis=-1)
    los = d / ranges[..., None]
    calls = [
        lambda: position_information(los, ranges),  # scalar σ, no mask: broadcast, read-only
        lambda: position_information(los, ranges, np.full((6, 3), 1e-3), np.ones((6, 3), bool)),
        lambda: position_information(np.asfortranarray(los), ranges[:, ::-1].copy()),
        lambda: weighted_fix(origins, los),
        lambda: weighted_fix(origins, los, mask=np.ones((6, 3), bool), sigma=np.full(3, 1e-3)),
        lambda: weighted_fix(np.broadcast_to(origins[:1], (6, 3, 3)), los),
    ]
    for call in calls:
        call()
    assert len(kernels.position_information_batch.signatures) == 1
    assert len(kernels.weighted_fix_batch.signatures) == 1
