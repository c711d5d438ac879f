"""Platform-manoeuvre environments over the bearings-only tracker (Gymnasium and vector)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode
from numpy.typing import NDArray

from sensorgym.envs.bearings_maneuver import simulation as core
from sensorgym.envs.bearings_maneuver.simulation import (
    OBS_CLIP,
    OBS_DIM,
    ManeuverParams,
    ManeuverState,
)
from sensorgym.envs.shells.gym_env import CoreEnv, CoreVectorEnv

FloatArray = NDArray[np.float64]


def _spaces() -> tuple[spaces.Box, spaces.Box]:
    obs = spaces.Box(-OBS_CLIP, OBS_CLIP, (OBS_DIM,), np.float32)
    act = spaces.Box(-1.0, 1.0, (2,), np.float32)
    return obs, act


def _one_platform(params: ManeuverParams | None) -> ManeuverParams:
    params = ManeuverParams() if params is None else params
    if params.platforms != 1:
        raise ValueError(
            f"params.platforms: the Gymnasium envs fly one platform, got {params.platforms} "
            "(use the PettingZoo env, sensorgym.envs.bearings_maneuver.parallel, for several)"
        )
    return params


@dataclass(frozen=True)
class BearingsManeuverCore:
    """:mod:`.bearings_maneuver_core` as the shells step it (``observe``: the one platform of
    the Gymnasium envs; ``observe_agents``: every platform, for PettingZoo)."""

    params: ManeuverParams

    def reset(
        self, rng: np.random.Generator, batch: int, like: ManeuverState | None = None
    ) -> ManeuverState:
        # fresh scenarios join a running batch on its tracker clock
        return core.reset(self.params, rng, batch, t=0.0 if like is None else like.bank.t)

    def step(self, state: ManeuverState, action: FloatArray, rng: np.random.Generator) -> tuple:
        return core.step(self.params, state, action, rng)

    def observe(self, state: ManeuverState) -> NDArray[np.float32]:
        return core.observe(self.params, state)[:, 0]  # the Gymnasium envs fly one platform

    def observe_agents(self, state: ManeuverState) -> NDArray[np.float32]:
        return core.observe(self.params, state)  # (B, K, obs_dim): one row per platform

    def where(
        self, mask: NDArray[np.bool_], new: ManeuverState, old: ManeuverState
    ) -> ManeuverState:
        return core.where(mask, new, old)

    def info(self, state: ManeuverState) -> dict[str, FloatArray]:
        """Diagnostics (ground truth included: for evaluation, never for the policy)."""
        est = state.estimate
        return {
            "range": state.range.min(axis=1),
            "bound": state.accuracy,
            "position_error": np.hypot(*(est.position - state.target[:, :2]).T),
            "tracker_t": np.full(state.batch_size, state.bank.t),
        }


class BearingsManeuverEnv(CoreEnv):
    """Steer a platform so that bearings alone locate a moving target.

    ## Description

    A platform (ship, vehicle or drone, 2-D) detects a target that moves at constant velocity
    (or nearly so) and measures only its bearing, once per step, with noise ``σ``. Range is
    observable only when the platform manoeuvres (SPEC §4, §7 OC-5): the agent chooses turns
    and speed changes, a range-parameterised EKF bank tracks the target from the bearings, and
    the reward is the shrinking of the Cramér–Rao bound on the target's position. Simulation
    core: :mod:`sensorgym.envs.bearings_maneuver.simulation`.

    ## Action Space

    ``Box(-1, 1, (2,), float32)``; values outside ``[-1, 1]`` are clipped, NaN raises.

    | index | action        | scaled to                                   | unit  |
    |-------|---------------|---------------------------------------------|-------|
    | 0     | turn          | heading rate ``a₀ · world.max_turn_rate``   | rad/s |
    | 1     | speed change  | ``a₁ · world.max_speed_change``, then the   | m/s   |
    |       |               | speed is clipped to the world's limits      |       |

    ## Observation Space

    ``Box(-10, 10, (10,), float32)``: the tracker's view, no ground truth (table in
    :func:`~sensorgym.envs.bearings_maneuver.simulation.observe`): the last bearing relative to the
    heading (sin, cos), own speed, the estimated relative position and velocity in the
    platform frame, and the estimate's position uncertainty (two log standard deviations and
    their correlation).

    ## Rewards

    ``ln m_k − ln m_{k+1}``, with ``m`` the position RMS bound ``√(P_xx + P_yy)`` of the
    posterior CRLB along the true trajectory (or ``σ_r/r`` with ``metric="relative_range"``).
    An episode's return is ``ln(m_0/m_T)``: e.g. 3.0 means the manoeuvres cut the bound
    e³ ≈ 20 times. Ending too close to the target costs ``close_penalty``.

    ## Starting State

    Platform at the origin with a uniform random heading at ``initial_platform_speed``; target
    at a uniform range in ``initial_range`` and a uniform bearing, with a uniform course and
    speed in ``target_speed``. The tracker starts from the first bearing.

    ## Episode End

    * Termination: the platform comes within ``min_range`` of the target.
    * Truncation: the time limit, ``max_episode_steps`` in the registration (30 steps of 60 s).

    ## Arguments

    ``gym.make("sensorgym/BearingsManeuver-v0", params=ManeuverParams(...), render_mode=None)``
    — every setting is a field of :class:`~sensorgym.envs.bearings_maneuver.simulation.ManeuverParams`
    (units in its docstrings). ``render_mode="rgb_array"`` draws the tracks, the estimate and
    its 2σ ellipse.

    ## Version History

    * v0: initial version.
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["rgb_array"], "render_fps": 4}

    def __init__(self, params: ManeuverParams | None = None, render_mode: str | None = None):
        super().__init__(BearingsManeuverCore(_one_platform(params)), *_spaces(), render_mode)

    def draw(self, history: list[ManeuverState]) -> NDArray[np.uint8]:
        from sensorgym.envs.bearings_maneuver.render import draw

        return draw(self.params, history)


class BearingsManeuverVectorEnv(CoreVectorEnv):
    """``num_envs`` independent :class:`BearingsManeuverEnv` scenarios in one batched core.

    Same spaces, rewards and episode ends as the single env (its docstring is the spec);
    autoreset modes as :class:`~sensorgym.envs.shells.gym_env.CoreVectorEnv`.
    """

    def __init__(
        self,
        num_envs: int = 1,
        params: ManeuverParams | None = None,
        max_episode_steps: int | None = 30,
        render_mode: str | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
    ):
        core_ = BearingsManeuverCore(_one_platform(params))
        super().__init__(
            core_, num_envs, *_spaces(), max_episode_steps, render_mode, autoreset_mode
        )
