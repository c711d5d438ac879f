"""The readable reference of the StereoPointing reset and step
(:mod:`sensorgym.envs.stereo_pointing.reference`) against the compiled simulation the envs run
(:mod:`sensorgym.envs.stereo_pointing.simulation`, its kernels).

Both are driven through :class:`~sensorgym.envs.shells.contract.Core` over whole episodes of a
batch of 8 scenarios, each restarted when its own (random, staggered) time limit runs out: the
fresh scenarios are drawn for the ended ones only and scattered in (:meth:`Core.scatter`), from
generators in the same state. The actions are seeded and random: each receiver slews at a
randomly assigned drone (the slew controller :func:`.simulation.assignment_actions`, on the
compiled simulation's observation) plus uniform noise of ±0.3, so that they reach 1.3 outside
the box (the cores clip) and the drones enter and leave the fields of view. Two modes: the
reference steps from the simulation's state each time (``same-state``: one step's difference,
and every reset from the same draws), or runs its own episodes beside it (``own-episodes``:
nothing the reference computes leaks in from the kernels). Every field of every state (checked
to be all of them), the observations (joint and per agent), the rewards, the terminations and
the infos are compared at every step and reset, and the generators must end in the same state.

Cases: both envs' params (``StereoPointing-v0``, ``StereoPointingCrowded-v0``: drones lost from
the fields of view, tracks that only predict) and settings that force the rare branches —
random initial pointing (the reset's own pointing rather than the cue); exact fixes without
process noise (no noise draws, ``σ_pos = 0`` and reward ``+R``, the certain track's singular
innovation covariance and its pseudo-inverse gain, covariances down to subnormal numbers); and
two receivers 8.7 cm apart (noisy near-parallel lines of sight that cross behind or on the
receivers: fixes refused by the in-front test although the true geometry is observable). Each
case checks that its episodes took its branch. Hand-made states cover what episodes do not
reach: a drone flying through a receiver (a zero line of sight), a prediction and a cue on a
receiver (a zero pointing offset; the cued receiver keeps its drawn pointing), a NaN action.

Tolerances: ``|ref − kernel| ≤ rtol · scale + ATOL`` entry by entry, ``scale`` the size the
rounding is relative to (a vector's norm, a position or velocity block's norm, ``√(P_ii P_jj)``
for a covariance entry, ``|σ_pos|``, π for an angle, 1 for the reward), ``ATOL = 1e-12`` in SI
units for entries that are zero in exact arithmetic (and the subnormal covariances). The two
compute the same equations by different algorithms: the kernels solve the 3×3 systems by
Gaussian elimination, take determinants by cofactors and eigenvalues by Jacobi rotations, and
numba may fuse and reorder float operations, where the reference calls LAPACK and numpy's
vectorised loops (whose ``sin``/``log`` differ by ulps between CPUs). Backward-stable solves
agree to about ``κ ε`` relative, ``κ`` the condition of a fix's information ``G`` and of the
Kalman update (a prior of 25 m² meets a fix of 0.01 m²). In the regular cases the largest
difference seen is 6e-12 (a covariance entry; tracks 6e-13, rewards 2e-15): ``rtol = 1e-9``.
The 8.7 cm pair sees a drone 100 m away along lines of sight about 1e-3 rad apart, ``κ(G)`` up
to about 1e6: the largest difference seen is 3e-9, ``rtol = 1e-6``. Both leave two orders of
margin for another CPU's last bits, while a real difference (a term, a factor, a frame, a draw)
moves something by far more. Observations are float32, compared to ``OBS_ATOL = 1e-5``: a
float64 difference may straddle a float32 rounding (one ulp is at most 9.5e-7 for entries
clipped to ±10; the largest difference seen is 1.2e-7, the close pair's own episodes). Flags
(views, fixes, terminations, the infos' counts) and clocks must be equal, and so must the
generators' states.
"""

from __future__ import annotations

import copy
import dataclasses

import numpy as np
import pytest

from sensorgym.envs.shells.contract import Core
from sensorgym.envs.stereo_pointing import reference, simulation
from sensorgym.envs.stereo_pointing.crowded import CrowdedPointingParams
from sensorgym.envs.stereo_pointing.simulation import PointingParams, PointingState
from sensorgym.trackers.geometry import wrap_angle
from sensorgym.trackers.stereo.information import MIN_FIX_RANGE, fix_in_front
from sensorgym.trackers.stereo.kalman import CVTrack
from tests.reference_checks import assert_close, norm

