"""The benchmark's chart: per env, every policy's mean return and its paired difference to the
best rule, each axis scaled to the policies that matter.

One rule that holds still can score −700 where the best policies score +60 (StereoPointing): on
a common scale the comparison the chart exists for vanishes. Each panel's axis therefore holds
the *core* rows — the best fieldable rule, every trained policy, every truth-informed rule —,
zero and the episodes' bound where the rows carry one, and takes in the other rows only while
the axis stays within ``SPAN_GROWTH`` times the core's span; a bar beyond it is cut at the axis
and its value written on it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from sensorgym.train.benchmark import TRUTH_PREFIX, is_rule, paired_to_best_rule

#: how far the other rows may widen a panel's axis: at most this times the core rows' span
SPAN_GROWTH = 2.0
#: the axis margin beyond the outermost interval drawn, a fraction of the span
MARGIN = 0.06
TRAINED_COLOR, RULE_COLOR, BOUND_COLOR = "#e8833a", "#4878a8", "#3a8a3a"


def bar_window(intervals: dict[str, tuple[float, float]], core: set[str]) -> tuple[float, float]:
    """The x-range of one panel of bars starting at zero: ``intervals`` per row ``(low, high)``
    (the mean ∓ its 95 % half-width); the range holds zero and every ``core`` row's interval,
    then the other rows nearest that range first, as long as the span stays within
    ``SPAN_GROWTH`` times the core's; a margin of ``MARGIN`` of the span on each side.
    Non-finite ends take no part (with nothing finite the range is ``(-1, 1)``)."""
    finite = {k: v for k, v in intervals.items() if np.all(np.isfinite(v))}
    core_values = [x for k in core & finite.keys() for x in finite[k]]
    lo, hi = min([0.0, *core_values]), max([0.0, *core_values])
    limit = SPAN_GROWTH * (hi - lo)
    others = sorted(
        (v for k, v in finite.items() if k not in core),
        key=lambda v: max(lo - v[0], v[1] - hi, 0.0),
    )
    for low, high in others:
        if max(hi, high) - min(lo, low) > limit:
            break
        lo, hi = min(lo, low), max(hi, high)
    span = hi - lo
    if span <= 0.0:
        return -1.0, 1.0
    return lo - MARGIN * span, hi + MARGIN * span


def core_rows(rows: dict[str, Any], best: str | None) -> set[str]:
    """The rows a panel must show whole: the best fieldable rule, every trained policy (a name
    with ``:``), every truth-informed rule."""
    core = {k for k in rows if not is_rule(k) or k.startswith(TRUTH_PREFIX)}
    return core | ({best} if best is not None else set())


def _bars(
    ax: Any,
    names: list[str],
    mean: list[float],
    ci: list[float],
    core: set[str],
    bounds: list[float] | None = None,
) -> None:
    """One panel: a bar per row from zero to its mean with its 95 % interval, the axis from
    :func:`bar_window`, each bar cut at the axis labelled with its value (on a white ground:
    the visible stub of a cut bar may be narrower than the text). ``bounds``: each row's mean
    episode bound (:mod:`.bounds`), drawn as the panel's ceiling: one dashed line where every
    row met the same episodes' bounds, else a mark on each row."""
    colors = [RULE_COLOR if is_rule(n) else TRAINED_COLOR for n in names]
    ax.barh(names, mean, xerr=ci, color=colors, capsize=3, height=0.6)
    intervals = {n: (m - c, m + c) for n, m, c in zip(names, mean, ci, strict=True)}
    if bounds is not None:  # the ceiling is always in view
        intervals["bound"] = (min(bounds), max(bounds))
        core = core | {"bound"}
    lo, hi = bar_window(intervals, core)
    if bounds is not None:
        if np.ptp(bounds) <= 1e-9 * max(abs(bounds[0]), 1.0):
            ax.axvline(bounds[0], color=BOUND_COLOR, linestyle="--", linewidth=1.2)
            ax.annotate(
                f"bound {bounds[0]:.4g}",
                (bounds[0], 1.0),
                xycoords=("data", "axes fraction"),
                xytext=(-3, -3),
                textcoords="offset points",
                ha="right",
                va="top",
                fontsize=7,
                color=BOUND_COLOR,
            )
        else:
            ax.plot(bounds, names, "|", color=BOUND_COLOR, markersize=12, label="episode bound")
    ax.set_xlim(lo, hi)
    for y, m in enumerate(mean):
        if np.isfinite(m) and not lo <= m <= hi:
            left = m < lo
            ax.annotate(
                f"◀ {m:.4g}" if left else f"{m:.4g} ▶",
                (0.0 if left else 1.0, y),
                xycoords=("axes fraction", "data"),
                xytext=(3 if left else -3, 0),
                textcoords="offset points",
                ha="left" if left else "right",
                va="center",
                fontsize=7,
                bbox={"facecolor": "white", "alpha": 0.85, "edgecolor": "none", "pad": 1.0},
            )
    ax.axvline(0.0, color="black", linewidth=0.6)
    ax.tick_params(labelsize=8)
    ax.grid(axis="x", alpha=0.3)


