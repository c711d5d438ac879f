"""Simulation core of GimbalTracking: keep a narrow field of view on an air target through losses.

The simulation contract of every env (:mod:`sensorgym.envs.shells.contract`): pure functions
over frozen, batched values (leading axis ``B`` = scenario) — :func:`spaces`, :func:`reset`
(:func:`start` builds scenarios from a given target), :func:`step`, :func:`observe`,
:func:`observe_agents` and :func:`info`. One step is one video frame; its stages, in order,
are the functions of :mod:`.reference` (theory §11.8):

1. the two-axis gimbal (azimuth α, elevation β, body frame) drives under the rate command
   ``a · max_rate``, each axis's rate changing by at most ``max_acceleration · T`` per frame;
2. the air target flies on (straight relative to the carrier, a level turn in a random
   interval), the carrier rolls, pitches and yaws (sums of sinusoids with random phases);
3. occlusions (random onset and length) hide the target; each imaging channel's view of it
   follows its Markov chain (paper 004: background, bright, dark); it is imaged only inside
   the square field of view, with less contrast off axis (vignetting);
4. the tracker: paper 004's fused tracker (:class:`~sensorgym.trackers.fusion.tracker.
   FusionTracker`, one per image plane) measures the target's offset from paper 001's
   predicted direction, weighting the channels by their posterior detection probabilities
   × view transitions; where detected (MAP: an object view in some channel, in both planes)
   the fused direction — plus the angle sensors' noise — is paper 001's predictor's
   (:class:`~sensorgym.trackers.angles.prediction.ABCPredictor`) measurement, otherwise the
   predictor coasts along its conditional trajectory (theory §8.6 step 7); after
   ``search_after`` frames without detection the gate searches at the boresight;
5. the reward ``clip(ln(σ_ref/σ_LOS), −R, R)`` with ``σ_LOS`` the fused direction's angular
   error bound, ``−R`` while the target is out of the field of view; the episode terminates
   when it has been out of view for more than ``reacquire_limit`` frames.

With ``n_gimbals = G > 1`` (theory §11.8.2) stages 1, 3 and 4 run per gimbal — its drives,
its channels' views, its field of view and clear sector (:attr:`GimbalParams.sectors`), its
gate and fused tracker — and the one predictor (the track) takes the fused direction of the
detecting gimbal of least posterior variance (:func:`.reference.measuring_gimbal`), whose
``σ_LOS`` is the reward's; "in view" is in some gimbal's view. The per-gimbal state fields and
draws carry a gimbal axis after the scenario's, for one gimbal too (which draws what it always
drew).

The step is compiled (:func:`.kernels.step_kernel`, the stages of :mod:`.reference` in
numba, large batches split over threads by :func:`sensorgym.envs.shells.rows.run_rows`), and so
are the reset's lock-on of paper 001's predictor (:func:`.kernels.lock_on_kernel`),
:func:`observe` and :func:`info`; the random draws stay numpy's, drawn here in the numpy
form's order and shapes and handed in, so seeded episodes are the reference's to rounding
(``tests/envs/gimbal_tracking/test_reference.py``).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sensorgym.envs.gimbal_tracking import kernels, reference
from sensorgym.envs.shells.contract import EnvSpaces
from sensorgym.envs.shells.params_pickle import FieldsOnlyPickle
from sensorgym.envs.shells.rows import MIN_ROWS_PER_THREAD, run_rows
from sensorgym.envs.worlds.imaging import box_profile
from sensorgym.trackers.angles.prediction import ABCPredictor, ABCState
from sensorgym.trackers.fusion.tracker import FusionModel, FusionTracker
from sensorgym.trackers.geometry import zup_angles_from_unit
from sensorgym.trackers.stereo.information import MAX_REWARD_CLIP
from sensorgym.trackers.validation import check_fields, finite_array

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
IntArray = NDArray[np.int64]

#: attitude (rad) and attitude rates (rad/s) are observed divided by this
ATTITUDE_SCALE = 0.1

#: the default sectors of ``G > 1`` gimbals reach this far past the equal split on each
#: side, rad (2.5°: neighbours share 5°, about three fields of view, for the hand-over)
SECTOR_OVERLAP = float(np.deg2rad(2.5))

#: no settings take compiled paths the defaults do not: every params compiles the same step and
#: lock-on (the channels, views, pixels, carrier terms and predictor window are array lengths,
#: read inside the loops; the switches of the trackers are fixed by the env)
COMPILE_VARIANTS: tuple[dict[str, object], ...] = ()


def _deg(x: float) -> float:
    return float(np.deg2rad(x))


@dataclass(frozen=True)
class GimbalParams(FieldsOnlyPickle):
    """Gimbal, carrier, target, losses, imaging channels, tracker and reward of GimbalTracking."""

    frame_period: float = 0.04
    """``T``: one step, one video frame, s (25 frames/s)."""
    field_of_view: float = _deg(1.5)
    """Full width of the square field of view, rad."""
    max_rate: float = 1.0
    """Rate limit of each drive, rad/s: the action ``±1``."""
    max_acceleration: float = 4.0
    """Acceleration limit of each drive, rad/s²."""
    elevation_limits: tuple[float, float] = (_deg(-10.0), _deg(85.0))
    """Stops of the elevation axis (body frame), rad."""
    roll_amplitude: tuple[float, ...] = (_deg(5.0), _deg(1.5))
    """Amplitudes of the carrier's roll sinusoids, rad (one per term; empty: no roll)."""
    roll_period: tuple[float, ...] = (8.0, 5.0)
    """Periods of the roll sinusoids, s (one per amplitude)."""
    pitch_amplitude: tuple[float, ...] = (_deg(2.0), _deg(0.7))
    """Amplitudes of the carrier's pitch sinusoids, rad."""
    pitch_period: tuple[float, ...] = (6.0, 4.0)
    """Periods of the pitch sinusoids, s."""
    yaw_amplitude: tuple[float, ...] = (_deg(1.0), _deg(0.3))
    """Amplitudes of the carrier's yaw sinusoids (about its mean heading), rad."""
    yaw_period: tuple[float, ...] = (10.0, 6.0)
    """Periods of the yaw sinusoids, s."""
    start_range: tuple[float, float] = (4000.0, 8000.0)
    """Target range at frame 0, drawn uniformly, m."""
    start_azimuth: tuple[float, float] = (-np.pi, np.pi)
    """Target azimuth at frame 0 (level frame, from the carrier's mean heading), uniform, rad."""
    start_elevation: tuple[float, float] = (_deg(2.0), _deg(15.0))
    """Target elevation at frame 0, uniform, rad."""
    target_speed: tuple[float, float] = (100.0, 250.0)
    """Target speed relative to the carrier, uniform, m/s."""
    target_aspect: tuple[float, float] = (_deg(30.0), _deg(150.0))
    """Angle between the target's horizontal velocity and the horizontal line of sight from the
    carrier, uniform, on a random side, rad (0: flying away, π: approaching). Near-radial paths
    make paper 001's elevation predictor ill-conditioned (theory §13.20), hence the default."""
    target_climb: tuple[float, float] = (_deg(-10.0), _deg(10.0))
    """Climb angle of the target's path, uniform, rad."""
    turn_rate: tuple[float, float] = (0.0, 0.15)
    """Magnitude of the target's level turn rate (uniform, random sign), rad/s; (0, 0): none."""
    turn_start: tuple[int, int] = (0, 400)
    """Frame after which the turn begins, uniform (inclusive), frames."""
    turn_length: tuple[int, int] = (50, 150)
    """Length of the turn, uniform (inclusive), frames."""
    occlusion_gap: tuple[int, int] = (50, 200)
    """Frames from the previous occlusion's end (frame 0 for the first) to the next onset,
    uniform (inclusive), frames."""
    occlusion_length: tuple[int, int] = (10, 60)
    """Length of an occlusion, uniform (inclusive), frames; (0, 0): no occlusions."""
    cue_error: float = 0.002
    """Standard deviation of the gimbal's pointing error at frame 0, per axis, rad."""
    channel_contrast: tuple[float, ...] = (5.0, 3.0)
    """Contrast of the target in each imaging channel (e.g. visible, infrared), in pixel-noise
    units of 1: its bright view has ``+c``, its dark view ``−c``."""
    channel_noise: tuple[float, ...] = (1.0, 1.0)
    """Pixel noise σ_n of each channel (same unit as the contrast)."""
    lose_probability: tuple[float, ...] = (0.02, 0.05)
    """Per channel, probability per frame that the target's view turns to background."""
    return_probability: tuple[float, ...] = (0.3, 0.2)
    """Per channel, probability per frame that a background view turns to an object view."""
    aspect_change_probability: tuple[float, ...] = (0.05, 0.02)
    """Per channel, probability per frame of a change between the bright and dark views."""
    target_size: float = 0.002
    """Angular size of the target in each image plane, rad."""
    blur: float = 0.0005
    """Standard deviation of the optics' Gaussian blur, rad."""
    pixel_pitch: float = 0.00025
    """Angular size of one pixel, rad."""
    gate_pixels: int = 32
    """Pixels across the tracking gate in each plane (the gate spans ``gate_pixels · pitch``)."""
    vignetting: float = 0.8
    """Contrast lost at the edge of the field of view: factor ``1 − v (ρ/h)²``, in [0, 1]."""
    residual_std: float = 0.002
    """σ_λ: prior standard deviation of the target's offset from the predicted direction,
    rad (paper 004's σ_λ; the fused variance grows back towards it through a loss)."""
    residual_correlation: float = 0.99
    """R_λ: frame-to-frame correlation of that offset (paper 004's R_λ), in [0, 1)."""
    sensor_noise: float = _deg(0.001)
    """Angle-sensor noise of each measured angle, rad (paper 001's σ = 0.001°)."""
    predictor_window: int = 50
    """Paper 001's N: frames between the samples A and C (even)."""
    predictor_memory: float = 10.0
    """Effective memory of paper 001's exponential filter, frames."""
    relock: bool = True
    """Re-lock paper 001's predictor on the first detection after a loss: its coasted window
    moved onto the new measurement (:meth:`~sensorgym.trackers.angles.prediction.ABCPredictor.
    relock`, theory §13.42; not in the paper). False: the literal predictor, whose window
    mixes coasted and measured samples after a loss and can diverge."""
    sigma_ref: float = 0.001
    """Angular error that earns zero reward, rad."""
    reward_clip: float = 5.0
    """``R``: the reward is clipped to ``[−R, R]``; ``−R`` while the target is out of view."""
    search_after: int = 25
    """Frames without detection after which the tracking gate leaves the coasting prediction
    for the boresight (search: re-acquisition where the gimbal points), frames."""
    reacquire_limit: int = 50
    """The episode terminates once the target has been out of view for more frames than this
    (out of view of every gimbal)."""
    n_gimbals: int = 1
    """Gimbals on the carrier, ``G``, sharing one target and one track (issue 40: a hand-over
    problem): each has its own drives, channels and paper 004 fused tracker, and is one
    PettingZoo agent (``gimbal_0`` …); they sit at the carrier's one point (their parallax at
    the target's kilometres is negligible)."""
    gimbal_sectors: tuple[tuple[float, float], ...] = ()
    """Per gimbal, the body-frame azimuth interval ``(low, high)``, rad, in which it has a clear
    view (``−π ≤ low < high ≤ low + 2π``, counter-clockwise from ``low`` to ``high`` as azimuth
    grows); outside it the carrier's superstructure blocks its line of sight: the target is
    not visible to that gimbal (an occlusion for it alone; the gimbal may still slew there).
    Empty: one gimbal sees the whole
    circle; ``G > 1`` gimbals get ``G`` equal sectors centred on ``2πk/G`` (gimbal 0 dead
    ahead), each widened by :data:`SECTOR_OVERLAP` on either side so that neighbours overlap
    and the target can be handed over (:attr:`sectors`)."""

    def __post_init__(self) -> None:
        check_fields(self)  # every field of its annotated type: no bool for a count or a number
        positive = (
            "frame_period", "field_of_view", "max_rate", "max_acceleration", "target_size",
            "blur", "pixel_pitch", "residual_std", "sigma_ref", "reward_clip",
        )  # fmt: skip
        for name in positive:
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0.0):
                raise ValueError(f"{name}: must be positive and finite, got {value!r}")
        for name in ("cue_error", "sensor_noise"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0.0):
                raise ValueError(f"{name}: must be finite and >= 0, got {value!r}")
        if not self.field_of_view < np.pi / 2:
            raise ValueError(f"field_of_view: must be below π/2 rad, got {self.field_of_view!r}")
        lo, hi = self.elevation_limits
        if not -np.pi / 2 < lo < hi < np.pi / 2:
            raise ValueError(f"elevation_limits: need −π/2 < low < high < π/2, got {(lo, hi)}")
        for axis in ("roll", "pitch", "yaw"):
            amp, per = getattr(self, f"{axis}_amplitude"), getattr(self, f"{axis}_period")
            if len(amp) != len(per):
                raise ValueError(f"{axis}_period: one period per amplitude, got {per!r}")
            if not all(np.isfinite(a) and 0.0 <= a < 1.0 for a in amp):
                raise ValueError(f"{axis}_amplitude: need values in [0, 1) rad, got {amp!r}")
            if not all(np.isfinite(p) and p > 0.0 for p in per):
                raise ValueError(f"{axis}_period: need positive values, got {per!r}")
        for name in ("start_range", "target_speed"):
            lo, hi = getattr(self, name)
            if not (np.isfinite(lo) and np.isfinite(hi) and 0.0 < lo <= hi):
                raise ValueError(f"{name}: need finite 0 < low <= high, got {(lo, hi)}")
        for name in ("start_azimuth", "target_aspect", "target_climb", "start_elevation"):
            lo, hi = getattr(self, name)
            if not (np.isfinite(lo) and np.isfinite(hi) and lo <= hi):
                raise ValueError(f"{name}: need finite low <= high, got {(lo, hi)}")
        for name in ("target_climb", "start_elevation"):
            lo, hi = getattr(self, name)
            if not -np.pi / 2 < lo <= hi < np.pi / 2:
                raise ValueError(f"{name}: must lie within (−π/2, π/2), got {(lo, hi)}")
        lo, hi = self.turn_rate
        if not (np.isfinite(hi) and 0.0 <= lo <= hi):
            raise ValueError(f"turn_rate: need finite 0 <= low <= high, got {(lo, hi)}")
        for name in ("turn_start", "turn_length", "occlusion_gap", "occlusion_length"):
            lo, hi = getattr(self, name)
            if not 0 <= lo <= hi:
                raise ValueError(f"{name}: need 0 <= low <= high, got {(lo, hi)}")
        if self.occlusion_gap[0] < 1:
            raise ValueError(f"occlusion_gap: need at least 1 frame, got {self.occlusion_gap}")
        n = len(self.channel_contrast)
        per_channel = (
            "channel_noise", "lose_probability", "return_probability", "aspect_change_probability",
        )  # fmt: skip
        if n < 1:
            raise ValueError("channel_contrast: need at least one channel")
        for name in per_channel:
            if len(getattr(self, name)) != n:
                raise ValueError(
                    f"{name}: one value per channel ({n}), got {getattr(self, name)!r}"
                )
        if not all(np.isfinite(c) and c > 0.0 for c in self.channel_contrast):
            raise ValueError(
                f"channel_contrast: need positive values, got {self.channel_contrast!r}"
            )
        if not all(np.isfinite(s) and s > 0.0 for s in self.channel_noise):
            raise ValueError(f"channel_noise: need positive values, got {self.channel_noise!r}")
        for lose, back, change in zip(
            self.lose_probability,
            self.return_probability,
            self.aspect_change_probability,
            strict=True,
        ):
            if not (0.0 <= lose and 0.0 <= change and lose + change <= 1.0 and 0.0 <= back <= 1.0):
                raise ValueError(
                    "lose_probability, return_probability, aspect_change_probability: need "
                    f"probabilities with lose + change <= 1, got {(lose, back, change)}"
                )
        if self.gate_pixels < 4:
            raise ValueError(f"gate_pixels: need at least 4, got {self.gate_pixels}")
        if not 0.0 <= self.vignetting <= 1.0:
            raise ValueError(f"vignetting: must lie in [0, 1], got {self.vignetting!r}")
        if not 0.0 <= self.residual_correlation < 1.0:
            raise ValueError(
                f"residual_correlation: must lie in [0, 1), got {self.residual_correlation!r}"
            )
        if self.predictor_window < 2 or self.predictor_window % 2:
            raise ValueError(
                f"predictor_window: must be an even integer >= 2, got {self.predictor_window}"
            )
        if not (np.isfinite(self.predictor_memory) and self.predictor_memory >= 1.0):
            raise ValueError(f"predictor_memory: must be >= 1 frame, got {self.predictor_memory}")
        if not 0.0 < self.reward_clip <= MAX_REWARD_CLIP:
            raise ValueError(
                f"reward_clip: must lie in (0, {MAX_REWARD_CLIP}], got {self.reward_clip}"
            )
        if self.search_after < 1:
            raise ValueError(f"search_after: must be >= 1 frame, got {self.search_after}")
        if self.reacquire_limit < 0:
            raise ValueError(f"reacquire_limit: must be >= 0, got {self.reacquire_limit}")
        if self.n_gimbals < 1:
            raise ValueError(f"n_gimbals: must be >= 1, got {self.n_gimbals}")
        if self.gimbal_sectors and len(self.gimbal_sectors) != self.n_gimbals:
            raise ValueError(
                f"gimbal_sectors: one (low, high) per gimbal ({self.n_gimbals}), "
                f"got {self.gimbal_sectors!r}"
            )
        for lo, hi in self.gimbal_sectors:
            if not (np.isfinite(lo) and np.isfinite(hi) and -np.pi <= lo < hi <= lo + 2 * np.pi):
                raise ValueError(
                    f"gimbal_sectors: need finite −π <= low < high <= low + 2π, got {(lo, hi)}"
                )

    @property
    def n_channels(self) -> int:
        """Number of imaging channels ``N``."""
        return len(self.channel_contrast)

    @functools.cached_property
    def sectors(self) -> FloatArray:
        """Each gimbal's clear sector as ``(low, width)`` ``(G, 2)``, rad: the body azimuth
        ``a`` is clear where ``(a − low) mod 2π <= width`` (:attr:`gimbal_sectors`, or its
        default: the whole circle for one gimbal, ``G`` overlapping equal sectors for more)."""
        if self.gimbal_sectors:
            pairs = np.array(self.gimbal_sectors, dtype=np.float64)
        elif self.n_gimbals == 1:
            pairs = np.array([[-np.pi, np.pi]])
        else:
            G = self.n_gimbals
            centre = 2.0 * np.pi * np.arange(G) / G
            half = np.pi / G + SECTOR_OVERLAP
            low = (centre - half + np.pi) % (2.0 * np.pi) - np.pi
            pairs = np.stack([low, low + 2.0 * half], -1)
        out = np.stack([pairs[:, 0], pairs[:, 1] - pairs[:, 0]], -1)
        out.flags.writeable = False
        return out

    @property
    def agent_obs_dim(self) -> int:
        """One gimbal's observation length: ``21 + N``, and ``26 + N`` for ``G > 1`` (its
        sector, own detection and own ``σ``: :func:`observe`)."""
        return 21 + self.n_channels + (5 if self.n_gimbals > 1 else 0)

    @property
    def half_field(self) -> float:
        """Half the field of view ``h``, rad."""
        return 0.5 * self.field_of_view

    @functools.cached_property
    def motion_terms(self) -> tuple[FloatArray, FloatArray, IntArray]:
        """The carrier's sinusoids, all axes: amplitudes ``A`` (rad), angular frequencies
        ``2π/T`` (rad/s) and axis (0 roll, 1 pitch, 2 yaw), each ``(K,)``."""
        amp = np.array([*self.roll_amplitude, *self.pitch_amplitude, *self.yaw_amplitude])
        per = np.array([*self.roll_period, *self.pitch_period, *self.yaw_period])
        axis = np.repeat(
            np.arange(3),
            [len(self.roll_amplitude), len(self.pitch_amplitude), len(self.yaw_amplitude)],
        )
        return amp, 2.0 * np.pi / per if per.size else per, axis

    @functools.cached_property
    def view_transition(self) -> FloatArray:
        """``π[n, μ, m]``: each channel's view chain (0 background, 1 bright, 2 dark),
        ``(N, 3, 3)``, row-stochastic."""
        rows = []
        for lose, back, change in zip(
            self.lose_probability,
            self.return_probability,
            self.aspect_change_probability,
            strict=True,
        ):
            stay = 1.0 - lose - change
            rows.append(
                [[1.0 - back, 0.5 * back, 0.5 * back], [lose, stay, change], [lose, change, stay]]
            )
        return np.array(rows)

    @functools.cached_property
    def model_transition(self) -> FloatArray:
        """The tracker's view chain ``(N, 3, 3)``: the true one with occlusions folded into the
        loss of the object view — an occlusion shows as background in every channel, its onset
        rate ``1/mean gap`` per frame — so that the tracker can declare the target lost even
        where a channel itself never loses it."""
        onset = 0.0
        if self.occlusion_length[1] > 0:
            onset = 1.0 / (0.5 * (self.occlusion_gap[0] + self.occlusion_gap[1]))
        pi = self.view_transition.copy()
        # P(background | object) = 1 − (1 − lose)(1 − onset), the rest scaled to keep the row
        for m in (1, 2):
            lose = pi[:, m, 0]
            pi[:, m, 1:] *= 1.0 - onset
            pi[:, m, 0] = 1.0 - (1.0 - lose) * (1.0 - onset)
        return pi

    @functools.cached_property
    def view_contrast(self) -> FloatArray:
        """Contrast of each channel's views ``(N, 3)``: background 0, bright ``+c``, dark ``−c``."""
        c = np.array(self.channel_contrast)
        return np.stack([np.zeros_like(c), c, -c], -1)

    @functools.cached_property
    def gate_centres_mrad(self) -> FloatArray:
        """Angular positions of the gate's pixel centres from its centre ``(J,)``, mrad."""
        J = self.gate_pixels
        return (np.arange(J) - 0.5 * (J - 1)) * self.pixel_pitch * reference.MRAD

    @functools.cached_property
    def fusion_tracker(self) -> FusionTracker:
        """Paper 004's tracker, its model matched to the channels (nominal contrast: it does not
        know the vignetting), in mrad."""
        value, slope = box_profile(
            self.gate_centres_mrad, self.target_size * reference.MRAD, self.blur * reference.MRAD
        )
        c = self.view_contrast[..., None]
        model = FusionModel(
            templates=c * value,
            template_slopes=c * slope,
            noise_std=np.array(self.channel_noise, dtype=np.float64),
            transition=self.model_transition,
            correlation=self.residual_correlation,
            prior_std=self.residual_std * reference.MRAD,
        )
        return FusionTracker(model)

    @functools.cached_property
    def predictor(self) -> ABCPredictor:
        """Paper 001's predictor with ``N = predictor_window`` and ``predictor_memory``."""
        return ABCPredictor(window=self.predictor_window, memory=self.predictor_memory)

    @functools.cached_property
    def kernel_settings(self) -> NDArray[np.void]:
        """The scalar settings the compiled kernels read, as one read-only record (a
        structured array of one element, dtype :data:`.kernels.SETTINGS`) that they read by
        field name; computed once per params."""
        model = self.fusion_tracker.model
        fields = {
            "dt": self.frame_period,
            "max_rate": self.max_rate,
            "max_acceleration": self.max_acceleration,
            "elevation_low": self.elevation_limits[0],
            "elevation_high": self.elevation_limits[1],
            "half_field": self.half_field,
            "vignetting": self.vignetting,
            "target_size": self.target_size * reference.MRAD,
            "blur": self.blur * reference.MRAD,
            "sensor_noise": self.sensor_noise,
            "sigma_ref": self.sigma_ref,
            "reward_clip": self.reward_clip,
            "attitude_scale": ATTITUDE_SCALE,
            "correlation": model.correlation,
            "transition_variance": model.transition_variance,
            "open_threshold": model.open_threshold,
            "predictor_gain": self.predictor.gain,
            "initial_scale": self.predictor.initial_scale,
            "gap_low": self.occlusion_gap[0],
            "gap_high": self.occlusion_gap[1],
            "length_low": self.occlusion_length[0],
            "length_high": self.occlusion_length[1],
            "search_after": self.search_after,
            "reacquire_limit": self.reacquire_limit,
            "relock": self.relock,
        }
        record = np.array(
            [tuple(fields[name] for name in kernels.SETTINGS.names)], kernels.SETTINGS
        )
        record.flags.writeable = False
        return record

    @functools.cached_property
    def kernel_model(self) -> tuple[NDArray[np.float64] | NDArray[np.int64], ...]:
        """The world's and the tracker's arrays the compiled step reads, in the order of
        :data:`.kernels.ModelArrays` (read-only, C-contiguous); computed once per params. The
        kernels run paper 004's tracker with its Gaussian factor and posterior gain (the
        env's :attr:`fusion_tracker`) and paper 001's predictor with δ_Z smoothed."""
        model = self.fusion_tracker.model
        if not (model.gaussian_factor and model.gain == "posterior"):
            raise ValueError("the compiled step runs the posterior gain with the Gaussian factor")
        if not self.predictor.smooth_delta_z:
            raise ValueError("the compiled step smooths δ_Z")
        amp, omega, axis = self.motion_terms
        s, ds = model.templates, model.template_slopes
        arrays = (
            amp,
            omega,
            axis.astype(np.int64),
            self.view_transition,
            self.view_contrast,
            model.noise_std,
            self.gate_centres_mrad,
            s,
            ds,
            np.sum(s * s, axis=-1),
            np.sum(s * ds, axis=-1),
            model.fisher_information,
            model.transition,
            self.sectors,
        )
        out = []
        for a in arrays:
            a = np.ascontiguousarray(a)
            a.flags.writeable = False
            out.append(a)
        return tuple(out)

    @property
    def obs_dim(self) -> int:
        """Observation length ``G ·`` :attr:`agent_obs_dim`: ``21 + N`` for one gimbal (23 for
        two channels, see :func:`observe`)."""
        return self.n_gimbals * self.agent_obs_dim


