"""``sensorgym/StereoPointing-v0``: point narrow-field receivers so that stereo fixes locate drones.

:mod:`.simulation` (params, state and the contract's functions), :mod:`.env` (Gymnasium, native
vector and PettingZoo envs), :mod:`.bound` (a true upper bound on the reward, per step and per
episode, on the truth) and :mod:`.render`.
"""

from sensorgym.envs.stereo_pointing.bound import episode_bound, step_bound
from sensorgym.envs.stereo_pointing.env import (
    StereoPointingEnv,
    StereoPointingParallelEnv,
    StereoPointingVectorEnv,
    parallel_env,
)
from sensorgym.envs.stereo_pointing.simulation import PointingParams, PointingState

__all__ = [
    "PointingParams",
    "PointingState",
    "StereoPointingEnv",
    "StereoPointingParallelEnv",
    "StereoPointingVectorEnv",
    "episode_bound",
    "parallel_env",
    "step_bound",
]
