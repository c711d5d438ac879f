"""``sensorgym/StereoPointingCrowded-v0``: more drones than receiver pairs, a scheduling problem.

StereoPointing with three drones for its four receivers as the default parameters
(:class:`CrowdedPointingParams`): the same simulation (:mod:`.simulation`), kernels, tracker and
reward, only ``n_drones`` differs. A fix takes two receivers, so four receivers fix at most two
drones at a time, and only when each of the two looks at a different drone: with three drones
at least one is unfixed at every step (it scores ``−R``, unless one receiver holds two drones in
its field of view), and its track only predicts. The agent has to schedule its receivers:
which drones to fix now, which track to let drift, and when to go back to it before it is lost
to the narrow fields of view.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

from sensorgym.envs.shells import aec_constructors
from sensorgym.envs.stereo_pointing.simulation import PointingParams
from sensorgym.envs.stereo_pointing.stereo_pointing import (
    StereoPointingEnv,
    StereoPointingParallelEnv,
    StereoPointingVectorEnv,
)

CROWDED_ENV_ID = "sensorgym/StereoPointingCrowded-v0"


@dataclass(frozen=True)
class CrowdedPointingParams(PointingParams):
    """:class:`~.simulation.PointingParams` with three drones for the four receivers (every
    field keeps its meaning; only the default of ``n_drones`` differs)."""

    n_drones: int = 3
    """Number of drones ``m``: three, more than the two pairs four receivers make."""


class StereoPointingCrowdedEnv(StereoPointingEnv):
    """Point four narrow-field receivers at three drones: fewer than two receivers per drone.

    ## Description

    :class:`~sensorgym.envs.stereo_pointing.stereo_pointing.StereoPointingEnv` (its docstring is the spec)
    with :class:`CrowdedPointingParams`: ``n = 4`` receivers on the circle, ``m = 3`` drones.
    A drone is fixed only while two receivers see it, so at most two of the three are fixed at
    any step unless a receiver holds two drones in its field of view at once; the others'
    tracks predict and their reward is ``−R``. Good play is a schedule: which pairs watch which
    drones, and when to hand a receiver over to the drifting track before the narrow field of
    view can no longer find it.

    ## Action Space

    ``Box(-1, 1, (8,), float32)``; values outside ``[-1, 1]`` are clipped, NaN raises.

    | index   | action                    | scaled to              | unit |
    |---------|---------------------------|------------------------|------|
    | 2k      | receiver k azimuth slew   | ``a · slew_rate · dt`` | rad  |
    | 2k + 1  | receiver k elevation slew | ``a · slew_rate · dt``, the elevation held within ``±max_elevation`` | rad |

    ## Observation Space

    ``Box(-10, 10, (72,), float32)`` (``3n + 3nm + 8m`` with ``n = 4``, ``m = 3``), the table of
    :func:`~sensorgym.envs.stereo_pointing.simulation.observe`:

    | entries | what                                                                  |
    |---------|-----------------------------------------------------------------------|
    | 12      | per receiver: ``sin α_k``, ``cos α_k``, ``ε_k / (π/2)``               |
    | 36      | per receiver and drone: predicted direction off the boresight in field-of-view half-angles, and whether it saw the drone |
    | 24      | per drone: predicted position and its log RMS error, estimated velocity and its log RMS error |

    ## Rewards

    Mean over the three drones of ``clip(ln(σ_ref / σ_pos), −R, R)`` (the Cramér–Rao bound of
    the receivers that see the drone now, true geometry); a drone seen by fewer than two
    receivers gives ``−R``. Defaults ``σ_ref = 1 m``, ``R = 5``.

    ## Starting State

    As StereoPointing: drones at a uniform horizontal distance in ``start_distance``, heights
    in ``start_altitude``, headings uniform; receiver ``k`` starts on drone ``k mod 3``'s cued
    position (``cued_start``), so drone 0 starts with a pair and drones 1 and 2 with one
    receiver each; the tracker starts from the cue (truth plus ``cue_sigma`` errors).

    ## Episode End

    * Termination: never.
    * Truncation: the time limit, ``max_episode_steps`` in the registration (150 steps of
      0.2 s, as StereoPointing).

    ## Arguments

    ``gym.make("sensorgym/StereoPointingCrowded-v0", render_mode=None, **fields)`` — every field
    of :class:`CrowdedPointingParams` as a keyword, or ``params=CrowdedPointingParams(...)``;
    the same keywords work for ``gym.make_vec`` and :func:`parallel_env`.

    ## Version History

    * v0: initial version (issue 37).
    """

    params_type = CrowdedPointingParams
    env_id = CROWDED_ENV_ID


class StereoPointingCrowdedVectorEnv(StereoPointingVectorEnv):
    """``num_envs`` :class:`StereoPointingCrowdedEnv` scenarios in one batched call."""

    params_type = CrowdedPointingParams
    env_id = CROWDED_ENV_ID


class StereoPointingCrowdedParallelEnv(StereoPointingParallelEnv):
    """The crowded scenario as a PettingZoo env: ``"receiver_0"`` … ``"receiver_3"`` share three
    drones (spaces as :class:`~sensorgym.envs.stereo_pointing.stereo_pointing.StereoPointingParallelEnv`,
    per-agent observation 72 + 4 entries).

    ## Version History

    * v0: initial version (issue 37).
    """

    metadata: ClassVar[dict[str, Any]] = {
        **StereoPointingParallelEnv.metadata,
        "name": "stereo_pointing_crowded_v0",
    }
    params_type = CrowdedPointingParams
    env_id = CROWDED_ENV_ID


def parallel_env(**kwargs: Any) -> StereoPointingCrowdedParallelEnv:
    """PettingZoo constructor of :class:`StereoPointingCrowdedParallelEnv` (``params`` fields as
    keywords and ``max_episode_steps``)."""
    return StereoPointingCrowdedParallelEnv(**kwargs)


#: PettingZoo's AEC constructors: ``env`` (order-checked) and ``raw_env``
env, raw_env = aec_constructors(parallel_env)
