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
        np.arange(24.0).reshape(3, 8)[:, ::2],  # strided
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


def test_geometry_and_filter_wrappers_compile_one_signature_too():
    from sensorgym.trackers import geometry_kernels
    from sensorgym.trackers.geometry import look_at_rotation, relative_pose
    from sensorgym.trackers.stereo.kalman import cv_prior, cv_update

    rng = np.random.default_rng(1)
    p = rng.normal(0.0, 10.0, (5, 3))
    t = p + rng.normal(0.0, 10.0, (5, 3)) + np.array([0.0, 0.0, 100.0])
    R = look_at_rotation(p, t)  # up broadcast: a read-only view
    look_at_rotation(np.asfortranarray(np.stack([p, p]))[0], t, np.tile([0.0, 1.0, 0.0], (5, 1)))
    relative_pose(R[0], p[0], R, p)  # R1, o1 broadcast
    relative_pose(R, p, R[::-1].copy(), p[::-1])
    track = cv_prior(p, np.zeros((5, 3)), 5.0, 2.0)
    cv_update(track, t, np.eye(3), True)  # R and mask broadcast
    cv_update(track, t, np.broadcast_to(np.eye(3), (5, 3, 3)).copy(), np.ones(5, bool))
    assert len(geometry_kernels.look_at_batch.signatures) == 1
    assert len(geometry_kernels.relative_pose_batch.signatures) == 1
    assert len(kernels.cv_update_batch.signatures) == 1
