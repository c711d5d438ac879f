"""The shells every env shares: the simulation contract and its one adapter
(:mod:`.contract`), and the Gymnasium (:mod:`.gym_env`), native vector (:mod:`.vector_env`) and
PettingZoo (:mod:`.parallel_env`) envs over it. Nothing here knows receivers or platforms."""

from sensorgym.envs.shells.contract import (
    OBS_CLIP,
    Core,
    EnvSpaces,
    Simulation,
    tree_scatter,
    tree_where,
)
from sensorgym.envs.shells.gym_env import CoreEnv
from sensorgym.envs.shells.parallel_env import CoreParallelEnv, aec_constructors
from sensorgym.envs.shells.vector_env import CoreVectorEnv

__all__ = [
    "OBS_CLIP",
    "Core",
    "CoreEnv",
    "CoreParallelEnv",
    "CoreVectorEnv",
    "EnvSpaces",
    "Simulation",
    "aec_constructors",
    "tree_scatter",
    "tree_where",
]
