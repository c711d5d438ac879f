"""``sensorgym/StereoPointing-v0``: the Gymnasium, native vector and PettingZoo envs.

Thin shells (:mod:`sensorgym.envs.shells`) over :mod:`.simulation`; the class docstring of
:class:`StereoPointingEnv` is the spec.
"""

from __future__ import annotations

from typing import Any, ClassVar

from sensorgym.envs.shells import CoreEnv, CoreParallelEnv, CoreVectorEnv, aec_constructors
from sensorgym.envs.shells.rendering import RENDER_MODES
from sensorgym.envs.stereo_pointing import simulation
from sensorgym.envs.stereo_pointing.simulation import PointingParams

#: the module that draws the frames (:mod:`sensorgym.envs.shells.rendering`)
RENDERER = "sensorgym.envs.stereo_pointing.render"
ENV_ID = "sensorgym/StereoPointing-v0"


class StereoPointingEnv(CoreEnv):
    """Point narrow-field receivers so that their stereo fixes locate several drones.

    ## Description

    ``n`` gimballed passive receivers stand on a circle of radius ``circle_radius`` (theory §10.3
    OC-3); each sees only what lies inside its narrow cone (half-angle ``fov``) and measures
    the direction to it with angular noise ``σ_ang``. ``m`` drones fly straight lines through
    the surveillance volume. A drone seen by two or more receivers is triangulated and its
    constant-velocity Kalman filter updated; otherwise the filter only predicts. The agent
    slews the receivers; it is rewarded for the accuracy its current pointing gives: the
    Cramér–Rao bound of the receivers that see each drone, best with near-orthogonal lines of
    sight (theory §4.4, §10.1 OC-1). Simulation core: :mod:`sensorgym.envs.stereo_pointing.simulation`.

    ## Action Space

    ``Box(-1, 1, (2n,), float32)``; values outside ``[-1, 1]`` are clipped, NaN raises.

    | index   | action                 | scaled to                     | unit |
    |---------|------------------------|-------------------------------|------|
    | 2k      | receiver k azimuth slew   | ``a · slew_rate · dt``     | rad  |
    | 2k + 1  | receiver k elevation slew | ``a · slew_rate · dt``, the elevation held within ``±max_elevation`` | rad |

    ## Observation Space

    ``Box(-10, 10, (3n + 3nm + 8m,), float32)`` (52 with the defaults): own gimbal angles,
    and the tracker's view, no ground truth (table in
    :func:`~sensorgym.envs.stereo_pointing.simulation.observe`): per receiver and drone the
    predicted drone direction relative to the boresight in field-of-view half-angles and
    whether the receiver saw it; per drone the predicted position and its log RMS error, the
    estimated velocity and its log RMS error.

    For training, :class:`~sensorgym.train.env_wrappers.stereo_pointing.AssignmentAction` (SB3
    wrapper ``pointing-assignment``) replaces the gimbal rates by an assignment,
    ``MultiDiscrete([m] * n)``: which drone each receiver watches, slewed onto by the env's
    slew controller (:func:`~sensorgym.envs.stereo_pointing.simulation.slew_actions`, the one
    the assignment rules use). Scenarios and rewards stay the env's.

    ## Rewards

    Mean over drones of ``clip(ln(σ_ref / σ_pos), −R, R)``, with ``σ_pos = √tr I⁻¹`` and
    ``I = Σ_k (I − u_k u_kᵀ)/(σ_ang² r_k²)`` over the receivers that see the drone now
    (:mod:`sensorgym.trackers.stereo.information`, true geometry). A drone seen by fewer than two receivers gives ``−R``.
    Defaults ``σ_ref = 1 m``, ``R = 5``: +2.3 per step is a 10 cm fix.

    ## Starting State

    Drones start at a uniform horizontal distance in ``start_distance`` from the circle centre,
    uniform bearing, height in ``start_altitude``, heading uniform, speed in ``drone_speed``,
    vertical speed in ``climb_rate``. Gimbals point at uniform azimuths and elevations in
    ``initial_elevation``. The tracker starts from an external cue: the truth plus Gaussian
    errors ``cue_sigma`` (position m, velocity m/s).

    Degenerate settings are refused or given finite fallbacks (the module docstring of
    :mod:`~sensorgym.envs.stereo_pointing.simulation` lists them): two receivers at one place
    raise ``ValueError`` (``receiver_angles_deg``); a fix behind or on a receiver is not
    trusted; a drone on a receiver is not seen by it; exact fixes with no process noise are
    taken as they are.

    ## Episode End

    * Termination: never (a drone leaving the volume is still tracked, if it can be).
    * Truncation: the time limit, ``max_episode_steps`` in the registration (150 steps of
      0.2 s).

    ## Arguments

    ``gym.make("sensorgym/StereoPointing-v0", render_mode=None, **fields)`` — every setting is a
    field of :class:`~sensorgym.envs.stereo_pointing.simulation.PointingParams` (units in its
    docstrings), given as a keyword (``n_drones=3``) or as ``params=PointingParams(...)``; the
    same keywords work for ``gym.make_vec`` and :func:`parallel_env`. ``render_mode="rgb_array"`` draws a top view: receivers and
    their field-of-view wedges, drone tracks and the estimates.

    ## Version History

    * v0: initial version; fallbacks and observation revised in place (issues 10, 13; CHANGELOG.md)
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": RENDER_MODES, "render_fps": 5}
    renderer = RENDERER
    simulation = simulation
    params_type = PointingParams
    env_id = ENV_ID


class StereoPointingVectorEnv(CoreVectorEnv):
    """``num_envs`` independent :class:`StereoPointingEnv` scenarios in one batched call.

    Same spaces and rewards as the single env (its docstring is the spec); autoreset modes and
    ``agent_view`` as :class:`~sensorgym.envs.shells.CoreVectorEnv`.
    """

    simulation = simulation
    params_type = PointingParams
    env_id = ENV_ID


class StereoPointingParallelEnv(CoreParallelEnv):
    """``n`` receivers each slew their own gimbal to fix several drones (PettingZoo Parallel).

    ## Description

    The multi-agent form of ``sensorgym/StereoPointing-v0`` (same core,
    :mod:`sensorgym.envs.stereo_pointing.simulation`): one agent per gimballed receiver; the tracker,
    its estimates and the reward are shared.

    ## Agents

    ``"receiver_0"`` … ``"receiver_{n-1}"``, all acting at once.

    ## Action Space (per agent)

    ``Box(-1, 1, (2,), float32)``: the receiver's slew in azimuth and elevation, scaled by
    ``slew_rate · dt``; clipped; NaN raises.

    ## Observation Space (per agent)

    ``Box(-10, 10, (obs_dim + n,), float32)``: the single env's observation (every receiver's
    pointing and view of every drone, the tracker's predictions; see
    :func:`~sensorgym.envs.stereo_pointing.simulation.observe`), followed by a one-hot of the agent's
    own index, so that one shared policy knows which receiver it drives.

    ## Rewards

    One team reward, given to every agent: the mean over drones of
    ``clip(ln(σ_ref/σ_pos), −R, R)`` (the single env's reward).

    ## Episode End

    Never terminated; truncated after ``max_episode_steps`` steps, for all agents together.

    ## Arguments

    ``parallel_env(**fields)``: the fields of
    :class:`~sensorgym.envs.stereo_pointing.simulation.PointingParams` as keywords (or
    ``params=``) and ``max_episode_steps`` (default: the registration's).

    ## Version History

    * v0: initial version; revised in place with :class:`StereoPointingEnv` (CHANGELOG.md)
    """

    metadata: ClassVar[dict[str, Any]] = {
        "name": "stereo_pointing_v0",
        "render_modes": RENDER_MODES,
        "render_fps": 5,
    }
    renderer = RENDERER
    simulation = simulation
    params_type = PointingParams
    env_id = ENV_ID


def parallel_env(**kwargs: Any) -> StereoPointingParallelEnv:
    """PettingZoo's conventional constructor: :class:`StereoPointingParallelEnv` (``params``
    fields as keywords, e.g. ``n_receivers=n``, and ``max_episode_steps``)."""
    return StereoPointingParallelEnv(**kwargs)


#: PettingZoo's AEC constructors: ``env`` (order-checked) and ``raw_env``
env, raw_env = aec_constructors(parallel_env)
