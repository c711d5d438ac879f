"""Learning curves: the policy's evaluation return against samples, with the rules as lines.

:class:`LearningCurve` evaluates the policy being trained at evenly spaced sample counts on a
fixed evaluation seed (the same scenarios every time, and the same as the rules'), so the curve
measures learning, not scenario luck. ``sensorgym train`` writes the points to ``curve.json``
and the picture to ``curve.png`` in the run folder.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env import VecEnv

from sensorgym.train.evaluation import evaluate


class LearningCurve(BaseCallback):
    """Evaluates the model every ``every`` samples (and once before the first update) on
    ``episodes`` episodes of ``env`` seeded with ``seed``; the points are in :attr:`points`."""

    def __init__(self, env: VecEnv, episodes: int, seed: int, every: int):
        super().__init__()
        if every < 1:
            raise ValueError(f"every: must be >= 1, got {every}")
        self.env, self.episodes, self.seed, self.every = env, episodes, seed, every
        self.points: list[dict[str, float]] = []
        self._next = 0

    def _point(self) -> None:
        stats = evaluate(self.model, self.env, self.episodes, self.seed)
        self.points.append(
            {"timesteps": int(self.num_timesteps), "mean": stats.mean, "ci95": stats.ci95}
        )

    def _on_training_start(self) -> None:
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


def write_curve(
    run_dir: Path,
    title: str,
    points: list[dict[str, float]],
    rules: dict[str, float],
    pretrain_loss: list[float] | None = None,
) -> tuple[Path, Path]:
    """``curve.json`` and ``curve.png`` in ``run_dir``: the evaluation return (mean ± 95 %)
    against samples, each rule's mean as a labelled horizontal line."""
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
    ax.plot(steps, mean, color="#e8833a", marker="o", markersize=3, label="trained policy")
    lo = [m - c for m, c in zip(mean, ci, strict=True)]
    hi = [m + c for m, c in zip(mean, ci, strict=True)]
    ax.fill_between(steps, lo, hi, color="#e8833a", alpha=0.2, linewidth=0)
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for k, (name, value) in enumerate(sorted(rules.items(), key=lambda kv: -kv[1])):
        color = colors[k % len(colors)]
        ax.axhline(value, color=color, linestyle="--", linewidth=1.0)
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
    ax.set_xlabel("samples (environment steps, all scenarios)")
    ax.set_ylabel("evaluation return (mean ± 95 %)")
    ax.set_title(title, fontsize=10, loc="left")
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    png_path = run_dir / "curve.png"
    fig.savefig(png_path, dpi=90)
    plt.close(fig)
    return json_path, png_path
