"""``sensorgym/StereoPlacement-v0``: drive receiver vehicles so that scanned fixes locate a drone.

:mod:`.simulation` (params, state and the contract's functions), :mod:`.scan` (one scan period
and its velocity-aware conjugation fix), :mod:`.stereo_placement` (Gymnasium, native vector and PettingZoo
envs), :mod:`.bound` (a true upper bound on the reward, per step and per episode) and
:mod:`.render`.
"""

from sensorgym.envs.stereo_placement.bound import episode_bound, step_bound
from sensorgym.envs.stereo_placement.simulation import PlacementParams, PlacementState
from sensorgym.envs.stereo_placement.stereo_placement import (
    StereoPlacementEnv,
    StereoPlacementParallelEnv,
    StereoPlacementVectorEnv,
    env,
    parallel_env,
    raw_env,
)

__all__ = [
    "PlacementParams",
    "PlacementState",
    "StereoPlacementEnv",
    "StereoPlacementParallelEnv",
    "StereoPlacementVectorEnv",
    "env",
    "episode_bound",
    "parallel_env",
    "raw_env",
    "step_bound",
]