SEED = 20260738
BATCH = 8
STEPS = 80
#: each scenario's episode lasts a random number of steps in [15, 40): several episodes per
#: scenario, restarts staggered (the registered 150-step limit is the shells' business)
EPISODE_STEPS = (15, 40)
ATOL = 1e-12
OBS_ATOL = 1e-5

#: name: (params, rtol)
CASES: dict[str, tuple[PointingParams, float]] = {
    "StereoPointing-v0": (PointingParams(), 1e-9),
    "StereoPointingCrowded-v0": (CrowdedPointingParams(), 1e-9),
    "random-pointing": (PointingParams(cued_start=False, fov=0.6), 1e-9),
    "exact-fixes": (PointingParams(sigma_ang=0.0, process_noise=0.0, fov=1.0), 1e-9),
    "close-pair": (
        PointingParams(receiver_angles_deg=(0.0, 0.1, 90.0, 180.0), fov=1.0),
        1e-6,
    ),
}


@dataclasses.dataclass
class Branches:
    """How often the episodes took the branches a case is there for."""

    fixes: int = 0
    unseen: int = 0  # drones no receiver sees
    refused: int = 0  # drones not fixed whose true geometry is observable (finite bound)
    certain: int = 0  # fixes whose innovation covariance is singular (pseudo-inverse gain)
    exact: int = 0  # drones with σ_pos = 0
    restarts: int = 0


@pytest.mark.parametrize("follow_kernel", [True, False], ids=["same-state", "own-episodes"])
@pytest.mark.parametrize("case", list(CASES))
def test_reference_matches_the_compiled_simulation(case: str, follow_kernel: bool) -> None:
    params, rtol = CASES[case]
    seen = _drive(params, rtol, follow_kernel)
    # several episodes per scenario; fixes, and drones lost (tracks that only predict)
    assert seen.restarts >= 2 * BATCH and seen.fixes > 0 and seen.unseen > 0
    if case == "exact-fixes":
        assert seen.certain > 0 and seen.exact > 0
    if case == "close-pair":
        assert seen.refused > 0


def _drive(params: PointingParams, rtol: float, follow_kernel: bool) -> Branches:
    """Reset, step and autoreset the simulation and the reference side by side (module
    docstring); ``follow_kernel``: the reference steps from the simulation's state."""
    sim, ref = Core(simulation, params), Core(reference, params)
    rng, rng_ref = np.random.default_rng(SEED), np.random.default_rng(SEED)
    episodes = np.random.default_rng(SEED + 1)  # actions, assignments and episode lengths
    s, r = sim.reset(rng, BATCH), ref.reset(rng_ref, BATCH)
    _assert_same(ref, r, s, rtol, "reset")
    n, m = params.n_receivers, params.n_drones
    target = episodes.integers(0, m, (BATCH, n))
    limit = episodes.integers(*EPISODE_STEPS, BATCH)
    count = np.zeros(BATCH, dtype=np.int64)
    branches = Branches()
    for t in range(STEPS):
        action = simulation.assignment_actions(params, sim.observe(s), target)
        action = action + episodes.uniform(-0.3, 0.3, action.shape)
        s_next, reward, terminated = sim.step(s, action, rng)
        r_next, r_reward, r_terminated = ref.step(s if follow_kernel else r, action, rng_ref)
        _assert_same(ref, r_next, s_next, rtol, f"step {t}")
        _assert_close(f"step {t}: reward", r_reward, reward, 1.0, rtol)
        np.testing.assert_array_equal(r_terminated, terminated, err_msg=f"step {t}")
        _count(params, s, s_next, branches)
        # autoreset: fresh scenarios drawn for the ended ones only, scattered in
        count += 1
        done = terminated | (count >= limit)
        if done.any():
            k = int(done.sum())
            rng_lock = copy.deepcopy(rng)
            fresh = sim.reset(rng, k, like=s_next)
            _assert_same(ref, ref.reset(rng_lock, k, like=s_next), fresh, rtol, "reset")
            s_next = sim.scatter(done, fresh, s_next)
            r_next = ref.scatter(done, ref.reset(rng_ref, k, like=r_next), r_next)
            count[done] = 0
            limit[done] = episodes.integers(*EPISODE_STEPS, k)
            target[done] = episodes.integers(0, m, (k, n))
            branches.restarts += k
        s, r = s_next, r_next
    # the generators were used alike to the end
    assert rng.bit_generator.state == rng_ref.bit_generator.state
    return branches


