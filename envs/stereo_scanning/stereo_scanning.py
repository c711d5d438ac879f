"""``sensorgym/StereoScanning-v0``: the Gymnasium, native vector and PettingZoo envs.

Thin shells (:mod:`sensorgym.envs.shells`) over :mod:`.simulation`; the class docstring of
:class:`StereoScanningEnv` is the spec.
"""

from __future__ import annotations

from typing import Any, ClassVar

from sensorgym.envs.shells import CoreEnv, CoreParallelEnv, CoreVectorEnv, aec_constructors
from sensorgym.envs.shells.rendering import RENDER_MODES
from sensorgym.envs.stereo_scanning import simulation
from sensorgym.envs.stereo_scanning.simulation import ScanningParams

#: the module that draws the frames (:mod:`sensorgym.envs.shells.rendering`)
RENDERER = "sensorgym.envs.stereo_scanning.render"
ENV_ID = "sensorgym/StereoScanning-v0"


class StereoScanningEnv(CoreEnv):
    """Choose where and how wide scanning receivers look, so that paper 000's velocity-aware
    tracker finds every close, moving, unlabelled drone and locates it accurately.

    ## Description

    ``n = n_receivers`` passive receivers (3) stand on a circle (radius ``circle_radius`` =
    120 m, azimuths 0°, 90°, 270°: paper 000's arc, orthogonal lines of sight possible), each
    with a fixed frame looking at the scene centre ``(0, aim_height, 0)``. ``m = n_drones`` (4) drones fly straight,
    gently accelerating paths over the scene: one (``close_drones``) a few metres from another
    on a near-parallel path, one (``late_drones``) entering later; a drone that leaves the scene
    box is gone for good. One step is one scan period ``τ`` (1 s). Each receiver sweeps a TV
    raster of ``L × L`` pixels (100 × 100) over the sector the action chose, in ``sweep_time``
    (0.5 s) starting ``scan_offsets[k]`` (0, 0.25, 0.5 s; evenly over ``[0, 0.5]`` s for other
    ``n``, receivers 1–3 at its start, middle and end) into the period; a drone inside the
    sector is fixed when the raster reaches its pixel (theory §6.3), so each receiver's direction
    carries its own time and the delays between receivers come from the offsets, the geometry
    and the sectors, not from constants. False detections (``clutter_rate``) are optional.

    The agent sees the world only through the tracker of paper 000 (theory §5.3, compiled in
    :mod:`sensorgym.envs.stereo_scanning.kernels`): every triple of fixes of receivers 1–3 (one
    per receiver, pairs pre-gated) is solved by the velocity-aware conjugation (``n = 3`` closed
    form, theory §3.5) for position, velocity and their exact first-order covariance under
    the angle noise (the triple's ``σ_pos``, ``σ_vel``: theory §3.5, §11.6); with ``n > 3`` each
    receiver 4 … n then adds the fix whose line of sight passes nearest the triple's predicted
    position (gated by its covariance) and the candidate is re-solved by least squares over all
    its receivers (the normal equations of theory §3.3 with the ranges eliminated, the
    papers' ``σ_e² (AᵀA)⁻¹``) — ``O(F³ + C n F)`` per period for ``F`` fixes per receiver and ``C``
    gated triples, never a product over the receivers; implausible candidates (non-positive range, speed above
    ``max_speed``, ``κ_F > cond_max``) are dropped; confirmed tracks take the candidate with the
    smallest ``ΔJ = ‖M − (M̂ + V̂ Δ)‖`` within the gate ``δ`` whose velocity agrees with the
    track's (paper 003's velocity consistency; one-to-one, no shared direction vector);
    tentative tracks grow every passing continuation as a child, in ascending
    cumulative index, and are confirmed after ``confirm_hits`` periods (paper 000's groups run
    online); candidates sharing no vector with a continued track open tentative tracks; a
    confirmed track is dropped after more than ``max_misses`` periods without a candidate.
    With ``n > 3`` a triple is also dropped before receivers 4 … n are searched when its speed
    exceeds ``max_speed`` by more than ``q σ_vel``, during the search when its prediction lies
    inside the sectors of ``ghost_misses`` of them, by more than its uncertainty and motion,
    with no fix in its gate there (negative information), and after it when the joint fit
    fails its χ² test at ``fit_false_alarm`` (theory §5.3).
    ``tracker="alternative"`` selects paper 000's alternative instead (receivers 1–2, delays
    ignored, line fits, theory §5.2), ``tracker="algorithmic"`` paper 003's algorithmic
    detector (receivers 1–2; each pair re-solved with the track's motion, ``B̂_2 = b_2 − V Δt_2``,
    and scored by ``c_1 J_1 + c_2 J_2 + c_3 J_3``, theory §5.5, run online in the same table).
    Under the papers' full sweep each of the three tracks most of the present drones
    (``tests/envs/stereo_scanning/test_env.py``).

    ## Action Space

    ``Box(-1, 1, (3n,), float32)`` (9 for n = 3, 48 for n = 16); values outside ``[-1, 1]`` are
    clipped, NaN raises.

    | index  | action                               | scaled to                              | unit |
    |--------|--------------------------------------|----------------------------------------|------|
    | 3k     | receiver k sector centre, azimuth     | ``a · field_of_regard/2`` (±45°)       | rad  |
    | 3k + 1 | receiver k sector centre, elevation   | ``a · field_of_regard/2``              | rad  |
    | 3k + 2 | receiver k sector width ``w``         | ``w_min + (a + 1)/2 (w_max − w_min)`` (5°…90°) | rad |

    Angles are about the receiver's fixed boresight (its own frame, theory §2.2).

    *The sector trade-off.* The raster always has ``L × L`` pixels swept in ``sweep_time``, so a
    wider sector has coarser pixels: a fix from a sector of width ``w`` carries angular noise
    ``σ_k = max(κ w, σ_min)`` (``κ = noise_per_width`` = 1e-3: 1.6 mrad at 90°, 0.09 mrad at 5°).
    A wide sector finds every drone but locates it coarsely; a narrow one locates well what it
    covers and misses the rest (a drone must be in the sectors of receivers 1–3 in the same
    period to be fixed by a triple; other receivers only refine it).

    ## Observation Space

    ``Box(-10, 10, (11 · track_slots + 4n,), float32)`` (100 by default): the tracker's table of
    confirmed tracks (``track_slots`` = 8 rows of 11: validity mask, predicted position relative
    to the scene centre, velocity, ``ln σ_pos``, ``ln σ_vel τ``, staleness, age) and per receiver
    its last sector and fix count — never ground truth (table in
    :func:`~sensorgym.envs.stereo_scanning.simulation.observe`).

    ## Rewards

    Per step, the mean over the drones present in the period of

    | drone                              | reward                                         |
    |------------------------------------|------------------------------------------------|
    | has a confirmed track (nearest within ``truth_gate`` = 4 m at the period end, one-to-one) | ``clip(ln(σ_ref/σ_pos), −R, R)`` |
    | has none                           | ``−R``                                         |

    less ``false_track_penalty`` (0.5) per confirmed track assigned to no drone. ``σ_pos`` is the
    track's own covariance, ``σ_e √([(AᵀA)⁻¹]_11 + 2)`` of its latest candidate (the range error
    along receiver 1's line of sight and ``σ_e`` across it), grown by ``σ_vel Δ`` to the period
    end, with ``σ_e² = σ_x² + (1/n) Σ_k (σ_k r̂_k)²`` (theory §13.4). Defaults ``σ_ref = 1 m``,
    ``R = 5``. Unlike the other stereo envs the reward is the tracker's covariance, not a bound
    at the true geometry: the issue asks for the papers' covariance analysis, and a drone the
    tracker has not found earns ``−R`` whatever the geometry.

    ## Starting State

    Drones start uniformly within ``±start_spread`` (30 m) of the origin in X and Z at heights in
    ``start_altitude``, horizontal speed in ``drone_speed`` (2–8 m/s), uniform heading, climb in
    ``climb_rate``, acceleration up to ``max_acceleration``; the close drone ``close_spacing``
    (2–4 m) from drone 0 with its velocity ±10 %; the late drone enters at a period start in
    ``enter_window`` (5–20 s). The track table starts empty; the observation of a reset shows
    no tracks and zero sectors.

    ## Episode End

    * Termination: every drone has entered and left the scene.
    * Truncation: the time limit, ``max_episode_steps`` in the registration (40 periods).

    ## Arguments

    ``gym.make("sensorgym/StereoScanning-v0", render_mode=None, **fields)`` — every setting is a
    field of :class:`~sensorgym.envs.stereo_scanning.simulation.ScanningParams` (units in its
    docstrings), given as a keyword or as ``params=ScanningParams(...)`` (on the command line
    ``--param NAME=VALUE``); the same keywords work for ``gym.make_vec`` and
    :func:`parallel_env`. The sizes:

    | field               | default            | range        | meaning                                   |
    |---------------------|--------------------|--------------|-------------------------------------------|
    | ``n_receivers``     | 3                  | ≥ 3 (16 tested) | receivers (agents); 1–3 form the triples |
    | ``receiver_azimuths`` | 0°, 90°, 270°    | ``n`` values | ``None``: paper 000's arc for 3, else an even spread with receivers 1–3 a third of the circle apart |
    | ``scan_offsets``    | 0, 0.25, 0.5 s     | ``n`` values | ``None``: evenly over ``[0, 0.5]`` s, receivers 1–3 at 0, ≈0.25, 0.5 s |
    | ``n_drones``        | 4                  | ≥ 1 (10 tested) | drones ``m``                            |
    | ``track_slots``     | 8                  | ≥ 1          | confirmed tracks observed (raise with ``m``) |
    | ``track_capacity``  | 32                 | ≥ 1          | rows of the tracker's table               |

    The observation has ``11 · track_slots + 4n`` entries (152 at 16 receivers). ``render_mode="rgb_array"`` draws a top view
    and a side view: the receivers' sectors and raster sweep, the rays at their fix times, the
    true paths and the confirmed tracks with their covariance ellipses.

    ## Version History

    * v0: initial version (issue 12); tracker and reward revised in place (issues 15, 35; CHANGELOG.md)
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": RENDER_MODES, "render_fps": 4}
    renderer = RENDERER
    simulation = simulation
    params_type = ScanningParams
    env_id = ENV_ID


class StereoScanningVectorEnv(CoreVectorEnv):
    """``num_envs`` independent :class:`StereoScanningEnv` scenarios in one batched call.

    Same spaces and rewards as the single env (its docstring is the spec); autoreset modes and
    ``agent_view`` as :class:`~sensorgym.envs.shells.CoreVectorEnv`.
    """

    simulation = simulation
    params_type = ScanningParams
    env_id = ENV_ID


class StereoScanningParallelEnv(CoreParallelEnv):
    """Each scanning receiver chooses its own sector (PettingZoo Parallel).

    ## Description

    The multi-agent form of ``sensorgym/StereoScanning-v0`` (same core,
    :mod:`sensorgym.envs.stereo_scanning.simulation`): one agent per receiver; the tracker, its
    table and the reward are shared.

    ## Agents

    ``"receiver_0"`` … ``"receiver_{n-1}"``, all acting at once.

    ## Action Space (per agent)

    ``Box(-1, 1, (3,), float32)``: the receiver's sector centre (azimuth, elevation) and width,
    scaled as in the single env; clipped; NaN raises.

    ## Observation Space (per agent)

    ``Box(-10, 10, (obs_dim + n,), float32)``: the single env's observation followed by a
    one-hot of the agent's own index.

    ## Rewards

    One team reward, given to every agent (the single env's).

    ## Episode End

    Terminated when every drone has left; truncated after ``max_episode_steps`` steps, for all
    agents together.

    ## Arguments

    ``parallel_env(**fields)``: the fields of
    :class:`~sensorgym.envs.stereo_scanning.simulation.ScanningParams` as keywords (or
    ``params=``) and ``max_episode_steps`` (default: the registration's).

    ## Version History

    * v0: initial version (issue 12); revised with :class:`StereoScanningEnv` (CHANGELOG.md)
    """

    metadata: ClassVar[dict[str, Any]] = {
        "name": "stereo_scanning_v0",
        "render_modes": RENDER_MODES,
        "render_fps": 4,
    }
    renderer = RENDERER
    simulation = simulation
    params_type = ScanningParams
    env_id = ENV_ID


def parallel_env(**kwargs: Any) -> StereoScanningParallelEnv:
    """PettingZoo's conventional constructor: :class:`StereoScanningParallelEnv` (``params``
    fields as keywords, and ``max_episode_steps``)."""
    return StereoScanningParallelEnv(**kwargs)


#: PettingZoo's AEC constructors: ``env`` (order-checked) and ``raw_env``
env, raw_env = aec_constructors(parallel_env)
