"""Trained policies shipped with sensorgym: what ``sensorgym benchmark`` scores beside the rules.

Each lives in ``train/policies/<env id with / as __>/<run>/`` as an ordinary ``sensorgym train``
run folder (``policy.safetensors``, ``config.yaml``, ``evaluation.json``), installed as package
data and loaded with the safe loader of :mod:`.models` (no pickle). A policy is shipped only when
it was trained on training seeds and re-scores, on the held-out seed 10000, to the number
committed in ``docs/scores/``; an env without one simply has none here.
"""

from __future__ import annotations

from pathlib import Path

#: the folder holding the shipped run folders, one sub-folder per env id
POLICIES_ROOT = Path(__file__).resolve().parent / "policies"


def env_folder_name(env_id: str) -> str:
    """The folder name of an env id (``/`` → ``__``), as ``sensorgym train`` names its runs."""
    return env_id.replace("/", "__")


def shipped_policies(env_id: str, root: Path = POLICIES_ROOT) -> dict[str, Path]:
    """Run name → run folder of every policy shipped for ``env_id`` (empty when there is none),
    sorted by name; a run folder is one with a ``policy.safetensors`` and a ``config.yaml``."""
    folder = Path(root) / env_folder_name(env_id)
    if not folder.is_dir():
        return {}
    return {
        run.name: run
        for run in sorted(folder.iterdir())
        if (run / "policy.safetensors").is_file() and (run / "config.yaml").is_file()
    }
