"""Every shipped policy re-scores, on the held-out seed, to the number committed in docs/scores/.

The numbers were committed from another machine: they agree to the tolerances of
:mod:`tests.arithmetic` (per episode while no episode end flips, the mean after a flip).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from sensorgym.train.benchmark import PolicySpec, registered_envs, score
from sensorgym.train.models import read_config
from sensorgym.train.shipped import POLICIES_ROOT, shipped_policies
from tests.arithmetic import assert_rescored

SCORES = Path(__file__).resolve().parents[2] / "docs" / "scores"
SHIPPED = [(env_id, run, folder) for env_id in registered_envs()
           for run, folder in shipped_policies(env_id).items()]  # fmt: skip


def test_the_policies_folder_holds_only_run_folders_of_registered_envs():
    envs = {e.replace("/", "__") for e in registered_envs()}
    for folder in POLICIES_ROOT.iterdir():
        assert folder.name in envs, folder
    assert SHIPPED


@pytest.mark.arithmetic
@pytest.mark.parametrize("env_id, run, folder", SHIPPED, ids=[f"{e}-{r}" for e, r, _ in SHIPPED])
def test_shipped_policy_rescores_to_the_committed_number(env_id, run, folder):
    config = read_config(folder)
    assert config["env"] == env_id and config["seed"] < 10_000  # trained on a training seed
    doc = json.loads((SCORES / f"{env_id.replace('/', '__')}.json").read_text())
    results = doc["results"]
    committed = results.get(f"shipped:{run}") or results[f"model:{run}"]
    settings = doc["settings"]
    assert settings["seed"] == 10_000
    again = score(env_id, PolicySpec("model", str(folder), shipped=True),
                  settings["episodes"], settings["n_envs"], settings["seed"])  # fmt: skip
    assert_rescored(again, committed)
