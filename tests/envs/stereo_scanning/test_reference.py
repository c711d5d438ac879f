"""The readable reference of the StereoScanning period (``envs/stereo_scanning/reference.py``)
against the compiled simulation the env runs (``simulation.reset``/``step``, :mod:`.kernels`),
and paper 000's numpy tracker (:mod:`sensorgym.trackers.stereo.period_tracking`) against both.

Both simulations are driven through :class:`~sensorgym.envs.shells.contract.Core` with
autoresets (:meth:`Core.scatter`: fresh scenarios only where an episode ended, terminated or
truncated at the case's time limit), over whole episodes of a batch of 4 scenarios, under
seeded random actions slightly outside the box (the cores clip them) that keep the sectors
near the scene, so that the tracker has drones to find. Each step is taken three times with
the same draws (generators seeded alike and checked to stay in step, to the end):

* the simulation, on its own state;
* the reference from the simulation's state (one period of each from the same state), and
  every autoreset's fresh scenarios from the same draws;
* the reference on its own state, from its own resets (whole episodes of the reference alone:
  nothing it computes leaks in from the kernel).

Every field of the state (checked to be all of them), the observations (joint and per agent),
the rewards, the terminations and the infos are compared. The cases: the defaults (three
receivers, the registered 40-period limit); five receivers with false detections,
apparent-position noise and three close drones (joint fits, their χ² test, negative
information, clutter slots); four receivers in a small scene with fast, hard-accelerating
drones, a noise floor, slow confirmation and a small table (terminations, a full table,
coasting and dropped tracks).

Tolerances. The two solve the same systems by different algorithms: the kernel the 6×6
candidates by Cramer's rule and the joint fits by the normal equations, the reference both by
the SVD. Backward-stable solves agree to about ``κ_F ε`` relative (``κ_F ≤ cond_max = 1e7``),
the normal equations to ``κ_F² ε`` (``κ_F ≤ 1e4`` there): at most about 2e-8 at those limits;
numba also orders some sums differently from numpy, and LAPACK's kernels and libm differ
between CPUs. Float64 values must agree to ``|ref − kernel| ≤ TOL (1 + |kernel|)`` in SI units
(m, m/s, s, rad; 1 for a count, a mean reward or a score) with ``TOL = 1e-7``, above both
limits. These episodes reach ``κ_F`` 3.4e3 (triples) and 4.7e2 (joint fits) and differ by
2e-11 at most (an entry of the track table; the fixes by 1e-16, the rewards by 2e-14), so a
real difference of a few parts in 1e7 would show. Observations are float32: a rounding-level
difference may flip the last bit, so they agree within ``2e-6`` (two float32 ulps at the clip
±10). Integers, flags, non-finite values (``σ = ∞`` of a drone without a track) and the
generators' states must be equal. A discrete decision of the tracker (a gate, a pixel edge)
could flip only where a value lies within that rounding of its threshold; no such case occurs
here. Deliberately broken stages of the reference (a term, a gate, an order, a frame: tried
outside this file) fail these episodes. The module runs in about 6 s.
"""

from __future__ import annotations

import copy
import dataclasses
from typing import Any

import numpy as np
import pytest

from sensorgym.envs.shells.contract import Core, registered_episode_steps
from sensorgym.envs.stereo_scanning import kernels, reference, simulation
from sensorgym.envs.stereo_scanning.simulation import ScanningParams, ScanningState
from sensorgym.envs.stereo_scanning.stereo_scanning import ENV_ID
from sensorgym.trackers.stereo import association
from sensorgym.trackers.stereo.period_tracking import ProposedParams, proposed_candidates
from tests.reference_checks import assert_same_draws

SEED = 20260738
BATCH = 4
#: float64 fields: |ref − kernel| ≤ TOL (1 + |kernel|) (module docstring)
TOL = 1e-7
#: float32 observations: two ulps at the clip ±10
OBS_TOL = 2e-6

