"""The readable reference of the GimbalTracking reset and step
(:mod:`sensorgym.envs.gimbal_tracking.reference`, numpy) against the compiled simulation the envs
run (:mod:`sensorgym.envs.gimbal_tracking.simulation`, its kernels).

Both are driven through :class:`~sensorgym.envs.shells.contract.Core`, with autoresets
(:meth:`Core.scatter`, fresh scenarios only where an episode ended: terminated, or truncated at
the registered ``max_episode_steps``), over whole episodes of a batch of 8 scenarios. Half of
the rows follow paper 001's servo (the rule ``Paper001Servo``) so that they keep the target in
the narrow field of view and run through detections, losses, occlusions and searches; the
other half add random rates (partly outside the box: the cores clip), which lose it and end
their episodes (``reacquire_limit``). Each step is taken three times with the same draws
(generators seeded alike and checked to stay in step):

* the simulation, on its own state;
* the reference from the simulation's state (one step of each from the same state), and
  every autoreset's fresh scenarios from the same draws (the compiled lock-on);
* the reference on its own state, from its own resets (whole episodes of the reference alone).

Every field of the state (the predictor's included), the observations, the rewards, the
terminations and the infos are compared.

Tolerances: ``RTOL = 1e-9`` relative, on the scale rounding is relative to (a vector's norm for
positions, velocities and the predictor's conditional trajectory, π for an angle — compared
as the wrapped difference —, 1 for probabilities, the value itself for variances, σ_LOS and
rates), plus ``ATOL = 1e-12`` in SI units (rad, m, mrad²) for entries that are zero in exact
arithmetic. Measured (defaults and three channels, two episodes each): the posteriors agree to
about 1e-12, the variances and σ_LOS to about 6e-12 relative, the angles, the target and the
predictor to 1e-16 or bit for bit, both after one step and over whole episodes of the reference
alone (the tracker's recursions are contractive) — except paper 001's conditional trajectory
(the predictor's ``delta`` and ``anchor``) over whole episodes of the reference alone, compared
to ``TRAJECTORY_RTOL = 1e-6``: where the target moves nearly along the line of sight
(``cos(θ_P − θ_A)`` about 0.01, a window spanning a few mrad, §8.5) the increments δ̂ amplify
the window's ulps about a millionfold while the window itself agrees to 1e-15 (measured: up to
1.7e-9 relative, "three channels"), and the scale rule ``Y_C ← Y_C + δ̂_Y`` carries that on. The LLRs reach hundreds, so their ulps
(and those of the exp and log that make posteriors of them) come to about 1e-13; numba reorders
the tracker's sums (numpy's einsums and pairwise sums), and the CPU's libm and numpy's SIMD
erf, atan2, exp and log differ by ulps. 1e-9 leaves over two orders of margin for any x86-64
CPU, while a real difference (a term, a sign, a frame, a draw) moves something by far moredraw) moves something by far more. The discrete fields — frame, views, occlusions, counters,
the predictor's count, detections, visibility — and the terminations must be equal: a decision
that flipped would show there first. Observations are float32 and compared to
``OBS_ATOL = 1e-5``: a float64 difference of 1e-12 may straddle a float32 rounding, one ulp
(≤ 9.5e-7 for entries clipped to ±10).
"""

from __future__ import annotations

import copy
import dataclasses
import types

import numpy as np
import pytest

from sensorgym.agents.gimbal_tracking import Paper001Servo
from sensorgym.envs.gimbal_tracking import reference, simulation
from sensorgym.envs.gimbal_tracking.simulation import GimbalParams, GimbalState
from sensorgym.envs.shells.contract import Core, registered_episode_steps
from sensorgym.trackers.angles.prediction import wrap_half_turn
from sensorgym.trackers.geometry import wrap_angle
from tests.reference_checks import assert_close, assert_same_draws, assert_same_observations, norm

ENV_ID = "sensorgym/GimbalTracking-v0"
SEED = 20261204
BATCH = 8
EPISODES = 2
RTOL = 1e-9
ATOL = 1e-12
OBS_ATOL = 1e-5
#: the predictor's conditional trajectory (δ̂, point C) over whole episodes of the reference
#: alone: near-radial motion makes it ill-conditioned in the window's angles (see above)
TRAJECTORY_RTOL = 1e-6

#: the reference as a simulation module (its reset, step, observation and diagnostics)
REFERENCE = types.SimpleNamespace(
    __name__=reference.__name__,
    spaces=simulation.spaces,
    reset=reference.reset,
    step=reference.step,
    observe=reference.observe,
    observe_agents=reference.observe_agents,
    info=reference.info,
)