def _count(
    params: PointingParams, before: PointingState, after: PointingState, b: Branches
) -> None:
    """Tally the branches one step of the simulation took (``b``, in place)."""
    views = after.seen.sum(axis=1)
    b.fixes += int(after.fixed.sum())
    b.unseen += int((views == 0).sum())
    b.refused += int((np.isfinite(after.bound) & ~after.fixed).sum())
    b.exact += int((after.bound == 0.0).sum())
    if params.sigma_ang == 0.0:  # R = 0: S = H P⁻ Hᵀ
        S = reference.kalman_predict(before.track, params.dt, params.process_noise).P[..., :3, :3]
        b.certain += int((reference.innovation_singular(S) & after.fixed).sum())


def _assert_same(
    core: Core,
    got: PointingState,
    want: PointingState,
    rtol: float,
    how: str,
) -> None:
    """Every field of the state, the observations and the infos of ``got`` (reference, viewed
    through ``core``) and ``want`` (simulation, viewed through its own module) within the
    module's tolerances."""
    compared = {"t", "azimuth", "elevation", "drone_position", "drone_velocity", "track"}
    compared |= {"seen", "fixed", "bound"}
    assert {f.name for f in dataclasses.fields(PointingState)} == compared, (
        "a new state field: compare it here"
    )
    for name in ("t", "seen", "fixed"):
        np.testing.assert_array_equal(getattr(got, name), getattr(want, name), err_msg=how)
    for name in ("azimuth", "elevation"):  # angles: the wrapped difference, on the scale π
        d = wrap_angle(getattr(got, name) - getattr(want, name))
        _assert_close(f"{how}: {name}", d, np.zeros_like(d), np.pi, rtol)
    for name in ("drone_position", "drone_velocity"):
        v = getattr(want, name)
        _assert_close(f"{how}: {name}", getattr(got, name), v, norm(v), rtol)
    x, P = want.track.x, want.track.P
    _assert_close(f"{how}: track x", got.track.x, x, _block_norms(x), rtol)
    sd = np.sqrt(np.abs(np.diagonal(P, axis1=-2, axis2=-1)))
    _assert_close(f"{how}: track P", got.track.P, P, sd[..., :, None] * sd[..., None, :], rtol)
    _assert_close(f"{how}: bound", got.bound, want.bound, np.abs(want.bound), rtol)
    want_core = Core(simulation, core.params)
    for view in ("observe", "observe_agents"):
        o_got, o_want = getattr(core, view)(got), getattr(want_core, view)(want)
        assert o_got.dtype == o_want.dtype == np.float32 and o_got.shape == o_want.shape
        _assert_close(f"{how}: {view}", o_got, o_want, 0.0, rtol, atol=OBS_ATOL)
    i_got, i_want = core.info(got), want_core.info(want)
    assert i_got.keys() == i_want.keys()
    for key in ("drones_fixed", "views", "unfixed_share", "fixed_sigma_count"):
        np.testing.assert_array_equal(i_got[key], i_want[key], err_msg=f"{how}: info {key}")
    # the error is a difference of coordinates of the drones' size; σ_pos summed
    drones = np.max(np.linalg.norm(want.drone_position, axis=-1), axis=-1)
    _assert_close(f"{how}: info position_error", i_got["position_error"],
                  i_want["position_error"], drones, rtol)  # fmt: skip
    sigma_sum = i_want["fixed_sigma_sum"]
    _assert_close(f"{how}: info fixed_sigma_sum", i_got["fixed_sigma_sum"], sigma_sum,
                  np.abs(sigma_sum), rtol)  # fmt: skip


def _assert_close(
    name: str,
    got: np.ndarray,
    want: np.ndarray,
    scale: np.ndarray | float,
    rtol: float,
    atol: float = ATOL,
) -> None:
    assert_close(name, got, want, scale, rtol, atol)


