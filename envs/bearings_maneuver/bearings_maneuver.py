"""``sensorgym/BearingsManeuver-v0``: the Gymnasium, native vector and PettingZoo envs.

Thin shells (:mod:`sensorgym.envs.shells`) over :mod:`.simulation`; the class docstring of
:class:`BearingsManeuverEnv` is the spec.
"""

from __future__ import annotations

from typing import Any, ClassVar

from sensorgym.envs.bearings_maneuver import simulation
from sensorgym.envs.bearings_maneuver.simulation import ManeuverParams
from sensorgym.envs.shells import CoreEnv, CoreParallelEnv, CoreVectorEnv, aec_constructors
from sensorgym.envs.shells.rendering import RENDER_MODES

#: the module that draws the frames (:mod:`sensorgym.envs.shells.rendering`)
RENDERER = "sensorgym.envs.bearings_maneuver.render"
ENV_ID = "sensorgym/BearingsManeuver-v0"


class BearingsManeuverEnv(CoreEnv):
    """Steer a platform so that bearings alone locate a moving target.

    ## Description

    A platform (ship, vehicle or drone, 2-D) detects a target that moves at constant velocity
    (or nearly so) and measures only its bearing, once per step, with noise ``σ``. Range is
    observable only when the platform manoeuvres (theory §7.6, §10.5 OC-5): the agent chooses turns
    and speed changes, a range-parameterised bank of second-order EKFs tracks the target from the bearings, and
    the reward is the shrinking of the Cramér–Rao bound on the target's position. Simulation
    core: :mod:`sensorgym.envs.bearings_maneuver.simulation`.

    ## Action Space

    ``Box(-1, 1, (2,), float32)``; values outside ``[-1, 1]`` are clipped, NaN raises.

    | index | action        | scaled to                                   | unit  |
    |-------|---------------|---------------------------------------------|-------|
    | 0     | turn          | heading rate ``a₀ · world.max_turn_rate``   | rad/s |
    | 1     | speed change  | ``a₁ · world.max_speed_change``, then the   | m/s   |
    |       |               | speed is clipped to the world's limits      |       |

    ## Observation Space

    ``Box(-10, 10, (13,), float32)``: the tracker's view, no ground truth (table in
    :func:`~sensorgym.envs.bearings_maneuver.simulation.observe_agents`): the last bearing relative to the
    heading (sin, cos), own speed, the estimated relative position and velocity in the
    platform frame, and the estimate's position and velocity uncertainty (for each, two log
    standard deviations along the platform's axes and their correlation, from the range bank's
    mixture covariance).

    | index  | observation                                            | scale           |
    |--------|--------------------------------------------------------|-----------------|
    | 0, 1   | sin, cos of the last bearing relative to the heading   | —               |
    | 2      | own speed                                              | ``max_speed``   |
    | 3, 4   | estimated target position (starboard, ahead)           | ``range_scale`` |
    | 5, 6   | estimated relative velocity (starboard, ahead)         | ``speed_scale`` |
    | 7, 8   | ln of the position standard deviations (same axes)     | ``range_scale`` |
    | 9      | correlation of the two position errors                 | —               |
    | 10, 11 | ln of the velocity standard deviations (same axes)     | ``speed_scale`` |
    | 12     | correlation of the two velocity errors                 | —               |

    ## Rewards

    ``ln m_k − ln m_{k+1}``, with ``m`` the position RMS bound ``√(P_xx + P_yy)`` of the
    posterior CRLB along the true trajectory (or ``σ_r/r`` with ``metric="relative_range"``).
    An episode's return is ``ln(m_0/m_T)``: e.g. 3.0 means the manoeuvres cut the bound
    e³ ≈ 20 times. Ending too close to the target costs ``close_penalty``.

    ## Starting State

    Platform at the origin with a uniform random heading at ``initial_platform_speed``; target
    at a uniform range in ``initial_range`` and a uniform bearing, with a uniform course and
    speed in ``target_speed`` (the angles' ranges are ``initial_heading``, ``initial_bearing``
    and ``target_course``, the full circle by default). The tracker starts from the first bearing with a prior that
    matches these draws: range uniform over ``bank_ranges`` (default ``initial_range``),
    course uniform over the full circle, speed moments of ``target_speed`` (or
    ``prior_speed``).

    ## Episode End

    * Termination: the platform comes within ``min_range`` of the target.
    * Truncation: the time limit, ``max_episode_steps`` in the registration (30 steps of 60 s).

    ## Arguments

    ``gym.make("sensorgym/BearingsManeuver-v0", render_mode=None, **fields)`` — every setting is
    a field of :class:`~sensorgym.envs.bearings_maneuver.simulation.ManeuverParams` (units in
    its docstrings), given as a keyword or as ``params=ManeuverParams(...)``; the same
    keywords work for ``gym.make_vec`` and :func:`parallel_env`. With ``platforms=K > 1`` one
    agent steers all ``K`` platforms: the action is every platform's ``(turn, speed change)``
    in turn, ``(2K,)``, and the observation every platform's view in turn
    (``K · (13 + 2(K − 1))``); the PettingZoo env makes each platform an agent. ``render_mode="rgb_array"`` draws the tracks, the estimate and
    its 2σ ellipse.

    ## Version History

    * v0: initial version; reward and observation revised in place (issues 10, 13, 35; CHANGELOG.md)
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": RENDER_MODES, "render_fps": 4}
    renderer = RENDERER
    simulation = simulation
    params_type = ManeuverParams
    env_id = ENV_ID


class BearingsManeuverVectorEnv(CoreVectorEnv):
    """``num_envs`` independent :class:`BearingsManeuverEnv` scenarios in one batched call.

    Same spaces, rewards and episode ends as the single env (its docstring is the spec);
    autoreset modes and ``agent_view`` as :class:`~sensorgym.envs.shells.CoreVectorEnv`.
    """

    simulation = simulation
    params_type = ManeuverParams
    env_id = ENV_ID


class BearingsManeuverParallelEnv(CoreParallelEnv):
    """``K`` platforms cooperate to locate one target from bearings (PettingZoo Parallel API).

    ## Description

    The multi-platform case of ``sensorgym/BearingsManeuver-v0`` (same simulation,
    :mod:`sensorgym.envs.bearings_maneuver.simulation`, with ``params.platforms = K``): every platform
    takes a bearing each step, one tracker fuses them all, and the Cramér–Rao bound adds their
    information. Cross-bearings from separated platforms make range observable without any
    manoeuvre; the agents decide how to spread and turn so that the bearings cross well.

    ## Agents

    ``"platform_0"`` … ``"platform_{K-1}"``, all acting at once.

    ## Action Space (per agent)

    ``Box(-1, 1, (2,), float32)``: turn (``a₀ · world.max_turn_rate``) and speed change
    (``a₁ · world.max_speed_change``); clipped to ``[-1, 1]``; NaN raises.

    ## Observation Space (per agent)

    ``Box(-10, 10, (13 + 2(K−1),), float32)``: the agent's own view of the shared tracker
    estimate in its own frame, then the other platforms' positions relative to it
    (:func:`~sensorgym.envs.bearings_maneuver.simulation.observe`). :meth:`state` concatenates every
    agent's observation (a centralised critic's input; still no ground truth).

    ## Rewards

    One team reward, given to every agent: ``ln m_k − ln m_{k+1}`` of the position bound (or
    ``σ_r/r``); ``close_penalty`` when a platform comes within ``min_range``.

    ## Episode End

    All agents end together: terminated when any platform comes within ``min_range`` of the
    target; truncated after ``max_episode_steps`` steps.

    ## Arguments

    ``parallel_env(platforms=2, ...)``: the fields of
    :class:`~sensorgym.envs.bearings_maneuver.simulation.ManeuverParams` as keywords (or
    ``params=``); two platforms unless ``platforms`` or ``params`` say otherwise.
    ``max_episode_steps`` defaults to the registration's.

    ## Version History

    * v0: initial version; revised in place with :class:`BearingsManeuverEnv` (CHANGELOG.md)
    """

    metadata: ClassVar[dict[str, Any]] = {
        "name": "bearings_maneuver_v0",
        "render_modes": RENDER_MODES,
        "render_fps": 4,
    }
    renderer = RENDERER
    simulation = simulation
    params_type = ManeuverParams
    env_id = ENV_ID
    default_fields: ClassVar[dict[str, Any]] = {"platforms": 2}


def parallel_env(**kwargs: Any) -> BearingsManeuverParallelEnv:
    """PettingZoo's conventional constructor: :class:`BearingsManeuverParallelEnv` (``params``
    fields as keywords, e.g. ``platforms=K``, and ``max_episode_steps``)."""
    return BearingsManeuverParallelEnv(**kwargs)


#: PettingZoo's AEC constructors: ``env`` (order-checked) and ``raw_env``
env, raw_env = aec_constructors(parallel_env)
