"""Learning curves: the policy's evaluation return against samples, with the rules as lines.

:class:`LearningCurve` evaluates the policy being trained at evenly spaced sample counts on a
fixed evaluation seed (the same scenarios every time, and the same as the rules'), so the curve
measures learning, not scenario luck. ``sensorgym train`` writes the points to ``curve.json``
and the picture to ``curve.png`` in the run folder. Each point carries ``wall_s``, the seconds
of training when it was taken (:class:`~.cost.RunClock`), and ``eval_s``, how many of them the
curve's own earlier evaluations took; ``curve.png`` then has a wall-clock axis on top (curves
of runs trained before it was recorded have none).
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import isotonic_regression
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env import VecEnv

from sensorgym.train.benchmark import best_rule
from sensorgym.train.cost import RunClock
from sensorgym.train.evaluation import evaluate


class LearningCurve(BaseCallback):
    """Evaluates the model every ``every`` samples (and once before the first update) on
    ``episodes`` episodes of ``env`` seeded with ``seed``; the points are in :attr:`points`.

    ``clock``: the run's clock, read for every point's ``wall_s`` (and its evaluations added to
    its ``eval_s``); without one, a clock started when learning starts.

    Each point also goes to the model's logger (TensorBoard with ``--tensorboard``) as
    ``eval/mean_return`` and ``eval/ci95``, with every rule's mean return on the same
    scenarios, ``lines`` (name → mean), as ``eval/<rule>`` beside it; the imitation phase's
    losses, ``pretrain_loss`` (one per data-collection round), go there as ``pretrain/loss``
    before learning."""

    def __init__(
        self,
        env: VecEnv,
        episodes: int,
        seed: int,
        every: int,
        clock: RunClock | None = None,
        lines: dict[str, float] | None = None,
        pretrain_loss: list[float] | None = None,
    ):
        super().__init__()
        if every < 1:
            raise ValueError(f"every: must be >= 1, got {every}")
        self.env, self.episodes, self.seed, self.every = env, episodes, seed, every
        self.clock = clock if clock is not None else RunClock()
        self.points: list[dict[str, float]] = []
        self.lines = dict(lines or {})
        self.pretrain_loss = list(pretrain_loss or [])
        self._next = 0
        self._resumed = False

    def resume(self, points: list[dict[str, float]]) -> None:
        """Continue a checkpointed run's curve (:mod:`.checkpoints`): its ``points`` so far; no
        point before learning resumes, the next at the first multiple of ``every`` after the
        last one."""
        self.points = [dict(p) for p in points]
        self._resumed = bool(self.points)

    def _point(self) -> None:
        wall, spent = self.clock.elapsed(), self.clock.eval_s
        begin = time.perf_counter()
        stats = evaluate(self.model, self.env, self.episodes, self.seed)
        self.clock.add_eval(time.perf_counter() - begin)
        self.points.append(
            {
                "timesteps": int(self.num_timesteps),
                "mean": stats.mean,
                "ci95": stats.ci95,
                "wall_s": round(wall, 3),
                "eval_s": round(spent, 3),
            }
        )
        self.logger.record("eval/mean_return", stats.mean)
        self.logger.record("eval/ci95", stats.ci95)
        for name, mean in self.lines.items():
            self.logger.record(f"eval/{name}", mean)
        self.logger.dump(self.num_timesteps)

    def _on_training_start(self) -> None:
        if self.clock.origin is None:
            self.clock.start()
        if self._resumed:
            self._next = (int(self.points[-1]["timesteps"]) // self.every + 1) * self.every
            return
        for round_, loss in enumerate(self.pretrain_loss, start=1):
            self.logger.record("pretrain/loss", loss)
            self.logger.dump(round_)
        self._point()
        self._next = self.every

    def _on_step(self) -> bool:
        if self.num_timesteps >= self._next:
            self._point()
            self._next += self.every
        return True

    def _on_training_end(self) -> None:
        if not self.points or self.points[-1]["timesteps"] < self.num_timesteps:
            self._point()


#: the margin around the curve's band and the best rule within which a rule's line is drawn, as a
#: fraction of their span; a rule further off (holding still at -700 beside a curve near +60)
#: is named in a note instead, so that it does not flatten the curve
WINDOW_MARGIN = 0.25
#: the least vertical distance between two rule labels, points
LABEL_GAP = 8.0


def curve_window(
    points: list[dict[str, float]], rules: dict[str, float]
) -> tuple[tuple[float, float], dict[str, float], dict[str, float]]:
    """The y-range of a learning curve, the rules drawn in it and those left out: the range
    holds the curve's 95 % band, the best fieldable rule (the one a trained policy must beat,
    :func:`~sensorgym.train.benchmark.best_rule`) and the highest line,
    widened by ``WINDOW_MARGIN`` of their span on each side (by 1 where the span is zero); a
    rule outside it is left out. Non-finite values (a diverged evaluation) take no part in the
    range and such rules are left out (the note names them); with nothing finite the range is
    ``(-1, 1)``: the picture is drawn whatever the numbers, at the end of a long run."""
    band = [p["mean"] + s * p["ci95"] for p in points for s in (-1.0, 1.0)]
    finite = {k: v for k, v in rules.items() if np.isfinite(v)}
    values = [v for v in band if np.isfinite(v)]
    if finite:
        values.append(max(finite.values()))
        best = best_rule({name: {"mean": value} for name, value in finite.items()})
        if best is not None:
            values.append(finite[best])
    lo, hi = (min(values), max(values)) if values else (0.0, 0.0)
    pad = WINDOW_MARGIN * (hi - lo) if hi > lo else 1.0
    lo, hi = lo - pad, hi + pad
    shown = {k: v for k, v in finite.items() if lo <= v <= hi}
    return (lo, hi), shown, {k: v for k, v in rules.items() if k not in shown}


def spread_labels(y: NDArray[np.float64], gap: float) -> NDArray[np.float64]:
    """Label heights nearest ``y`` (least squares) with at least ``gap`` between neighbours, in
    the same order: sorted from the top, ``a_i <= a_(i-1) - gap`` is ``a_i + i gap``
    non-increasing, an isotonic regression of ``y_i + i gap``."""
    y = np.asarray(y, dtype=np.float64)
    order = np.argsort(-y, kind="stable")
    shift = gap * np.arange(y.size)
    fitted = isotonic_regression(y[order] + shift, increasing=False).x - shift
    out = np.empty_like(y)
    out[order] = fitted
    return out


#: the least distance between two wall-clock ticks, as a fraction of the samples axis
CLOCK_TICK_GAP = 0.09


def wall_clock_axis(ax: Any, points: list[dict[str, float]]) -> Any:
    """A wall-clock axis on top of ``ax``: ticks at curve points (as many as fit, the first and
    the last among them) labelled with the training seconds recorded there (``wall_s``; minutes
    past ten minutes), so every label is a measured time, not an interpolation. ``None``, and
    nothing drawn, unless every point has ``wall_s``."""
    if not points or not all("wall_s" in p for p in points):
        return None
    steps = [float(p["timesteps"]) for p in points]
    wall = [float(p["wall_s"]) for p in points]
    gap = CLOCK_TICK_GAP * max(steps[-1] - steps[0], 1.0)
    kept = [0]
    for i in range(1, len(points)):
        if steps[i] - steps[kept[-1]] >= gap:
            kept.append(i)
    if kept[-1] != len(points) - 1:  # the last point's time is the run's: always shown
        if len(kept) > 1 and steps[-1] - steps[kept[-1]] < gap:
            kept.pop()
        kept.append(len(points) - 1)
    minutes = wall[-1] > 600.0
    unit = "min" if minutes else "s"
    labels = [f"{wall[i] / 60.0:.1f}" if minutes else f"{wall[i]:.0f}" for i in kept]
    top = ax.secondary_xaxis("top")
    top.set_xticks([steps[i] for i in kept], labels=labels)
    top.set_xlabel(f"wall-clock of training at the evaluations ({unit})", fontsize=8)
    top.tick_params(labelsize=7)
    return top


#: the trained policy's colour in ``curve.png``
POLICY_COLOUR = "#e8833a"
#: rule colours nearer than this to the policy's (Euclidean distance in RGB, 0–1 per channel)
#: are left out of the rules' palette
COLOUR_GAP = 0.25


def rule_colours() -> list[str]:
    """The palette of the rules' lines in ``curve.png``: matplotlib's colour cycle without the
    colours that read as the policy's (:data:`POLICY_COLOUR`; tab10's orange), so that no
    rule's line is taken for the curve."""
    import matplotlib.pyplot as plt
    from matplotlib.colors import to_rgb

    policy = np.array(to_rgb(POLICY_COLOUR))
    cycle = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    return [c for c in cycle if np.linalg.norm(np.array(to_rgb(c)) - policy) >= COLOUR_GAP]


