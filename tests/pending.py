"""What a registered env does not have yet, while its issue delivers it in parts.

A repository-wide test that needs one of these parts of every env picks the envs that have it
(:func:`having`); ``tests/test_pending.py`` checks every entry against the repository, so an
entry cannot outlive the part's arrival (the check fails once the part exists: remove the
entry then, and the repository-wide tests take the env in) nor hide a part an env should have.

| part | what it is | where it lands |
|------|------------|----------------|
| ``golden`` | seeded episodes of every door | ``tests/golden/episodes.npz`` |
| ``kernels`` | the compiled step, its ``COMPILE_VARIANTS`` and ``test_reference.py`` | ``envs/<env>/kernels.py`` |
| ``picture`` | the docs site's picture of a rule's episode | ``docs/make_pictures.py``, PNG |
| ``ppo_recipe`` | a PPO recipe | ``train/hyperparams/ppo.yml`` |
| ``scores`` | committed benchmark scores | ``docs/scores/<env>.json`` |
| ``bound`` | a true upper bound on an episode's return | ``train/bounds.py`` |
| ``policies`` | shipped trained policies | ``train/policies/<env>/`` |
"""

from __future__ import annotations

from collections.abc import Iterable

#: env id -> the parts it does not have yet (issue 40 delivers GimbalTracking-v0 in parts)
PENDING: dict[str, frozenset[str]] = {}

#: every part an entry may name
PARTS = frozenset({"golden", "kernels", "picture", "ppo_recipe", "scores", "bound", "policies"})


def having(part: str, env_ids: Iterable[str]) -> list[str]:
    """``env_ids`` (in order) without the envs for which ``part`` is pending."""
    if part not in PARTS:
        raise KeyError(f"part: one of {sorted(PARTS)}, got {part!r}")
    return [env_id for env_id in env_ids if part not in PENDING.get(env_id, frozenset())]
