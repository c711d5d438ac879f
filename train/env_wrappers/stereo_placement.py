"""Action re-parameterisation and imitation teacher for training on ``sensorgym/StereoPlacement-v0``.

:class:`PlanTargetAction` makes the policy's action the point the drone will be one period
ahead — as a correction to the tracker's own prediction — and drives the receivers with
:class:`~sensorgym.agents.stereo_placement.GreedyPlacement`'s one-period search towards it.
The tracker's single-period fix is noisy (median position error some 10 m, velocity error some
15 m/s, heavy tails), and the greedy rule plans on it as is; the same search on the true drone
(:class:`~sensorgym.agents.stereo_placement.TruthGreedyPlacement`) scores some 8 more per
episode. A policy that sees a stack of recent observations can learn where the drone really
is. The zero action is exactly the greedy rule; the scenarios and rewards are the env's.

:func:`truth_target` is the teacher for imitation pre-training: the action that moves the
target onto the true drone's position one period ahead (it reads the simulator; the student
sees only the observation).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray
from stable_baselines3.common.vec_env import VecEnv

from sensorgym.agents.stereo_placement import GreedyPlacement
from sensorgym.envs.stereo_placement.simulation import PlacementParams, split_observation
from sensorgym.train.wrappers import ObservedActionWrapper, find_wrapper

FloatArray = NDArray[np.float64]

#: the target correction of a unit action along world (X, Y, Z), m (the correction is
#: ``s a |a|``: fine near zero, where most corrections are, and reaching the tails)
TARGET_SCALE = (400.0, 100.0, 400.0)


def predicted_target(params: PlacementParams, obs: NDArray[Any]) -> FloatArray:
    """The tracker's prediction of the drone one period ahead, ``p̂ + τ v̂`` ``(N, 3)``, from
    base observations ``(N, obs_dim)`` — what :class:`GreedyPlacement` plans on."""
    view = split_observation(params, obs)
    return view["position"] + params.period * view["velocity"]


class PlanTargetAction(ObservedActionWrapper):
    """Action ``a ∈ [−1, 1]³``: the planning target ``q = p̂ + τ v̂ + s ⊙ a ⊙ |a|`` (``s`` =
    ``scale`` m per world axis); each receiver then takes the move of the greedy one-period
    search (:meth:`GreedyPlacement.plan`) that maximises the predicted reward at ``q``."""

    def __init__(self, venv: VecEnv, scale: tuple[float, float, float] = TARGET_SCALE):
        s = np.asarray(scale, dtype=np.float64)
        if s.shape != (3,) or not np.all(np.isfinite(s) & (s > 0.0)):
            raise ValueError(f"scale: need three positive lengths, got {scale}")
        super().__init__(venv, spaces.Box(-1.0, 1.0, (3,), np.float32))
        self.params: PlacementParams = venv.get_attr("params")[0]
        self.scale = s
        self.rule = GreedyPlacement(self.params)

    def env_action(self, actions: NDArray[Any], obs: NDArray[Any]) -> NDArray[Any]:
        a = np.asarray(actions, dtype=np.float64).reshape(self.num_envs, 3)
        if not np.all(np.isfinite(a)):
            raise ValueError("actions: contain NaN or infinite values")
        a = np.clip(a, -1.0, 1.0)
        q = predicted_target(self.params, obs) + self.scale * a * np.abs(a)
        view = split_observation(self.params, obs)
        return self.rule.plan(view["receivers"], q, np.zeros_like(q))


def plan_target(venv: VecEnv, **kwargs: Any) -> VecEnv:
    """The ``placement-target`` wrapper factory (``sensorgym.train.wrappers.WRAPPERS``)."""
    return PlanTargetAction(venv, **kwargs)


class TruthTarget:
    """The teacher of :class:`PlanTargetAction`: the action whose target is the true drone one
    period ahead, ``a |a| = (p + τ v − (p̂ + τ v̂)) / s`` (clipped to ``[−1, 1]``), the truth
    ``p``, ``v`` and the tracker's estimate read from the simulator."""

    def __init__(self, state_fn: Any, params: PlacementParams, scale: FloatArray):
        self.state_fn, self.params, self.scale = state_fn, params, scale

    def predict(
        self,
        observation: NDArray[Any],
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[NDArray[np.float32], None]:
        """SB3's ``predict``: the teacher's actions ``(N, 3)`` for the simulator's scenarios."""
        s = self.state_fn()
        tau = self.params.period
        truth = s.drone_position + tau * s.drone_velocity
        guess = s.estimate[:, :3] + tau * s.estimate[:, 3:]
        x = np.clip((truth - guess) / self.scale, -1.0, 1.0)
        return (np.sign(x) * np.sqrt(np.abs(x))).astype(np.float32), None


def truth_target(env: VecEnv) -> TruthTarget:
    """The ``placement-truth-target`` expert factory (``sensorgym.train.experts.EXPERTS``):
    :class:`TruthTarget` for the :class:`PlanTargetAction` in ``env``'s wrapper stack."""
    from sensorgym.train.evaluation import simulator_state

    inner = find_wrapper(env, PlanTargetAction)
    return TruthTarget(simulator_state(env), inner.params, inner.scale)
