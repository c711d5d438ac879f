"""``sensorgym/BearingsManeuver-v0``: steer platforms so that bearings alone locate a target.

:mod:`.simulation` (params, state and the contract's functions), :mod:`.bearings_maneuver` (Gymnasium, native
vector and PettingZoo envs), :mod:`.render`, :mod:`.book` (the textbook scenario,
``sensorgym/BearingsManeuverBook-v0``) and :mod:`.bound` (the hindsight optimum: the
per-episode bound on the return).
"""

from sensorgym.envs.bearings_maneuver.bearings_maneuver import (
    BearingsManeuverEnv,
    BearingsManeuverParallelEnv,
    BearingsManeuverVectorEnv,
    env,
    parallel_env,
    raw_env,
)
from sensorgym.envs.bearings_maneuver.book import (
    BearingsManeuverBookEnv,
    BearingsManeuverBookParallelEnv,
    BearingsManeuverBookVectorEnv,
    BookManeuverParams,
)
from sensorgym.envs.bearings_maneuver.book import parallel_env as book_parallel_env
from sensorgym.envs.bearings_maneuver.simulation import ManeuverParams, ManeuverState

__all__ = [
    "BearingsManeuverBookEnv",
    "BearingsManeuverBookParallelEnv",
    "BearingsManeuverBookVectorEnv",
    "BearingsManeuverEnv",
    "BearingsManeuverParallelEnv",
    "BearingsManeuverVectorEnv",
    "BookManeuverParams",
    "ManeuverParams",
    "ManeuverState",
    "book_parallel_env",
    "env",
    "parallel_env",
    "raw_env",
]
