"""Comparing an env's numpy reference step with its compiled step (``tests/envs/*/test_reference.py``):
entry by entry, each against the scale its rounding depends on."""

from __future__ import annotations

import numpy as np


def assert_close(
    name: str,
    got: np.ndarray,
    want: np.ndarray,
    scale: np.ndarray | float,
    rtol: float,
    atol: float,
) -> None:
    """``|got − want| ≤ rtol · scale + atol`` entry by entry (``scale`` broadcasts); entries
    that are not finite in ``want`` must be equal in ``got``. The message names the worst entry."""
    got, want = np.asarray(got, dtype=np.float64), np.asarray(want, dtype=np.float64)
    assert got.shape == want.shape, f"{name}: shape {got.shape}, expected {want.shape}"
    finite = np.isfinite(want)
    if not np.array_equal(got[~finite], want[~finite]):
        np.testing.assert_array_equal(got[~finite], want[~finite], err_msg=name)
    err = np.abs(np.where(finite, got, 0.0) - np.where(finite, want, 0.0))
    tol = rtol * np.where(finite, np.broadcast_to(scale, err.shape), 0.0) + atol
    if not np.all(err <= tol):  # NaN fails too
        i = np.unravel_index(np.nanargmax(np.where(err <= tol, 0.0, err / tol)), err.shape)
        raise AssertionError(
            f"{name}: at {tuple(map(int, i))}, {got[i]!r} vs {want[i]!r} "
            f"(|Δ| = {err[i]:.3g}, tolerance {tol[i]:.3g})"
        )


def norm(v: np.ndarray) -> np.ndarray:
    """The norm over the last axis, kept for broadcasting (a vector's scale)."""
    return np.linalg.norm(v, axis=-1, keepdims=True)


def assert_same_draws(*generators: np.random.Generator) -> None:
    """Every generator consumed the same draws (same state): the reference drew what the
    compiled step drew, in the same order."""
    first = generators[0].bit_generator.state
    for g in generators[1:]:
        assert g.bit_generator.state == first, "the reference consumed other draws"


def assert_same_observations(
    core: object, got: object, want: object, how: str, atol: float
) -> None:
    """The float32 observations (``observe`` and ``observe_agents``) of the states ``got``
    (reference) and ``want`` (simulation) of a core, within ``atol`` (a float64 difference at
    rounding can cross one float32 step)."""
    for name in ("observe", "observe_agents"):
        view = getattr(core, name)
        o_got, o_want = view(got), view(want)
        assert o_got.dtype == o_want.dtype == np.float32
        assert o_got.shape == o_want.shape
        assert_close(f"{how}: {name}", o_got, o_want, 0.0, rtol=0.0, atol=atol)
