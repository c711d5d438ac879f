"""An oracle ceiling for ``sensorgym/BearingsManeuver-v0``: planning on the true state.

Heuristics and trained policies act on the tracker's estimate; the oracle peeks at the
simulator (true target, true Fisher information) and plans on the very bound the reward
measures. It is not a policy one could field: it shows how much of the gap to the best
manoeuvres comes from not knowing the target (the rules) and how much from planning.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from sensorgym.agents.protocol import MemorylessRule
from sensorgym.envs.bearings_maneuver.simulation import ManeuverParams, ManeuverState
from sensorgym.envs.worlds.platform import fly
from sensorgym.trackers.bearings.crlb import (
    bearing_information,
    crlb,
    position_rms_bound,
    predict_information,
    relative_range_bound,
)
from sensorgym.trackers.bearings.models import cv_transition

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class OracleLookahead(MemorylessRule):
    """Hold each candidate action for ``horizon`` steps on the true, noise-free trajectory and
    take the first action of the plan with the smallest bound (receding horizon).

    ``state_fn`` returns the simulator's current :class:`ManeuverState` (batch = the
    observations' batch), e.g. ``lambda: vec_env.get_attr("_state")[0]`` for an SB3 view of the
    native vector env. One platform only (the Gymnasium env). The target's future is its mean
    path ``F x`` (exact for ``q̃ = 0``); plans that come within ``safety · min_range`` of it are
    ruled out.
    """

    state_fn: Callable[[], ManeuverState]
    """The simulator's current state (the oracle's privilege)."""
    params: ManeuverParams = field(default_factory=ManeuverParams)
    """Env settings (kinematics, bearing noise, reward metric, ``min_range``)."""
    turns: int = 7
    """Candidate turn actions, evenly spaced in ``[−1, 1]``."""
    speeds: tuple[float, ...] = (-1.0, 0.0, 1.0)
    """Candidate speed actions."""
    horizon: int = 5
    """Steps each candidate is held for."""
    safety: float = 1.5
    """Plans predicted within ``safety · min_range`` of the target are not taken."""

    def __post_init__(self) -> None:
        if self.params.platforms != 1:
            raise ValueError("params.platforms: the oracle plans for one platform")
        if self.horizon < 1 or self.turns < 1 or not self.speeds:
            raise ValueError("horizon, turns and speeds: need at least one each")

    def candidates(self) -> NDArray[np.float64]:
        """Candidate actions ``(C, 2)``."""
        turn, speed = np.meshgrid(np.linspace(-1.0, 1.0, self.turns), self.speeds)
        return np.stack([turn.ravel(), speed.ravel()], -1)

    def plan_bounds(self, s: ManeuverState) -> NDArray[np.float64]:
        """Bound after ``horizon`` steps of each candidate, ``(B, C)`` (``inf`` if too close)."""
        p, w = self.params, self.params.world
        cand = self.candidates()
        C = cand.shape[0]
        command = np.broadcast_to(
            cand * [w.max_turn_rate, w.max_speed_change], (s.batch_size, C, 2)
        )
        pos = np.repeat(s.platform_position[:, :1], C, axis=1)  # (B, C, 2)
        heading = np.repeat(s.heading[:, :1], C, axis=1)
        speed = np.repeat(s.speed[:, :1], C, axis=1)
        target = s.target[:, None, :]
        J = np.repeat(s.information[:, None], C, axis=1)
        F = cv_transition(w.dt)
        too_close = np.zeros((s.batch_size, C), dtype=bool)
        for _ in range(self.horizon):
            pos, heading, speed = fly(pos, heading, speed, command, w)
            target = target @ F.T
            # J_{k+1} = (I + J̄ Q)⁻¹ J̄ + Hᵀ H / σ², as the env's reward does
            J = predict_information(J, w.dt, w.q_tilde) + bearing_information(
                target, pos, w.sigma_bearing
            )
            d = target[..., :2] - pos
            too_close |= np.hypot(d[..., 0], d[..., 1]) < self.safety * p.min_range
        P = crlb(J)
        if p.metric == "position":
            bound = position_rms_bound(P)
        else:
            bound = relative_range_bound(P, target[..., :2], pos)
        return np.where(too_close, np.inf, bound)

    def act(self, obs: FloatArray) -> FloatArray:
        """Actions ``(N, action size)`` for observations ``(N, obs_dim)``."""
        s = self.state_fn()
        if s.batch_size != obs.shape[0]:
            raise ValueError(
                f"state_fn: simulator batch {s.batch_size} != {obs.shape[0]} observations"
            )
        return self.candidates()[np.argmin(self.plan_bounds(s), axis=1)]
