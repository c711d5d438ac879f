"""Simulated worlds and the Gymnasium / PettingZoo environments built on them.

Importing this package registers the environments with Gymnasium (``gym.make`` also imports it
itself when given ``"sensorgym.envs:ID"``). Episode lengths live here, not in the envs.
"""

from gymnasium.envs.registration import register, registry

_ENVS = [
    {
        "id": "sensorgym/BearingsManeuver-v0",
        "entry_point": "sensorgym.envs.bearings_maneuver.env:BearingsManeuverEnv",
        "vector_entry_point": "sensorgym.envs.bearings_maneuver.env:BearingsManeuverVectorEnv",
        "max_episode_steps": 30,
    },
    {
        "id": "sensorgym/StereoPointing-v0",
        "entry_point": "sensorgym.envs.stereo_pointing.env:StereoPointingEnv",
        "vector_entry_point": "sensorgym.envs.stereo_pointing.env:StereoPointingVectorEnv",
        "max_episode_steps": 150,
    },
    {
        "id": "sensorgym/StereoPlacement-v0",
        "entry_point": "sensorgym.envs.stereo_placement.env:StereoPlacementEnv",
        "vector_entry_point": "sensorgym.envs.stereo_placement.env:StereoPlacementVectorEnv",
        "max_episode_steps": 60,
    },
]

for _spec in _ENVS:
    if _spec["id"] not in registry:
        register(**_spec)

ENV_IDS = [spec["id"] for spec in _ENVS]