@dataclass(frozen=True)
class GimbalState:
    """``B`` scenarios after frame ``frame``."""

    frame: IntArray
    """(B,) frames since the episode start."""
    target_position: FloatArray = field(repr=False)
    """(B, 3) target position, level frame, m (ground truth: never observed)."""
    target_velocity: FloatArray = field(repr=False)
    """(B, 3) target velocity relative to the carrier, m/s (ground truth)."""
    turn_rate: FloatArray = field(repr=False)
    """(B,) the target's level turn rate during its turn, rad/s (ground truth)."""
    turn_start: IntArray = field(repr=False)
    """(B,) the turn covers frames ``turn_start + 1 … turn_end``."""
    turn_end: IntArray = field(repr=False)
    """(B,) last frame of the turn."""
    carrier_phase: FloatArray = field(repr=False)
    """(B, K) phases of the carrier's sinusoids, rad."""
    gimbal_angles: FloatArray
    """(B, G, 2) each gimbal's azimuth α and elevation β, body frame, rad."""
    gimbal_rates: FloatArray
    """(B, G, 2) their rates, rad/s."""
    views: IntArray = field(repr=False)
    """(B, G, N) each gimbal's channels' true views (0 background, 1 bright, 2 dark)."""
    occlusion_start: IntArray = field(repr=False)
    """(B,) first frame of the current or next occlusion."""
    occlusion_end: IntArray = field(repr=False)
    """(B,) the frame after it."""
    out_of_view: IntArray
    """(B,) consecutive frames, up to this one, with the target out of every gimbal's view."""
    since_detection: IntArray
    """(B,) frames since the tracker last detected the target (0: detected this frame)."""
    fusion_variance: FloatArray
    """(B, G, 2) each gimbal's paper 004 posterior variance ``d`` in the azimuth and elevation
    planes, mrad²."""
    view_posterior: FloatArray = field(repr=False)
    """(B, G, 2, N, 3) each gimbal's paper 004 view posteriors per plane and channel."""
    predictor: ABCState = field(repr=False)
    """Paper 001's predictor, in the level frame turned by ``predictor_origin``."""
    predictor_origin: FloatArray = field(repr=False)
    """(B,) level azimuth of the ``OY`` axis of the predictor's frame, rad."""
    reference: FloatArray = field(repr=False)
    """(B, G, 2) level azimuth and elevation each gimbal's gate was centred on this frame (the
    prediction, or its boresight in search), rad."""
    estimate: FloatArray
    """(B, 2) the tracker's level azimuth and elevation of the target this frame, rad."""
    predicted: FloatArray
    """(B, 2) its prediction for the next frame, rad."""
    detected: BoolArray
    """(B,) some gimbal's tracker detected the target this frame, and the track measured it
    (else its predictor coasted)."""
    in_view: BoolArray
    """(B,) the target lies in some gimbal's view: its field of view and its clear sector
    (ground truth)."""
    occluded: BoolArray = field(repr=False)
    """(B,) the target is occluded this frame (ground truth)."""
    visible: BoolArray = field(repr=False)
    """(B, G, N) the target stands out in gimbal g's channel n this frame (ground truth)."""
    sigma_los: FloatArray
    """(B,) ``σ_LOS``, the angular error bound of the measuring gimbal's fused direction
    (:func:`.reference.measuring_gimbal`), rad."""

    @property
    def batch_size(self) -> int:
        """Number of scenarios ``B``."""
        return int(self.frame.shape[0])


