"""``sensorgym/GimbalTracking-v0``: the Gymnasium, native vector and PettingZoo envs.

Thin shells (:mod:`sensorgym.envs.shells`) over :mod:`.simulation`; the class docstring of
:class:`GimbalTrackingEnv` is the spec.
"""

from __future__ import annotations

from typing import Any, ClassVar

from sensorgym.envs.gimbal_tracking import simulation
from sensorgym.envs.gimbal_tracking.simulation import GimbalParams
from sensorgym.envs.shells import CoreEnv, CoreParallelEnv, CoreVectorEnv, aec_constructors
from sensorgym.envs.shells.rendering import RENDER_MODES

#: the module that draws the frames (:mod:`sensorgym.envs.shells.rendering`)
RENDERER = "sensorgym.envs.gimbal_tracking.render"
ENV_ID = "sensorgym/GimbalTracking-v0"


class GimbalTrackingEnv(CoreEnv):
    """Steer a two-axis gimbal on a rolling carrier so that its narrow field of view keeps an air
    target, through occlusions and channels that lose the target's image.

    ## Description

    An optical-mechanical gimbal (EO/IR turret, papers 001 and 004) on a ship: azimuth and
    elevation drives with rate and acceleration limits, a square field of view of
    ``field_of_view`` (1.5°), a carrier that rolls, pitches and yaws as sums of sinusoids with
    random phases (its attitude known to the tracker). An air target flies straight relative
    to the carrier at 4–8 km, with a level turn at a random time. Occlusions of random onset
    and length hide it; in each of the imaging channels (``channel_contrast``: a visible and an
    infrared channel by default, with different contrast and view statistics) its view follows
    paper 004's Markov chain (background, bright, dark: the target may not stand out in a band
    for a while).

    Every frame the tracker centres a tracking gate on paper 001's predicted direction; paper
    004's fused tracker (:class:`~sensorgym.trackers.fusion.tracker.FusionTracker`, one per
    image plane) measures the target's offset from it, weighting the channels' discriminators
    by their posterior detection probabilities and view transitions (theory §9.2); while it
    detects the target, the fused direction is the measurement of paper 001's angle predictor
    (:class:`~sensorgym.trackers.angles.prediction.ABCPredictor`, conditional trajectory and
    exponential smoothing, theory §8.3–8.6), which carries the track through a short loss. Once
    the target has gone undetected for ``search_after`` frames (25: 1 s) the gate searches at
    the boresight instead: re-acquisition takes pointing the field of view's centre at the
    target. The agent commands the drives; the optics lose contrast off axis (``vignetting``)
    and a target out of view is not seen at all.

    Several gimbals (``n_gimbals = G``, theory §11.8.2; a hand-over problem) share the carrier,
    the target and the one track: each has its own drives, channels and fused tracker and sees
    the target only inside its clear body-azimuth sector (``gimbal_sectors``; by default ``G``
    equal sectors overlapping by 5°), outside it the superstructure blocks its view. The track
    measures the fused direction of the detecting gimbal of least posterior variance; the
    target is in view while it is in some gimbal's. One gimbal (the default) sees the whole
    circle and is the env as it always was. Simulation core:
    :mod:`sensorgym.envs.gimbal_tracking.simulation` (its step compiled in :mod:`.kernels`,
    the stages readable in numpy in :mod:`.reference`).

    ## Action Space

    ``Box(-1, 1, (2G,), float32)`` (``(2,)`` for one gimbal); values outside ``[-1, 1]`` are
    clipped, NaN raises.

    | index  | action                                  | scaled to         | unit  |
    |--------|-----------------------------------------|-------------------|-------|
    | 2g     | gimbal g's azimuth drive rate command   | ``a · max_rate``  | rad/s |
    | 2g + 1 | gimbal g's elevation drive rate command | ``a · max_rate``  | rad/s |

    Each drive's rate moves towards its command by at most ``max_acceleration · T`` per frame
    (``T = frame_period``); elevation stops at ``elevation_limits``.

    ## Observation Space

    ``Box(-10, 10, (G · A,), float32)``: each gimbal's ``A`` entries in turn, ``A = 21 + N``
    for one gimbal (23 for two channels), ``26 + N`` for several; no ground truth (table in
    :func:`~sensorgym.envs.gimbal_tracking.simulation.observe`): the gimbal's angles and rates,
    the carrier's attitude and rates, where the track's estimate and its next-frame
    prediction lie relative to the gimbal's boresight (in half fields of view) and in the level
    frame, ``ln(σ_LOS/σ_ref)``, each of its channels' posterior detection probability, whether
    the target was detected this frame and the frames since it last was; with several gimbals
    also whether its clear sector holds the prediction, the sector's edges, its own detection
    and its own ``ln(σ/σ_ref)``.

    ## Rewards

    Per frame ``clip(ln(σ_ref/σ_LOS), −R, R)`` with ``σ_LOS = √(d_α + d_β + 2σ_s²)`` the angular
    error bound of the fused direction (``d`` paper 004's posterior variances in the two
    planes, ``σ_s`` the angle sensors' noise; with several gimbals the measuring gimbal's);
    ``−R`` while the target is outside every gimbal's view (field of view and clear sector).
    Defaults ``σ_ref = 1 mrad``, ``R = 5``.

    ## Starting State

    The tracker has locked on: its predictor has seen the ``N + 1`` frames before the episode.
    The target at a uniform range in ``start_range``, azimuth, elevation, speed, aspect (the
    angle between its path and the line of sight) and climb uniform in their params; each
    gimbal points at it within ``cue_error`` per axis (where its clear sector does not hold the
    target: at its elevation and the nearer edge of the sector), at rest; each channel sees an
    object view.

    ## Episode End

    * Termination: the target has been out of every gimbal's view for more than
      ``reacquire_limit`` frames (50: 2 s).
    * Truncation: the time limit, ``max_episode_steps`` in the registration (500 frames, 20 s).

    ## Arguments

    ``gym.make("sensorgym/GimbalTracking-v0", render_mode=None, **fields)`` — every setting is
    a field of :class:`~sensorgym.envs.gimbal_tracking.simulation.GimbalParams` (units in its
    docstrings), given as a keyword or as ``params=GimbalParams(...)``; the same keywords work
    for ``gym.make_vec`` and :func:`parallel_env`. ``render_mode="rgb_array"`` draws the field
    of view around the boresight (of the measuring gimbal): the target, the tracker's estimate
    and prediction.

    | argument          | default | meaning                                                   |
    |-------------------|---------|-----------------------------------------------------------|
    | ``n_gimbals``     | 1       | gimbals on the carrier, one agent each                    |
    | ``gimbal_sectors``| ``()``  | per gimbal its clear body-azimuth sector ``(low, high)``, |
    |                   |         | rad; empty: the whole circle for one gimbal, ``G`` equal  |
    |                   |         | sectors overlapping by 5° for more                        |

    (the other fields: channels, losses, carrier motion, tracker and reward, as documented
    in :class:`~sensorgym.envs.gimbal_tracking.simulation.GimbalParams`).

    ## Version History

    * v0: initial version (issue 40; CHANGELOG.md); ``n_gimbals`` added (the default one
      gimbal unchanged)
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": RENDER_MODES, "render_fps": 25}
    renderer = RENDERER
    simulation = simulation
    params_type = GimbalParams
    env_id = ENV_ID


class GimbalTrackingVectorEnv(CoreVectorEnv):
    """``num_envs`` independent :class:`GimbalTrackingEnv` scenarios in one batched call.

    Same spaces and rewards as the single env (its docstring is the spec); autoreset modes and
    ``agent_view`` as :class:`~sensorgym.envs.shells.CoreVectorEnv`.
    """

    simulation = simulation
    params_type = GimbalParams
    env_id = ENV_ID


class GimbalTrackingParallelEnv(CoreParallelEnv):
    """The gimbals as PettingZoo agents (PettingZoo Parallel).

    ## Description

    The multi-agent form of ``sensorgym/GimbalTracking-v0`` (same core,
    :mod:`sensorgym.envs.gimbal_tracking.simulation`): ``n_gimbals`` gimbals on one carrier
    share one target and one track, each clear over its own sector of body azimuth
    (``gimbal_sectors``), so that keeping the target takes handing it over between them
    (issue 40, theory §11.8.2).

    ## Agents

    ``"gimbal_0" … "gimbal_{G−1}"`` (one for the default ``n_gimbals = 1``).

    ## Action Space (per agent)

    ``Box(-1, 1, (2,), float32)``: the azimuth and elevation rate commands, scaled by
    ``max_rate``; clipped; NaN raises.

    ## Observation Space (per agent)

    ``Box(-10, 10, (A,), float32)``: the gimbal's block of the single env's observation,
    ``A = 21 + N`` for one gimbal, ``26 + N`` for several (own drives, the track seen from its
    boresight, its channels, its sector, its own detection and ``σ``).

    ## Rewards

    One team reward: ``clip(ln(σ_ref/σ_LOS), −R, R)``, ``−R`` out of every gimbal's view (the
    single env's).

    ## Episode End

    Terminated when the target has been out of every gimbal's view for more than
    ``reacquire_limit`` frames;
    truncated after ``max_episode_steps`` steps.

    ## Arguments

    ``parallel_env(**fields)``: the fields of
    :class:`~sensorgym.envs.gimbal_tracking.simulation.GimbalParams` as keywords (or
    ``params=``) and ``max_episode_steps`` (default: the registration's).

    ## Version History

    * v0: initial version (issue 40; CHANGELOG.md)
    """

    metadata: ClassVar[dict[str, Any]] = {
        "name": "gimbal_tracking_v0",
        "render_modes": RENDER_MODES,
        "render_fps": 25,
    }
    renderer = RENDERER
    simulation = simulation
    params_type = GimbalParams
    env_id = ENV_ID


def parallel_env(**kwargs: Any) -> GimbalTrackingParallelEnv:
    """PettingZoo's conventional constructor: :class:`GimbalTrackingParallelEnv` (``params``
    fields as keywords, and ``max_episode_steps``)."""
    return GimbalTrackingParallelEnv(**kwargs)


#: PettingZoo's AEC constructors: ``env`` (order-checked) and ``raw_env``
env, raw_env = aec_constructors(parallel_env)
