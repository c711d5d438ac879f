"""sensorgym's environments, each a package over one simulation, and the worlds they simulate.

Importing this package registers the environments with Gymnasium (``gym.make`` also imports it
itself when given ``"sensorgym.envs:ID"``). The registration below is the one place an episode
length is set; the vector and PettingZoo doors read it from there.

| id | package | PettingZoo constructors |
|----|---------|-------------------------|
| ``sensorgym/BearingsManeuver-v0`` | :mod:`.bearings_maneuver` | ``bearings_maneuver`` |
| ``sensorgym/BearingsManeuverBook-v0`` | :mod:`.bearings_maneuver.book` | ``bearings_maneuver.book`` |
| ``sensorgym/StereoPointing-v0`` | :mod:`.stereo_pointing` | ``stereo_pointing`` |
| ``sensorgym/StereoPointingCrowded-v0`` | :mod:`.stereo_pointing.crowded` | ``stereo_pointing.crowded`` |
| ``sensorgym/StereoPlacement-v0`` | :mod:`.stereo_placement` | ``stereo_placement`` |
| ``sensorgym/StereoScanning-v0`` | :mod:`.stereo_scanning` | ``stereo_scanning`` |
| ``sensorgym/GimbalTracking-v0`` | :mod:`.gimbal_tracking` | ``gimbal_tracking`` |

Each module of the last column has PettingZoo's three constructors: ``parallel_env`` (the
native parallel env), ``env`` (the AEC env, agents acting in turn) and ``raw_env`` (the AEC
env without PettingZoo's order checks), e.g. ``stereo_pointing.env(render_mode="rgb_array")``;
all take the params fields, ``max_episode_steps`` and ``render_mode`` as keywords.

:mod:`.shells` holds the contract every simulation follows and the shells over it;
:mod:`.worlds` the simulated worlds and sensors that are not envs (reproductions, benchmarks).
"""

from gymnasium.envs.registration import register, registry

_ENVS = [
    {
        "id": "sensorgym/BearingsManeuver-v0",
        "entry_point": "sensorgym.envs.bearings_maneuver.bearings_maneuver:BearingsManeuverEnv",
        "vector_entry_point": "sensorgym.envs.bearings_maneuver.bearings_maneuver:BearingsManeuverVectorEnv",
        "max_episode_steps": 30,
    },
    {
        "id": "sensorgym/BearingsManeuverBook-v0",
        "entry_point": "sensorgym.envs.bearings_maneuver.book:BearingsManeuverBookEnv",
        "vector_entry_point": "sensorgym.envs.bearings_maneuver.book:BearingsManeuverBookVectorEnv",
        "max_episode_steps": 32,
    },
    {
        "id": "sensorgym/StereoPointing-v0",
        "entry_point": "sensorgym.envs.stereo_pointing.stereo_pointing:StereoPointingEnv",
        "vector_entry_point": "sensorgym.envs.stereo_pointing.stereo_pointing:StereoPointingVectorEnv",
        "max_episode_steps": 150,
    },
    {
        "id": "sensorgym/StereoPointingCrowded-v0",
        "entry_point": "sensorgym.envs.stereo_pointing.crowded:StereoPointingCrowdedEnv",
        "vector_entry_point": (
            "sensorgym.envs.stereo_pointing.crowded:StereoPointingCrowdedVectorEnv"
        ),
        "max_episode_steps": 150,
    },
    {
        "id": "sensorgym/StereoPlacement-v0",
        "entry_point": "sensorgym.envs.stereo_placement.stereo_placement:StereoPlacementEnv",
        "vector_entry_point": "sensorgym.envs.stereo_placement.stereo_placement:StereoPlacementVectorEnv",
        "max_episode_steps": 60,
    },
    {
        "id": "sensorgym/StereoScanning-v0",
        "entry_point": "sensorgym.envs.stereo_scanning.stereo_scanning:StereoScanningEnv",
        "vector_entry_point": "sensorgym.envs.stereo_scanning.stereo_scanning:StereoScanningVectorEnv",
        "max_episode_steps": 40,
    },
    {
        "id": "sensorgym/GimbalTracking-v0",
        "entry_point": "sensorgym.envs.gimbal_tracking.gimbal_tracking:GimbalTrackingEnv",
        "vector_entry_point": "sensorgym.envs.gimbal_tracking.gimbal_tracking:GimbalTrackingVectorEnv",
        "max_episode_steps": 500,
    },
]

for _spec in _ENVS:
    if _spec["id"] not in registry:
        register(**_spec)

ENV_IDS = [spec["id"] for spec in _ENVS]

from sensorgym.envs import (  # noqa: E402
    bearings_maneuver,
    gimbal_tracking,
    stereo_placement,
    stereo_pointing,
    stereo_scanning,
)
from sensorgym.envs.bearings_maneuver import (  # noqa: E402  (registered first)
    BearingsManeuverEnv,
    BearingsManeuverParallelEnv,
    BearingsManeuverVectorEnv,
    ManeuverParams,
)
from sensorgym.envs.gimbal_tracking import (  # noqa: E402
    GimbalParams,
    GimbalTrackingEnv,
    GimbalTrackingParallelEnv,
    GimbalTrackingVectorEnv,
)
from sensorgym.envs.stereo_placement import (  # noqa: E402
    PlacementParams,
    StereoPlacementEnv,
    StereoPlacementParallelEnv,
    StereoPlacementVectorEnv,
)
from sensorgym.envs.stereo_pointing import (  # noqa: E402
    PointingParams,
    StereoPointingEnv,
    StereoPointingParallelEnv,
    StereoPointingVectorEnv,
)
from sensorgym.envs.stereo_scanning import (  # noqa: E402
    ScanningParams,
    StereoScanningEnv,
    StereoScanningParallelEnv,
    StereoScanningVectorEnv,
)

#: env id -> its PettingZoo factory (``parallel_env`` of the env's package; params fields and
#: ``max_episode_steps`` as keywords)
PARALLEL_ENVS = {
    "sensorgym/BearingsManeuver-v0": bearings_maneuver.parallel_env,
    "sensorgym/BearingsManeuverBook-v0": bearings_maneuver.book_parallel_env,
    "sensorgym/StereoPointing-v0": stereo_pointing.parallel_env,
    "sensorgym/StereoPointingCrowded-v0": stereo_pointing.crowded_parallel_env,
    "sensorgym/StereoPlacement-v0": stereo_placement.parallel_env,
    "sensorgym/StereoScanning-v0": stereo_scanning.parallel_env,
    "sensorgym/GimbalTracking-v0": gimbal_tracking.parallel_env,
}

__all__ = [
    "ENV_IDS",
    "PARALLEL_ENVS",
    "BearingsManeuverEnv",
    "BearingsManeuverParallelEnv",
    "BearingsManeuverVectorEnv",
    "GimbalParams",
    "GimbalTrackingEnv",
    "GimbalTrackingParallelEnv",
    "GimbalTrackingVectorEnv",
    "ManeuverParams",
    "PlacementParams",
    "PointingParams",
    "ScanningParams",
    "StereoPlacementEnv",
    "StereoPlacementParallelEnv",
    "StereoPlacementVectorEnv",
    "StereoPointingEnv",
    "StereoPointingParallelEnv",
    "StereoPointingVectorEnv",
    "StereoScanningEnv",
    "StereoScanningParallelEnv",
    "StereoScanningVectorEnv",
    "bearings_maneuver",
    "gimbal_tracking",
    "stereo_placement",
    "stereo_pointing",
    "stereo_scanning",
]
