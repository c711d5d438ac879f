"""Action re-parameterisation and imitation teacher for training on ``sensorgym/GimbalTracking-v0``.

:class:`AimOffsetAction` makes the policy's action an offset of the gimbal's aim from the
direction a fieldable servo drives to: :class:`~sensorgym.agents.gimbal_tracking.CarrierFeedForward`
(paper 001's predicted direction, the carrier's motion fed forward) or
:class:`~sensorgym.agents.gimbal_search.FeedForwardSearch` (the same, searching about the
prediction once the gate searches). The zero action is exactly that rule. Where the rule fails — the predictor coasts straight through an
occlusion while the target turns, and the servo keeps pointing where a straight path would
be — a policy that sees a stack of recent observations can aim elsewhere: ahead into the turn
it saw begin, or around the prediction to find the target again. The scenarios and rewards are
the env's.

:func:`truth_aim` is the teacher for imitation pre-training: the offset that moves the aim
onto the target's true direction next frame (it reads the simulator; the student sees only
its observations).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray
from stable_baselines3.common.vec_env import VecEnv

from sensorgym.agents.gimbal_search import FeedForwardSearch
from sensorgym.agents.gimbal_tracking import CarrierFeedForward, TruthServo, rate_action
from sensorgym.envs.gimbal_tracking.simulation import GimbalParams
from sensorgym.train.wrappers import ObservedActionWrapper, find_wrapper

FloatArray = NDArray[np.float64]

#: the aim offset of a unit action, in fields of view (the offset is ``s a |a|``: fine near the
#: prediction, where most corrections are, and reaching two fields out for a search)
AIM_SCALE = 2.0


#: the fieldable servos an aim offset can be taken from (``base``), by their rule names
BASE_RULES = {"carrier-feedforward": CarrierFeedForward, "feedforward-search": FeedForwardSearch}


class AimOffsetAction(ObservedActionWrapper):
    """Action ``a ∈ [−1, 1]²``: aim the boresight at the ``base`` servo's next-frame direction
    (carrier-feedforward, or the same with its re-acquisition search) offset by
    ``δ = s · FOV · a ⊙ |a|`` in body azimuth and elevation (rad), with the servo's deadbeat
    rate command (``s = scale`` fields of view)."""

    def __init__(self, venv: VecEnv, scale: float = AIM_SCALE, base: str = "carrier-feedforward"):
        if not (np.isfinite(scale) and scale > 0.0):
            raise ValueError(f"scale: need a positive number of fields of view, got {scale!r}")
        if base not in BASE_RULES:
            raise ValueError(f"base: expected one of {sorted(BASE_RULES)}, got {base!r}")
        super().__init__(venv, spaces.Box(-1.0, 1.0, (2,), np.float32))
        self.params: GimbalParams = venv.get_attr("params")[0]
        self.scale = float(scale) * self.params.field_of_view
        """Aim offset of a unit action, rad."""
        self.rule: CarrierFeedForward | FeedForwardSearch = BASE_RULES[base](self.params)

    def env_action(self, actions: NDArray[Any], obs: NDArray[Any]) -> NDArray[Any]:
        a = np.asarray(actions, dtype=np.float64).reshape(self.num_envs, 2)
        if not np.all(np.isfinite(a)):
            raise ValueError("actions: contain NaN or infinite values")
        a = np.clip(a, -1.0, 1.0)
        view = np.asarray(obs, dtype=np.float64)
        return rate_action(self.params, self.rule.change(view) + self.scale * a * np.abs(a))


def aim_offset(venv: VecEnv, **kwargs: Any) -> VecEnv:
    """The ``gimbal-aim`` wrapper factory (``sensorgym.train.wrappers.WRAPPERS``)."""
    return AimOffsetAction(venv, **kwargs)


class TruthAim:
    """The teacher of :class:`AimOffsetAction`: the action whose offset moves the servo's aim onto
    the target's true direction next frame, ``a |a| = (Δ_true − Δ_servo) / s`` (clipped to
    ``[−1, 1]``), ``Δ`` the body-frame angle changes of :class:`TruthServo` and
    :class:`CarrierFeedForward`."""

    def __init__(self, state_fn: Any, wrapper: AimOffsetAction):
        self.wrapper = wrapper
        self.truth = TruthServo(wrapper.params, state_fn)

    def predict(
        self,
        observation: NDArray[Any],
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[NDArray[np.float32], None]:
        """SB3's ``predict``: the teacher's actions ``(N, 2)`` for the simulator's scenarios
        (the observation is the student's; the teacher reads the wrapper's latest)."""
        obs = np.asarray(self.wrapper.last_obs, dtype=np.float64)
        offset = self.truth.change(obs) - self.wrapper.rule.change(obs)
        x = np.clip(offset / self.wrapper.scale, -1.0, 1.0)
        return (np.sign(x) * np.sqrt(np.abs(x))).astype(np.float32), None


def truth_aim(env: VecEnv) -> TruthAim:
    """The ``gimbal-truth-aim`` expert factory (``sensorgym.train.experts.EXPERTS``):
    :class:`TruthAim` for the :class:`AimOffsetAction` in ``env``'s wrapper stack."""
    from sensorgym.train.evaluation import simulator_state

    inner = find_wrapper(env, AimOffsetAction)
    return TruthAim(simulator_state(env), inner)