#: :class:`GimbalState`'s fields in order with the dtype the kernels take them in
#: (``predictor``: its six arrays, :func:`state_arrays`)
_FIELD_DTYPES: tuple[tuple[str, type], ...] = tuple(
    (name, {"I": np.int64, "B": np.bool_}.get(kind, np.float64))
    for name, kind in (
        ("frame", "I"), ("target_position", "F"), ("target_velocity", "F"), ("turn_rate", "F"),
        ("turn_start", "I"), ("turn_end", "I"), ("carrier_phase", "F"), ("gimbal_angles", "F"),
        ("gimbal_rates", "F"), ("views", "I"), ("occlusion_start", "I"), ("occlusion_end", "I"),
        ("out_of_view", "I"), ("since_detection", "I"), ("fusion_variance", "F"),
        ("view_posterior", "F"), ("predictor", "P"), ("predictor_origin", "F"),
        ("reference", "F"), ("estimate", "F"), ("predicted", "F"), ("detected", "B"),
        ("in_view", "B"), ("occluded", "B"), ("visible", "B"), ("sigma_los", "F"),
    )
)  # fmt: skip


def spaces(params: GimbalParams) -> EnvSpaces:
    """One agent per gimbal, ``gimbal_0 … gimbal_{G−1}``, each commanding the rates of its two
    axes; each agent's view is its row of :func:`observe_agents`, the joint view
    (:func:`observe`) theirs one after another (for one gimbal: the same)."""
    G = params.n_gimbals
    return EnvSpaces.build("gimbal", G, params.obs_dim, params.agent_obs_dim, 2)


