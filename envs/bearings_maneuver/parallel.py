"""PettingZoo version of the platform-manoeuvre env: every platform is an agent."""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces

from sensorgym.envs.bearings_maneuver.env import BearingsManeuverCore
from sensorgym.envs.bearings_maneuver.simulation import OBS_CLIP, ManeuverParams
from sensorgym.envs.shells.parallel_env import CoreParallelEnv


class BearingsManeuverParallelEnv(CoreParallelEnv):
    """``K`` platforms cooperate to locate one target from bearings (PettingZoo Parallel API).

    ## Description

    The multi-platform case of ``sensorgym/BearingsManeuver-v0`` (same core,
    :mod:`sensorgym.envs.bearings_maneuver.simulation`, with ``params.platforms = K``): every platform
    takes a bearing each step, one tracker fuses them all, and the Cramér–Rao bound adds their
    information. Cross-bearings from separated platforms make range observable without any
    manoeuvre; the agents decide how to spread and turn so that the bearings cross well.

    ## Agents

    ``"platform_0"`` … ``"platform_{K-1}"``, all acting at once.

    ## Action Space (per agent)

    ``Box(-1, 1, (2,), float32)``: turn (``a₀ · world.max_turn_rate``) and speed change
    (``a₁ · world.max_speed_change``); clipped to ``[-1, 1]``; NaN raises.

    ## Observation Space (per agent)

    ``Box(-10, 10, (10 + 2(K−1),), float32)``: the agent's own view of the shared tracker
    estimate in its own frame, then the other platforms' positions relative to it
    (:func:`~sensorgym.envs.bearings_maneuver.simulation.observe`). :meth:`state` concatenates every
    agent's observation (a centralised critic's input; still no ground truth).

    ## Rewards

    One team reward, given to every agent: ``ln m_k − ln m_{k+1}`` of the position bound (or
    ``σ_r/r``); ``close_penalty`` when a platform comes within ``min_range``.

    ## Episode End

    All agents end together: terminated when any platform comes within ``min_range`` of the
    target; truncated after ``max_episode_steps`` steps.

    ## Arguments

    ``BearingsManeuverParallelEnv(params=ManeuverParams(platforms=2, ...),
    max_episode_steps=30)``.

    ## Version History

    * v0: initial version.
    """

    metadata: ClassVar[dict[str, Any]] = {"name": "bearings_maneuver_v0", "render_modes": []}

    def __init__(
        self,
        params: ManeuverParams | None = None,
        max_episode_steps: int = 30,
        render_mode: str | None = None,
    ):
        params = ManeuverParams(platforms=2) if params is None else params
        super().__init__(
            BearingsManeuverCore(params),
            [f"platform_{k}" for k in range(params.platforms)],
            spaces.Box(-OBS_CLIP, OBS_CLIP, (params.obs_dim,), np.float32),
            spaces.Box(-1.0, 1.0, (2,), np.float32),
            max_episode_steps,
            render_mode,
        )


def parallel_env(**kwargs: Any) -> BearingsManeuverParallelEnv:
    """PettingZoo's conventional constructor name; ``platforms=K`` sets the number of agents."""
    platforms = kwargs.pop("platforms", None)
    params = kwargs.pop("params", None) or ManeuverParams(platforms=2)
    if platforms is not None:
        params = dataclasses.replace(params, platforms=platforms)
    return BearingsManeuverParallelEnv(params=params, **kwargs)
