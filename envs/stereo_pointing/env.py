"""Receiver-pointing environments over the multi-receiver stereo tracker (Gymnasium and vector)."""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode
from numpy.typing import NDArray

from sensorgym.envs.shells.gym_env import CoreEnv, CoreVectorEnv, ReceiverTeamCore, receiver_spaces
from sensorgym.envs.stereo_pointing import simulation as core
from sensorgym.envs.stereo_pointing.simulation import PointingParams, PointingState

FloatArray = NDArray[np.float64]


def _spaces(params: PointingParams) -> tuple[spaces.Box, spaces.Box]:
    return receiver_spaces(params.obs_dim, params.n_receivers, core.OBS_CLIP)


class StereoPointingCore(ReceiverTeamCore):
    """:mod:`.stereo_pointing_core` as the shells step it (``observe_agents`` for PettingZoo)."""

    functions = core

    def info(self, state: PointingState) -> dict[str, FloatArray]:
        return _info(state)


def _info(state: PointingState) -> dict[str, FloatArray]:
    """Diagnostics (ground truth included: for evaluation, never for the policy)."""
    error = np.linalg.norm(state.track.position - state.drone_position, axis=-1)
    return {
        "position_error": error.mean(axis=-1),
        "drones_fixed": state.fixed.sum(axis=-1).astype(np.float64),
        "views": state.seen.sum(axis=(1, 2)).astype(np.float64),
    }


class StereoPointingEnv(CoreEnv):
    """Point narrow-field receivers so that their stereo fixes locate several drones.

    ## Description

    ``n`` gimballed passive receivers stand on a circle of radius ``circle_radius`` (SPEC §7
    OC-3); each sees only what lies inside its narrow cone (half-angle ``fov``) and measures
    the direction to it with angular noise ``σ_ang``. ``m`` drones fly straight lines through
    the surveillance volume. A drone seen by two or more receivers is triangulated and its
    constant-velocity Kalman filter updated; otherwise the filter only predicts. The agent
    slews the receivers; it is rewarded for the accuracy its current pointing gives: the
    Cramér–Rao bound of the receivers that see each drone, best with near-orthogonal lines of
    sight (SPEC §2.2, §7 OC-1). Simulation core: :mod:`sensorgym.envs.stereo_pointing.simulation`.

    ## Action Space

    ``Box(-1, 1, (2n,), float32)``; values outside ``[-1, 1]`` are clipped, NaN raises.

    | index   | action                 | scaled to                     | unit |
    |---------|------------------------|-------------------------------|------|
    | 2k      | receiver k azimuth slew   | ``a · slew_rate · dt``     | rad  |
    | 2k + 1  | receiver k elevation slew | ``a · slew_rate · dt``, the elevation held within ``±max_elevation`` | rad |

    ## Observation Space

    ``Box(-10, 10, (3n + 3nm + 4m,), float32)`` (44 with the defaults): own gimbal angles,
    and the tracker's view, no ground truth (table in
    :func:`~sensorgym.envs.stereo_pointing.simulation.observe`): per receiver and drone the
    predicted drone direction relative to the boresight in field-of-view half-angles and
    whether the receiver saw it; per drone the predicted position and its log RMS error.

    ## Rewards

    Mean over drones of ``clip(ln(σ_ref / σ_pos), −R, R)``, with ``σ_pos = √tr I⁻¹`` and
    ``I = Σ_k (I − u_k u_kᵀ)/(σ_ang² r_k²)`` over the receivers that see the drone now
    (``position_crlb``, true geometry). A drone seen by fewer than two receivers gives ``−R``.
    Defaults ``σ_ref = 1 m``, ``R = 5``: +2.3 per step is a 10 cm fix.

    ## Starting State

    Drones start at a uniform horizontal distance in ``start_distance`` from the circle centre,
    uniform bearing, height in ``start_altitude``, heading uniform, speed in ``drone_speed``,
    vertical speed in ``climb_rate``. Gimbals point at uniform azimuths and elevations in
    ``initial_elevation``. The tracker starts from an external cue: the truth plus Gaussian
    errors ``cue_sigma`` (position m, velocity m/s).

    ## Episode End

    * Termination: never (a drone leaving the volume is still tracked, if it can be).
    * Truncation: the time limit, ``max_episode_steps`` in the registration (150 steps of
      0.2 s).

    ## Arguments

    ``gym.make("sensorgym/StereoPointing-v0", params=PointingParams(...), render_mode=None)``
    — every setting is a field of :class:`~sensorgym.envs.stereo_pointing.simulation.PointingParams`
    (units in its docstrings). ``render_mode="rgb_array"`` draws a top view: receivers and
    their field-of-view wedges, drone tracks and the estimates.

    ## Version History

    * v0: initial version.
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["rgb_array"], "render_fps": 5}

    def __init__(self, params: PointingParams | None = None, render_mode: str | None = None):
        params = PointingParams() if params is None else params
        super().__init__(StereoPointingCore(params), *_spaces(params), render_mode)

    def draw(self, history: list[PointingState]) -> NDArray[np.uint8]:
        from sensorgym.envs.stereo_pointing.render import draw

        return draw(self.params, history)


class StereoPointingVectorEnv(CoreVectorEnv):
    """``num_envs`` independent :class:`StereoPointingEnv` scenarios in one batched core.

    Same spaces and rewards as the single env (its docstring is the spec); autoreset modes as
    :class:`~sensorgym.envs.shells.gym_env.CoreVectorEnv`.
    """

    def __init__(
        self,
        num_envs: int = 1,
        params: PointingParams | None = None,
        max_episode_steps: int | None = 150,
        render_mode: str | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
    ):
        params = PointingParams() if params is None else params
        super().__init__(
            StereoPointingCore(params),
            num_envs,
            *_spaces(params),
            max_episode_steps,
            render_mode,
            autoreset_mode,
        )
