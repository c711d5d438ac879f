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
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper

from sensorgym.agents.gimbal_search import FeedForwardSearch
from sensorgym.agents.gimbal_tracking import (
    ANGLE_SCALE,
    ESTIMATE_LEVEL,
    CarrierFeedForward,
    TruthServo,
    detected,
    rate_action,
)
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
        params: GimbalParams = venv.get_attr("params")[0]
        if params.n_gimbals != 1:
            raise ValueError(f"n_gimbals: the aim offset drives one gimbal, got {params.n_gimbals}")
        super().__init__(venv, spaces.Box(-1.0, 1.0, (2,), np.float32))
        self.params = params
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

    def __init__(self, state_fn: Any, wrapper: AimOffsetAction, centre: bool = False):
        self.wrapper = wrapper
        self.truth = TruthServo(wrapper.params, state_fn)
        self.centre = centre
        """Teach the offset from the carrier-feedforward servo's aim, not the base rule's: over
        a ``feedforward-search`` base, where the search pattern should be centred."""
        self.servo = CarrierFeedForward(wrapper.params)

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
        reference = self.servo if self.centre else self.wrapper.rule
        offset = self.truth.change(obs) - reference.change(obs)
        x = np.clip(offset / self.wrapper.scale, -1.0, 1.0)
        return (np.sign(x) * np.sqrt(np.abs(x))).astype(np.float32), None


def truth_aim(env: VecEnv) -> TruthAim:
    """The ``gimbal-truth-aim`` expert factory (``sensorgym.train.experts.EXPERTS``):
    :class:`TruthAim` for the :class:`AimOffsetAction` in ``env``'s wrapper stack."""
    from sensorgym.train.evaluation import simulator_state

    inner = find_wrapper(env, AimOffsetAction)
    return TruthAim(simulator_state(env), inner)


def truth_centre(env: VecEnv) -> TruthAim:
    """The ``gimbal-truth-centre`` expert factory: :class:`TruthAim` teaching the offset of the
    true direction from the carrier-feedforward servo's aim, so that over a
    ``feedforward-search`` base the student learns where to centre the search (the pattern's
    own hops are added by the wrapper)."""
    from sensorgym.train.evaluation import simulator_state

    inner = find_wrapper(env, AimOffsetAction)
    return TruthAim(simulator_state(env), inner, centre=True)


