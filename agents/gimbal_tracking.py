"""Rules for ``sensorgym/GimbalTracking-v0``: drive a two-axis gimbal to keep the target in view.

Every rule turns the body-frame angle change ``Δ`` it wants within one frame into the deadbeat
rate command ``ω = Δ/T`` (``T`` the frame period; the drive lands on the angle when its rate and
acceleration limits allow), as a fraction of ``max_rate`` (:func:`rate_action`). They differ in
where they aim:

* :class:`HoldStill` — nowhere (the passive rule: the carrier's motion alone moves the axis);
* :class:`Paper001Servo` — at paper 001's predicted direction for the next frame, which the
  env's predictor carries through a loss (theory §8.6 step 7);
* :class:`HoldLastRate` — the same while the target is detected; through a loss the drives keep
  their last rates (no predictor);
* :class:`KalmanServo` — at the next-frame direction of its own constant-velocity Kalman filter
  on the tracker's detected directions (:class:`~sensorgym.trackers.angles.baselines.
  AngleKalmanPredictor`, theory §8.9);
* :class:`CarrierFeedForward` — at paper 001's predicted direction as the carrier will be
  turned by then (its attitude extrapolated with the attitude rates: the feed-forward of the
  carrier's motion);
* :class:`TruthServo` (truth-informed) — at the target's true direction next frame, from the
  true attitude then.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sensorgym.agents.protocol import MemorylessRule, as_batch
from sensorgym.envs.gimbal_tracking.reference import body_angles, carrier_attitude, fly_target
from sensorgym.envs.gimbal_tracking.simulation import ATTITUDE_SCALE, GimbalParams, GimbalState
from sensorgym.trackers.angles.baselines import AngleKalmanPredictor, KalmanAngleState
from sensorgym.trackers.geometry import unit_from_zup_angles, wrap_angle
from sensorgym.trackers.validation import check_fields

FloatArray = NDArray[np.float64]

#: slices of the observation (:func:`sensorgym.envs.gimbal_tracking.simulation.observe`)
GIMBAL, RATES, ATTITUDE, ATTITUDE_RATES = slice(0, 2), slice(2, 4), slice(4, 7), slice(7, 10)
ESTIMATE_OFFSET, PREDICTED_OFFSET = slice(10, 12), slice(12, 14)
ESTIMATE_LEVEL, PREDICTED_LEVEL = slice(14, 16), slice(16, 18)
#: the observation's level and gimbal angles are divided by these (azimuth, elevation), rad
ANGLE_SCALE = np.array([np.pi, np.pi / 2])


def rate_action(params: GimbalParams, change: FloatArray) -> FloatArray:
    """Actions ``(n, 2)`` for body-frame angle changes ``(n, 2)`` (rad) within one frame:
    ``ω = Δ/T`` as a fraction of ``max_rate``, clipped to ``[−1, 1]``."""
    return np.clip(change / (params.frame_period * params.max_rate), -1.0, 1.0)


def detected(params: GimbalParams, obs: FloatArray) -> NDArray[np.bool_]:
    """Whether the tracker detected the target this frame, ``(n,)``."""
    return obs[:, 19 + params.n_channels] > 0.5


def aim_change(obs: FloatArray, level: FloatArray, attitude: FloatArray) -> FloatArray:
    """Body-frame angle change ``(n, 2)`` that points the gimbal at level angles ``level (n, 2)``
    seen from a carrier at ``attitude (n, 3)`` (azimuth wrapped)."""
    target = body_angles(unit_from_zup_angles(level[:, 0], level[:, 1]), attitude)
    change = target - obs[:, GIMBAL] * ANGLE_SCALE
    change[:, 0] = wrap_angle(change[:, 0])
    return change


@dataclass(frozen=True)
class HoldStill(MemorylessRule):
    """Command zero rates: the gimbal stays fixed to the carrier (the passive rule)."""

    params: GimbalParams

    def act(self, obs: FloatArray) -> FloatArray:
        return np.zeros((obs.shape[0], 2))


@dataclass(frozen=True)
class Paper001Servo(MemorylessRule):
    """Drive to paper 001's predicted direction for the next frame (theory §8.6), whether the
    target is seen or the predictor coasts through a loss; the carrier's motion is corrected a
    frame late, as an error."""

    params: GimbalParams

    def act(self, obs: FloatArray) -> FloatArray:
        return rate_action(self.params, obs[:, PREDICTED_OFFSET] * self.params.half_field)


@dataclass(frozen=True)
class HoldLastRate(MemorylessRule):
    """While the target is detected, :class:`Paper001Servo`; through a loss, keep the drives'
    last rates (a servo without a predictor)."""

    params: GimbalParams

    def act(self, obs: FloatArray) -> FloatArray:
        servo = rate_action(self.params, obs[:, PREDICTED_OFFSET] * self.params.half_field)
        return np.where(detected(self.params, obs)[:, None], servo, obs[:, RATES])


@dataclass(frozen=True)
class CarrierFeedForward(MemorylessRule):
    """Drive to paper 001's predicted direction in the body frame the carrier will have next
    frame, its attitude extrapolated by the observed attitude rates: the servo with the
    carrier's motion fed forward."""

    params: GimbalParams

    def change(self, obs: FloatArray) -> FloatArray:
        """The body-frame angle change ``(n, 2)`` (rad) it drives within the next frame."""
        T = self.params.frame_period
        # attitude_{k+1} ≈ attitude_k + ȧ_k T
        ahead = (obs[:, ATTITUDE] + obs[:, ATTITUDE_RATES] * T) * ATTITUDE_SCALE
        level = obs[:, PREDICTED_LEVEL] * ANGLE_SCALE
        return aim_change(obs, level, ahead)

    def act(self, obs: FloatArray) -> FloatArray:
        return rate_action(self.params, self.change(obs))


