"""``sensorgym/StereoPlacement-v0``: the Gymnasium, native vector and PettingZoo envs.

Thin shells (:mod:`sensorgym.envs.shells`) over :mod:`.simulation`; the class docstring of
:class:`StereoPlacementEnv` is the spec.
"""

from __future__ import annotations

from typing import Any, ClassVar

from sensorgym.envs.shells import CoreEnv, CoreParallelEnv, CoreVectorEnv, aec_constructors
from sensorgym.envs.shells.rendering import RENDER_MODES
from sensorgym.envs.stereo_placement import simulation
from sensorgym.envs.stereo_placement.simulation import PlacementParams

#: the module that draws the frames (:mod:`sensorgym.envs.shells.rendering`)
RENDERER = "sensorgym.envs.stereo_placement.render"
ENV_ID = "sensorgym/StereoPlacement-v0"


class StereoPlacementEnv(CoreEnv):
    """Drive ground receivers so that their scanned fixes locate a flying drone accurately.

    ## Description

    ``n`` passive receivers (``n_receivers``: 3 registered, any n ≥ 3) ride ground vehicles
    (speed limit ``max_speed``) inside a permitted disc of radius ``arena_radius``. They start clustered within ``cluster_radius``
    of the origin — the layout theory §10.3 OC-3 calls unsatisfactory (baseline small against the
    range). One drone flies a straight level line. Each step is one scan period ``τ``: receiver
    ``k`` fixes the drone at its own delay ``d_k`` (theory §6.4, §10.4 OC-4) with angular noise
    ``σ_ang``, in its own frame (looking at the predicted drone), and the velocity-aware
    conjugation tracker (theory §3.5: the n = 3 closed form, compiled normal equations for more
    receivers) solves the period for the ranges, the position and the velocity. The agent drives the receivers; it is rewarded for the accuracy
    their geometry allows: best with near-orthogonal lines of sight (OC-1) from receivers
    spread around the drone (OC-3). Simulation core: :mod:`sensorgym.envs.stereo_placement.simulation`.

    ## Action Space

    ``Box(-1, 1, (2n,), float32)``; values outside ``[-1, 1]`` are clipped, NaN raises.

    | index  | action                      | scaled to                                  | unit |
    |--------|-----------------------------|--------------------------------------------|------|
    | 2k     | receiver k velocity, world X | ``a · max_speed``                         | m/s  |
    | 2k + 1 | receiver k velocity, world Z | ``a · max_speed``                         | m/s  |

    The speed ``‖(v_x, v_z)‖`` is capped at ``max_speed``; a receiver driving out of the
    permitted disc is held on its edge.

    ## Observation Space

    ``Box(-10, 10, (5n + 9 + n(n−1)/2,), float32)`` (27 for n = 3): own positions, and the
    tracker's output only, no ground truth (table in
    :func:`~sensorgym.envs.stereo_placement.simulation.observe`): the receivers relative to the
    estimated drone ground point, the estimated position and velocity, the log range σ's of
    ``σ_e² (AᵀA)⁻¹``, the log velocity σ, ``log10 κ_F``, the angles between the lines of sight
    to the estimate, and whether the last solve was degenerate.

    ## Rewards

    ``clip(ln(σ_ref / σ_pos), −R, R)`` per step with ``σ_pos = √tr I⁻¹``,
    ``I = Σ_k (I − u_k u_kᵀ)/(σ_ang² r_k²)`` the angle-noise Cramér–Rao bound of the true
    geometry at the fix times (:mod:`sensorgym.trackers.stereo.information`; no noise draw in it, so the reward scores
    the placement, not the luck of the period). A degenerate conjugation — the tracker's solve
    took the pseudo-inverse fallback, or the noise-free solve of the true geometry would
    (coplanar lines of sight, equal delays) — or singular information gives ``−R``.
    Defaults ``σ_ref = 1 m``, ``R = 5``: +2.3 per step is a 10 cm bound.

    ## Starting State

    Receivers uniform in the disc of radius ``cluster_radius``; the drone at a uniform
    horizontal distance in ``start_distance`` from the origin, uniform bearing, height in
    ``start_altitude``, speed in ``drone_speed``, uniform heading. The tracker starts from a
    cue (truth plus ``cue_sigma`` errors) and its first fix is one period of the receivers
    standing still.

    ## Episode End

    * Termination: never (a drone flying away is still tracked, ever less accurately).
    * Truncation: the time limit, ``max_episode_steps`` in the registration (60 periods of 1 s).

    ## Arguments

    ``gym.make("sensorgym/StereoPlacement-v0", render_mode=None, **fields)`` — every setting is
    a field of :class:`~sensorgym.envs.stereo_placement.simulation.PlacementParams` (units in
    its docstrings), given as a keyword or as ``params=PlacementParams(...)``; the same keywords
    work for ``gym.make_vec`` and :func:`parallel_env`. ``render_mode="rgb_array"`` draws a top view: the permitted
    disc, the receivers' tracks and lines of sight, the drone's track and the estimate.

    ## Version History

    * v0: initial version; step compiled, ``n_receivers`` added in place (issues 11, 15; CHANGELOG.md)
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": RENDER_MODES, "render_fps": 4}
    renderer = RENDERER
    simulation = simulation
    params_type = PlacementParams
    env_id = ENV_ID


class StereoPlacementVectorEnv(CoreVectorEnv):
    """``num_envs`` independent :class:`StereoPlacementEnv` scenarios in one batched call.

    Same spaces and rewards as the single env (its docstring is the spec); autoreset modes and
    ``agent_view`` as :class:`~sensorgym.envs.shells.CoreVectorEnv`.
    """

    simulation = simulation
    params_type = PlacementParams
    env_id = ENV_ID


class StereoPlacementParallelEnv(CoreParallelEnv):
    """``n`` receiver vehicles each drive themselves to fix one drone (PettingZoo Parallel).

    ## Description

    The multi-agent form of ``sensorgym/StereoPlacement-v0`` (same core,
    :mod:`sensorgym.envs.stereo_placement.simulation`): one agent per receiver vehicle; the
    conjugation tracker, its estimate and the reward are shared.

    ## Agents

    ``"receiver_0"`` … ``"receiver_{n-1}"``, all acting at once.

    ## Action Space (per agent)

    ``Box(-1, 1, (2,), float32)``: the vehicle's velocity along world X and Z, scaled by
    ``max_speed`` (speed capped at it); clipped; NaN raises.

    ## Observation Space (per agent)

    ``Box(-10, 10, (obs_dim + n,), float32)``: the single env's observation (every receiver's
    position and the tracker's output, see
    :func:`~sensorgym.envs.stereo_placement.simulation.observe`), followed by a one-hot of the agent's
    own index, so that one shared policy knows which receiver it drives.

    ## Rewards

    One team reward, given to every agent: ``clip(ln(σ_ref/σ_pos), −R, R)`` (the single env's).

    ## Episode End

    Never terminated; truncated after ``max_episode_steps`` steps, for all agents together.

    ## Arguments

    ``parallel_env(**fields)``: the fields of
    :class:`~sensorgym.envs.stereo_placement.simulation.PlacementParams` as keywords (or
    ``params=``) and ``max_episode_steps`` (default: the registration's).

    ## Version History

    * v0: initial version; revised in place with :class:`StereoPlacementEnv` (CHANGELOG.md)
    """

    metadata: ClassVar[dict[str, Any]] = {
        "name": "stereo_placement_v0",
        "render_modes": RENDER_MODES,
        "render_fps": 4,
    }
    renderer = RENDERER
    simulation = simulation
    params_type = PlacementParams
    env_id = ENV_ID


def parallel_env(**kwargs: Any) -> StereoPlacementParallelEnv:
    """PettingZoo's conventional constructor: :class:`StereoPlacementParallelEnv` (``params``
    fields as keywords, and ``max_episode_steps``)."""
    return StereoPlacementParallelEnv(**kwargs)


#: PettingZoo's AEC constructors: ``env`` (order-checked) and ``raw_env``
env, raw_env = aec_constructors(parallel_env)