def _block_norms(x: np.ndarray) -> np.ndarray:
    """A track's scales ``(..., 6)``: its position entries that of its position's norm, its
    velocity entries that of its velocity's (the two have different units)."""
    pos, vel = norm(x[..., :3]), norm(x[..., 3:])
    return np.concatenate([pos, pos, pos, vel, vel, vel], axis=-1)


# --- what episodes do not reach ------------------------------------------------------------------


def test_an_invalid_action_raises_after_the_same_draws() -> None:
    """A NaN action raises in both, after the step's noise has been drawn."""
    params = PointingParams()
    rng, rng_ref = np.random.default_rng(5), np.random.default_rng(5)
    state = simulation.reset(params, rng, 2)
    reference.reset(params, rng_ref, 2)
    action = np.zeros((2, params.n_receivers, 2))
    action[1, 2, 0] = np.nan
    for module, generator in ((simulation, rng), (reference, rng_ref)):
        with pytest.raises(ValueError, match="NaN"):
            module.step(params, state, action, generator)
    assert rng.bit_generator.state == rng_ref.bit_generator.state


def test_a_drone_flying_through_a_receiver() -> None:
    """Receiver 0 stands at (0, 0, 50); drone 0 flies along the Z axis through it and is exactly
    on it after one step (52 − 10·0.2 = 50): a zero line of sight, not seen by receiver 0 (the
    others see it in their wide cones), and measured as zero."""
    params = PointingParams(fov=1.2)
    o = params.receiver_positions
    assert np.array_equal(o[0], [0.0, 0.0, 50.0])
    p = np.array([[[0.0, 0.0, 52.0], [60.0, 40.0, 90.0]]])
    v = np.array([[[0.0, 0.0, -10.0], [1.0, 0.0, -2.0]]])
    az = np.arctan2(-o[:, 0], -o[:, 2])[None]  # every receiver looks at the circle centre
    el = np.zeros((1, params.n_receivers))
    rng, rng_ref = np.random.default_rng(5), np.random.default_rng(5)
    s = simulation.start(params, p, v, az, el, rng)
    r = reference.start(params, p, v, az, el, rng_ref)
    _assert_same(Core(reference, params), r, s, 1e-9, "start")
    on_receiver = 0
    for t in range(4):
        action = np.zeros((1, params.n_receivers, 2))
        s_next, reward, _ = simulation.step(params, s, action, rng)
        r_next, r_reward, _ = reference.step(params, s, action, rng_ref)
        _assert_same(Core(reference, params), r_next, s_next, 1e-9, f"step {t}")
        _assert_close(f"step {t}: reward", r_reward, reward, 1.0, 1e-9)
        if np.array_equal(s_next.drone_position[0, 0], o[0]):
            on_receiver += 1
            assert not s_next.seen[0, 0, 0] and s_next.seen[0, 1:, 0].sum() >= 2
        s = s_next
    assert on_receiver == 1
    assert rng.bit_generator.state == rng_ref.bit_generator.state


def test_a_prediction_on_a_receiver_reads_as_a_zero_offset() -> None:
    """The tracker's prediction exactly on receiver 0 (a track there, at rest): no direction
    from it, a zero pointing offset in the observation."""
    params = PointingParams()
    state = simulation.reset(params, np.random.default_rng(6), 2)
    x = state.track.x.copy()
    x[:, 0, :3] = params.receiver_positions[0]
    x[:, 0, 3:] = 0.0
    state = dataclasses.replace(state, track=CVTrack(x, state.track.P))
    got, want = reference.observe(params, state), simulation.observe(params, state)
    n, m = params.n_receivers, params.n_drones
    pair = 3 * params.n_receivers  # receiver 0, drone 0: the first offset
    np.testing.assert_array_equal(want[:, pair : pair + 2], 0.0)
    assert want[:, 3 * n : 3 * n + 3 * n * m].any()  # the other offsets are not all zero
    _assert_close("observe", got, want, 0.0, 0.0, atol=OBS_ATOL)


