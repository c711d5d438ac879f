"""The readable reference of StereoPlacement's step (``envs/stereo_placement/reference.py``)
against the compiled step the env runs (``simulation.reset``/``step``, :mod:`.kernels`).

Both are driven over whole episodes — a batch of 8 scenarios, each restarted when its own
(random, staggered) time limit runs out, the fresh scenarios drawn for the ended ones only and
scattered in with the contract's :func:`tree_scatter` — from generators in the same state, under
the same random actions (some outside the Box, to exercise the clip and the speed cap). Every
field of every state (true geometry, fix, estimate, bound, observation, diagnostics), the
rewards, terminations and infos are compared at each step and each reset. Two modes: the
reference steps from the kernel's own state each time (``same-state``: one period's
difference), or runs its own episodes beside it (``own-episodes``: nothing the reference
computes leaks in from the kernel).

Tolerances. The two solve the same conjugation systems by different algorithms: the kernel by
Cramer's rule (n = 3) or the normal equations (n ≥ 4, up to ``κ_F = 1e4``), the reference by the
SVD (as the kernel above those). Backward-stable solves of one system agree to about ``κ_F ε``
relative, the normal equations to ``κ_F² ε`` (≤ 2e-8 at their limit); numba may also order or
fuse float operations differently from numpy, and LAPACK's kernels differ between CPUs. So
float64 values must agree to ``|ref − kernel| ≤ tol (1 + |kernel|)`` in SI units (m, m/s, rad,
and 1 for ``κ_F`` and the reward), ``tol = 1e-8`` for n = 3 and ``1e-7`` for n ≥ 4. These
episodes reach ``κ_F ≈ 5e5`` (n = 3) and ``1e3`` (n = 5); the largest difference seen uses 4 %
of ``tol`` for n = 3 and 1.3 % for n = 5. Observations are float32: a rounding-level
difference may flip the last bit, so they agree within ``2e-6`` (two float32 ulps at the clip
±10). Flags (degenerate fixes, terminations) and non-finite values (``κ_F = ∞``) must be equal.
:func:`test_a_real_difference_fails` shows that small real changes of the reference fail.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from sensorgym.envs.shells.contract import tree_scatter
from sensorgym.envs.stereo_placement import reference, simulation
from sensorgym.envs.stereo_placement.scan import boresight_rotations
from sensorgym.envs.stereo_placement.simulation import PlacementParams, PlacementState

#: float64 fields: |ref − kernel| ≤ tol · (1 + |kernel|), tol by the kernel's solver of n
#: receivers: Cramer (n = 3) or the normal equations (module docstring)
TOL_CRAMER = 1e-8
TOL_NORMAL_EQUATIONS = 1e-7
#: float32 observations: two ulps at the clip ±10
OBS_TOL = 2e-6

BATCH = 8
STEPS = 48
#: each scenario's episode lasts a random number of steps in [4, 16): several episodes per
#: scenario, restarts staggered (the registered 60-step limit is the shells' business)
EPISODE_STEPS = (4, 16)

PARAMS = {
    # n = 3: the kernel's closed form (Cramer)
    "default": PlacementParams(),
    # n = 5: the kernel's normal equations, the SVD above κ_F = 1e4
    "five-receivers": PlacementParams(n_receivers=5),
    # equal delays: every solve degenerate (pseudo-inverse), the tracker coasts, reward −R
    "equal-delays": PlacementParams(delays=(0.3, 0.3, 0.3)),
    # no noise (no draws, exact fixes, reward +R) in a small disc the fast vehicles hit
    "noise-free-small-arena": PlacementParams(sigma_ang=0.0, arena_radius=30.0, max_speed=20.0),
}


def _fields(state: Any, prefix: str = "") -> dict[str, Any]:
    """Every array of a state, by dotted field name (nested dataclasses flattened)."""
    out: dict[str, Any] = {}
    for f in dataclasses.fields(state):
        value = getattr(state, f.name)
        if dataclasses.is_dataclass(value):
            out.update(_fields(value, f"{prefix}{f.name}."))
        else:
            out[f"{prefix}{f.name}"] = value
    return out


def _tolerance(params: PlacementParams) -> float:
    return TOL_CRAMER if params.n_receivers == 3 else TOL_NORMAL_EQUATIONS


def _within(ref: np.ndarray, kernel: np.ndarray, tol: float) -> bool:
    """``|ref − kernel| ≤ tol (1 + |kernel|)`` where finite, equal where not."""
    finite = np.isfinite(kernel)
    if not np.array_equal(ref[~finite], kernel[~finite], equal_nan=True):
        return False
    r, k = ref[finite], kernel[finite]
    return bool(np.all(np.abs(r - k) <= tol * (1.0 + np.abs(k))))


def _close(name: str, ref: np.ndarray, kernel: np.ndarray, tol: float) -> None:
    """One array of the reference against the kernel's, within the module's tolerances."""
    ref, kernel = np.asarray(ref), np.asarray(kernel)
    assert ref.shape == kernel.shape and ref.dtype == kernel.dtype, name
    if kernel.dtype == np.float64 and _within(ref, kernel, tol):
        return  # the common case, without assert_allclose's cost (it reports a failure)
    if kernel.dtype == np.bool_:
        np.testing.assert_array_equal(ref, kernel, err_msg=name)
    elif kernel.dtype == np.float32:
        np.testing.assert_allclose(ref, kernel, rtol=0.0, atol=OBS_TOL, err_msg=name)
    else:  # float64; non-finite entries must match exactly (assert_allclose checks them)
        np.testing.assert_allclose(ref, kernel, rtol=tol, atol=tol, err_msg=name)


def _same_state(
    params: PlacementParams, ref: PlacementState, kernel: PlacementState, when: str
) -> None:
    """Every field, the observations and the infos of two states."""
    tol = _tolerance(params)
    ref_fields, kernel_fields = _fields(ref), _fields(kernel)
    assert ref_fields.keys() == kernel_fields.keys()
    for name, value in kernel_fields.items():
        _close(f"{when}: {name}", ref_fields[name], value, tol)
    _close(
        f"{when}: observe_agents",
        simulation.observe_agents(params, ref),
        simulation.observe_agents(params, kernel),
        tol,
    )
    ref_info, kernel_info = simulation.info(params, ref), simulation.info(params, kernel)
    assert ref_info.keys() == kernel_info.keys()
    for key, value in kernel_info.items():
        _close(f"{when}: info[{key}]", ref_info[key], value, tol)


def _drive(params: PlacementParams, follow_kernel: bool, seed: int, steps: int = STEPS) -> None:
    """Reset, step and autoreset the kernel and the reference side by side (module docstring);
    ``follow_kernel``: the reference steps from the kernel's state, else from its own."""
    n = params.n_receivers
    kernel_rng, ref_rng = np.random.default_rng(seed), np.random.default_rng(seed)
    episodes = np.random.default_rng(seed + 1)  # actions and episode lengths
    kernel = simulation.reset(params, kernel_rng, BATCH)
    ref = reference.reset(params, ref_rng, BATCH)
    _same_state(params, ref, kernel, "reset")
    limit = episodes.integers(*EPISODE_STEPS, BATCH)
    count = np.zeros(BATCH, dtype=np.int64)
    restarts = 0
    for t in range(steps):
        action = episodes.uniform(-1.3, 1.3, (BATCH, n, 2))
        kernel_next, kernel_reward, kernel_end = simulation.step(params, kernel, action, kernel_rng)
        ref_next, ref_reward, ref_end = reference.step(
            params, kernel if follow_kernel else ref, action, ref_rng
        )
        _same_state(params, ref_next, kernel_next, f"step {t}")
        _close(f"step {t}: reward", ref_reward, kernel_reward, _tolerance(params))
        _close(f"step {t}: terminated", ref_end, kernel_end, 0.0)
        # autoreset: fresh scenarios drawn for the ended ones only, scattered in
        count += 1
        done = kernel_end | (count >= limit)
        if done.any():
            k = int(done.sum())
            fresh_kernel = simulation.reset(params, kernel_rng, k, like=kernel_next)
            fresh_ref = reference.reset(params, ref_rng, k, like=ref_next)
            _same_state(params, fresh_ref, fresh_kernel, f"reset after step {t}")
            kernel_next = tree_scatter(done, fresh_kernel, kernel_next)
            ref_next = tree_scatter(done, fresh_ref, ref_next)
            count[done] = 0
            limit[done] = episodes.integers(*EPISODE_STEPS, k)
            restarts += k
        kernel, ref = kernel_next, ref_next
    # the generators were used alike to the end
    assert kernel_rng.bit_generator.state == ref_rng.bit_generator.state
    if steps == STEPS:
        assert restarts >= 2 * BATCH  # several episodes per scenario