def draw_target(
    params: GimbalParams, rng: np.random.Generator, batch: int
) -> tuple[FloatArray, FloatArray]:
    """Target position and velocity ``(B, 3)`` (level frame) at frame 0, drawn in this order:
    range, azimuth, elevation, speed, aspect, its side, climb."""
    rng_range = rng.uniform(*params.start_range, batch)
    az = rng.uniform(*params.start_azimuth, batch)
    el = rng.uniform(*params.start_elevation, batch)
    speed = rng.uniform(*params.target_speed, batch)
    heading = az + rng.uniform(*params.target_aspect, batch) * reference.draw_signs(rng, batch)
    climb = rng.uniform(*params.target_climb, batch)
    ce, cc = np.cos(el), np.cos(climb)
    p = rng_range[:, None] * np.stack([ce * np.sin(az), ce * np.cos(az), np.sin(el)], -1)
    v = speed[:, None] * np.stack([cc * np.sin(heading), cc * np.cos(heading), np.sin(climb)], -1)
    return p, v


def start(
    params: GimbalParams,
    target_position: ArrayLike,
    target_velocity: ArrayLike,
    rng: np.random.Generator,
) -> GimbalState:
    """Scenarios from a given target ``(B, 3)`` position (m) and velocity (m/s), level frame,
    at frame 0 (the rest drawn: :func:`.reference.start`)."""
    p = finite_array(target_position, "target_position", tail=(3,))
    v = finite_array(target_velocity, "target_velocity", tail=(3,))
    if p.ndim != 2 or v.shape != p.shape:
        raise ValueError(f"target_position, target_velocity: expected equal (B, 3), got {p.shape}")
    if np.any(np.linalg.norm(p, axis=-1) == 0.0):
        raise ValueError("target_position: the target cannot start at the carrier")
    return reference.start(params, p, v, rng, lock=lock_on)


