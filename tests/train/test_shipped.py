"""Every shipped policy re-scores, on the held-out seed, to the number committed in docs/scores/.

The numbers were committed from another machine: they agree to the tolerances of
:mod:`tests.arithmetic` (per episode while no episode end flips, the mean after a flip). An env
scored on more than :data:`RESCORED_EPISODES` episodes is re-scored on its first ones: every
episode draws from its own stream, keyed by its scenario and round, so they are the same
episodes whatever the total.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from sensorgym.train.benchmark import PolicySpec, registered_envs, score
from sensorgym.train.models import read_config
from sensorgym.train.shipped import POLICIES_ROOT, shipped_policies
from tests.arithmetic import assert_rescored

SCORES = Path(__file__).resolve().parents[2] / "docs" / "scores"
#: the most episodes a shipped policy is re-scored on (the first rounds of the committed ones)
RESCORED_EPISODES = 256
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
    episodes = min(settings["episodes"], RESCORED_EPISODES)
    again = score(env_id, PolicySpec("model", str(folder), shipped=True),
                  episodes, settings["n_envs"], settings["seed"])  # fmt: skip
    assert_rescored(again, first_episodes(committed, episodes, again["mean_length"]))


def first_episodes(committed: dict, k: int, mean_length: float) -> dict:
    """The committed result of the first ``k`` episodes (the returns' first ``k``, in rounds of
    the scenarios; their statistics recomputed). Lengths are not recorded per episode: a subset
    takes ``mean_length`` as given (the returns are compared episode by episode)."""
    if k == committed["episodes"]:
        return committed
    r = np.asarray(committed["returns"][:k], dtype=np.float64)
    std = float(r.std(ddof=1))
    return {"episodes": k, "returns": r.tolist(), "mean": float(r.mean()), "std": std,
            "ci95": 1.96 * std / float(np.sqrt(k)), "mean_length": mean_length}  # fmt: skip


def test_the_first_episodes_of_a_longer_score_are_the_shorter_score():
    """What :func:`first_episodes` relies on, checked with a rule (cheap): 48 episodes of 16
    scenarios begin with the 16 of one round, episode by episode."""
    env_id = "sensorgym/GimbalTracking-v0"
    rule = PolicySpec("rule", "feedforward-search")
    long, short = score(env_id, rule, 48, 16, 10_000), score(env_id, rule, 16, 16, 10_000)
    np.testing.assert_array_equal(long["returns"][:16], short["returns"])