_STILL = {
    f"{axis}_{kind}": () for axis in ("roll", "pitch", "yaw") for kind in ("amplitude", "period")
}

#: params, seed
CASES = {
    "defaults": (GimbalParams(), SEED),
    "defaults, another seed": (GimbalParams(), SEED + 1),
    "one channel": (
        GimbalParams(
            channel_contrast=(4.0,),
            channel_noise=(1.0,),
            lose_probability=(0.03,),
            return_probability=(0.3,),
            aspect_change_probability=(0.05,),
        ),
        SEED + 2,
    ),
    "three channels": (
        GimbalParams(
            channel_contrast=(5.0, 3.0, 2.0),
            channel_noise=(1.0, 1.0, 0.8),
            lose_probability=(0.02, 0.05, 0.1),
            return_probability=(0.3, 0.2, 0.4),
            aspect_change_probability=(0.05, 0.02, 0.1),
        ),
        SEED + 3,
    ),
    # search at the boresight soon, a turn in every episode, more vignetting
    "no occlusions": (
        GimbalParams(occlusion_length=(0, 0), search_after=5, turn_rate=(0.1, 0.2), vignetting=1.0),
        SEED + 4,
    ),
    "no carrier motion": (GimbalParams(**_STILL), SEED + 5),
    # two gimbals clear to port and to starboard of dead ahead, 0.04 rad in common, targets
    # starting near it: hand-overs (and the carrier's yaw moving the target across the edges)
    "two gimbals, hand-over": (
        GimbalParams(
            n_gimbals=2,
            gimbal_sectors=((-np.pi, 0.02), (-0.02, np.pi)),
            start_azimuth=(-0.3, 0.3),
        ),
        SEED + 6,
    ),
}


@pytest.mark.parametrize("case", list(CASES))
def test_reference_matches_the_compiled_simulation(case: str) -> None:
    params, seed = CASES[case]
    max_steps = registered_episode_steps(ENV_ID)
    assert max_steps is not None
    sim, ref = Core(simulation, params), Core(REFERENCE, params)
    rule = Paper001Servo(params)
    rng, rng_ref = np.random.default_rng(seed), np.random.default_rng(seed)
    actions = np.random.default_rng(seed + 100)
    s, r = sim.reset(rng, BATCH), ref.reset(rng_ref, BATCH)
    steps, episodes = np.zeros(BATCH, int), np.zeros(BATCH, int)
    terminations = truncations = detections = misses = 0
    measured_by = np.zeros(params.n_gimbals, int)  # detected frames each gimbal measured
    while episodes.min() < EPISODES:
        # the reference on its own matches the simulation (resets included)
        _assert_same_view(ref, r, s, "own state")
        a, _ = rule.predict(sim.observe(s))
        wild = np.arange(BATCH) % 2 == 1
        a = np.where(wild[:, None], a + actions.uniform(-1.2, 1.2, a.shape), a)
        rng_lock = copy.deepcopy(rng)
        s_next, reward, terminated = sim.step(s, a, rng)
        l_next, l_reward, l_terminated = ref.step(s, a, rng_lock)
        r_next, r_reward, r_terminated = ref.step(r, a, rng_ref)
        assert_same_draws(rng, rng_lock, rng_ref)
        # the reference from the simulation's state, and on its own
        _assert_same_view(ref, l_next, s_next, "one step")
        for got, got_terminated, how in (
            (l_reward, l_terminated, "one step"),
            (r_reward, r_terminated, "own state"),
        ):
            np.testing.assert_array_equal(got_terminated, terminated, err_msg=how)
            _assert_close(f"{how}: reward", got, reward, 1.0 + np.abs(reward))
        terminations += int(terminated.sum())
        detections += int(s_next.detected.sum())
        misses += int((~s_next.detected & s_next.in_view).sum())
        by = sim.info(s_next)["measuring_gimbal"].astype(int)[s_next.detected]
        measured_by += np.bincount(by, minlength=params.n_gimbals)
        steps += 1
        truncated = ~terminated & (steps >= max_steps)
        truncations += int(truncated.sum())
        done = terminated | truncated
        if done.any():
            k = int(done.sum())
            rng_lock = copy.deepcopy(rng)
            fresh = sim.reset(rng, k, like=s_next)
            _assert_same_view(ref, ref.reset(rng_lock, k, like=s_next), fresh, "reset")
            s_next = sim.scatter(done, fresh, s_next)
            r_next = ref.scatter(done, ref.reset(rng_ref, k, like=r_next), r_next)
            assert_same_draws(rng, rng_lock, rng_ref)
            steps[done] = 0
            episodes += done
        s, r = s_next, r_next
    # the episodes exercised what they are meant to: ends of both kinds, detections and losses
    assert terminations > 0 and truncations > 0, (terminations, truncations)
    assert detections > 0 and misses > 0, (detections, misses)
    assert np.all(measured_by > 0), measured_by  # every gimbal measured the track: hand-overs


