"""The Gymnasium shell every sensorgym env shares: one scenario of a batched simulation.

An env package subclasses :class:`CoreEnv` with its simulation module, params type, id and
renderer module (:mod:`.rendering`); episode bookkeeping, action checks, seeding and the params-as-keywords door live
here once (the time limit is the ``TimeLimit`` wrapper ``gym.make`` adds from the
registration).
"""

from __future__ import annotations

from types import ModuleType
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

from sensorgym.envs.shells.contract import Core, check_action, resolve_params
from sensorgym.envs.shells.rendering import RENDER_MODES, Frames, check_render_mode


class CoreEnv(gym.Env[NDArray[np.float32], NDArray[np.float32]]):
    """One scenario of a batched simulation (batch of one). Subclasses set ``simulation``,
    ``params_type``, ``env_id``, ``renderer`` (the module that draws its frames, see
    :mod:`.rendering`) and ``metadata["render_fps"]``.

    Construct with ``params=`` a params instance and/or its fields as keywords.
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": RENDER_MODES, "render_fps": 4}
    simulation: ClassVar[ModuleType]
    params_type: ClassVar[type]
    env_id: ClassVar[str]
    renderer: ClassVar[str | None] = None

    def __init__(self, params: Any = None, render_mode: str | None = None, **fields: Any):
        modes = self.metadata.get("render_modes", []) if self.renderer else []
        check_render_mode(render_mode, modes)
        self.core = Core(self.simulation, resolve_params(self.params_type, params, **fields))
        self.params = self.core.params
        self.render_mode = render_mode
        self.observation_space = self.core.spaces.observation
        self.action_space = self.core.spaces.action
        self._state: Any = None
        self._frames = Frames(self.renderer, render_mode, self.metadata.get("render_fps", 4))

    @property
    def simulator_state(self) -> Any:
        """The simulation's current state, a batch of one (ground truth included: for
        truth-informed rules, bounds, rendering and diagnostics, never for a policy one could field)."""
        if self._state is None:
            raise RuntimeError("simulator_state: call reset() first")
        return self._state

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[NDArray[np.float32], dict[str, Any]]:
        super().reset(seed=seed)
        self._state = self.core.reset(self.np_random, 1)
        self._frames.start(self._state)
        return self.core.observe(self._state)[0], self._info()

    def step(
        self, action: NDArray[np.float32]
    ) -> tuple[NDArray[np.float32], float, bool, bool, dict[str, Any]]:
        if self._state is None:
            raise RuntimeError("step: call reset() first")
        a = check_action(action, self.action_space.shape)
        self._state, reward, terminated = self.core.step(self._state, a[None], self.np_random)
        self._frames.add(self._state, float(reward[0]))
        # truncation=False: the time limit is the TimeLimit wrapper added by gym.make
        obs = self.core.observe(self._state)[0]
        return obs, float(reward[0]), bool(terminated[0]), False, self._info()

    def _info(self) -> dict[str, Any]:
        return {k: float(v[0]) for k, v in self.core.info(self._state).items()}

    def render(self) -> NDArray[np.uint8] | None:
        """The frame of scenario 0 (``"rgb_array"``) or ``None`` after showing it (``"human"``)."""
        return self._frames.render(self.params)

    def close(self) -> None:
        self._frames.close()
        super().close()
