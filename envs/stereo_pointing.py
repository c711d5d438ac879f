"""Receiver-pointing environments over the multi-receiver stereo tracker (Gymnasium and vector)."""

from __future__ import annotations

from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space
from numpy.typing import NDArray

from . import stereo_pointing_core as core
from .stereo_pointing_core import OBS_CLIP, PointingParams, PointingState

FloatArray = NDArray[np.float64]


def _spaces(params: PointingParams) -> tuple[spaces.Box, spaces.Box]:
    obs = spaces.Box(-OBS_CLIP, OBS_CLIP, (params.obs_dim,), np.float32)
    # flattened (n·2,): SB3 policies handle one-dimensional Box actions everywhere
    act = spaces.Box(-1.0, 1.0, (2 * params.n_receivers,), np.float32)
    return obs, act


def _action(action: Any, shape: tuple[int, ...]) -> FloatArray:
    """The action as float64 of ``shape``; wrong shapes and NaN raise ``ValueError``."""
    try:
        a = np.asarray(action, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"action: cannot be read as floats ({exc})") from None
    if a.shape != shape:
        raise ValueError(f"action: expected shape {shape}, got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError("action: contains NaN or infinite values")
    return a


def _info(state: PointingState) -> dict[str, FloatArray]:
    """Diagnostics (ground truth included: for evaluation, never for the policy)."""
    error = np.linalg.norm(state.track.position - state.drone_position, axis=-1)
    return {
        "position_error": error.mean(axis=-1),
        "drones_fixed": state.fixed.sum(axis=-1).astype(np.float64),
        "views": state.seen.sum(axis=(1, 2)).astype(np.float64),
    }


class StereoPointingEnv(gym.Env[NDArray[np.float32], NDArray[np.float32]]):
    """Point narrow-field receivers so that their stereo fixes locate several drones.

    ## Description

    ``n`` gimballed passive receivers stand on a circle of radius ``circle_radius`` (SPEC §7
    OC-3); each sees only what lies inside its narrow cone (half-angle ``fov``) and measures
    the direction to it with angular noise ``σ_ang``. ``m`` drones fly straight lines through
    the surveillance volume. A drone seen by two or more receivers is triangulated and its
    constant-velocity Kalman filter updated; otherwise the filter only predicts. The agent
    slews the receivers; it is rewarded for the accuracy its current pointing gives: the
    Cramér–Rao bound of the receivers that see each drone, best with near-orthogonal lines of
    sight (SPEC §2.2, §7 OC-1). Simulation core: :mod:`sensorgym.envs.stereo_pointing_core`.

    ## Action Space

    ``Box(-1, 1, (2n,), float32)``; values outside ``[-1, 1]`` are clipped, NaN raises.

    | index   | action                 | scaled to                     | unit |
    |---------|------------------------|-------------------------------|------|
    | 2k      | receiver k azimuth slew   | ``a · slew_rate · dt``     | rad  |
    | 2k + 1  | receiver k elevation slew | ``a · slew_rate · dt``, the elevation held within ``±max_elevation`` | rad |

    ## Observation Space

    ``Box(-10, 10, (3n + 3nm + 4m,), float32)`` (44 with the defaults): own gimbal angles,
    and the tracker's view, no ground truth (table in
    :func:`~sensorgym.envs.stereo_pointing_core.observe`): per receiver and drone the
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
    — every setting is a field of :class:`~sensorgym.envs.stereo_pointing_core.PointingParams`
    (units in its docstrings). ``render_mode="rgb_array"`` draws a top view: receivers and
    their field-of-view wedges, drone tracks and the estimates.

    ## Version History

    * v0: initial version.
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["rgb_array"], "render_fps": 5}

    def __init__(self, params: PointingParams | None = None, render_mode: str | None = None):
        self.params = PointingParams() if params is None else params
        if render_mode not in (None, *self.metadata["render_modes"]):
            raise ValueError(
                f"render_mode: one of {self.metadata['render_modes']}, got {render_mode!r}"
            )
        self.render_mode = render_mode
        self.observation_space, self.action_space = _spaces(self.params)
        self._state: PointingState | None = None
        self._history: list[PointingState] = []

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[NDArray[np.float32], dict[str, Any]]:
        super().reset(seed=seed)
        self._state = core.reset(self.params, self.np_random, 1)
        self._history = [self._state]
        return core.observe(self.params, self._state)[0], self._single_info()

    def step(
        self, action: NDArray[np.float32]
    ) -> tuple[NDArray[np.float32], float, bool, bool, dict[str, Any]]:
        if self._state is None:
            raise RuntimeError("step: call reset() first")
        a = _action(action, self.action_space.shape)
        self._state, reward = core.step(self.params, self._state, a[None], self.np_random)
        if self.render_mode is not None:
            self._history.append(self._state)
        # terminated=False: nothing physical ends an episode; truncation=False: the time limit
        # is the TimeLimit wrapper added by gym.make
        obs = core.observe(self.params, self._state)[0]
        return obs, float(reward[0]), False, False, self._single_info()

    def _single_info(self) -> dict[str, Any]:
        return {k: float(v[0]) for k, v in _info(self._state).items()}

    def render(self) -> NDArray[np.uint8] | None:
        if self.render_mode is None:
            gym.logger.warn("render: no render_mode was given to the environment")
            return None
        if self._state is None:
            raise RuntimeError("render: call reset() first")
        from .stereo_pointing_render import draw

        return draw(self.params, self._history)


class StereoPointingVectorEnv(VectorEnv[NDArray[np.float32], NDArray[np.float32], np.ndarray]):
    """``num_envs`` independent :class:`StereoPointingEnv` scenarios in one batched core.

    Same spaces and rewards as the single env (its docstring is the spec); truncation after
    ``max_episode_steps`` is done here. Autoreset is ``NEXT_STEP`` (Gymnasium's default): the
    step after an episode ends returns the first observation of the next one, with reward 0 and
    both flags False. With ``num_envs=1`` and one seed it produces exactly the single env's
    episodes.
    """

    metadata: ClassVar[dict[str, Any]] = {
        "render_modes": [],
        "autoreset_mode": AutoresetMode.NEXT_STEP,
    }

    def __init__(
        self,
        num_envs: int = 1,
        params: PointingParams | None = None,
        max_episode_steps: int | None = 150,
        render_mode: str | None = None,
    ):
        if num_envs < 1:
            raise ValueError(f"num_envs: must be >= 1, got {num_envs}")
        if render_mode is not None:
            raise ValueError("render_mode: the vector env does not render (use the single env)")
        if max_episode_steps is not None and max_episode_steps < 1:
            raise ValueError(f"max_episode_steps: must be >= 1 or None, got {max_episode_steps}")
        self.num_envs = num_envs
        self.params = PointingParams() if params is None else params
        self.max_episode_steps = max_episode_steps
        self.render_mode = render_mode
        self.single_observation_space, self.single_action_space = _spaces(self.params)
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self._state: PointingState | None = None
        self._steps = np.zeros(num_envs, dtype=np.int64)
        self._done = np.zeros(num_envs, dtype=bool)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[NDArray[np.float32], dict[str, Any]]:
        super().reset(seed=seed)
        self._state = core.reset(self.params, self.np_random, self.num_envs)
        self._steps[:] = 0
        self._done[:] = False
        return core.observe(self.params, self._state), self._infos(self._state)

    def step(
        self, actions: NDArray[np.float32]
    ) -> tuple[NDArray[np.float32], FloatArray, NDArray[np.bool_], NDArray[np.bool_], dict]:
        if self._state is None:
            raise RuntimeError("step: call reset() first")
        a = _action(actions, self.action_space.shape)
        done = self._done
        if done.all():
            new, reward = (
                core.reset(self.params, self.np_random, self.num_envs),
                np.zeros(self.num_envs),
            )
        else:
            new, reward = core.step(self.params, self._state, a, self.np_random)
            if done.any():
                fresh = core.reset(self.params, self.np_random, self.num_envs)
                new = core.where(done, fresh, new)
                reward = np.where(done, 0.0, reward)
        self._steps = np.where(done, 0, self._steps + 1)
        terminated = np.zeros(self.num_envs, dtype=bool)
        truncated = np.zeros(self.num_envs, dtype=bool)
        if self.max_episode_steps is not None:
            truncated = (self._steps >= self.max_episode_steps) & ~done
        self._state, self._done = new, truncated
        return core.observe(self.params, new), reward, terminated, truncated, self._infos(new)

    def _infos(self, state: PointingState) -> dict[str, Any]:
        # Gymnasium's vector-info layout: the values and a "_key" mask of the envs that set them
        infos: dict[str, Any] = {}
        for key, value in _info(state).items():
            infos[key], infos[f"_{key}"] = value, np.ones(self.num_envs, dtype=bool)
        return infos