def _assert_same_view(core: Core, got: GimbalState, want: GimbalState, how: str) -> None:
    """The states, the observations and the infos of ``got`` (reference) and ``want``
    (simulation) agree within the module's tolerances."""
    _assert_same_state(got, want, how)
    assert_same_observations(core, got, want, how, OBS_ATOL)
    i_got, i_want = core.info(got), core.info(want)
    assert i_got.keys() == i_want.keys()
    for key in ("in_view", "occluded", "detected", "visible_channels", "measuring_gimbal"):
        np.testing.assert_array_equal(i_got[key], i_want[key], err_msg=f"{how}: info {key}")
    for key in ("los_error", "pointing_error", "estimate_error_elevation", "sigma_los"):
        # angles between directions: differences of unit vectors' entries, on the scale 1
        _assert_close(f"{how}: info {key}", i_got[key], i_want[key], 1.0)
    d = wrap_angle(i_got["estimate_error_azimuth"] - i_want["estimate_error_azimuth"])
    _assert_close(f"{how}: info estimate_error_azimuth", d, np.zeros_like(d), np.pi)


#: fields compared for equality (discrete: a flipped decision shows here first)
EXACT = (
    "frame", "turn_start", "turn_end", "views", "occlusion_start", "occlusion_end",
    "out_of_view", "since_detection", "detected", "in_view", "occluded", "visible",
)  # fmt: skip
#: angles, compared as the wrapped difference on the scale π
ANGLES = (
    "carrier_phase",
    "gimbal_angles",
    "predictor_origin",
    "reference",
    "estimate",
    "predicted",
)


def _assert_same_state(got: GimbalState, want: GimbalState, how: str) -> None:
    """Every field of the state, each on the scale its rounding is relative to."""
    scaled = {
        "target_position": norm,
        "target_velocity": norm,
        "turn_rate": lambda a: np.abs(a),
        "gimbal_rates": lambda a: 1.0,  # rad/s, of the drives' max_rate 1
        "fusion_variance": lambda a: np.abs(a),
        "view_posterior": lambda a: 1.0,  # probabilities
        "sigma_los": lambda a: np.abs(a),
    }
    assert {f.name for f in dataclasses.fields(GimbalState)} == {
        *scaled,
        *EXACT,
        *ANGLES,
        "predictor",
    }, "a new state field: compare it here"
    for name in EXACT:
        a, b = getattr(got, name), getattr(want, name)
        assert a.dtype == b.dtype, f"{how}: {name} dtype {a.dtype}, expected {b.dtype}"
        np.testing.assert_array_equal(a, b, err_msg=f"{how}: {name}")
    for name, scale in scaled.items():
        a, b = getattr(got, name), getattr(want, name)
        _assert_close(f"{how}: {name}", a, b, scale(b))
    for name in ANGLES:
        d = wrap_angle(getattr(got, name) - getattr(want, name))
        _assert_close(f"{how}: {name}", d, np.zeros_like(d), np.pi)
    # paper 001's predictor: its window of angles, its count, its direction (modulo π) and
    # its conditional trajectory (point C and increments, each on the scale of its norm)
    p, q = got.predictor, want.predictor
    np.testing.assert_array_equal(p.count, q.count, err_msg=f"{how}: predictor count")
    for name in ("azimuth_window", "elevation_window"):
        d = wrap_angle(getattr(p, name) - getattr(q, name))
        _assert_close(f"{how}: predictor {name}", d, np.zeros_like(d), np.pi)
    d = wrap_half_turn(p.slope_angle - q.slope_angle)
    _assert_close(f"{how}: predictor slope_angle", d, np.zeros_like(d), np.pi)
    rtol = TRAJECTORY_RTOL if how == "own state" else RTOL
    for name in ("delta", "anchor"):
        a, b = getattr(p, name), getattr(q, name)
        assert_close(f"{how}: predictor {name}", a, b, norm(b), rtol, ATOL)


def _assert_close(
    name: str, got: np.ndarray, want: np.ndarray, scale: np.ndarray | float, atol: float = ATOL
) -> None:
    assert_close(name, got, want, scale, RTOL, atol)
