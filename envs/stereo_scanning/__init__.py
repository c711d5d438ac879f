"""``sensorgym/StereoScanning-v0``: steer scanning receivers' sectors so that paper 000's tracker
finds and locates close, moving, unlabelled drones.

:mod:`.simulation` (params, state and the contract's functions), :mod:`.kernels` (the compiled
period: rasters, fixes, candidates, association, reward), :mod:`.stereo_scanning` (Gymnasium, native vector
and PettingZoo envs) and :mod:`.render`.
"""

from sensorgym.envs.stereo_scanning.simulation import ScanningParams, ScanningState
from sensorgym.envs.stereo_scanning.stereo_scanning import (
    StereoScanningEnv,
    StereoScanningParallelEnv,
    StereoScanningVectorEnv,
    env,
    parallel_env,
    raw_env,
)

__all__ = [
    "ScanningParams",
    "ScanningState",
    "StereoScanningEnv",
    "StereoScanningParallelEnv",
    "StereoScanningVectorEnv",
    "env",
    "parallel_env",
    "raw_env",
]
