"""The readable reference of the BearingsManeuver reset and step
(:mod:`sensorgym.envs.bearings_maneuver.reference`) against the compiled simulation the envs run
(:mod:`sensorgym.envs.bearings_maneuver.simulation`, its kernels).

Both are driven through :class:`~sensorgym.envs.shells.contract.Core`, with autoresets
(:meth:`Core.scatter`, fresh scenarios only where an episode ended: terminated, or truncated at
the registered ``max_episode_steps``), over several whole episodes of a batch of 8 scenarios,
under random actions (partly outside the box: the cores clip). Each step is taken three times
with the same draws (generators seeded alike and checked to stay in step):

* the simulation, on its own state;
* the reference from the simulation's state (one step of each from the same state), and
  every autoreset's fresh scenarios from the same draws;
* the reference on its own state, from its own resets (whole episodes of the reference alone).

Every field of the state, the observations (joint and per agent), the rewards, the
terminations and the infos are compared.

Tolerances: ``RTOL = 1e-9`` relative, on the scale rounding is relative to (a vector's
position or velocity block norm, ``√(P_ii P_jj)`` for a covariance entry, a square root's row
norm, an angle's π), plus ``ATOL = 1e-9`` in SI units (m, m/s, m², rad) for entries that are
zero in exact arithmetic. One step of the two agrees to about 1e-14 and whole episodes of
the reference alone to about 1e-12: numba may contract ``a·b + c`` into FMAs and reorder sums,
the CPU's libm and numpy's SIMD transcendental functions differ by ulps, and the trackers
carry that from step to step. 1e-9 leaves three orders of margin for any x86-64 CPU, while a
real difference (a term, a sign, a frame, a draw) moves something by far more. Observations
are float32 and compared to ``OBS_ATOL = 1e-5``: a float64 difference of 1e-12 may straddle a
float32 rounding, one ulp (≤ 9.5e-7 for entries clipped to ±10). Terminations, clocks and the
generators' states must be equal.
"""

from __future__ import annotations

import copy
import dataclasses

import numpy as np
import pytest

from sensorgym.envs.bearings_maneuver import reference, simulation
from sensorgym.envs.bearings_maneuver.bearings_maneuver import ENV_ID
from sensorgym.envs.bearings_maneuver.book import BOOK_ENV_ID, BookManeuverParams
from sensorgym.envs.bearings_maneuver.simulation import ManeuverParams, ManeuverState
from sensorgym.envs.shells.contract import Core, registered_episode_steps
from sensorgym.trackers.geometry import wrap_angle
from tests.reference_checks import assert_close, assert_same_draws, assert_same_observations, norm

SEED = 20260738
BATCH = 8
EPISODES = 3
RTOL = 1e-9
ATOL = 1e-9
OBS_ATOL = 1e-5

#: (env id, params, whether the episodes must include terminations)
CASES = {
    "BearingsManeuver-v0": (ENV_ID, ManeuverParams(), False),
    "BearingsManeuverBook-v0": (BOOK_ENV_ID, BookManeuverParams(), False),
    # two platforms (sequential fusion, cross-bearings), the relative range metric, and a
    # stand-off that ends episodes (the penalty, autoresets at any step)
    "two platforms, relative range, stand-off": (
        ENV_ID,
        ManeuverParams(
            platforms=2, metric="relative_range", initial_range=(5e3, 8e3), min_range=3.5e3
        ),
        True,
    ),
}


@pytest.mark.parametrize("case", list(CASES))
def test_reference_matches_the_compiled_simulation(case: str) -> None:
    env_id, params, must_terminate = CASES[case]
    max_steps = registered_episode_steps(env_id)
    assert max_steps is not None
    sim, ref = Core(simulation, params), Core(reference, params)
    rng, rng_ref = np.random.default_rng(SEED), np.random.default_rng(SEED)
    actions = np.random.default_rng(SEED + 1)
    s, r = sim.reset(rng, BATCH), ref.reset(rng_ref, BATCH)
    steps, episodes, terminations = np.zeros(BATCH, int), np.zeros(BATCH, int), 0
    while episodes.min() < EPISODES:
        # the reference on its own matches the simulation (resets included)
        _assert_same_view(ref, r, s, "own state")
        a = actions.uniform(-1.2, 1.2, (BATCH, *sim.spaces.action.shape))
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
        steps += 1
        done = terminated | (steps >= max_steps)
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
    if must_terminate:
        assert terminations > 0, "the stand-off case must exercise terminations"


