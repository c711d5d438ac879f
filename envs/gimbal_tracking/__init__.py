"""``sensorgym/GimbalTracking-v0``: keep a gimbal's narrow field of view on an air target.

:mod:`.simulation` (params, state and the contract's functions), :mod:`.kernels` (the compiled
step), :mod:`.reference` (its stages in readable numpy, what the kernels are checked against),
:mod:`.gimbal_tracking` (Gymnasium, native vector and PettingZoo envs) and
:mod:`.render`.
"""

from sensorgym.envs.gimbal_tracking.gimbal_tracking import (
    GimbalTrackingEnv,
    GimbalTrackingParallelEnv,
    GimbalTrackingVectorEnv,
    env,
    parallel_env,
    raw_env,
)
from sensorgym.envs.gimbal_tracking.simulation import GimbalParams, GimbalState

__all__ = [
    "GimbalParams",
    "GimbalState",
    "GimbalTrackingEnv",
    "GimbalTrackingParallelEnv",
    "GimbalTrackingVectorEnv",
    "env",
    "parallel_env",
    "raw_env",
]