def lock_on(
    params: GimbalParams, position: FloatArray, velocity: FloatArray, rng: np.random.Generator
) -> tuple[ABCState, FloatArray]:
    """:func:`.reference.lock_on` compiled (:func:`.kernels.lock_on_kernel`): the same draws
    (the sensors' noise ``(B, N + 1, 2)``), the frames' true angles in numpy, the predictor's
    ``N + 1`` updates in the kernel."""
    B, N, T = position.shape[0], params.predictor_window, params.frame_period
    frames = np.arange(-N, 1, dtype=np.float64)
    past = position[:, None, :] + frames[None, :, None] * T * velocity[:, None, :]
    az, el = zup_angles_from_unit(past)
    noise = rng.standard_normal((B, N + 1, 2))
    state = params.predictor.initial_state(B)
    arrays = (
        state.azimuth_window,
        state.elevation_window,
        state.count,
        state.slope_angle,
        state.delta,
        state.anchor,
    )
    origin = np.empty(B)
    kernels.lock_on_kernel(params.kernel_settings, az, el, noise, arrays, origin)
    return state, origin


def reset(
    params: GimbalParams, rng: np.random.Generator, batch: int, like: GimbalState | None = None
) -> GimbalState:
    """``batch`` fresh scenarios after lock-on. Scenarios share nothing: ``like`` is unused."""
    if batch < 1:
        raise ValueError(f"batch: must be >= 1, got {batch}")
    p, v = draw_target(params, rng, batch)
    return reference.start(params, p, v, rng, lock=lock_on)