class TurnMemory(VecEnvWrapper):
    """Appends what the tracker's estimate did before the target was last lost: a quadratic fit
    ``θ(t) ≈ θ₀ + θ̇ t + ½ θ̈ t²`` (level azimuth and elevation, ``t`` in frames from the last
    detection) to the estimates of the last ``window`` frames with a detection, and the offset
    ``½ θ̈ (s + 1)²`` its curvature adds to the straight path ``s`` frames after the last
    detection. A turn begun before an occlusion bends the path the search should follow; the
    env's observation (and a short frame stack) no longer shows it once the target has been
    lost for a while.

    Six features in fields of view, clipped to ``[−10, 10]``: ``θ̇ W`` (2) and ``½ θ̈ W²`` (2),
    the motion and the bend over a window of ``W`` frames, and the offset (2). Zero until ``window/2``
    detected frames of the episode exist; a slot's memory restarts with its episode."""

    def __init__(self, venv: VecEnv, window: int = 40):
        if isinstance(window, bool) or not isinstance(window, int) or window < 6:
            raise ValueError(f"window: need an integer >= 6, got {window!r}")
        box = venv.observation_space
        if not isinstance(box, spaces.Box) or len(box.shape) != 1:
            raise ValueError(f"gimbal-turn-memory: needs a flat Box observation, got {box}")
        self.params: GimbalParams = venv.get_attr("params")[0]
        if self.params.n_gimbals != 1:
            raise ValueError(
                f"n_gimbals: the turn memory reads one gimbal, got {self.params.n_gimbals}"
            )
        self.window = window
        low = np.append(box.low, np.full(6, -10.0, np.float32)).astype(box.dtype)
        high = np.append(box.high, np.full(6, 10.0, np.float32)).astype(box.dtype)
        super().__init__(venv, observation_space=spaces.Box(low, high, dtype=box.dtype))
        n = venv.num_envs
        self._angles = np.zeros((n, window, 2))  # detected level angles, oldest first
        self._frames = np.zeros((n, window))  # their frame numbers in the episode
        self._count = np.zeros(n, dtype=np.int64)  # detected frames held (≤ window)
        self._frame = np.zeros(n, dtype=np.int64)  # frames into the episode

    def _record(self, obs: NDArray[Any]) -> None:
        """Push the detected slots' level estimates (oldest first: every held row shifts one
        place towards the start)."""
        seen = detected(self.params, np.asarray(obs, dtype=np.float64))
        if not seen.any():
            return
        level = np.asarray(obs, dtype=np.float64)[seen][:, ESTIMATE_LEVEL] * ANGLE_SCALE
        self._angles[seen] = np.roll(self._angles[seen], -1, axis=1)
        self._frames[seen] = np.roll(self._frames[seen], -1, axis=1)
        self._angles[seen, -1] = level
        self._frames[seen, -1] = self._frame[seen]
        self._count[seen] = np.minimum(self._count[seen] + 1, self.window)

    def features(self) -> NDArray[np.float64]:
        """The six features ``(n, 6)`` of every slot: the least-squares fits of all slots at once
        through their 3 × 3 normal equations, in ``τ = t / W`` (well conditioned), over each
        slot's held rows."""
        n, W = self.num_envs, self.window
        out = np.zeros((n, 6))
        fit = np.flatnonzero(self._count >= W // 2)
        if fit.size == 0:
            return out
        fov = self.params.field_of_view
        count = self._count[fit]
        held = np.arange(W)[None, :] >= (W - count)[:, None]  # the last `count` rows
        y = self._angles[fit].copy()
        # unwrap the azimuth from the first held row on (rows before it are stale)
        first = W - count
        az = np.where(held, y[..., 0], y[np.arange(fit.size), first, 0][:, None])
        y[..., 0] = np.unwrap(az, axis=1)
        tau = (self._frames[fit] - self._frames[fit, -1:]) / W  # ≤ 0, the last detection at 0
        basis = np.stack([np.ones_like(tau), tau, tau * tau], -1) * held[..., None]
        # least squares y = d₀ + d₁ τ + d₂ τ²  ⇔  (BᵀB) d = Bᵀy; then θ̇ = d₁ / W, θ̈ = 2 d₂ / W²
        d = np.linalg.solve(basis.transpose(0, 2, 1) @ basis, basis.transpose(0, 2, 1) @ y)
        since = (self._frame[fit] - self._frames[fit, -1])[:, None]
        out[fit, 0:2] = d[:, 1] / fov  # θ̇ W: the motion over a window
        out[fit, 2:4] = d[:, 2] / fov  # ½ θ̈ W²: the bend over a window
        out[fit, 4:6] = d[:, 2] * ((since + 1.0) / W) ** 2 / fov
        return np.clip(out, -10.0, 10.0)

    def _with_features(self, obs: NDArray[Any]) -> NDArray[Any]:
        return np.concatenate([obs, self.features().astype(obs.dtype)], axis=1)

    def reset(self) -> NDArray[Any]:
        obs = self.venv.reset()
        self._count[:] = 0
        self._frame[:] = 0
        self._record(obs)
        return self._with_features(obs)

    def step_wait(self) -> Any:
        obs, rewards, dones, infos = self.venv.step_wait()
        self._frame += 1
        if np.any(dones):  # the terminal observations keep the ended episodes' memory
            ended = self.features()
            for i in np.flatnonzero(dones):
                terminal = infos[i].get("terminal_observation")
                if terminal is not None:
                    infos[i]["terminal_observation"] = np.append(
                        terminal, ended[i].astype(terminal.dtype)
                    )
        self._frame[dones] = 0
        self._count[dones] = 0
        self._record(obs)
        return self._with_features(obs), rewards, dones, infos


def turn_memory(venv: VecEnv, **kwargs: Any) -> VecEnv:
    """The ``gimbal-turn-memory`` wrapper factory (``sensorgym.train.wrappers.WRAPPERS``)."""
    return TurnMemory(venv, **kwargs)
