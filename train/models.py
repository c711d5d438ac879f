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


class RunFolderError(ValueError):
    """A path that is not a usable ``sensorgym train`` run folder (the message names the file)."""


def run_dir_of(path: Path) -> Path:
    """The run folder of ``path`` (the folder itself, or the folder of its ``model.zip``)."""
    path = Path(path)
    return path.parent if path.suffix == ".zip" else path


def read_config(run_dir: Path) -> dict[str, Any]:
    """The checked ``config.yaml`` of a run folder: a mapping with a registered ``env`` id and a
    known ``algo``; anything else raises :class:`RunFolderError` naming the file."""
    import gymnasium as gym

    import sensorgym.envs  # noqa: F401  (registers the ids)

    path = Path(run_dir) / CONFIG_FILE
    if not path.is_file():
        raise RunFolderError(f"{path}: not a `sensorgym train` run folder (no {CONFIG_FILE})")
    try:
        config = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise RunFolderError(f"{path}: not valid YAML ({exc})") from None
    if not isinstance(config, dict):
        raise RunFolderError(f"{path}: expected a mapping with env and algo, got {config!r}")
    for key in ("env", "algo"):
        if key not in config:
            raise RunFolderError(f"{path}: no {key!r} entry")
    if config["algo"] not in ALGORITHMS:
        raise RunFolderError(f"{path}: algo {config['algo']!r} is not one of {sorted(ALGORITHMS)}")
    if config["env"] not in gym.registry:
        raise RunFolderError(f"{path}: env {config['env']!r} is not a registered id")
    return config


def check_run_folder(path: Path) -> dict[str, Any]:
    """The checked config of the run folder of ``path`` (a folder or its ``model.zip``), whose
    model file must exist; :class:`RunFolderError` names what is wrong."""
    run_dir = run_dir_of(path)
    config = read_config(run_dir)
    model_file = run_dir / MODEL_FILE
    if not model_file.is_file():
        raise RunFolderError(f"{model_file}: no such model file")
    return config


def load_model(path: Path, env: Any = None) -> BaseAlgorithm:
    """Load a trained model from its run folder (or the ``model.zip`` inside it) on the CPU."""
    config = check_run_folder(path)
    algo = ALGORITHMS[config["algo"]]
    return algo.load(run_dir_of(path) / MODEL_FILE, env=env, device="cpu")
