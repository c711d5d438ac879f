"""Action re-parameterisations of ``sensorgym/StereoPointing-v0`` for training, as SB3 wrappers.

:class:`AssignmentAction` replaces the gimbal-rate action by an *assignment*: for each receiver,
which drone's track it watches. The env's own slew controller
(:func:`~sensorgym.envs.stereo_pointing.simulation.slew_actions`, the one the assignment rules
use) turns it into gimbal rates that slew each receiver onto the tracker's predicted position of
its drone. The scenarios and rewards are the base env's, so the episode return stays the env's
accuracy measure and a policy acting through the wrapper is scored beside the rules on the same
seed. ``sensorgym.train.wrappers.WRAPPERS["pointing-assignment"]`` builds it from a
hyperparameter set's ``wrappers:`` list.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper

from sensorgym.envs.stereo_pointing.simulation import PointingParams, assignment_actions
from sensorgym.train.wrappers import ObservedActionWrapper


class AssignmentAction(ObservedActionWrapper):
    """``MultiDiscrete([m] * n)`` actions over an SB3 vector env of StereoPointing: action
    ``i`` is the drone receiver ``i`` watches; the wrapper slews it onto the tracker's predicted
    position of that drone (:func:`~sensorgym.envs.stereo_pointing.simulation.assignment_actions`
    of the latest observation). Observations, rewards and episodes are the base env's."""

    def __init__(self, venv: VecEnv, params: PointingParams | None = None):
        p = params if params is not None else venv.get_attr("params")[0]
        if not isinstance(p, PointingParams):
            raise TypeError(f"venv: expected a StereoPointing env, its params are {type(p)!r}")
        shape = venv.observation_space.shape
        if shape != (p.obs_dim,):
            raise ValueError(
                f"venv: expected the joint observation ({p.obs_dim},), got {shape}"
                " (the assignment action drives all receivers of a scenario at once)"
            )
        super().__init__(venv, spaces.MultiDiscrete([p.n_drones] * p.n_receivers))
        self.params = p

    def env_action(self, actions: NDArray[Any], obs: NDArray[Any]) -> NDArray[Any]:
        target = actions.reshape(self.num_envs, self.params.n_receivers)
        return assignment_actions(self.params, obs, target)


def assignment_wrapper(venv: VecEnv) -> VecEnv:
    """Factory of the ``pointing-assignment`` wrapper (``WRAPPERS`` registry)."""
    return AssignmentAction(venv)


def find_assignment(env: VecEnv) -> AssignmentAction:
    """The :class:`AssignmentAction` in an SB3 wrapper stack (outer wrappers such as frame
    stacks or a time feature may lie over it); ``ValueError`` if there is none."""
    e: Any = env
    while True:
        if isinstance(e, AssignmentAction):
            return e
        if not isinstance(e, VecEnvWrapper):
            raise ValueError("env: no pointing-assignment wrapper in the stack")
        e = e.venv


class AssignmentExpert:
    """A teacher for behaviour cloning in the assignment action's space: SB3's ``predict``,
    answering with ``choose(observation)`` of the base env's latest observation (read from the
    :class:`AssignmentAction` under any outer wrappers, so frame stacks or a time feature over
    it do not matter)."""

    def __init__(self, env: VecEnv, choose: Any):
        self.wrapper = find_assignment(env)
        self.choose = choose
        """``(N, obs_dim)`` base observations → ``(N, n)`` drone per receiver."""

    def predict(
        self,
        observation: NDArray[Any],
        state: Any = None,
        episode_start: NDArray[np.bool_] | None = None,
        deterministic: bool = True,
    ) -> tuple[NDArray[np.int64], None]:
        obs = self.wrapper.last_obs
        if obs is None or len(obs) != len(np.atleast_2d(observation)):
            raise ValueError("observation: the expert acts on the wrapped env's own batch")
        return np.asarray(self.choose(obs), dtype=np.int64), None


def _rule_expert(env: VecEnv, name: str) -> AssignmentExpert:
    from sensorgym.agents.registry import rules_for

    wrapper = find_assignment(env)
    rule = rules_for("sensorgym/StereoPointing-v0", wrapper.params, lambda: None)[name]
    return AssignmentExpert(env, rule.assign)  # type: ignore[attr-defined]


def hold_cue_expert(env: VecEnv) -> AssignmentExpert:
    """The ``hold-cue`` rule as an assignment teacher (``EXPERTS["pointing-hold-cue"]``)."""
    return _rule_expert(env, "hold-cue")


def orthogonal_pairs_expert(env: VecEnv) -> AssignmentExpert:
    """The ``orthogonal-pairs`` rule as an assignment teacher."""
    return _rule_expert(env, "orthogonal-pairs")


def plan_estimate_expert(env: VecEnv) -> AssignmentExpert:
    """The ``plan-estimate`` rule (the planner on the tracker's estimate) as a teacher."""
    return _rule_expert(env, "plan-estimate")


def greedy_expert(env: VecEnv) -> AssignmentExpert:
    """The ``greedy-information`` rule as an assignment teacher."""
    return _rule_expert(env, "greedy-information")


def oracle_plan_expert(env: VecEnv) -> AssignmentExpert:
    """The ``oracle-plan`` ceiling as an assignment teacher: it plans on the simulator's truth
    (:func:`sensorgym.train.evaluation.simulator_state`); the student only sees the
    observation."""
    from sensorgym.agents.stereo_pointing import OraclePlan
    from sensorgym.train.evaluation import simulator_state

    wrapper = find_assignment(env)
    oracle = OraclePlan(simulator_state(env), wrapper.params)
    return AssignmentExpert(env, oracle.assign)
