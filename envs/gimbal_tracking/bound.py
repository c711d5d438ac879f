"""A true upper bound on the ``sensorgym/GimbalTracking-v0`` return, per frame and per episode.

**What the reward depends on.** Frame ``k`` pays (theory §11.8, :func:`.reference.reward`)

    r_k = clip(ln(σ_ref/σ_k), −R, R)   (target in the field of view),   r_k = −R   (out of it)

with ``σ_k = √((d_α,k + d_β,k)/MRAD² + 2σ_s²)`` and ``d`` paper 004's posterior variance in each
image plane (mrad²). Its recursion (theory §9.2, :meth:`~sensorgym.trackers.fusion.tracker.
FusionTracker.update`) is, per plane,

    D_k = R_λ² d_{k−1} + d₀ ,      d_k = [D_k⁻¹ + Σ_n Σ_m P_k(ϑ_m^{(n)}) I_n(ϑ_m^{(n)})]⁻¹

or ``d_k = D_k`` when the loop opens. The Fisher information ``I`` comes from the tracker's
model (the channels' nominal contrast), not from the image: what the images, the pointing and
the noise move is only the view posterior ``P``.

**The bound.** ``P`` is a distribution over the views and the background view carries no
information, so ``Σ_m P_m I_n(ϑ_m) ≤ I_n* = max_m I_n(ϑ_m)``; the right-hand side of the update
decreases in that sum and increases in ``d_{k−1}`` (opening the loop gives the larger ``D_k``).
By induction from the state's own ``d_0``, every policy's ``d_k`` is at least

    d*_k = [(R_λ² d*_{k−1} + d₀)⁻¹ + Σ_n I_n*]⁻¹ ,     d*_0 = d_0 ,

the variance of a tracker sure of the object in every channel every frame. So
``r_k ≤ B_k = clip(ln(σ_ref/σ*_k), −R, R)`` (and ``−R ≤ B_k`` covers the frames out of view).

**Several gimbals** (``n_gimbals = G > 1``, theory §11.8.2): each gimbal's fused tracker runs
the recursion above on its own images, so each gimbal's ``d_{g,k} ≥ d*_{g,k}`` from its own
start; the track's ``σ_k`` is one gimbal's (the measuring gimbal's,
:func:`.reference.measuring_gimbal`), so ``σ_k ≥ min_g σ*_{g,k}`` and
``B_k = clip(ln(σ_ref/min_g σ*_{g,k}), −R, R)``. It holds whichever gimbal measures and however
the policy hands the target over; it does not credit two gimbals' estimates combined, which
the env never does.
An episode that terminates early sums fewer frames; its return is at most the largest partial
sum ``max_T Σ_{k≤T} B_k`` over the time limit, which is the episode bound.

**What it gives away.** It credits every frame with every channel's full information: the
views the channels' Markov chains take (background for a while), the occlusions, the off-axis
loss of contrast and the noise's effect on the posterior all cost a policy reward the bound
still counts. The first three follow from draws no action moves (the chains and the
occlusions), so most of the room between a policy and this bound is not reachable; where none
of them act (no losses, high contrast, the gimbal on the target) a policy reaches it
(``tests/envs/gimbal_tracking/test_bound.py``).
"""

from __future__ import annotations

import gymnasium
import numpy as np
from numpy.typing import NDArray

from sensorgym.envs.gimbal_tracking.reference import los_sigma
from sensorgym.envs.gimbal_tracking.simulation import GimbalParams, GimbalState

FloatArray = NDArray[np.float64]

ENV_ID = "sensorgym/GimbalTracking-v0"


def least_variance(params: GimbalParams, start: FloatArray, steps: int) -> FloatArray:
    """``d*_k`` ``(B, steps, …, 2)`` (mrad²): the least posterior variance of each plane in each
    of the next ``steps`` frames from the variances ``start (B, …, 2)`` (the state's
    ``(B, G, 2)``: per gimbal; module docstring)."""
    if steps < 1:
        raise ValueError(f"steps: must be >= 1, got {steps}")
    model = params.fusion_tracker.model
    R2 = model.correlation**2
    d0 = model.transition_variance
    info = float(np.sum(np.max(model.fisher_information, axis=1)))  # Σ_n I_n*
    d = np.array(start, dtype=np.float64)
    out = np.empty((d.shape[0], steps, *d.shape[1:]))
    for k in range(steps):
        D = R2 * d + d0  # D_k = R_λ² d*_{k−1} + d₀
        d = 1.0 / (1.0 / D + info)  # d*_k = [D_k⁻¹ + Σ_n I_n*]⁻¹
        out[:, k] = d
    return out


def step_bounds(params: GimbalParams, state: GimbalState, steps: int) -> FloatArray:
    """``B_k`` ``(B, steps)`` of the module docstring: no policy's reward in each of the next
    ``steps`` frames from ``state`` exceeds it."""
    d = least_variance(params, state.fusion_variance, steps)  # (B, steps, G, 2)
    sigma = los_sigma(params, d).min(-1)  # min_g σ*_{g,k}, rad
    R = params.reward_clip
    return np.clip(np.log(params.sigma_ref / sigma), -R, R)


def episode_bound(params: GimbalParams, state: GimbalState, steps: int | None = None) -> FloatArray:
    """``(B,)`` the bound of the return from ``state`` over at most ``steps`` frames (None: the
    registration's ``max_episode_steps``, 500 — from a reset state, the whole episode): the
    largest partial sum of :func:`step_bounds`, so that an episode ending sooner is bounded
    too. No policy's return from ``state`` can exceed it."""
    if steps is None:
        steps = int(gymnasium.spec(ENV_ID).max_episode_steps)
    values = step_bounds(params, state, steps)
    total = np.zeros(values.shape[0])
    best = np.full(values.shape[0], -np.inf)
    for k in range(steps):  # in frame order, as a return is summed
        total += values[:, k]
        best = np.maximum(best, total)
    return best


__all__ = ["episode_bound", "least_variance", "step_bounds"]