@dataclass(frozen=True)
class KalmanServo:
    """Drive to the next-frame direction of a constant-velocity Kalman filter on the tracker's
    detected level directions (theory §8.9), coasting on its rates through a loss; its first
    rate is the tracker's (prediction − estimate).

    ``predict``'s ``state`` is the filter's :class:`~sensorgym.trackers.angles.baselines.
    KalmanAngleState` of the batch (``None`` at the start; rows restart at ``episode_start``).
    """

    params: GimbalParams
    measurement_std: float = 1e-4
    """σ of a fused direction's angles, rad."""
    accel_psd: float = 1e-9
    """Spectral density of the target's angular acceleration, rad²/frame³."""

    def __post_init__(self) -> None:
        check_fields(self)
        for name in ("measurement_std", "accel_psd"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0.0):
                raise ValueError(f"{name}: must be positive and finite, got {value!r}")

    @property
    def filter(self) -> AngleKalmanPredictor:
        """The Kalman predictor with these settings (per-frame units)."""
        return AngleKalmanPredictor(measurement_std=self.measurement_std, accel_psd=self.accel_psd)

    def predict(
        self,
        observation: NDArray[Any],
        state: KalmanAngleState | None = None,
        episode_start: NDArray[np.bool_] | None = None,
        deterministic: bool = True,
    ) -> tuple[NDArray[np.float32], KalmanAngleState]:
        obs, single = as_batch(observation, self.params.obs_dim)
        kf, n = self.filter, obs.shape[0]
        fresh = kf.initial_state(n)
        if state is None or state.count.shape[0] != n:
            state = fresh
        elif episode_start is not None:
            restart = np.asarray(episode_start, dtype=bool).reshape(n)
            state = KalmanAngleState(
                np.where(restart[:, None, None], fresh.mean, state.mean),
                np.where(restart[:, None, None, None], fresh.covariance, state.covariance),
                np.where(restart, 0, state.count),
            )
        seen = detected(self.params, obs)
        level = obs[:, ESTIMATE_LEVEL] * ANGLE_SCALE
        first = seen & (state.count == 0)
        state = kf.update(state, level[:, 0], level[:, 1], seen)
        # the first rate: the tracker's own one-frame step, (prediction − estimate) per frame
        step = obs[:, PREDICTED_LEVEL] * ANGLE_SCALE - level
        step[:, 0] = wrap_angle(step[:, 0])
        mean = state.mean.copy()
        mean[:, :, 1] = np.where(first[:, None], step, mean[:, :, 1])
        state = KalmanAngleState(mean, state.covariance, state.count)
        az, el = kf.predict(state, 1.0)
        aim = np.where((state.count > 0)[:, None], np.stack([az, el], -1), level)
        attitude = obs[:, ATTITUDE] * ATTITUDE_SCALE
        action = rate_action(self.params, aim_change(obs, aim, attitude)).astype(np.float32)
        return (action[0] if single else action), state


@dataclass(frozen=True)
class TruthServo(MemorylessRule):
    """Truth-informed: drive to the target's true direction next frame, seen from the carrier's
    true attitude then (reads the simulator's state; neither fieldable nor a bound)."""

    params: GimbalParams
    state_fn: Any = None
    """Returns the simulator's current :class:`~sensorgym.envs.gimbal_tracking.simulation.
    GimbalState`, as many scenarios as observations."""

    def change(self, obs: FloatArray) -> FloatArray:
        """The body-frame angle change ``(n, 2)`` (rad) onto the true direction next frame."""
        s: GimbalState = self.state_fn()
        p = self.params
        frame = s.frame + 1
        turning = (frame > s.turn_start) & (frame <= s.turn_end)
        position, _ = fly_target(p, s.target_position, s.target_velocity, s.turn_rate, turning)
        attitude, _ = carrier_attitude(p, s.carrier_phase, frame)
        los = position / np.linalg.norm(position, axis=-1, keepdims=True)
        change = body_angles(los, attitude) - s.gimbal_angles
        change[:, 0] = wrap_angle(change[:, 0])
        return change

    def act(self, obs: FloatArray) -> FloatArray:
        return rate_action(self.params, self.change(obs))
