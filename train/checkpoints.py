"""Checkpoints of a training run, and resuming from one (``sensorgym train --checkpoint-every N``,
``sensorgym train --resume RUN``).

Every ``N`` samples the run writes ``RUN/checkpoint/``: ``model.zip`` (Stable-Baselines3's own
save: weights, optimizer state, the algorithm's counters) and ``checkpoint.json`` (the samples
done, the arguments the run was started with, the learning curve's points so far, the imitation
phase's losses and the run's clock). ``--resume RUN`` rebuilds the run from those arguments,
loads the model, skips the imitation phase and learns the samples still to go; the learning
curve and the clock continue where the checkpoint left them, and the run folder is completed
as an uninterrupted run's would be.

A resumed run continues from the checkpoint's weights and optimizer, not bit for bit from where
the process stopped: the training envs start fresh episodes from the run's seed. ``model.zip``
holds pickled objects (SB3's format): load only checkpoints you wrote; the shipped policies
use the pickle-free run format (:mod:`.models`).
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from stable_baselines3.common.callbacks import BaseCallback

#: the checkpoint folder inside a run folder
CHECKPOINT_DIR = "checkpoint"
#: the model file of a checkpoint (SB3's save)
MODEL_FILE = "model.zip"
#: the checkpoint's record
STATE_FILE = "checkpoint.json"
CHECKPOINT_FORMAT = 1


class Checkpointer(BaseCallback):
    """Writes the run's checkpoint every ``every`` samples, once the updates of those samples
    are made, and at the end of learning.

    ``run``: the arguments the run was started with (what :func:`read_checkpoint` hands back
    to resume it); ``curve``: the run's learning-curve callback (its points are saved), or
    ``None``; ``clock``: the run's :class:`~.cost.RunClock`; ``pretrain_loss``: the imitation
    phase's losses."""

    def __init__(
        self,
        folder: Path,
        every: int,
        run: dict[str, Any],
        curve: Any = None,
        clock: Any = None,
        pretrain_loss: list[float] | None = None,
    ):
        super().__init__()
        if every < 1:
            raise ValueError(f"checkpoint_every: must be >= 1, got {every}")
        self.folder, self.every, self.run = Path(folder), int(every), run
        self.curve, self.clock, self.pretrain_loss = curve, clock, list(pretrain_loss or [])
        self._next = 0
        self._rollouts = False
        self.saved: list[int] = []

    def _on_training_start(self) -> None:
        self._next = (self.num_timesteps // self.every + 1) * self.every
        self._rollouts = False

    def _due(self) -> None:
        if self.num_timesteps >= self._next:
            self.save()
            self._next = (self.num_timesteps // self.every + 1) * self.every

    def _on_rollout_start(self) -> None:
        # PPO and SAC: a rollout starts after the previous one's gradient steps, so the
        # weights saved here hold every update of the samples counted
        self._rollouts = True
        self._due()

    def _on_step(self) -> bool:
        if not self._rollouts:  # ARS: one call per iteration, after its update
            self._due()
        return True

    def _on_training_end(self) -> None:
        self.save()  # after the last update

    def save(self) -> None:
        """Write ``model.zip`` and ``checkpoint.json`` (each written whole, then renamed, so
        that a run stopped while saving leaves the previous checkpoint readable)."""
        self.folder.mkdir(parents=True, exist_ok=True)
        partial = self.folder / f"partial_{MODEL_FILE}"
        self.model.save(partial)
        os.replace(partial, self.folder / MODEL_FILE)
        state = {
            "format": CHECKPOINT_FORMAT,
            "timesteps": int(self.num_timesteps),
            "run": self.run,
            "curve_points": None if self.curve is None else list(self.curve.points),
            "pretrain_loss": self.pretrain_loss,
            "clock": None
            if self.clock is None
            else {"elapsed_s": self.clock.elapsed(), "eval_s": self.clock.eval_s},
        }
        text = json.dumps(state, indent=1) + "\n"
        (self.folder / f"partial_{STATE_FILE}").write_text(text)
        os.replace(self.folder / f"partial_{STATE_FILE}", self.folder / STATE_FILE)
        self.saved.append(int(self.num_timesteps))


def read_checkpoint(run_dir: Path) -> dict[str, Any]:
    """The checkpoint record of the run folder ``run_dir`` (``ValueError`` naming what is
    missing), with ``model`` set to its model file."""
    folder = Path(run_dir) / CHECKPOINT_DIR
    state_path, model_path = folder / STATE_FILE, folder / MODEL_FILE
    if not state_path.is_file() or not model_path.is_file():
        raise ValueError(
            f"{run_dir}: no checkpoint ({CHECKPOINT_DIR}/{STATE_FILE} and "
            f"{CHECKPOINT_DIR}/{MODEL_FILE}); was the run started with --checkpoint-every?"
        )
    state = json.loads(state_path.read_text())
    if state.get("format") != CHECKPOINT_FORMAT:
        raise ValueError(
            f"{state_path}: format {state.get('format')!r}, expected {CHECKPOINT_FORMAT}"
        )
    return {**state, "model": str(model_path)}
