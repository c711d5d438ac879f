"""One random stream per episode: common random numbers for a vector env's scenarios.

A vector env drawing every slot's resets and noise from one ``np.random.Generator`` hands a
slot's next scenario whatever the stream holds when its episode ends, so an episode that one
policy ends early (a termination the policy caused, or a last-bit flip on another CPU) moves
every later scenario of every slot. :class:`EpisodeStreams` gives slot ``i``'s ``k``-th
episode its own generator,

    default_rng(SeedSequence(entropy, spawn_key=(i, k)))

(NumPy's independent-stream construction), from which that episode's reset and every step's
noise are drawn. Two policies evaluated with one seed and batch then meet the same scenarios,
draw for draw, episode by episode, however either ends its episodes.

The cores take a generator and draw batch-shaped arrays (``rng.uniform(lo, hi, (B, m))``,
``rng.standard_normal((B, n, 3))``). :class:`RowGenerator` is that generator for a set of
rows: every draw of leading size ``B`` takes row ``r`` from row ``r``'s generator. It offers
the draws the cores make; one whose leading size is not the number of rows is refused with a
clear error (its rows could not be told apart).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray


class RowGenerator:
    """The draws of a batch, row ``r`` from ``generators[r]`` (module docstring)."""

    def __init__(self, generators: Sequence[np.random.Generator]):
        self.generators = list(generators)

    def __len__(self) -> int:
        return len(self.generators)

    def _size(self, size: Any, name: str) -> tuple[int, ...]:
        shape = (size,) if isinstance(size, (int, np.integer)) else tuple(size or ())
        if not shape or shape[0] != len(self.generators):
            raise ValueError(
                f"{name}: a draw of one stream per row needs a leading size of "
                f"{len(self.generators)} rows, got size {size!r}"
            )
        return shape

    def _draw(self, name: str, size: Any, *args: ArrayLike, dtype: Any = np.float64) -> NDArray:
        shape = self._size(size, name)
        rows = [np.broadcast_to(np.asarray(a), shape) for a in args]
        out = np.empty(shape, dtype=dtype)
        for r, g in enumerate(self.generators):
            out[r] = getattr(g, name)(*(a[r] for a in rows), size=shape[1:])
        return out

    def uniform(self, low: ArrayLike = 0.0, high: ArrayLike = 1.0, size: Any = None) -> NDArray:
        return self._draw("uniform", size, low, high)

    def normal(self, loc: ArrayLike = 0.0, scale: ArrayLike = 1.0, size: Any = None) -> NDArray:
        return self._draw("normal", size, loc, scale)

    def poisson(self, lam: ArrayLike = 1.0, size: Any = None) -> NDArray:
        return self._draw("poisson", size, lam, dtype=np.int64)

    def random(self, size: Any = None) -> NDArray:
        return self._draw("random", size)

    def standard_normal(self, size: Any = None, out: NDArray | None = None) -> NDArray:
        if out is not None:
            self.standard_normal_rows(out, 0, out.shape[0] if out.ndim else 0)
            return out
        return self._draw("standard_normal", size)

    def standard_normal_rows(self, out: NDArray[np.float64], lo: int, hi: int) -> None:
        """Rows ``out[lo:hi]`` filled with standard normals, each from its row's stream
        (:func:`~sensorgym.envs.shells.normals.standard_normal_rows`' contract)."""
        self._size(out.shape, "standard_normal")
        for r in range(lo, hi):
            self.generators[r].standard_normal(out=out[r])


def episode_generator(seed: int, slot: int, episode: int) -> np.random.Generator:
    """The generator of slot ``slot``'s ``episode``-th episode (0 the first) under ``reset(seed=
    seed)``: a fresh copy, as that episode's reset found it."""
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(slot, episode)))


class EpisodeStreams:
    """The generators of a vector env's ``num_envs`` slots, one per episode (module
    docstring)."""

    def __init__(self, num_envs: int, seed: int | None = None):
        self.entropy = np.random.SeedSequence(seed).entropy  # ``seed`` itself when given
        self.rounds = np.zeros(num_envs, dtype=np.int64)
        self._generators = [self._generator(i, 0) for i in range(num_envs)]

    def _generator(self, slot: int, episode: int) -> np.random.Generator:
        return episode_generator(self.entropy, slot, episode)

    def generator(self, slot: int) -> np.random.Generator:
        """The generator of slot ``slot``'s current episode."""
        return self._generators[slot]

    def next_episode(self, slots: ArrayLike) -> None:
        """Slots ``slots`` (indices, or a mask over the slots) start their next episode."""
        idx = np.asarray(slots)
        if idx.dtype == bool:
            idx = np.flatnonzero(idx)
        for i in idx.tolist():
            self.rounds[i] += 1
            self._generators[i] = self._generator(i, int(self.rounds[i]))

    def rows(self, slots: ArrayLike | None = None) -> RowGenerator:
        """The draws of the rows of ``slots`` (indices or a mask; all slots when ``None``)."""
        if slots is None:
            return RowGenerator(self._generators)
        idx = np.asarray(slots)
        if idx.dtype == bool:
            idx = np.flatnonzero(idx)
        return RowGenerator([self._generators[i] for i in idx.tolist()])