#: (params, time limit, steps): the registered limit for the defaults, shorter ones elsewhere
CASES: dict[str, tuple[ScanningParams, int, int]] = {
    "default": (ScanningParams(), 40, 56),
    # receivers 4 and 5 join the triples (joint fits and their χ² test, negative information),
    # false detections fill the fix slots, σ_x is drawn, three drones fly close together
    "five receivers, clutter, apparent noise": (
        ScanningParams(
            n_receivers=5, n_drones=6, close_drones=2, clutter_rate=1.0, position_sigma=0.05
        ),
        12,
        26,
    ),
    # drones leave a small scene fast (terminations) and accelerate hard (the gates' drift
    # margins), narrow sectors hit the noise floor, three periods to confirm, one miss allowed,
    # a table of ten rows (it fills), one receiver enough to call a triple a ghost
    "small scene, small table": (
        ScanningParams(
            n_receivers=4,
            n_drones=5,
            close_drones=2,
            scene_half_width=45.0,
            drone_speed=(6.0, 10.0),
            max_acceleration=1.0,
            enter_window=(2.0, 6.0),
            sigma_ang_min=8e-4,
            confirm_hits=3,
            max_misses=1,
            track_capacity=10,
            ghost_misses=1,
            clutter_rate=0.5,
            max_clutter=3,
        ),
        20,
        26,
    ),
}


def _actions(rng: np.random.Generator, n: int) -> np.ndarray:
    """Sector centres within ±0.45 of the boresights, widths over the whole range and a bit
    beyond it (the cores clip): a random policy that still finds drones."""
    a = np.empty((BATCH, n, 3))
    a[..., :2] = rng.uniform(-0.45, 0.45, (BATCH, n, 2))
    a[..., 2] = rng.uniform(-0.3, 1.2, (BATCH, n))
    return a


@pytest.mark.parametrize("case", list(CASES))
def test_reference_matches_the_compiled_simulation(case: str) -> None:
    params, limit, steps_total = CASES[case]
    if case == "default":
        assert registered_episode_steps(ENV_ID) == limit
    sim, ref = Core(simulation, params), Core(reference, params)
    rng, rng_ref = np.random.default_rng(SEED), np.random.default_rng(SEED)
    actions = np.random.default_rng(SEED + 1)
    lock = copy.deepcopy(rng)
    s, r = sim.reset(rng, BATCH), ref.reset(rng_ref, BATCH)
    _assert_same_view(params, ref, ref.reset(lock, BATCH), s, "reset")
    steps = np.zeros(BATCH, int)
    seen = {"episodes": 0, "terminations": 0, "confirmed": 0, "false": 0}
    for t in range(steps_total):
        _assert_same_view(params, ref, r, s, f"own state, step {t}")
        a = _actions(actions, params.n_receivers)
        lock = copy.deepcopy(rng)
        s_next, reward, terminated = sim.step(s, a, rng)
        l_next, l_reward, l_terminated = ref.step(s, a, lock)
        r_next, r_reward, r_terminated = ref.step(r, a, rng_ref)
        assert_same_draws(rng, lock, rng_ref)
        _assert_same_view(params, ref, l_next, s_next, f"one step {t}")
        for got, got_terminated, how in ((l_reward, l_terminated, "one step"),
                                         (r_reward, r_terminated, "own state")):  # fmt: skip
            np.testing.assert_array_equal(got_terminated, terminated, err_msg=how)
            _close(f"{how} {t}: reward", got, reward)
        seen["terminations"] += int(terminated.sum())
        seen["confirmed"] += int(s_next.parts[:, 5].sum())
        seen["false"] += int(s_next.parts[:, 2].sum())
        steps += 1
        done = terminated | (steps >= limit)
        if done.any():
            k = int(done.sum())
            lock = copy.deepcopy(rng)
            fresh = sim.reset(rng, k, like=s_next)
            _assert_same_view(params, ref, ref.reset(lock, k, like=s_next), fresh, f"reset {t}")
            s_next = sim.scatter(done, fresh, s_next)
            r_next = ref.scatter(done, ref.reset(rng_ref, k, like=r_next), r_next)
            assert_same_draws(rng, lock, rng_ref)
            steps[done] = 0
            seen["episodes"] += k
        s, r = s_next, r_next
    _assert_same_view(params, ref, r, s, "own state, last")
    assert_same_draws(rng, rng_ref)
    # the episodes did what the case is for
    assert seen["episodes"] >= BATCH and seen["confirmed"] > 0 and seen["false"] > 0, seen
    if case == "small scene, small table":
        assert seen["terminations"] > 0, seen