def step(
    params: GimbalParams, state: GimbalState, action: ArrayLike, rng: np.random.Generator
) -> tuple[GimbalState, FloatArray, BoolArray]:
    """Advance every scenario one frame under ``action`` ``(B, G, 2)`` (or ``(B, 2G)``): each
    gimbal's rate commands in ``[−1, 1]`` (clipped); NaN or infinite values raise
    ``ValueError``. Returns ``(state, reward (B,), terminated (B,))``; the time limit is the
    shells'."""
    B, G = state.batch_size, params.n_gimbals
    try:
        a = np.asarray(action, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"action: cannot be read as floats ({exc})") from None
    if a.size != 2 * B * G:
        raise ValueError(f"action: expected {2 * B * G} values (B, {G}, 2), got shape {a.shape}")
    a = a.reshape(B, G, 2)
    if not np.all(np.isfinite(a)):
        raise ValueError("action: contains NaN or infinite values")
    N, J = params.n_channels, params.gate_pixels
    # the draws of the numpy step, in its order: the occlusions' gaps and lengths, the views'
    # chains, the gates' pixel noise (per scenario, gimbal, plane, channel, pixel), the angle
    # sensors' noise
    draws = (
        rng.uniform(0.0, 1.0, B),
        rng.uniform(0.0, 1.0, B),
        rng.uniform(size=(B, G, N)),
        rng.standard_normal((B, G, 2, N, J)),
        rng.standard_normal((B, 2)),
    )
    old = state_arrays(state)
    W = params.predictor_window + 1
    new = (
        np.empty(B, dtype=np.int64),  # frame
        np.empty((B, 3)),  # target_position
        np.empty((B, 3)),  # target_velocity
        *old[3:7],  # the turn and the carrier's phases do not change
        np.empty((B, G, 2)),  # gimbal_angles
        np.empty((B, G, 2)),  # gimbal_rates
        np.empty((B, G, N), dtype=np.int64),  # views
        np.empty(B, dtype=np.int64),  # occlusion_start
        np.empty(B, dtype=np.int64),  # occlusion_end
        np.empty(B, dtype=np.int64),  # out_of_view
        np.empty(B, dtype=np.int64),  # since_detection
        np.empty((B, G, 2)),  # fusion_variance
        np.empty((B, G, 2, N, 3)),  # view_posterior
        np.empty((B, W)),  # the predictor's azimuth_window
        np.empty((B, W)),  # elevation_window
        np.empty(B, dtype=np.int64),  # count
        np.empty(B),  # slope_angle
        np.empty((B, 3)),  # delta
        np.empty((B, 3)),  # anchor
        np.empty(B),  # predictor_origin
        np.empty((B, G, 2)),  # reference
        np.empty((B, 2)),  # estimate
        np.empty((B, 2)),  # predicted
        np.empty(B, dtype=bool),  # detected
        np.empty(B, dtype=bool),  # in_view
        np.empty(B, dtype=bool),  # occluded
        np.empty((B, G, N), dtype=bool),  # visible
        np.empty(B),  # sigma_los
    )
    reward, terminated = np.empty(B), np.empty(B, dtype=bool)
    args = (params.kernel_settings, params.kernel_model, old, a, draws, new, (reward, terminated))
    if B < 2 * MIN_ROWS_PER_THREAD:  # run_rows would not split it: skip its bookkeeping
        kernels.step_kernel(0, B, *args)
    else:
        run_rows(B, lambda lo, hi: kernels.step_kernel(lo, hi, *args))
    return from_arrays(new), reward, terminated