@pytest.mark.parametrize("follow_kernel", [True, False], ids=["same-state", "own-episodes"])
@pytest.mark.parametrize("name", list(PARAMS))
def test_reference_matches_the_compiled_step_over_whole_episodes(name, follow_kernel):
    _drive(PARAMS[name], follow_kernel, seed=38)


def test_the_receiver_frames_are_the_kernels():
    """The frames change no output beyond rounding (the system in frame 1 is the world's
    turned by ``R_1ᵀ``), so the episodes cannot see them: compared here directly, the aim
    anywhere from the horizon to straight overhead (the elevation clip). Both compute
    ``Z`` from the same angles; the kernel's ``(O + Z) − O`` costs a few ulps of ``|O|``."""
    rng = np.random.default_rng(38)
    origins = rng.uniform(-200.0, 200.0, (64, 3, 3)) * np.array([1.0, 0.0, 1.0])
    aim = rng.uniform(-300.0, 300.0, (64, 3)) * np.array([1.0, 0.2, 1.0])
    aim[:8] = origins[:8, 0] + np.array([0.0, 50.0, 0.0])  # right above receiver 1
    aim[8:16, 1] = 1e4  # far above all of them
    ref = reference.boresight_rotations(origins, aim, PARAMS["default"].max_boresight_elevation)
    kernel = boresight_rotations(origins, aim, PARAMS["default"].max_boresight_elevation)
    np.testing.assert_allclose(ref, kernel, rtol=0.0, atol=1e-12)


