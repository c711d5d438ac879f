"""PettingZoo version of the receiver-placement env: every receiver vehicle is an agent."""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces

from sensorgym.envs.shells.parallel_env import CoreParallelEnv
from sensorgym.envs.stereo_placement.env import StereoPlacementCore
from sensorgym.envs.stereo_placement.simulation import OBS_CLIP, PlacementParams


class StereoPlacementParallelEnv(CoreParallelEnv):
    """``n`` receiver vehicles each drive themselves to fix one drone (PettingZoo Parallel).

    ## Description

    The multi-agent form of ``sensorgym/StereoPlacement-v0`` (same core,
    :mod:`sensorgym.envs.stereo_placement.simulation`): one agent per receiver vehicle; the
    conjugation tracker, its estimate and the reward are shared.

    ## Agents

    ``"receiver_0"`` … ``"receiver_{n-1}"``, all acting at once.

    ## Action Space (per agent)

    ``Box(-1, 1, (2,), float32)``: the vehicle's velocity along world X and Z, scaled by
    ``max_speed`` (speed capped at it); clipped; NaN raises.

    ## Observation Space (per agent)

    ``Box(-10, 10, (obs_dim + n,), float32)``: the single env's observation (every receiver's
    position and the tracker's output, see
    :func:`~sensorgym.envs.stereo_placement.simulation.observe`), followed by a one-hot of the agent's
    own index, so that one shared policy knows which receiver it drives.

    ## Rewards

    One team reward, given to every agent: ``clip(ln(σ_ref/σ_pos), −R, R)`` (the single env's).

    ## Episode End

    Never terminated; truncated after ``max_episode_steps`` steps, for all agents together.

    ## Arguments

    ``StereoPlacementParallelEnv(params=PlacementParams(...), max_episode_steps=60)``.

    ## Version History

    * v0: initial version.
    """

    metadata: ClassVar[dict[str, Any]] = {"name": "stereo_placement_v0", "render_modes": []}

    def __init__(
        self,
        params: PlacementParams | None = None,
        max_episode_steps: int = 60,
        render_mode: str | None = None,
    ):
        params = PlacementParams() if params is None else params
        n = params.n_receivers
        super().__init__(
            StereoPlacementCore(params),
            [f"receiver_{k}" for k in range(n)],
            spaces.Box(-OBS_CLIP, OBS_CLIP, (params.obs_dim + n,), np.float32),
            spaces.Box(-1.0, 1.0, (2,), np.float32),
            max_episode_steps,
            render_mode,
        )


def parallel_env(**kwargs: Any) -> StereoPlacementParallelEnv:
    """PettingZoo's conventional constructor name; ``PlacementParams`` fields as keywords."""
    params = kwargs.pop("params", None) or PlacementParams()
    fields = {f.name for f in dataclasses.fields(PlacementParams)}
    overrides = {k: kwargs.pop(k) for k in list(kwargs) if k in fields}
    return StereoPlacementParallelEnv(params=dataclasses.replace(params, **overrides), **kwargs)