def test_a_cue_on_a_receiver_keeps_the_drawn_pointing() -> None:
    """The cued aim of receiver ``k`` at a point: where the point is on the receiver (no
    direction) it keeps the given pointing, elsewhere it looks at the point, within the
    elevation limit."""
    params = PointingParams(n_drones=1)
    o = params.receiver_positions
    points = np.array([[[10.0, 40.0, 120.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [3.0, -2.0, 1.0]]])
    points[0, 1] = o[1] + [1e-3, 100.0, 0.0]  # nearly overhead: held at the elevation limit
    points[0, 2] = o[2]  # on receiver 2
    az0, el0 = np.full((1, 4), 0.7), np.full((1, 4), 0.1)
    az, el = simulation.aim_at(params, points, az0, el0)
    assert az[0, 2] == 0.7 and el[0, 2] == 0.1 and el[0, 1] == params.max_elevation
    got_az, got_el = reference.aim(params, points, az0, el0)
    _assert_close("azimuth", wrap_angle(got_az - az), np.zeros_like(az), np.pi, 1e-15)
    _assert_close("elevation", got_el, el, np.pi, 1e-15)


def test_a_certain_track_takes_the_exact_fix() -> None:
    """Exact fixes (``σ_ang = 0``, ``R = 0``) of tracks that claim to be exact where they are
    not, 1 m off the drone: the innovation covariance ``S = P_pp`` is zero (all of the track
    certain), zero along one axis only, or regular; the pseudo-inverse gain takes the fix on
    the null space of ``S``. Episodes reach ``S = 0`` only with the track on the truth."""
    params = PointingParams(sigma_ang=0.0, process_noise=0.0, n_drones=1)
    p = np.repeat([[[30.0, 50.0, 100.0]]], 3, axis=0)
    v = np.repeat([[[2.0, 0.0, -3.0]]], 3, axis=0)
    points = np.broadcast_to(p + params.dt * v, (3, params.n_receivers, 3))
    zeros = np.zeros((3, params.n_receivers))
    az, el = simulation.aim_at(params, points, zeros, zeros)
    rng, rng_ref = np.random.default_rng(9), np.random.default_rng(9)
    state = simulation.start(params, p, v, az, el, rng)
    reference.start(params, p, v, az, el, rng_ref)
    x = np.concatenate([p + np.array([1.0, -0.5, 0.25]), v + 0.1], axis=-1)
    P = np.zeros((3, 1, 6, 6))
    P[1, 0] = np.diag([1.0, 1.0, 0.0, 0.5, 0.5, 0.5])  # certain along Z only
    P[2, 0] = np.diag([1.0, 2.0, 3.0, 0.5, 0.5, 0.5])  # regular
    state = dataclasses.replace(state, track=CVTrack(x, P))
    action = np.zeros((3, params.n_receivers, 2))
    new, reward, _ = simulation.step(params, state, action, rng)
    got, got_reward, _ = reference.step(params, state, action, rng_ref)
    assert new.fixed.all() and np.all(reward == params.reward_clip)
    _assert_same(Core(reference, params), got, new, 1e-9, "step")
    _assert_close("reward", got_reward, reward, 1.0, 1e-9)
    # the fix (the truth) on the null space of S, the prediction elsewhere
    np.testing.assert_allclose(new.track.position[:2], new.drone_position[:2], atol=1e-9)


def test_the_in_front_test_is_the_trackers() -> None:
    """The in-front test of the fix at its 1 cm threshold (which the episodes' refused fixes,
    all behind their receivers, do not come near) against the tracker's compiled one:
    fixes from 2 cm behind to 2 cm in front of a receiver that sees them."""
    rng = np.random.default_rng(10)
    o = PointingParams().receiver_positions
    z = rng.standard_normal((64, 4, 1, 3))
    z /= np.linalg.norm(z, axis=-1, keepdims=True)
    k = rng.integers(0, 4, 64)  # the one receiver that sees the fix
    seen = np.arange(4)[None, :, None] == k[:, None, None]
    ahead = np.linspace(-0.02, 0.02, 64)  # along its line of sight
    M = o[k] + ahead[:, None] * z[np.arange(64), k, 0]
    want = fix_in_front(M, o, z[:, :, 0], seen[..., 0])
    got = reference.in_front(M[:, None], o, z, seen)[:, 0]
    np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(want, ahead > MIN_FIX_RANGE)  # none within 1e-4 m of it
