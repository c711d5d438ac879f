"""The shared grouping / gating / beam / selection machinery (trackers/association.py)."""

import numpy as np
import pytest

from sensorgym.trackers.stereo import association as assoc


def test_combinations_cover_every_tuple_in_order():
    C = assoc.combinations([2, 3])
    assert C.tolist() == [[0, 0], [0, 1], [0, 2], [1, 0], [1, 1], [1, 2]]
    assert assoc.combinations([3, 0, 2]).shape == (0, 3)
    assert assoc.combinations([2, 2, 2]).shape == (8, 3)


def test_norm_quantile_matches_monte_carlo():
    assert assoc.norm_quantile(1.0, 0.999) == pytest.approx(4.03, abs=0.01)
    x = np.random.default_rng(0).normal(0.0, 0.2, (200_000, 3))
    q = assoc.norm_quantile(0.2, 0.9)
    assert np.mean(np.linalg.norm(x, axis=1) <= q) == pytest.approx(0.9, abs=0.003)


def test_extend_gates_sorts_and_beams():
    parent = np.array([0.0, 1.0])
    cost = np.array([[0.5, 3.0, np.nan], [0.1, 0.2, np.inf]])
    g, c, s = assoc.extend(parent, cost, threshold=1.0)
    assert list(zip(g.tolist(), c.tolist(), strict=True)) == [(0, 0), (1, 0), (1, 1)]
    np.testing.assert_allclose(s, [0.5, 1.1, 1.2])
    g, c, s = assoc.extend(parent, cost, threshold=np.inf, beam=2)
    assert list(zip(g.tolist(), c.tolist(), strict=True)) == [(0, 0), (1, 0)]


def test_extend_beam_equals_full_sort_truncated():
    rng = np.random.default_rng(1)
    parent, cost = rng.random(50), rng.random((50, 40))
    full = assoc.extend(parent, cost, 0.7)
    cut = assoc.extend(parent, cost, 0.7, beam=100)
    for a, b in zip(full, cut, strict=True):
        np.testing.assert_array_equal(a[:100], b)


def test_shared_vectors_ignore_missing_slots():
    members = np.array([[[0, 1], [-1, 2]], [[0, 2], [-1, 2]], [[1, 0], [3, 3]]])
    S = assoc.shared_vectors(members)
    assert S[0, 1] == 2 and S[0, 2] == 0 and S[1, 1] == 3


def test_select_greedy_with_overlap_allowance():
    members = np.array(
        [
            [[0, 0], [0, 0]],  # best
            [[0, 1], [1, 1]],  # shares one vector with the best
            [[1, 1], [1, 1]],  # shares 3 with the second and none with the best
            [[0, 0], [0, 1]],  # shares 3 with the best
        ]
    )
    score = np.array([1.0, 2.0, 3.0, 1.5])
    assert assoc.select(members, score, max_shared=0).tolist() == [0, 2]
    assert assoc.select(members, score, max_shared=1).tolist() == [0, 1]
    assert assoc.select(
        members, score, 1, eligible=np.array([False, True, True, True])
    ).tolist() == [3, 2]
    assert assoc.select(members, score, 0, max_objects=1).tolist() == [0]


def test_match_tracks_one_to_one_within_gate():
    d = np.array([[0.5, 0.4], [0.3, 9.0], [7.0, 8.0]])
    assert assoc.match_tracks(d, 4.0).tolist() == [1, 0, -1]
    assert assoc.match_tracks(d, np.inf).tolist() == [1, 0, -1]
    assert assoc.match_tracks(np.zeros((2, 0)), 1.0).tolist() == [-1, -1]


def test_bad_shapes_raise():
    with pytest.raises(ValueError, match="step_cost"):
        assoc.extend(np.zeros(2), np.zeros(3))
    with pytest.raises(ValueError, match="members"):
        assoc.select(np.zeros((2, 3)), np.zeros(2))


def test_detection_latest_picks_each_groups_last_estimate():
    pos = np.arange(2 * 3 * 3, dtype=float).reshape(2, 3, 3)
    times = np.array([[0.0, 1.0, np.nan], [0.0, 1.0, 2.0]])
    det = assoc.Detection(
        np.zeros((2, 3, 2), dtype=np.int64), np.array([1.0, 2.0]), pos, pos, times
    )
    p, _, t = det.latest()
    assert det.m_hat == 2
    np.testing.assert_array_equal(t, [1.0, 2.0])
    np.testing.assert_array_equal(p, [pos[0, 1], pos[1, 2]])
