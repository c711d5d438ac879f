"""A true upper bound on the ``sensorgym/StereoScanning-v0`` return, per step and per episode.

**What the reward depends on.** Period ``k = 1, 2, …`` of an episode (theory §11.5,
:func:`.kernels.step_rows`, its step 4) pays

    r_k = (1/N_k) Σ_{present d} u_d − λ · (confirmed tracks no drone is assigned to)   (N_k > 0)
    r_k = −λ · (confirmed tracks)                                                      (N_k = 0)

with ``u_d = clip(ln(σ_ref/σ_d), −R, R)`` for a drone with an assigned confirmed track and
``u_d = −R`` without one, ``N_k`` the drones present at the period's start (entered and not yet
gone), ``R = reward_clip`` and ``λ = false_track_penalty ≥ 0``.

**The bound.** Three facts hold whatever the sectors were:

1. ``u_d ≤ R`` and the false-track term is ``≤ 0``: ``r_k ≤ R`` when ``N_k > 0``, ``r_k ≤ 0``
   when ``N_k = 0``.
2. A track gains at most one member per period, the table is empty at the reset, and a track
   is confirmed once it has members in ``h = confirm_hits`` periods (at once when ``h ≤ 1``).
   So no confirmed track exists in periods ``k < h``: every present drone has ``u_d = −R`` and
   ``r_k = −R`` (``N_k > 0``) or ``0``.
3. ``N_k`` and the episode's end (every drone gone) follow from the drones' paths alone —
   straight, constantly accelerating, leaving the scene box for good — which no action and no
   measurement noise moves.

Hence ``B_k = −R`` (``k < h``, ``N_k > 0``), ``R`` (``k ≥ h``, ``N_k > 0``), ``0`` (``N_k = 0``)
and ``Σ_k B_k ≥`` the return of every policy on that episode. The periods past the episode's
end add ``B_k ≥ 0`` (``k ≥ h`` there when the episode is longer than ``h``), so summing up to
the registered time limit is safe even for an episode that ends sooner.

**What it gives away.** It is loose, and says so: every present drone is credited with the
clip ``R`` from period ``h`` on, as if a narrow sector had fixed it with ``σ_d ≤ σ_ref e^{−R}``
(7 mm) every period. A floor on ``σ_d`` does not tighten it usefully: the exact covariance of
a triple gives ``σ_pos ≥ √2 σ_1 r̂_1`` (§3.5; the other terms are positive semi-definite), and
with the narrowest sector (5°, ``σ_1 = 0.09`` mrad) and ``r̂_1 ≈ 120`` m that is 15 mm, a reward of
4.2 rather than 5 — but only for a track fixed in the period; a coasting track is compared
at ``p̂ + v̂ Δ``, and its estimated velocity (bounded only by ``max_speed`` plus its own
spread) lets ``r̂_1`` at its last fix lie anywhere within ``(max_misses + 1) τ · max_speed``
of the drone, where the floor vanishes. What remains unclaimed between a policy and this bound
is therefore not all reachable: most of it is that a receiver's narrow sector cannot cover
every drone every period.

:func:`step_bounds` replays the episode's truth through the env's own step (any action, any
noise: fact 3) and reads ``N_k`` from its ``parts``; one implementation of the drones' flight.
"""

from __future__ import annotations

import gymnasium
import numpy as np
from numpy.typing import NDArray

from sensorgym.envs.stereo_scanning import simulation
from sensorgym.envs.stereo_scanning.simulation import ScanningParams, ScanningState

FloatArray = NDArray[np.float64]

ENV_ID = "sensorgym/StereoScanning-v0"


def present_drones(params: ScanningParams, state: ScanningState, steps: int) -> FloatArray:
    """``N_k`` ``(B, steps)``: the drones present in each of the next ``steps`` periods from
    ``state`` (0 once every drone is gone), from the env's own step on the truth (fact 3 of
    the module docstring: the actions and the noise drawn do not move it)."""
    if steps < 1:
        raise ValueError(f"steps: must be >= 1, got {steps}")
    B = state.batch_size
    action = np.zeros((B, params.receivers.shape[0], 3))
    rng = np.random.default_rng(0)  # the fixes' noise: the drones' flight draws nothing
    out = np.zeros((B, steps))
    gone = np.zeros(B, dtype=bool)
    s = state
    for k in range(steps):
        s, _, terminated = simulation.step(params, s, action, rng)
        out[:, k] = np.where(gone, 0.0, s.parts[:, 0])
        gone |= terminated
        if gone.all():
            break
    return out


def step_bounds(params: ScanningParams, state: ScanningState, steps: int) -> FloatArray:
    """``B_k`` ``(B, steps)`` of the module docstring for the next ``steps`` periods from
    ``state``. Fact 2 applies to the scenarios at a reset (``t = 0``, an empty track table);
    from a state inside an episode, where confirmed tracks may exist, every period with a
    drone present is bounded by ``R`` (a bound on the rest of that episode's return)."""
    n = present_drones(params, state, steps)
    R = params.reward_clip
    k = np.arange(1, steps + 1)
    at_reset = (state.t == 0.0) & ~np.any(state.track_int[..., 2] != 0, axis=1)
    per_drone = np.where(at_reset[:, None] & (k[None, :] < params.confirm_hits), -R, R)
    return np.where(n > 0, per_drone, 0.0)


def episode_bound(
    params: ScanningParams, state: ScanningState, steps: int | None = None
) -> FloatArray:
    """``(B,)`` the bound of the return from ``state`` over ``steps`` periods (None: the
    registration's ``max_episode_steps``, 40 — from a reset state, the whole episode): no
    policy's return from ``state`` can exceed it (module docstring, :func:`step_bounds`)."""
    if steps is None:
        steps = int(gymnasium.spec(ENV_ID).max_episode_steps)
    values = step_bounds(params, state, steps)
    out = np.zeros(values.shape[0])
    for k in range(steps):  # in step order, as a return is summed
        out += values[:, k]
    return out
