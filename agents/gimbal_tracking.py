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

With several gimbals (``n_gimbals > 1``) every rule acts per gimbal on that gimbal's block of
the joint observation (:func:`gimbal_rows`): each aims at the shared track's direction, and a
gimbal whose clear sector does not hold the direction it would aim at pre-points to the
nearer edge of its sector at that elevation (:func:`pre_point`), ready to take the target over
as it crosses into the sector. With one gimbal (whose sector is the whole circle) the rules
act as they always have.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sensorgym.agents.protocol import MemorylessRule, as_batch
from sensorgym.envs.gimbal_tracking.reference import (
    body_angles,
    carrier_attitude,
    fly_target,
    nearest_in_sector,
)
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


def gimbal_rows(params: GimbalParams, obs: FloatArray) -> FloatArray:
    """The joint observations ``(n, G · A)`` as one row per gimbal ``(n G, A)`` (scenario-major):
    each row is laid out as one gimbal's observation
    (:func:`~sensorgym.envs.gimbal_tracking.simulation.observe`)."""
    return obs.reshape(obs.shape[0] * params.n_gimbals, params.agent_obs_dim)


def pre_point(params: GimbalParams, rows: FloatArray, change: FloatArray) -> FloatArray:
    """Body-frame changes ``(n G, 2)`` of the gimbals' rows ``rows (n G, A)`` with each aim's
    azimuth moved into its gimbal's clear sector (:func:`~sensorgym.envs.gimbal_tracking.
    reference.nearest_in_sector`: the nearer edge where the aim lies outside it); unchanged
    for one gimbal."""
    G = params.n_gimbals
    if G == 1:
        return change
    azimuth = rows[:, GIMBAL][:, 0] * np.pi
    aim = (azimuth + change[:, 0]).reshape(-1, G)
    out = change.copy()
    out[:, 0] = wrap_angle(nearest_in_sector(params, aim).reshape(-1) - azimuth)
    return out


def joint_action(params: GimbalParams, change: FloatArray) -> FloatArray:
    """The joint action ``(n, 2G)`` of the gimbals' body-frame changes ``(n G, 2)``
    (:func:`rate_action`)."""
    return rate_action(params, change).reshape(-1, 2 * params.n_gimbals)


def rate_action(params: GimbalParams, change: FloatArray) -> FloatArray:
    """Actions ``(n, 2)`` for body-frame angle changes ``(n, 2)`` (rad) within one frame:
    ``ω = Δ/T`` as a fraction of ``max_rate``, clipped to ``[−1, 1]``."""
    return np.clip(change / (params.frame_period * params.max_rate), -1.0, 1.0)


def detected(params: GimbalParams, obs: FloatArray) -> NDArray[np.bool_]:
    """Whether the track measured the target this frame, ``(n,)``, from observations or from
    one gimbal's rows."""
    return obs[:, 19 + params.n_channels] > 0.5


def frames_since_detection(params: GimbalParams, obs: FloatArray) -> NDArray[np.int64]:
    """Frames since the track last measured the target, ``(n,)``, from observations or from
    one gimbal's rows (the env observes them divided by ``reacquire_limit + 1``)."""
    return np.rint(obs[:, 20 + params.n_channels] * (params.reacquire_limit + 1)).astype(np.int64)


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
        return np.zeros((obs.shape[0], 2 * self.params.n_gimbals))


@dataclass(frozen=True)
class Paper001Servo(MemorylessRule):
    """Drive to paper 001's predicted direction for the next frame (theory §8.6), whether the
    target is seen or the predictor coasts through a loss; the carrier's motion is corrected a
    frame late, as an error. Several gimbals: each pre-points outside its sector."""

    params: GimbalParams

    def act(self, obs: FloatArray) -> FloatArray:
        rows = gimbal_rows(self.params, obs)
        change = rows[:, PREDICTED_OFFSET] * self.params.half_field
        return joint_action(self.params, pre_point(self.params, rows, change))


@dataclass(frozen=True)
class HoldLastRate(MemorylessRule):
    """While the target is detected, :class:`Paper001Servo`; through a loss, keep the drives'
    last rates (a servo without a predictor)."""

    params: GimbalParams

    def act(self, obs: FloatArray) -> FloatArray:
        rows = gimbal_rows(self.params, obs)
        change = pre_point(self.params, rows, rows[:, PREDICTED_OFFSET] * self.params.half_field)
        servo = rate_action(self.params, change)
        action = np.where(detected(self.params, rows)[:, None], servo, rows[:, RATES])
        return action.reshape(obs.shape[0], -1)


@dataclass(frozen=True)
class CarrierFeedForward(MemorylessRule):
    """Drive to paper 001's predicted direction in the body frame the carrier will have next
    frame, its attitude extrapolated by the observed attitude rates: the servo with the
    carrier's motion fed forward."""

    params: GimbalParams

    def change(self, obs: FloatArray) -> FloatArray:
        """The body-frame angle change ``(n G, 2)`` (rad) each gimbal drives within the next
        frame (pre-pointed outside its sector)."""
        T = self.params.frame_period
        rows = gimbal_rows(self.params, obs)
        # attitude_{k+1} ≈ attitude_k + ȧ_k T
        ahead = (rows[:, ATTITUDE] + rows[:, ATTITUDE_RATES] * T) * ATTITUDE_SCALE
        level = rows[:, PREDICTED_LEVEL] * ANGLE_SCALE
        return pre_point(self.params, rows, aim_change(rows, level, ahead))

    def act(self, obs: FloatArray) -> FloatArray:
        return joint_action(self.params, self.change(obs))


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
        # every gimbal aims at the filter's direction (the track's: one filter per scenario)
        rows = gimbal_rows(self.params, obs)
        G = self.params.n_gimbals
        attitude = rows[:, ATTITUDE] * ATTITUDE_SCALE
        change = pre_point(self.params, rows, aim_change(rows, np.repeat(aim, G, 0), attitude))
        action = joint_action(self.params, change).astype(np.float32)
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
        """The body-frame angle change ``(n G, 2)`` (rad) of each gimbal onto the true direction
        next frame (outside its clear sector: onto the nearer edge at that elevation)."""
        s: GimbalState = self.state_fn()
        p = self.params
        frame = s.frame + 1
        turning = (frame > s.turn_start) & (frame <= s.turn_end)
        position, _ = fly_target(p, s.target_position, s.target_velocity, s.turn_rate, turning)
        attitude, _ = carrier_attitude(p, s.carrier_phase, frame)
        los = position / np.linalg.norm(position, axis=-1, keepdims=True)
        aim = np.repeat(body_angles(los, attitude)[:, None, :], p.n_gimbals, 1)
        if p.n_gimbals > 1:
            aim[..., 0] = nearest_in_sector(p, aim[..., 0])
        change = aim - s.gimbal_angles
        change[..., 0] = wrap_angle(change[..., 0])
        return change.reshape(-1, 2)

    def act(self, obs: FloatArray) -> FloatArray:
        return joint_action(self.params, self.change(obs))
