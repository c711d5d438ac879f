"""A re-acquisition search for ``sensorgym/GimbalTracking-v0``: the carrier-feedforward servo that,
once the tracking gate searches at the boresight, hops the boresight over rings around the
prediction.

After ``search_after`` frames without a detection the env's tracker stops looking at paper 001's
coasted prediction and images its gate (``gate_pixels · pixel_pitch`` across, ±4 mrad at the
defaults) about the boresight instead (theory §11.8). A target that turned during an occlusion
is then typically a few milliradians off the straight-line prediction, still in the field of
view but outside the gate: a servo that keeps the boresight on the prediction never sees it
again. :class:`FeedForwardSearch` moves the boresight, in the body frame, over two hexagonal
rings about the prediction, of radii one and two half-gates (the gate's positions then tile the
field of view out to three half-gates), back to the prediction between every two positions,
dwelling ``dwell`` frames at each so the fused tracker can build up its detection. The pattern's position follows from the frames
since the last detection alone (an observation), so the rule is memoryless; with a detection the
count restarts and the servo is the carrier-feedforward servo again.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from sensorgym.agents.gimbal_tracking import (
    CarrierFeedForward,
    frames_since_detection,
    gimbal_rows,
    joint_action,
)
from sensorgym.agents.protocol import MemorylessRule
from sensorgym.envs.gimbal_tracking.simulation import GimbalParams

FloatArray = NDArray[np.float64]


def search_offsets(half_gate: float, rings: int = 2) -> FloatArray:
    """The pattern ``(2P, 2)`` of body-frame offsets (rad), ``P = 3 rings (rings + 1)``: ring
    ``j = 1 … rings`` has ``6j`` points at radius ``j · half_gate`` (points ``2πi/(6j)`` round,
    in azimuth and elevation), and the centre comes back between every two of them — a target
    that reappears on the prediction (an occlusion ending on a straight path) is looked at
    every other position."""
    points = []
    for j in range(1, rings + 1):
        angle = 2.0 * np.pi * np.arange(6 * j) / (6 * j)
        points.append(j * half_gate * np.stack([np.cos(angle), np.sin(angle)], -1))
    ring = np.concatenate(points) if points else np.zeros((0, 2))
    pattern = np.zeros((2 * len(ring), 2))
    pattern[1::2] = ring  # centre, ring point, centre, ring point, …
    return pattern if len(ring) else np.zeros((1, 2))


@dataclass(frozen=True)
class FeedForwardSearch(MemorylessRule):
    """:class:`~sensorgym.agents.gimbal_tracking.CarrierFeedForward`, plus — once the gate
    searches (``search_after`` frames undetected) — an offset from the prediction that hops over
    :func:`search_offsets`, ``dwell`` frames at each, then starts over."""

    params: GimbalParams
    dwell: int = 2
    """Frames at each position of the pattern."""
    rings: int = 2
    """Rings of the pattern about the centre."""

    def __post_init__(self) -> None:
        if self.dwell < 1 or self.rings < 0:
            raise ValueError(f"dwell must be >= 1 and rings >= 0, got {self.dwell}, {self.rings}")

    @functools.cached_property
    def offsets(self) -> FloatArray:
        """The pattern (rad), radii in half-gates of the env's tracking gate."""
        p = self.params
        return search_offsets(0.5 * p.gate_pixels * p.pixel_pitch, self.rings)

    @functools.cached_property
    def servo(self) -> CarrierFeedForward:
        """The carrier-feedforward servo it offsets."""
        return CarrierFeedForward(self.params)

    def change(self, obs: FloatArray) -> FloatArray:
        """The body-frame angle change ``(n G, 2)`` (rad) each gimbal drives within the next
        frame; with several gimbals only those whose clear sector holds the prediction search
        (the others pre-point to their sector's edge)."""
        p = self.params
        rows = gimbal_rows(p, obs)
        since = frames_since_detection(p, rows)
        searching = since >= p.search_after
        if p.n_gimbals > 1:
            searching &= rows[:, 21 + p.n_channels] > 0.5
        pattern = self.offsets
        index = (np.maximum(since - p.search_after, 0) // self.dwell) % len(pattern)
        offset = np.where(searching[:, None], pattern[index], 0.0)
        return self.servo.change(obs) + offset

    def act(self, obs: FloatArray) -> FloatArray:
        return joint_action(self.params, self.change(obs))