def test_an_invalid_action_raises_after_the_same_draws():
    """A NaN action raises in both, after the period's noise has been drawn."""
    params = PARAMS["default"]
    kernel_rng, ref_rng = np.random.default_rng(5), np.random.default_rng(5)
    state = simulation.reset(params, kernel_rng, 2)
    reference.reset(params, ref_rng, 2)
    action = np.zeros((2, 3, 2))
    action[1, 2, 0] = np.nan
    for module, rng in ((simulation, kernel_rng), (reference, ref_rng)):
        with pytest.raises(ValueError, match="NaN"):
            module.step(params, state, action, rng)
    assert kernel_rng.bit_generator.state == ref_rng.bit_generator.state


def _uncapped_drive(params, receivers, action):
    # the speed cap forgotten: components clipped, ‖a‖ up to √2
    a = np.clip(action, -1.0, 1.0)
    v = params.max_speed * np.stack([a[..., 0], np.zeros_like(a[..., 0]), a[..., 1]], -1)
    return reference.in_arena(params, receivers + params.period * v)


def _swapped_noise(noisy_directions):
    # the right draws given to the wrong receivers
    return lambda los, normals, sigma: noisy_directions(los, normals[:, ::-1], sigma)


def _slightly_optimistic(fix_in_world):
    # σ_e one part in a million too small
    def mutant(*args):
        position, velocity, range_sigma, velocity_sigma = fix_in_world(*args)
        return position, velocity, range_sigma * (1 - 1e-6), velocity_sigma * (1 - 1e-6)

    return mutant


def _never_coasting(tracker_estimate):
    # the degenerate fix trusted instead of coasting
    return lambda params, p, v, degenerate, previous: tracker_estimate(
        params, p, v, np.zeros_like(degenerate), previous
    )


MUTANTS: dict[str, tuple[str, str, Callable[[Any], Any]]] = {
    "uncapped-speed": ("default", "drive", lambda _: _uncapped_drive),
    "swapped-noise": ("default", "noisy_directions", _swapped_noise),
    "sigma-e-1e-6": ("default", "fix_in_world", _slightly_optimistic),
    "no-coasting": ("equal-delays", "tracker_estimate", _never_coasting),
}


@pytest.mark.parametrize("mutant", list(MUTANTS))
def test_a_real_difference_fails(mutant, monkeypatch):
    """The comparison is tight enough to see small real changes of the reference (one stage
    replaced by a wrong one): they fail within a few steps."""
    params_name, stage, wrong = MUTANTS[mutant]
    monkeypatch.setattr(reference, stage, wrong(getattr(reference, stage)))
    with pytest.raises(AssertionError):
        _drive(PARAMS[params_name], follow_kernel=True, seed=38, steps=8)