def plot_scores(
    scores: dict[str, dict[str, dict[str, Any]]], path: Path, title: str = "episode return"
) -> Path:
    """A PNG at ``path``: per env a row of panels, each on its own scale (:func:`bar_window`):
    a horizontal bar per policy with its mean ``title`` and 95 % interval (trained policies in
    orange, rules in blue; the mean of the episodes' true bounds, where the rows carry them, as
    the panel's ceiling), and, where the rows carry per-episode ``returns``, beside it each
    policy's paired difference to the best fieldable rule (per episode, on the same scenarios;
    mean and 95 % interval), the comparison a trained policy must win."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    envs = [e for e, rows in scores.items() if rows]
    if not envs:
        raise ValueError("scores: no env has any result to plot")
    paired = {e: paired_to_best_rule(scores[e]) for e in envs}
    columns = 2 if any(p for _, p in paired.values()) else 1
    heights = [0.6 + 0.32 * len(scores[e]) for e in envs]
    fig, axes = plt.subplots(
        len(envs),
        columns,
        figsize=(7.5 if columns == 1 else 11.0, sum(heights) + 0.6),
        gridspec_kw={"height_ratios": heights},
        squeeze=False,
    )
    for k, env_id in enumerate(envs):
        rows = sorted(scores[env_id].items(), key=lambda kv: kv[1]["mean"])
        names = [name for name, _ in rows]
        best, diffs = paired[env_id]
        core = core_rows(scores[env_id], best)
        ax = axes[k, 0]
        bounds = [float(np.mean(r["bounds"])) for _, r in rows if r.get("bounds")]
        _bars(ax, names, [r["mean"] for _, r in rows], [r["ci95"] for _, r in rows], core,
              bounds if len(bounds) == len(rows) else None)  # fmt: skip
        ax.set_title(env_id, fontsize=10, loc="left")
        if columns == 2:
            ax = axes[k, 1]
            if diffs:
                d = [diffs[n]["mean"] if n in diffs else 0.0 for n in names]
                c = [diffs[n]["ci95"] if n in diffs else 0.0 for n in names]
                _bars(ax, names, d, c, core - {best})
                ax.set_yticklabels([])  # the rows of the panel on the left
                ax.annotate(
                    "best rule",
                    (0.0, names.index(best)),
                    xytext=(3, 0),
                    textcoords="offset points",
                    va="center",
                    fontsize=7,
                    color="0.35",
                )
                ax.set_title(f"paired − best rule ({best})", fontsize=10, loc="left")
            else:
                ax.axis("off")
    axes[-1, 0].set_xlabel(f"{title} (mean ± 95 % interval)", fontsize=9)
    if columns == 2:
        axes[-1, 1].set_xlabel("paired difference per episode (mean ± 95 % interval)", fontsize=9)
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path
