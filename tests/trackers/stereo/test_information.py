"""trackers.stereo.information: the shared position information, its observability test, the
weighted fix and the in-front test that rejects fixes on or behind a receiver (issue 10,
defect 4)."""

from __future__ import annotations

import numpy as np

from sensorgym.trackers.stereo.information import (
    MIN_FIX_RANGE,
    fix_in_front,
    observable,
    position_information,
    position_sigma,
    weighted_fix,
)


def _views(rng: np.random.Generator, batch: int, n: int, spread: float = 60.0):
    M = rng.normal(size=(batch, 3)) * 40.0 + [0.0, 50.0, 100.0]
    o = rng.normal(size=(batch, n, 3)) * spread
    u = M[:, None] - o
    return M, o, u / np.linalg.norm(u, axis=-1, keepdims=True)


def test_a_good_fix_is_in_front_of_every_receiver():
    rng = np.random.default_rng(0)
    M, o, u = _views(rng, 200, 4)
    fix, _, ok = weighted_fix(o, u)
    assert ok.all() and fix_in_front(fix, o, u).all()
    np.testing.assert_allclose(fix, M, atol=1e-9)


def test_a_fix_behind_on_or_next_to_a_receiver_is_not_in_front():
    o = np.array([[0.0, 0.0, 0.0], [10.0, 0.0, 0.0]])
    u = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]])
    for point, want in (
        ([0.0, 0.0, 5.0], True),
        ([0.0, 0.0, -5.0], False),  # behind
        ([0.0, 0.0, 0.0], False),  # on receiver 0
        ([3.0, 0.0, 0.5 * MIN_FIX_RANGE], False),  # within MIN_FIX_RANGE along the sight line
        ([3.0, 0.0, 2.0 * MIN_FIX_RANGE], True),
    ):
        assert bool(fix_in_front(np.array(point), o, u)) is want, point
    # receivers that do not see the point do not count
    assert fix_in_front(np.array([0.0, 0.0, -5.0]), o, u, mask=[False, False])
    assert not fix_in_front(np.array([0.0, 0.0, -5.0]), o, u, mask=[False, True])
    assert fix_in_front(np.array([0.0, 0.0, -5.0]), o, u, min_range=-10.0)
    # NaN fixes are never in front
    assert not fix_in_front(np.array([np.nan, 0.0, 5.0]), o, u)


def test_co_located_receivers_fix_on_themselves_and_the_in_front_test_catches_it():
    """The defect: noisy lines of sight from receivers at one place all pass through that
    place, so the least-squares fix is the place itself, the information at its own (floored)
    ranges passes the observability test, and only the in-front test refuses it."""
    rng = np.random.default_rng(1)
    o = np.broadcast_to([0.0, 0.0, 50.0], (100, 4, 3))
    u = np.array([0.3, 0.4, 0.866])
    u = u / np.linalg.norm(u)
    noisy = u + 1e-3 * rng.normal(size=(100, 4, 3))
    noisy /= np.linalg.norm(noisy, axis=-1, keepdims=True)
    fix, _, ok = weighted_fix(o, noisy)
    assert ok.all()  # the observability test alone trusts these fixes
    np.testing.assert_allclose(fix, o[:, 0], atol=1e-6)
    assert not fix_in_front(fix, o, noisy).any()


def test_existing_functions_are_unchanged_on_regular_inputs():
    """Hand checks of the shared functions (their results must stay bit-identical: the
    environments' recorded episodes depend on them)."""
    u = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    info = position_information(u, [2.0, 4.0], 0.5)
    np.testing.assert_array_equal(info, np.diag([1.0 / 4.0, 1.0, 1.0 + 1.0 / 4.0]))
    assert observable(info) and not observable(position_information(u[:1], [2.0]))
    np.testing.assert_allclose(position_sigma(info, True), np.sqrt(4.0 + 1.0 + 0.8), rtol=1e-15)
    assert position_sigma(info, False) == np.inf
    o = np.array([[0.0, 0.0, 0.0], [10.0, 0.0, 0.0]])
    d = np.array([5.0, 0.0, 5.0]) - o
    fix, _, ok = weighted_fix(o, d / np.linalg.norm(d, axis=-1, keepdims=True))
    assert ok and fix_in_front(fix, o, d / np.linalg.norm(d, axis=-1, keepdims=True))
    np.testing.assert_allclose(fix, [5.0, 0.0, 5.0], atol=1e-12)


def test_a_masked_zero_line_of_sight_adds_nothing():
    """The environments' fallback for a point on a receiver: the zero line of sight, never
    seen. Masked out, it leaves the information, the fix and the in-front test as without it."""
    rng = np.random.default_rng(2)
    _, o, u = _views(rng, 50, 3)
    u0 = u.copy()
    u0[:, 2] = 0.0
    mask = np.broadcast_to([True, True, False], (50, 3))
    info_with = position_information(u0, np.ones((50, 3)), 1e-3, mask)
    info_without = position_information(u[:, :2], np.ones((50, 2)), 1e-3)
    np.testing.assert_array_equal(info_with, info_without)
    fix, _, ok = weighted_fix(o, u0, mask)
    fix2, _, ok2 = weighted_fix(o[:, :2], u[:, :2])
    np.testing.assert_allclose(fix, fix2, rtol=1e-12, atol=1e-9)
    np.testing.assert_array_equal(ok, ok2)
    np.testing.assert_array_equal(
        fix_in_front(fix, o, u0, mask), fix_in_front(fix2, o[:, :2], u[:, :2])
    )
