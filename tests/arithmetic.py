"""What a result recorded on one machine promises on another: the suite's cross-CPU tolerances.

Every test that compares a computation with a number committed from another machine (golden
episodes and reproduction reports, shipped policies' scores) is marked ``arithmetic`` and uses
the comparisons below; ``scripts/test_arithmetic.sh`` (run by ``.ci/run``) repeats those tests
under other arithmetic paths. Comparisons of two runs in one process, on one thread split,
stay bit for bit: there the same instructions meet the same inputs, which is guaranteed.

Where the last bits come from on another x86-64 CPU: glibc's libm picks its ``sin``/``exp``/
``atan2`` variant by CPU (FMA or not), numpy its SIMD loops (AVX2 against AVX-512 reductions
and SVML ``sin``/``cos``), MKL the summation order of torch's matmuls (``MKL_CBWR``, the
instruction set), numba the code LLVM emits for the CPU (``NUMBA_CPU_NAME``). Each changes a
value by a few units in its last place; the tolerances say how far the envs carry that.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from typing import Any

import numpy as np

#: Golden episodes (40 seeded steps of every door): a CPU's last-bit change is a relative
#: nudge ε ~ 1e-15; ``benchmarks/arithmetic.py`` nudges every action by far larger ε and
#: records how far the arrays move and that no episode end flips
#: (``benchmarks/results/arithmetic.json``, ``golden``): 1e-6 of the array's scale leaves a
#: wide margin and still catches any change of behaviour.
EPISODE_TOL = 1e-6

#: Reproduction reports: a number printed with d decimals may differ by one unit of its last
#: digit (a last-bit change rounds the other way), or by this relative amount.
REPORT_RTOL = 1e-6

#: Shipped policies, per episode: torch's float32 matmuls round differently across BLAS paths
#: and CPUs (a last-bit change in an action), and the bearings envs carry it into the return
#: (``benchmarks/results/arithmetic.json``, ``blas_path``: the drift of the policies whose
#: episode ends all held under ``MKL_CBWR=COMPATIBLE``); 5 % separates that drift from a
#: path flip.
EPISODE_RETURN_RTOL = 0.05

#: Shipped policies: at most this share of the episodes (and at least one) may flip its path
#: (an episode end, or a discrete choice, decided by a last-bit change). The benchmark draws
#: every episode from its own stream (``sensorgym.envs.shells.streams``): a flip moves its own
#: episode only. Measured under ``MKL_CBWR=COMPATIBLE`` (``benchmarks/results/arithmetic.json``):
#: no flip in the 3,840 episodes of the 15 shipped runs, the largest drift of an episode 2.2 %
#: (a BearingsManeuver run); before the streams, one flip there redrew 10 later episodes.
MAX_FLIPPED_SHARE = 0.02


def assert_episodes_close(got: Mapping[str, np.ndarray], recorded: Mapping[str, np.ndarray],
                          prefix: str) -> None:  # fmt: skip
    """Each array of ``got`` equals ``recorded[f"{prefix}/{key}"]``: booleans (episode ends)
    exactly, numbers within :data:`EPISODE_TOL` of the recorded array's scale and value."""
    for key, value in got.items():
        want = recorded[f"{prefix}/{key}"]
        where = f"{prefix}/{key}"
        assert value.shape == want.shape and value.dtype == want.dtype, where
        if value.dtype == bool:
            np.testing.assert_array_equal(value, want, err_msg=where)
            continue
        scale = float(np.max(np.abs(want), initial=0.0))
        np.testing.assert_allclose(
            value, want, rtol=EPISODE_TOL, atol=EPISODE_TOL * scale, err_msg=where
        )


_NUMBER = re.compile(r"[-+]?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?")


def _last_digit_unit(text: str) -> float:
    """One unit in the last printed place of ``text`` (``"0.184"`` → 0.001, ``"1.2e-05"`` →
    1e-06, ``"2004"`` → 1)."""
    mantissa, _, exponent = text.lower().partition("e")
    decimals = len(mantissa.partition(".")[2])
    return 10.0 ** (int(exponent or 0) - decimals)


def assert_reports_close(got: str, expected: str) -> None:
    """``got`` reads as ``expected``: the same lines and words, every number printed to the
    same place and within one unit of its last digit or :data:`REPORT_RTOL`."""
    got_lines, want_lines = got.splitlines(), expected.splitlines()
    assert len(got_lines) == len(want_lines), f"{len(got_lines)} lines, {len(want_lines)} recorded"
    for n, (line, want) in enumerate(zip(got_lines, want_lines, strict=True), 1):
        where = f"line {n}:\n  got      {line!r}\n  recorded {want!r}"
        assert _NUMBER.split(line) == _NUMBER.split(want), where
        for a, b in zip(_NUMBER.findall(line), _NUMBER.findall(want), strict=True):
            assert _last_digit_unit(a) == _last_digit_unit(b), where  # the printed precision
            tol = max(_last_digit_unit(b), REPORT_RTOL * abs(float(b)))
            assert abs(float(a) - float(b)) <= tol * (1 + 1e-9), where


def assert_rescored(again: Mapping[str, Any], committed: Mapping[str, Any]) -> None:
    """A policy re-scored on the committed scenarios agrees with its committed result.

    Every episode's return lies within :data:`EPISODE_RETURN_RTOL` (of ``max(|return|, 1)``)
    but for at most :data:`MAX_FLIPPED_SHARE` of them (at least one): the path flips, each
    free to move its own episode only, since every episode draws from its own stream. The
    statistics agree to 1e-3 when nothing flipped; after a flip the mean within what the
    flipped episodes moved it (``Σ |Δr| / n`` over them, plus 1e-3 of the rest).
    """
    assert again["episodes"] == committed["episodes"]
    r0 = np.asarray(committed["returns"], dtype=np.float64)
    r1 = np.asarray(again["returns"], dtype=np.float64)
    assert r1.shape == r0.shape
    drift = np.abs(r1 - r0) / np.maximum(np.abs(r0), 1.0)
    flipped = drift > EPISODE_RETURN_RTOL
    if not flipped.any():
        for key in ("mean", "std", "ci95", "mean_length"):
            assert math.isclose(again[key], committed[key], rel_tol=1e-3, abs_tol=1e-9), key
        return
    allowed = max(1, int(MAX_FLIPPED_SHARE * r0.size))
    assert flipped.sum() <= allowed, (
        f"{int(flipped.sum())} of {r0.size} episodes moved beyond {EPISODE_RETURN_RTOL:.0%} "
        f"(at most {allowed} may flip): {np.flatnonzero(flipped)[:10].tolist()}"
    )
    moved = float(np.sum(np.abs(r1 - r0)[flipped])) / r0.size
    slack = 1e-3 * max(abs(committed["mean"]), 1.0)
    assert abs(again["mean"] - committed["mean"]) <= moved + slack