def state_arrays(state: GimbalState) -> tuple[NDArray[np.generic], ...]:
    """The state's arrays in the order the kernels take them (:data:`.kernels.StateArrays`):
    its fields in order, the predictor's (``ABCState``) in place of ``predictor``; each
    C-contiguous, of the dtype the kernels are compiled for (no copy when it is one)."""
    arrays: list[NDArray[np.generic]] = []
    for name, dtype in _FIELD_DTYPES:
        if name == "predictor":
            pr = state.predictor
            arrays += [
                np.ascontiguousarray(pr.azimuth_window, dtype=np.float64),
                np.ascontiguousarray(pr.elevation_window, dtype=np.float64),
                np.ascontiguousarray(pr.count, dtype=np.int64),
                np.ascontiguousarray(pr.slope_angle, dtype=np.float64),
                np.ascontiguousarray(pr.delta, dtype=np.float64),
                np.ascontiguousarray(pr.anchor, dtype=np.float64),
            ]
        else:
            arrays.append(np.ascontiguousarray(getattr(state, name), dtype=dtype))
    return tuple(arrays)


def from_arrays(arrays: tuple[NDArray[np.generic], ...]) -> GimbalState:
    """The :class:`GimbalState` of arrays in the order of :data:`.kernels.StateArrays`."""
    head, predictor, tail = arrays[:16], arrays[16:22], arrays[22:]
    return GimbalState(*head, ABCState(*predictor), *tail)


