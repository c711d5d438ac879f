"""PettingZoo version of the receiver-pointing env: every receiver is an agent."""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces

from sensorgym.envs.shells.parallel_env import CoreParallelEnv
from sensorgym.envs.stereo_pointing.env import StereoPointingCore
from sensorgym.envs.stereo_pointing.simulation import OBS_CLIP, PointingParams


class StereoPointingParallelEnv(CoreParallelEnv):
    """``n`` receivers each slew their own gimbal to fix several drones (PettingZoo Parallel).

    ## Description

    The multi-agent form of ``sensorgym/StereoPointing-v0`` (same core,
    :mod:`sensorgym.envs.stereo_pointing.simulation`): one agent per gimballed receiver; the tracker,
    its estimates and the reward are shared.

    ## Agents

    ``"receiver_0"`` … ``"receiver_{n-1}"``, all acting at once.

    ## Action Space (per agent)

    ``Box(-1, 1, (2,), float32)``: the receiver's slew in azimuth and elevation, scaled by
    ``slew_rate · dt``; clipped; NaN raises.

    ## Observation Space (per agent)

    ``Box(-10, 10, (obs_dim + n,), float32)``: the single env's observation (every receiver's
    pointing and view of every drone, the tracker's predictions; see
    :func:`~sensorgym.envs.stereo_pointing.simulation.observe`), followed by a one-hot of the agent's
    own index, so that one shared policy knows which receiver it drives.

    ## Rewards

    One team reward, given to every agent: the mean over drones of
    ``clip(ln(σ_ref/σ_pos), −R, R)`` (the single env's reward).

    ## Episode End

    Never terminated; truncated after ``max_episode_steps`` steps, for all agents together.

    ## Arguments

    ``StereoPointingParallelEnv(params=PointingParams(...), max_episode_steps=150)``.

    ## Version History

    * v0: initial version.
    """

    metadata: ClassVar[dict[str, Any]] = {"name": "stereo_pointing_v0", "render_modes": []}

    def __init__(
        self,
        params: PointingParams | None = None,
        max_episode_steps: int = 150,
        render_mode: str | None = None,
    ):
        params = PointingParams() if params is None else params
        n = params.n_receivers
        super().__init__(
            StereoPointingCore(params),
            [f"receiver_{k}" for k in range(n)],
            spaces.Box(-OBS_CLIP, OBS_CLIP, (params.obs_dim + n,), np.float32),
            spaces.Box(-1.0, 1.0, (2,), np.float32),
            max_episode_steps,
            render_mode,
        )


def parallel_env(**kwargs: Any) -> StereoPointingParallelEnv:
    """PettingZoo's conventional constructor name; ``n_receivers=n`` sets the number of agents."""
    params = kwargs.pop("params", None) or PointingParams()
    fields = {f.name for f in dataclasses.fields(PointingParams)}
    overrides = {k: kwargs.pop(k) for k in list(kwargs) if k in fields}
    return StereoPointingParallelEnv(params=dataclasses.replace(params, **overrides), **kwargs)
