"""``sensorgym/StereoPointing-v0``: point narrow-field receivers so that stereo fixes locate drones.

:mod:`.simulation` (params, state and the contract's functions), :mod:`.stereo_pointing` (Gymnasium, native
vector and PettingZoo envs), :mod:`.bound` (a true upper bound on the reward, per step and per
episode, on the truth), :mod:`.render` and :mod:`.crowded` (three drones for four receivers,
``sensorgym/StereoPointingCrowded-v0``).
"""

from sensorgym.envs.stereo_pointing.bound import episode_bound, step_bound
from sensorgym.envs.stereo_pointing.crowded import (
    CrowdedPointingParams,
    StereoPointingCrowdedEnv,
    StereoPointingCrowdedParallelEnv,
    StereoPointingCrowdedVectorEnv,
)
from sensorgym.envs.stereo_pointing.crowded import parallel_env as crowded_parallel_env
from sensorgym.envs.stereo_pointing.simulation import PointingParams, PointingState
from sensorgym.envs.stereo_pointing.stereo_pointing import (
    StereoPointingEnv,
    StereoPointingParallelEnv,
    StereoPointingVectorEnv,
    env,
    parallel_env,
    raw_env,
)

__all__ = [
    "CrowdedPointingParams",
    "PointingParams",
    "PointingState",
    "StereoPointingCrowdedEnv",
    "StereoPointingCrowdedParallelEnv",
    "StereoPointingCrowdedVectorEnv",
    "StereoPointingEnv",
    "StereoPointingParallelEnv",
    "StereoPointingVectorEnv",
    "crowded_parallel_env",
    "env",
    "episode_bound",
    "parallel_env",
    "raw_env",
    "step_bound",
]
