"""Compiled standard normal draws in the Generator's own stream
(:mod:`sensorgym.envs.shells.normals`)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from sensorgym.envs.shells.normals import COMPILED_MIN_DRAWS, standard_normal_rows

BIT_GENERATORS = [np.random.PCG64, np.random.PCG64DXSM, np.random.Philox, np.random.SFC64,
                  np.random.MT19937]  # fmt: skip


@pytest.mark.parametrize("bit_generator", BIT_GENERATORS)
@pytest.mark.parametrize("splits", [(0, 300), (0, 7, 8, 200, 300), (0, 0, 150, 300)])
def test_row_ranges_draw_what_one_numpy_call_draws(bit_generator, splits):
    shape = (300, 4, 3, 3)  # 108 draws a row: ranges above and below COMPILED_MIN_DRAWS
    ours, theirs = np.random.Generator(bit_generator(7)), np.random.Generator(bit_generator(7))
    ours.random(3), theirs.random(3)  # not at the stream's start
    out = np.empty(shape)
    for lo, hi in itertools.pairwise(splits):
        standard_normal_rows(ours, out, lo, hi)
    np.testing.assert_array_equal(out, theirs.standard_normal(shape), strict=True)
    assert ours.random() == theirs.random()  # both Generators are at the same place
    assert 300 * 36 * 3 >= COMPILED_MIN_DRAWS > 7 * 108  # both paths ran


def test_bad_arguments_are_named():
    rng = np.random.default_rng(0)
    with pytest.raises(TypeError, match="rng"):
        standard_normal_rows(np.random.RandomState(0), np.empty((2, 2)), 0, 2)
    with pytest.raises(ValueError, match="out"):
        standard_normal_rows(rng, np.empty((2, 2), dtype=np.float32), 0, 2)
    with pytest.raises(ValueError, match="out"):
        standard_normal_rows(rng, np.empty((4, 4))[:, ::2], 0, 2)
    with pytest.raises(ValueError, match="rows"):
        standard_normal_rows(rng, np.empty((2, 2)), 1, 3)