def _assert_same_view(
    params: ScanningParams, core: Core, got: ScanningState, want: ScanningState, how: str
) -> None:
    """Every field, the observations and the infos of ``got`` (reference) and ``want``
    (simulation)."""
    fields = {f.name for f in dataclasses.fields(ScanningState)}
    assert fields == {
        "t", "drone_position", "drone_velocity", "drone_acceleration", "enter", "exited",
        "sectors", "fixes", "fix_count", "fix_drone", "tracks", "track_int", "next_id",
        "assigned", "drone_sigma", "parts", "observation",
    }, "a new state field: make sure it is compared"  # fmt: skip
    for name in sorted(fields):
        _close(f"{how}: {name}", getattr(got, name), getattr(want, name))
    for name, view in (("observe", core.observe), ("observe_agents", core.observe_agents)):
        _close(f"{how}: {name}", view(got), view(want))
    i_got, i_want = core.info(got), core.info(want)
    assert i_got.keys() == i_want.keys()
    for key, value in i_want.items():
        _close(f"{how}: info {key}", i_got[key], value)


def _close(name: str, got: Any, want: Any) -> None:
    """One array of the reference against the simulation's, within the module's tolerances:
    float64 ``|Δ| ≤ TOL (1 + |want|)`` where finite, float32 ``|Δ| ≤ OBS_TOL``, the rest (and
    non-finite values) equal."""
    got, want = np.asarray(got), np.asarray(want)
    assert got.shape == want.shape and got.dtype == want.dtype, (
        f"{name}: {got.dtype}{got.shape}, expected {want.dtype}{want.shape}"
    )
    if want.dtype.kind != "f":
        np.testing.assert_array_equal(got, want, err_msg=name)
        return
    finite = np.isfinite(want)
    np.testing.assert_array_equal(got[~finite], want[~finite], err_msg=f"{name} (non-finite)")
    err = np.abs(got[finite].astype(np.float64) - want[finite])
    tol = OBS_TOL if want.dtype == np.float32 else TOL * (1.0 + np.abs(want[finite]))
    if not np.all(err <= tol):  # NaN in got fails too
        i = int(np.nanargmax(np.where(err <= tol, 0.0, err / tol)))
        where = tuple(int(x) for x in np.argwhere(finite)[i])
        raise AssertionError(
            f"{name}: at {where}, {got[where]!r} vs {want[where]!r} (|Δ| = {err[i]:.3g})"
        )


# --- paper 000's numpy tracker and the env's -----------------------------------------------------


@dataclasses.dataclass(frozen=True)
class _Fixes:
    """One receiver's fixes as :mod:`.period_tracking` reads them (:class:`association.Fixes`)."""

    directions: np.ndarray
    times: np.ndarray
    powers: np.ndarray


