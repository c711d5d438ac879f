"""The benchmark chart: each panel's axis holds the policies that matter and cuts the far ones."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from sensorgym.train.benchmark import TRUTH_PREFIX
from sensorgym.train.score_chart import MARGIN, SPAN_GROWTH, bar_window, core_rows, plot_scores


def test_the_window_holds_zero_and_the_core_and_takes_others_while_the_span_allows():
    core = {"best", "shipped:a"}
    intervals = {
        "best": (50.0, 70.0),
        "shipped:a": (55.0, 75.0),
        "near": (20.0, 40.0),
        "still": (-700.0, -690.0),
    }
    # the core and zero span 0..75; "near" lies inside, "still" would widen it past 2 x 75
    lo, hi = bar_window(intervals, core)
    assert (lo, hi) == pytest.approx((0.0 - MARGIN * 75.0, 75.0 + MARGIN * 75.0))
    # the nearest other rows first: "mid" fits (span 115 <= 150), "low" then does not (165)
    assert SPAN_GROWTH * 75.0 == 150.0
    intervals |= {"low": (-90.0, -80.0), "mid": (-40.0, -30.0)}
    lo, hi = bar_window(intervals, core)
    assert (lo, hi) == pytest.approx((-40.0 - MARGIN * 115.0, 75.0 + MARGIN * 115.0))
    # every row fits: the window is the whole range
    lo, hi = bar_window({"best": (1.0, 2.0), "other": (-1.0, 0.5)}, {"best"})
    assert (lo, hi) == pytest.approx((-1.0 - MARGIN * 3.0, 2.0 + MARGIN * 3.0))


def test_the_window_ignores_non_finite_values_and_never_collapses():
    nan = float("nan")
    assert bar_window({"best": (nan, nan)}, {"best"}) == (-1.0, 1.0)
    assert bar_window({}, set()) == (-1.0, 1.0)
    lo, hi = bar_window({"best": (1.0, 3.0), "broken": (nan, np.inf)}, {"best"})
    assert (lo, hi) == pytest.approx((-MARGIN * 3.0, 3.0 + MARGIN * 3.0))


def test_the_core_is_the_best_rule_the_trained_policies_and_the_truth_informed():
    truth = f"{TRUTH_PREFIX}x"
    rows = {"a": {}, "best": {}, truth: {}, "shipped:p": {}, "model:q": {}}
    assert core_rows(rows, "best") == {"best", truth, "shipped:p", "model:q"}
    assert core_rows(rows, None) == {truth, "shipped:p", "model:q"}


def _row(returns: list[float]) -> dict:
    r = np.asarray(returns)
    return {"mean": float(r.mean()), "ci95": float(1.96 * r.std(ddof=1) / np.sqrt(r.size)),
            "returns": returns}  # fmt: skip


def test_the_chart_has_a_paired_panel_where_the_returns_allow(tmp_path):
    rng = np.random.default_rng(0)
    base = rng.normal(50.0, 10.0, 32)
    rows = {
        "rule": _row(list(base)),
        "shipped:p": _row(list(base + rng.normal(2.0, 1.0, 32))),
        "still": _row(list(rng.normal(-700.0, 5.0, 32))),
    }
    with_pairs = plot_scores({"env/A-v0": rows, "env/B-v0": {}}, tmp_path / "a.png")
    no_returns = {k: {"mean": v["mean"], "ci95": v["ci95"]} for k, v in rows.items()}
    single = plot_scores({"env/A-v0": no_returns}, tmp_path / "b.png")
    with Image.open(with_pairs) as two, Image.open(single) as one:
        assert two.size[0] > 1.3 * one.size[0]  # two panels side by side, then one
    with pytest.raises(ValueError, match="no env"):
        plot_scores({"env/A-v0": {}}, tmp_path / "c.png")


def test_the_bound_is_drawn_as_the_ceiling_and_kept_in_view():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from sensorgym.train.score_chart import _bars

    fig, ax = plt.subplots()
    names = ["hold", "best", "shipped:a"]
    _bars(ax, names, [-700.0, 60.0, 62.0], [5.0, 3.0, 3.0], {"best", "shipped:a"}, [90.0] * 3)
    ceiling = [line for line in ax.lines if list(line.get_xdata()) == [90.0, 90.0]]
    assert len(ceiling) == 1 and ceiling[0].get_linestyle() == "--"
    assert ax.get_xlim()[1] > 90.0  # the bound widens the axis to stay in view
    plt.close(fig)
    fig, ax = plt.subplots()  # bounds that differ between rows: a mark on each row
    _bars(ax, names, [-700.0, 60.0, 62.0], [5.0, 3.0, 3.0], {"best"}, [90.0, 91.0, 92.0])
    marks = [line for line in ax.lines if line.get_label() == "episode bound"]
    assert len(marks) == 1 and list(marks[0].get_xdata()) == [90.0, 91.0, 92.0]
    plt.close(fig)
