"""The cross-machine comparisons of :mod:`tests.arithmetic` pass what a CPU's last bits can do
and fail on anything more."""

from __future__ import annotations

import numpy as np
import pytest

from tests.arithmetic import assert_episodes_close, assert_reports_close, assert_rescored

REPORT = """Paper 000 — 4 runs per cell, seed 0
   1       0.1 |    1.25/0.89      1.745/1.635  |       1.00  0.750  1.000
RT-3   missed   ratio 2.5 ± 0.3: ours 1.40 — outside 2.2–2.8
PCRLB                       2004    1916    1509
ML NEES 1.2e-05
"""


def test_a_report_may_round_its_last_digit_the_other_way():
    assert_reports_close(REPORT.replace("1.745", "1.746").replace("1916", "1915"), REPORT)
    assert_reports_close(REPORT.replace("1.2e-05", "1.3e-05"), REPORT)


@pytest.mark.parametrize(
    ("old", "new"),
    [
        ("1.745", "1.747"),  # two units of the last digit
        ("1916", "1918"),
        ("missed", "matched"),  # a word
        ("0.750", "0.75"),  # the printed precision
        ("1.2e-05", "1.2e-04"),
    ],
)
def test_a_report_that_reads_otherwise_fails(old, new):
    with pytest.raises(AssertionError):
        assert_reports_close(REPORT.replace(old, new), REPORT)


def test_a_report_with_a_line_more_fails():
    with pytest.raises(AssertionError):
        assert_reports_close(REPORT + "extra\n", REPORT)


def _episode(rng: np.random.Generator) -> dict[str, np.ndarray]:
    return {
        "obs": rng.normal(size=(41, 6)).astype(np.float32) * 1e3,
        "reward": rng.normal(size=40),
        "terminated": rng.random(40) < 0.1,
    }


def test_episodes_pass_last_bit_changes_and_fail_a_real_one():
    rng = np.random.default_rng(0)
    recorded = {f"E/single/0/{k}": v for k, v in _episode(rng).items()}
    got = {k.split("/")[-1]: v.copy() for k, v in recorded.items()}
    got["reward"] = got["reward"] * (1 + 1e-12)
    got["obs"] = np.nextafter(got["obs"], np.float32(np.inf))
    assert_episodes_close(got, recorded, "E/single/0")
    for key, change in (
        ("reward", lambda r: r + 1e-4 * np.abs(r).max()),
        ("obs", lambda o: o * np.float32(1 + 1e-5)),
        ("terminated", lambda t: ~t),
    ):
        bad = dict(got)
        bad[key] = change(got[key])
        with pytest.raises(AssertionError):
            assert_episodes_close(bad, recorded, "E/single/0")


def _scores(returns: np.ndarray, lengths: float = 30.0) -> dict:
    std = float(returns.std(ddof=1))
    return {
        "mean": float(returns.mean()),
        "std": std,
        "ci95": 1.96 * std / np.sqrt(returns.size),
        "episodes": int(returns.size),
        "mean_length": lengths,
        "returns": list(returns),
    }


def test_a_rescore_without_a_flip_holds_the_statistics():
    r = np.random.default_rng(1).normal(4.3, 1.5, 256)
    committed = _scores(r)
    assert_rescored(_scores(r * (1 + 3e-4)), committed)  # the drift measured under MKL_CBWR
    with pytest.raises(AssertionError):  # every episode 1 % better: no flip, another policy
        assert_rescored(_scores(r + 0.01 * np.maximum(np.abs(r), 1.0)), committed)
    with pytest.raises(AssertionError):  # a longer episode in every slot
        assert_rescored(_scores(r, lengths=30.5), committed)


def test_a_flip_may_move_its_own_episode_only():
    rng = np.random.default_rng(2)
    r = rng.normal(4.3, 1.5, 256)
    committed = _scores(r)
    flipped = r.copy()
    flipped[100] -= 3.0  # one episode's end decided the other way: that episode alone moves
    assert_rescored(_scores(flipped), committed)
    many = r.copy()
    many[100:110] -= 3.0  # ten episodes moved: more than flips explain
    with pytest.raises(AssertionError, match="at most 5 may flip"):
        assert_rescored(_scores(many), committed)
    with pytest.raises(AssertionError):  # one flip, and the policy 0.6 worse throughout
        assert_rescored(_scores(flipped - 0.6), committed)
