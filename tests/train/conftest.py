"""The plumbing tests train on the registered recipes with a token imitation phase.

A recipe's ``pretrain`` (``train/hyperparams/*.yml``) collects tens of thousands of expert
transitions before RL; tests that only check how runs are saved, loaded and scored keep the
recipe (its wrappers, expert, network) but imitate for a few hundred transitions, one epoch.
"""

from __future__ import annotations

from typing import Any

import pytest

from sensorgym.train import trainer

TOKEN_PRETRAIN = {"steps": 256, "rounds": 1, "epochs": 1}


@pytest.fixture(autouse=True)
def token_pretrain(monkeypatch: pytest.MonkeyPatch) -> None:
    load = trainer.load_hyperparams

    def small(algo: str, env_id: str) -> dict[str, Any]:
        hp = load(algo, env_id)
        if hp.get("pretrain"):
            hp["pretrain"] = {**hp["pretrain"], **TOKEN_PRETRAIN}
        return hp

    monkeypatch.setattr(trainer, "load_hyperparams", small)
