"""Every part :mod:`tests.pending` lists as missing is missing: once it lands, this fails until
the entry goes, and the repository-wide tests (golden episodes, docs pictures, recipes) take the
env in."""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from sensorgym.envs import ENV_IDS
from sensorgym.train.bounds import EPISODE_BOUNDS, HINDSIGHT_BOUNDS
from tests.golden_record import GOLDEN
from tests.pending import PARTS, PENDING, having

ROOT = Path(__file__).resolve().parents[1]


def _package(env_id: str) -> Path:
    """The env's package folder, from its registered entry point."""
    module = gym.spec(env_id).entry_point.split(":")[0]
    return ROOT / "envs" / module.split(".")[2]


def _has(part: str, env_id: str) -> bool:
    name, file_name = env_id.split("/")[1], env_id.replace("/", "__")
    if part == "golden":
        with np.load(GOLDEN / "episodes.npz") as data:
            return any(key.startswith(f"{name}/") for key in data.files)
    if part == "kernels":
        return (_package(env_id) / "kernels.py").is_file()
    if part == "picture":
        from tests.test_docs_site import _pictures_script_rules, ext

        return env_id in _pictures_script_rules() or ext.picture_path(env_id).is_file()
    if part == "ppo_recipe":
        from sensorgym.train.config import load_hyperparams

        try:
            load_hyperparams("ppo", env_id)
        except KeyError:
            return False
        return True
    if part == "scores":
        return (ROOT / "docs" / "scores" / f"{file_name}.json").is_file()
    if part == "bound":
        return env_id in EPISODE_BOUNDS or env_id in HINDSIGHT_BOUNDS
    if part == "policies":
        return (ROOT / "train" / "policies" / file_name).is_dir()
    raise KeyError(part)


def test_pending_entries_name_registered_envs_and_known_parts():
    assert set(PENDING) <= set(ENV_IDS)
    for parts in PENDING.values():
        assert parts and parts <= PARTS
    for part in PARTS:
        assert having(part, ENV_IDS) == [e for e in ENV_IDS if part not in PENDING.get(e, ())]
    with pytest.raises(KeyError, match="part"):
        having("docs", ENV_IDS)


@pytest.mark.parametrize(
    "env_id, part", [(env_id, part) for env_id, parts in PENDING.items() for part in sorted(parts)]
)
def test_a_pending_part_is_really_missing(env_id, part):
    assert not _has(part, env_id), (
        f"{env_id} has its {part!r} now: remove it from tests/pending.py PENDING"
    )


@pytest.mark.parametrize("part", ["golden", "picture", "ppo_recipe"])
def test_every_env_not_pending_has_the_parts_the_repository_wide_tests_need(part):
    for env_id in having(part, ENV_IDS):
        assert _has(part, env_id), (env_id, part)