def _assert_same_view(core: Core, got: ManeuverState, want: ManeuverState, how: str) -> None:
    """The states, the observations and the infos of ``got`` (reference) and ``want``
    (simulation) agree within the module's tolerances."""
    _assert_same_state(got, want, how)
    assert_same_observations(core, got, want, how, OBS_ATOL)
    i_got, i_want = core.info(got), core.info(want)
    assert i_got.keys() == i_want.keys()
    np.testing.assert_array_equal(i_got["tracker_t"], i_want["tracker_t"])
    for key in ("range", "bound", "position_bound"):
        _assert_close(f"{how}: info {key}", i_got[key], i_want[key], np.abs(i_want[key]))
    _assert_close(
        f"{how}: info position_error",
        i_got["position_error"],
        i_want["position_error"],
        norm(want.target[:, :2])[:, 0],  # a difference of coordinates of the target's size
    )


def _assert_same_state(got: ManeuverState, want: ManeuverState, how: str) -> None:
    """Every field of the state, each on the scale its rounding is relative to."""
    compared = {
        "t": lambda a: np.abs(a),
        "platform_position": norm,
        "speed": lambda a: np.abs(a),
        "target": _block_norms,
        "bound_factor": norm,  # row i of a square root L: √P_ii
        "accuracy": lambda a: np.abs(a),
        "nearest_range": lambda a: np.abs(a),
        "position_error": lambda a: norm(want.target[:, :2])[:, 0],
    }
    assert {f.name for f in dataclasses.fields(ManeuverState)} == {
        *compared,
        "heading",
        "bearing",
        "bank",
        "observation",
    }, "a new state field: compare it here"
    for name, scale in compared.items():
        a, b = getattr(got, name), getattr(want, name)
        _assert_close(f"{how}: {name}", a, b, scale(b))
    for name in ("heading", "bearing"):  # angles: the wrapped difference, on the scale π
        d = wrap_angle(getattr(got, name) - getattr(want, name))
        _assert_close(f"{how}: {name}", d, np.zeros_like(d), np.pi)
    _assert_close(f"{how}: observation", got.observation, want.observation, 0.0, atol=OBS_ATOL)
    assert got.observation.dtype == want.observation.dtype == np.float32
    # the tracker: clock, log weights, members' means and covariances
    assert got.bank.t == want.bank.t
    lw, x, P = want.bank.log_weights, want.bank.members.x, want.bank.members.P
    _assert_close(f"{how}: bank log weights", got.bank.log_weights, lw, np.abs(lw))
    _assert_close(f"{how}: bank means", got.bank.members.x, x, _block_norms(x))
    sd = np.sqrt(np.abs(np.diagonal(P, axis1=-2, axis2=-1)))
    _assert_close(f"{how}: bank covariances", got.bank.members.P, P, _outer(sd, sd))


def _assert_close(
    name: str, got: np.ndarray, want: np.ndarray, scale: np.ndarray | float, atol: float = ATOL
) -> None:
    assert_close(name, got, want, scale, RTOL, atol)


def _block_norms(x: np.ndarray) -> np.ndarray:
    """A target state's scales ``(..., 4)``: its position entries that of its position's norm,
    its velocity entries that of its velocity's (the two have different units)."""
    pos, vel = norm(x[..., :2]), norm(x[..., 2:])
    return np.concatenate([pos, pos, vel, vel], axis=-1)


def _outer(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return u[..., :, None] * v[..., None, :]