def test_paper_000_tracker_and_the_env_agree_on_the_same_fixes() -> None:
    """Paper 000's proposed algorithm in numpy (:func:`proposed_candidates`,
    :func:`association.extrapolation_residual`) and the env's compiled tracker, on the fixes of
    the env's own episodes (defaults: three receivers).

    * Spatial step: every candidate of the env (:func:`reference.candidates`, which the test
      above holds to the kernel) is one of ``proposed_candidates``'s triples, with the same
      ``M`` and ``V`` (frame 1 there, the world here) and time; every track the kernel moved to
      a candidate this period holds one of those ``(M, V, t)``. The env keeps fewer: its pairs
      pre-gate the triples and it drops ``κ_F > cond_max`` (module docstring of the reference).
    * Temporal step: each confirmed track the kernel continued grew its cumulative index by
      ``ΔJ = ‖M − (M̂_s + V̂_s (t − t_s))‖``, :func:`association.extrapolation_residual`.

    They differ by design in the rest (batch groups, a fixed gate and a final selection there;
    an online table with covariance gates, confirmation, births and misses here)."""
    params = ScanningParams()
    sim = Core(simulation, params)
    rng, actions = np.random.default_rng(SEED + 2), np.random.default_rng(SEED + 3)
    P, b = params.relative
    R1, O1 = params.rotations[0], params.receivers[0]
    spec = ProposedParams(max_speed=params.max_speed, cond_max=params.cond_max)
    s = sim.reset(rng, BATCH)
    counts = {"env": 0, "paper": 0, "moved": 0, "continued": 0}
    for _ in range(30):
        a = _actions(actions, params.n_receivers)
        s_next, _, terminated = sim.step(s, a, rng)
        for i in range(BATCH):
            # the fixes of receivers 1–3 in their own frames
            local = np.einsum("kji,kfj->kfi", params.rotations, s_next.fix_world[i])
            per = [_Fixes(local[k, : s_next.fix_count[i, k]],
                          s_next.fix_time[i, k, : s_next.fix_count[i, k]],
                          np.ones(s_next.fix_count[i, k])) for k in range(3)]  # fmt: skip
            paper = proposed_candidates(per, P[:2], b[:2], spec)
            M, V = O1 + paper.position @ R1.T, paper.velocity @ R1.T  # frame 1 → world
            fixes = reference.PeriodFixes(
                local[None], s_next.fix_world[i : i + 1], s_next.fix_time[i : i + 1],
                s_next.fix_count[i : i + 1], s_next.fix_drone[i : i + 1],
            )  # fmt: skip
            sigma = reference.fix_sigma(params, s_next.sectors[i, :, 2])
            env = reference.candidates(params, fixes, sigma, s_next.sectors[i], float(s.t[i]))
            counts["env"] += env.time.shape[0]
            counts["paper"] += paper.time.shape[0]
            for c in range(env.time.shape[0]):
                same = np.flatnonzero(np.all(paper.members == env.members[c, :3], axis=1))
                assert same.size == 1, "an env candidate is not one of paper 000's triples"
                _near(env.position[c], M[same[0]])
                _near(env.velocity[c], V[same[0]])
                assert env.time[c] == paper.time[same[0]]
            # the kernel's tracks that took a candidate this period hold one of paper 000's
            status, t_s = s_next.track_status[i], s_next.track_t[i]
            for q in np.flatnonzero((status != kernels.EMPTY) & (t_s >= s.t[i])):
                match = np.flatnonzero(paper.time == t_s[q])
                hit = [j for j in match if _is_near(s_next.track_x[i, q], np.r_[M[j], V[j]])]
                assert hit, "a track holds no candidate of paper 000's"
                counts["moved"] += 1
            # confirmed tracks continued in place: I grew by paper 000's ΔJ
            before, after = s.track_int[i], s_next.track_int[i]
            kept = ((before[:, 2] == kernels.CONFIRMED) & (after[:, 2] == kernels.CONFIRMED)
                    & (before[:, 3] == after[:, 3]) & (after[:, 0] == before[:, 0] + 1))  # fmt: skip
            for q in np.flatnonzero(kept):
                x0, x1 = s.track_x[i, q], s_next.track_x[i, q]
                dJ = association.extrapolation_residual(
                    x0[None, :3], x0[None, 3:], s.track_t[i, q : q + 1], x1[None, :3],
                    s_next.track_t[i, q : q + 1],
                )[0, 0]  # fmt: skip
                _near(s_next.track_score[i, q] - s.track_score[i, q], dJ)
                counts["continued"] += 1
        if terminated.any():
            s_next = sim.scatter(terminated, sim.reset(rng, int(terminated.sum())), s_next)
        s = s_next
    # the env keeps a non-empty share of paper 000's candidates (here all of them: without
    # false detections its pair pre-gates and κ_F limit rarely refuse a triple)
    assert 0 < counts["env"] <= counts["paper"], counts
    assert counts["moved"] > 0 and counts["continued"] > 0, counts


def _is_near(got: np.ndarray, want: np.ndarray) -> bool:
    return bool(np.all(np.abs(got - want) <= TOL * (1.0 + np.abs(want))))


def _near(got: Any, want: Any) -> None:
    assert _is_near(np.asarray(got), np.asarray(want)), (got, want)


# --- the contract's edges -------------------------------------------------------------------------


def test_an_invalid_action_raises_after_the_same_draws() -> None:
    """A NaN action raises in both, after the period's noise has been drawn."""
    params = CASES["five receivers, clutter, apparent noise"][0]
    kernel_rng, ref_rng = np.random.default_rng(5), np.random.default_rng(5)
    state = simulation.reset(params, kernel_rng, 2)
    reference.reset(params, ref_rng, 2)
    action = np.zeros((2, params.n_receivers, 3))
    action[1, 2, 0] = np.nan
    for module, rng in ((simulation, kernel_rng), (reference, ref_rng)):
        with pytest.raises(ValueError, match="NaN"):
            module.step(params, state, action, rng)
    assert kernel_rng.bit_generator.state == ref_rng.bit_generator.state


@pytest.mark.parametrize("tracker", ["alternative", "algorithmic"])
def test_the_other_trackers_are_refused(tracker: str) -> None:
    """The reference covers the proposed tracker only (its module docstring says why)."""
    with pytest.raises(ValueError, match="proposed"):
        reference.reset(ScanningParams(tracker=tracker), np.random.default_rng(0), 1)
