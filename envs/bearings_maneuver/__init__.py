"""``sensorgym/BearingsManeuver-v0``: steer platforms so that bearings alone locate a target.

:mod:`.simulation` (params, state and the contract's functions), :mod:`.env` (Gymnasium, native
vector and PettingZoo envs) and :mod:`.render`.
"""

from sensorgym.envs.bearings_maneuver.env import (
    BearingsManeuverEnv,
    BearingsManeuverParallelEnv,
    BearingsManeuverVectorEnv,
    parallel_env,
)
from sensorgym.envs.bearings_maneuver.simulation import ManeuverParams, ManeuverState

__all__ = [
    "BearingsManeuverEnv",
    "BearingsManeuverParallelEnv",
    "BearingsManeuverVectorEnv",
    "ManeuverParams",
    "ManeuverState",
    "parallel_env",
]
