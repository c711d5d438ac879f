"""Saved models: the folder layout ``sensorgym train`` writes and loading it back.

A run folder holds ``model.zip`` (SB3's file), ``config.yaml`` (env id, algorithm, seed and
the resolved hyperparameters) and ``evaluation.json`` (the trained policy beside the rules).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml
from stable_baselines3.common.base_class import BaseAlgorithm

from sensorgym.train.config import ALGORITHMS

MODEL_FILE = "model.zip"
CONFIG_FILE = "config.yaml"


def read_config(run_dir: Path) -> dict[str, Any]:
    """The ``config.yaml`` of a run folder."""
    path = Path(run_dir) / CONFIG_FILE
    if not path.is_file():
        raise FileNotFoundError(f"{path}: not a `sensorgym train` run folder (no {CONFIG_FILE})")
    return yaml.safe_load(path.read_text())


def load_model(path: Path, env: Any = None) -> BaseAlgorithm:
    """Load a trained model from its run folder (or the ``model.zip`` inside it) on the CPU."""
    path = Path(path)
    run_dir = path.parent if path.suffix == ".zip" else path
    config = read_config(run_dir)
    algo = ALGORITHMS[config["algo"]]
    return algo.load(run_dir / MODEL_FILE, env=env, device="cpu")
