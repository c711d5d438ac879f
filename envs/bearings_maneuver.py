"""Platform-manoeuvre environments over the bearings-only tracker (Gymnasium and vector)."""

from __future__ import annotations

from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space
from numpy.typing import NDArray

from . import bearings_maneuver_core as core
from .bearings_maneuver_core import OBS_CLIP, OBS_DIM, ManeuverParams, ManeuverState

FloatArray = NDArray[np.float64]


def _spaces() -> tuple[spaces.Box, spaces.Box]:
    obs = spaces.Box(-OBS_CLIP, OBS_CLIP, (OBS_DIM,), np.float32)
    act = spaces.Box(-1.0, 1.0, (2,), np.float32)
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


def _one_platform(params: ManeuverParams) -> ManeuverParams:
    if params.platforms != 1:
        raise ValueError(
            f"params.platforms: the Gymnasium envs fly one platform, got {params.platforms} "
            "(use the PettingZoo env, sensorgym.envs.bearings_maneuver_pz, for several)"
        )
    return params


def _info(params: ManeuverParams, state: ManeuverState) -> dict[str, FloatArray]:
    """Diagnostics (ground truth included: for evaluation, never for the policy)."""
    est = state.estimate
    return {
        "range": state.range.min(axis=1),
        "bound": state.accuracy,
        "position_error": np.hypot(*(est.position - state.target[:, :2]).T),
        "tracker_t": np.full(state.batch_size, state.bank.t),
    }