def carrier_attitude(params: GimbalParams, state: GimbalState) -> tuple[FloatArray, FloatArray]:
    """Attitude ``(B, 3)`` (roll, pitch, yaw, rad) and its rates (rad/s) at the state's frame:
    known to the tracker (paper 001's assumption), observed."""
    return reference.carrier_attitude(params, state.carrier_phase, state.frame)


def observe(params: GimbalParams, state: GimbalState) -> NDArray[np.float32]:
    """The joint observation ``(B, G · A)`` float32 — the gimbals' observations
    (:func:`observe_agents`, ``A = agent_obs_dim``) one after another; for one gimbal its
    ``(B, 21 + N)`` — own drives, the carrier's attitude and the track's output, no ground
    truth. ``h`` is half the field of view; "body offset" of a level direction is its
    body-frame (azimuth, elevation) minus the gimbal's (α, β), azimuth wrapped. Gimbal ``g``'s
    entries start at ``g · A``:

    | index      | meaning                                                                   |
    |------------|---------------------------------------------------------------------------|
    | 0, 1       | the gimbal's ``α/π``, ``β/(π/2)``                                            |
    | 2, 3       | its rates ``/ max_rate``                                                    |
    | 4–6        | carrier roll, pitch, yaw ``/ 0.1`` rad                                      |
    | 7–9        | their rates ``/ 0.1`` rad/s                                                 |
    | 10, 11     | body offset of the track's estimate this frame from its boresight ``/ h``  |
    | 12, 13     | body offset of its prediction for the next frame, at this frame's attitude ``/ h`` |
    | 14, 15     | the estimate's level ``θ/π``, ``ϕ/(π/2)``                                   |
    | 16, 17     | the prediction's level ``θ/π``, ``ϕ/(π/2)``                                 |
    | 18         | ``ln(σ_LOS/σ_ref)`` of the track                                            |
    | 19 … 18+N  | its channels' posterior object probability (mean of the two planes)        |
    | 19+N       | 1.0 if the track measured the target this frame (some gimbal detected it)   |
    | 20+N       | frames since the last detection ``/ reacquire_limit`` (``+ 1``)              |
    | 21+N       | ``G > 1`` only: 1.0 if its clear sector holds the prediction's body azimuth |
    | 22+N, 23+N | ``G > 1`` only: its sector's edges ``low/π``, ``high/π`` (body azimuth)     |
    | 24+N       | ``G > 1`` only: 1.0 if its own fused tracker detected the target            |
    | 25+N       | ``G > 1`` only: ``ln(σ/σ_ref)`` of its own fused direction                  |

    Every entry is clipped to ``[−OBS_CLIP, OBS_CLIP]``.
    """
    obs = np.empty((state.batch_size, params.obs_dim), dtype=np.float32)
    kernels.observe_kernel(params.kernel_settings, params.kernel_model, state_arrays(state), obs)
    return obs


def observe_agents(params: GimbalParams, state: GimbalState) -> NDArray[np.float32]:
    """Each gimbal's view ``(B, G, agent_obs_dim)`` (the table of :func:`observe`)."""
    return observe(params, state).reshape(state.batch_size, params.n_gimbals, -1)


def info(params: GimbalParams, state: GimbalState) -> dict[str, FloatArray]:
    """Diagnostics (ground truth included: for evaluation, never for the policy): the angle
    between the track's estimate and the target (``los_error``, rad), between the boresight
    and the target (``pointing_error``, rad; for several gimbals the least over those whose
    clear sector holds the target, over all where none does), the estimate's azimuth and elevation errors
    (``estimate_error_azimuth``, ``estimate_error_elevation``, rad: paper 001's prediction
    error through a loss), ``σ_LOS`` (rad), whether the target is in some gimbal's view,
    occluded, detected, in how many channels (of all gimbals) it stands out, and which gimbal
    the track measured (``measuring_gimbal``, its index: 0 for one gimbal; a change between
    frames is a hand-over)."""
    diag = np.empty((len(INFO_KEYS), state.batch_size))
    kernels.info_kernel(params.kernel_settings, params.kernel_model, state_arrays(state), diag)
    return dict(zip(INFO_KEYS, diag, strict=True))


#: the keys of :func:`info`, in the order of the compiled kernel's rows
INFO_KEYS = (
    "los_error",
    "pointing_error",
    "estimate_error_azimuth",
    "estimate_error_elevation",
    "sigma_los",
    "in_view",
    "occluded",
    "detected",
    "visible_channels",
    "measuring_gimbal",
)
