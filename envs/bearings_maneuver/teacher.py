"""Teachers for imitation pre-training on ``sensorgym/BearingsManeuver-v0``.

:func:`oracle_teacher` is the expert a run's ``pretrain`` names (``oracle-lookahead``,
registered in :data:`sensorgym.train.experts.EXPERTS`): the oracle rule
(:class:`sensorgym.agents.bearings_maneuver.OracleLookahead`), which plans on the true target
and the true bound, acting on the training env's scenarios whatever wrappers change the
observation. The student sees only its (wrapped) observation: what it learns is a fieldable
policy; the teacher's truth only labels the states.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from stable_baselines3.common.vec_env import VecEnv

from sensorgym.agents.bearings_maneuver import EstimateLookahead, OracleLookahead
from sensorgym.agents.protocol import MemorylessRule


@dataclass(frozen=True)
class OracleTeacher:
    """SB3's ``predict`` over :class:`OracleLookahead`, for observations of any shape: the
    action comes from the simulator's state, so the observation only fixes the batch size."""

    oracle: OracleLookahead
    """The oracle rule, reading the training env's simulator state."""

    def predict(
        self,
        observation: NDArray[Any],
        state: Any = None,
        episode_start: NDArray[np.bool_] | None = None,
        deterministic: bool = True,
    ) -> tuple[NDArray[np.float32], None]:
        obs = np.asarray(observation)
        single = obs.ndim == 1
        s = self.oracle.state_fn()
        n = 1 if single else obs.shape[0]
        if s.batch_size != n:
            raise ValueError(f"observation: batch {n} != simulator batch {s.batch_size}")
        plans = self.oracle.plan_bounds(s)
        action = self.oracle.candidates()[np.argmin(plans, axis=1)].astype(np.float32)
        return (action[0] if single else action), None


def oracle_teacher(env: VecEnv) -> OracleTeacher:
    """The oracle teacher on ``env`` (an SB3 view of the native vector env, wrapped or not)."""
    from sensorgym.train.evaluation import env_params, simulator_state

    return OracleTeacher(OracleLookahead(simulator_state(env), env_params(env)))


@dataclass(frozen=True)
class ObservationTeacher:
    """SB3's ``predict`` of a rule that reads the env's own observation, for a wrapped env whose
    observation starts with it (wrappers such as ``time-feature`` append entries after it)."""

    rule: MemorylessRule
    """The rule, acting on the first ``rule.obs_dim`` entries of each observation."""

    def predict(
        self,
        observation: NDArray[Any],
        state: Any = None,
        episode_start: NDArray[np.bool_] | None = None,
        deterministic: bool = True,
    ) -> tuple[NDArray[np.float32], None]:
        obs = np.asarray(observation)
        return self.rule.predict(obs[..., : self.rule.obs_dim], None, episode_start)


def estimate_teacher(env: VecEnv) -> ObservationTeacher:
    """The estimate-lookahead rule (:class:`EstimateLookahead`) on ``env``'s observations."""
    from sensorgym.train.evaluation import env_params

    return ObservationTeacher(EstimateLookahead(env_params(env)))