def write_curve(
    run_dir: Path,
    title: str,
    points: list[dict[str, float]],
    rules: dict[str, float],
    pretrain_loss: list[float] | None = None,
) -> tuple[Path, Path]:
    """``curve.json`` and ``curve.png`` in ``run_dir``: the evaluation return (mean ± 95 %)
    against samples, each rule's mean as a labelled horizontal line (labels spread apart where
    the lines crowd; the rules far below the curve and the best rule named in a note, see
    :func:`curve_window`)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    run_dir = Path(run_dir)
    doc: dict[str, Any] = {"points": points, "rules": rules}
    if pretrain_loss:
        doc["pretrain_loss"] = pretrain_loss
    json_path = run_dir / "curve.json"
    json_path.write_text(json.dumps(doc, indent=2) + "\n")

    fig, ax = plt.subplots(figsize=(7.0, 4.2))
    steps = [p["timesteps"] for p in points]
    mean = [p["mean"] for p in points]
    ci = [p["ci95"] for p in points]
    ax.plot(steps, mean, color=POLICY_COLOUR, marker="o", markersize=3, label="trained policy")
    lo = [m - c for m, c in zip(mean, ci, strict=True)]
    hi = [m + c for m, c in zip(mean, ci, strict=True)]
    ax.fill_between(steps, lo, hi, color=POLICY_COLOUR, alpha=0.2, linewidth=0)
    (y_lo, y_hi), shown, hidden = curve_window(points, rules)
    ax.set_ylim(y_lo, y_hi)
    colors = rule_colours()
    ranked = sorted(shown.items(), key=lambda kv: -kv[1])
    labels = []
    for k, (name, value) in enumerate(ranked):
        color = colors[k % len(colors)]
        ax.axhline(value, color=color, linestyle="--", linewidth=1.0)
        labels.append(
            ax.annotate(
                name,
                (1.0, value),
                xycoords=("axes fraction", "data"),
                xytext=(3, 0),
                textcoords="offset points",
                va="center",
                fontsize=7,
                color=color,
            )
        )
    if hidden:
        note = "not drawn (off the scale): " + ", ".join(
            f"{name} {value:.3g}" for name, value in sorted(hidden.items(), key=lambda kv: -kv[1])
        )
        ax.text(
            0.01, 0.02, note, transform=ax.transAxes, fontsize=7, color="0.35", wrap=True,
            bbox={"facecolor": "white", "alpha": 0.8, "edgecolor": "none", "pad": 1.0},
        )  # fmt: skip
    ax.set_xlabel("samples (environment steps, all scenarios)")
    wall_clock_axis(ax, points)
    ax.set_ylabel("evaluation return (mean ± 95 %)")
    ax.set_title(title, fontsize=10, loc="left")
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    if labels:  # spread the labels in points, now that the axes have their final size
        to_points = 72.0 / fig.dpi
        at = np.array([ax.transData.transform((0.0, v))[1] for _, v in ranked]) * to_points
        for label, dy in zip(labels, spread_labels(at, LABEL_GAP) - at, strict=True):
            label.set_position((3, dy))
    png_path = run_dir / "curve.png"
    fig.savefig(png_path, dpi=90)
    plt.close(fig)
    return json_path, png_path