class BearingsManeuverEnv(gym.Env[NDArray[np.float32], NDArray[np.float32]]):
    """Steer a platform so that bearings alone locate a moving target.

    ## Description

    A platform (ship, vehicle or drone, 2-D) detects a target that moves at constant velocity
    (or nearly so) and measures only its bearing, once per step, with noise ``σ``. Range is
    observable only when the platform manoeuvres (SPEC §4, §7 OC-5): the agent chooses turns
    and speed changes, a range-parameterised EKF bank tracks the target from the bearings, and
    the reward is the shrinking of the Cramér–Rao bound on the target's position. Simulation
    core: :mod:`sensorgym.envs.bearings_maneuver_core`.

    ## Action Space

    ``Box(-1, 1, (2,), float32)``; values outside ``[-1, 1]`` are clipped, NaN raises.

    | index | action        | scaled to                                   | unit  |
    |-------|---------------|---------------------------------------------|-------|
    | 0     | turn          | heading rate ``a₀ · world.max_turn_rate``   | rad/s |
    | 1     | speed change  | ``a₁ · world.max_speed_change``, then the   | m/s   |
    |       |               | speed is clipped to the world's limits      |       |

    ## Observation Space

    ``Box(-10, 10, (10,), float32)``: the tracker's view, no ground truth (table in
    :func:`~sensorgym.envs.bearings_maneuver_core.observe`): the last bearing relative to the
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
    — every setting is a field of :class:`~sensorgym.envs.bearings_maneuver_core.ManeuverParams`
    (units in its docstrings). ``render_mode="rgb_array"`` draws the tracks, the estimate and
    its 2σ ellipse.

    ## Version History

    * v0: initial version.
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["rgb_array"], "render_fps": 4}

    def __init__(self, params: ManeuverParams | None = None, render_mode: str | None = None):
        self.params = _one_platform(ManeuverParams() if params is None else params)
        if render_mode not in (None, *self.metadata["render_modes"]):
            raise ValueError(
                f"render_mode: one of {self.metadata['render_modes']}, got {render_mode!r}"
            )
        self.render_mode = render_mode
        self.observation_space, self.action_space = _spaces()
        self._state: ManeuverState | None = None
        self._history: list[ManeuverState] = []

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[NDArray[np.float32], dict[str, Any]]:
        super().reset(seed=seed)
        self._state = core.reset(self.params, self.np_random, 1)
        self._history = [self._state]
        return core.observe(self.params, self._state)[0, 0], self._single_info()

    def step(
        self, action: NDArray[np.float32]
    ) -> tuple[NDArray[np.float32], float, bool, bool, dict[str, Any]]:
        if self._state is None:
            raise RuntimeError("step: call reset() first")
        a = _action(action, (2,))
        self._state, reward, terminated = core.step(
            self.params, self._state, a[None], self.np_random
        )
        if self.render_mode is not None:
            self._history.append(self._state)
        # truncation=False: the time limit is the TimeLimit wrapper added by gym.make
        obs = core.observe(self.params, self._state)[0, 0]
        return obs, float(reward[0]), bool(terminated[0]), False, self._single_info()

    def _single_info(self) -> dict[str, Any]:
        return {k: float(v[0]) for k, v in _info(self.params, self._state).items()}

    def render(self) -> NDArray[np.uint8] | None:
        if self.render_mode is None:
            gym.logger.warn("render: no render_mode was given to the environment")
            return None
        if self._state is None:
            raise RuntimeError("render: call reset() first")
        from .bearings_maneuver_render import draw

        return draw(self.params, self._history)


class BearingsManeuverVectorEnv(VectorEnv[NDArray[np.float32], NDArray[np.float32], np.ndarray]):
    """``num_envs`` independent :class:`BearingsManeuverEnv` scenarios in one batched core.

    Same spaces, rewards and episode ends as the single env (its docstring is the spec);
    truncation after ``max_episode_steps`` is done here. ``autoreset_mode``: ``NEXT_STEP``
    (Gymnasium's default) — the step after an episode ends returns the first observation of
    the next one, with reward 0 and both flags False; with ``num_envs=1`` and one seed it
    produces exactly the single env's episodes. ``SAME_STEP`` — an ending scenario restarts
    within the step (its last observation in ``infos["final_obs"]``), as SB3 expects
    (:class:`sensorgym.train.sb3_vec_env.SB3VecEnv`).
    """

    metadata: ClassVar[dict[str, Any]] = {
        "render_modes": [],
        "autoreset_mode": AutoresetMode.NEXT_STEP,
    }

    def __init__(
        self,
        num_envs: int = 1,
        params: ManeuverParams | None = None,
        max_episode_steps: int | None = 30,
        render_mode: str | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
    ):
        if num_envs < 1:
            raise ValueError(f"num_envs: must be >= 1, got {num_envs}")
        if render_mode is not None:
            raise ValueError("render_mode: the vector env does not render (use the single env)")
        if max_episode_steps is not None and max_episode_steps < 1:
            raise ValueError(f"max_episode_steps: must be >= 1 or None, got {max_episode_steps}")
        self.autoreset_mode = AutoresetMode(autoreset_mode)
        if self.autoreset_mode is AutoresetMode.DISABLED:
            raise ValueError("autoreset_mode: NEXT_STEP or SAME_STEP (DISABLED is not supported)")
        self.metadata = {**self.metadata, "autoreset_mode": self.autoreset_mode}
        self.num_envs = num_envs
        self.params = _one_platform(ManeuverParams() if params is None else params)
        self.max_episode_steps = max_episode_steps
        self.render_mode = render_mode
        self.single_observation_space, self.single_action_space = _spaces()
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self._state: ManeuverState | None = None
        self._steps = np.zeros(num_envs, dtype=np.int64)
        self._done = np.zeros(num_envs, dtype=bool)  # NEXT_STEP: ended on the last step

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[NDArray[np.float32], dict[str, Any]]:
        super().reset(seed=seed)
        self._state = core.reset(self.params, self.np_random, self.num_envs)
        self._steps[:] = 0
        self._done[:] = False
        return self._observe(self._state), self._infos(self._state)

    def step(
        self, actions: NDArray[np.float32]
    ) -> tuple[NDArray[np.float32], FloatArray, NDArray[np.bool_], NDArray[np.bool_], dict]:
        if self._state is None:
            raise RuntimeError("step: call reset() first")
        a = _action(actions, (self.num_envs, 2))
        if self.autoreset_mode is AutoresetMode.SAME_STEP:
            return self._step_same(a)
        return self._step_next(a)

    def _restart(self, done: NDArray[np.bool_], state: ManeuverState) -> ManeuverState:
        """Fresh scenarios where ``done``; when all restart, the tracker clock restarts too."""
        if done.all():
            return core.reset(self.params, self.np_random, self.num_envs)
        fresh = core.reset(self.params, self.np_random, self.num_envs, t=state.bank.t)
        return core.where(done, fresh, state)

    def _truncated(self) -> NDArray[np.bool_]:
        if self.max_episode_steps is None:
            return np.zeros(self.num_envs, dtype=bool)
        return self._steps >= self.max_episode_steps

    def _step_next(self, a: FloatArray) -> tuple:
        """NEXT_STEP: scenarios that ended last step restart now (reward 0, flags down)."""
        done = self._done
        reward = np.zeros(self.num_envs)
        terminated = np.zeros(self.num_envs, dtype=bool)
        if done.all():
            new = self._restart(done, self._state)
        else:
            new, reward, terminated = core.step(self.params, self._state, a, self.np_random)
            if done.any():
                new = self._restart(done, new)
                reward = np.where(done, 0.0, reward)
                terminated = terminated & ~done
        self._steps = np.where(done, 0, self._steps + 1)
        # as the TimeLimit wrapper of the single env: both flags may be set on one step
        truncated = self._truncated() & ~done
        self._state, self._done = new, terminated | truncated
        return self._observe(new), reward, terminated, truncated, self._infos(new)

    def _step_same(self, a: FloatArray) -> tuple:
        """SAME_STEP: scenarios that end now restart at once; their last observation and info
        go to ``infos["final_obs"]`` ``(num_envs, 10)`` and ``infos["final_info"]`` (valid
        where the masks ``"_final_obs"``/``"_final_info"`` are True) — what SB3's VecEnv needs."""
        new, reward, terminated = core.step(self.params, self._state, a, self.np_random)
        self._steps = self._steps + 1
        truncated = self._truncated()
        done = terminated | truncated
        obs, infos = self._observe(new), self._infos(new)
        if done.any():
            final = {"final_obs": obs, "_final_obs": done, "final_info": infos, "_final_info": done}
            new = self._restart(done, new)
            self._steps = np.where(done, 0, self._steps)
            obs, infos = self._observe(new), {**self._infos(new), **final}
        self._state = new
        return obs, reward, terminated, truncated, infos

    def _observe(self, state: ManeuverState) -> NDArray[np.float32]:
        return core.observe(self.params, state)[:, 0]

    def _infos(self, state: ManeuverState) -> dict[str, Any]:
        # Gymnasium's vector-info layout: the values and a "_key" mask of the envs that set them
        infos: dict[str, Any] = {}
        for key, value in _info(self.params, state).items():
            infos[key], infos[f"_{key}"] = value, np.ones(self.num_envs, dtype=bool)
        return infos
