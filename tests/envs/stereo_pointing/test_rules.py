"""The pointing rules on the compiled assignment scores choose exactly what their numpy forms
(kept here as the reference) chose."""

from __future__ import annotations

import numpy as np
import pytest

from sensorgym.agents.stereo_pointing import (
    GreedyPointing,
    OrthogonalPairs,
    all_assignments,
    hysteresis_bonus,
    rule_view,
)
from sensorgym.envs.stereo_pointing.simulation import PointingParams
from sensorgym.envs.stereo_pointing.stereo_pointing import StereoPointingVectorEnv
from sensorgym.trackers.stereo.information import position_information


def _orthogonal_numpy(rule: OrthogonalPairs, view) -> np.ndarray:
    cand = all_assignments(rule.params)
    m = rule.params.n_drones
    member = (cand[:, None, :] == np.arange(m)[None, :, None]).astype(np.float64)
    cos = np.einsum("Nkji,Nlji->Njkl", view.los, view.los)
    sin2 = np.clip(1.0 - cos**2, 0.0, 1.0)
    total = np.einsum("cjl,Njkl->Ncjk", member, sin2)
    total = np.where(member[None] > 0.0, total, 0.0).max(axis=-1)
    objective = 0.5 * np.log(np.maximum(total, 1e-300)).sum(axis=-1)
    objective = objective + hysteresis_bonus(view, cand, rule.keep_bonus)
    return cand[np.argmax(objective, axis=-1)]


def _greedy_numpy(rule: GreedyPointing, view) -> np.ndarray:
    cand = all_assignments(rule.params)
    m = rule.params.n_drones
    member = (cand[:, None, :] == np.arange(m)[None, :, None]).astype(np.float64)
    sigma = max(rule.params.sigma_ang, 1e-9)
    u = np.swapaxes(view.los, 1, 2)[:, None]
    r = np.swapaxes(view.ranges, 1, 2)[:, None]
    info = position_information(u, r, sigma, mask=member[None] > 0.0)
    pair = (member.sum(axis=-1) >= 2.0)[None]
    sign, logdet = np.linalg.slogdet(np.where(pair[..., None, None], info, np.eye(3)))
    logdet = np.where(pair & (sign > 0.0), logdet, -rule.no_fix_cost)
    objective = logdet.sum(axis=-1) + hysteresis_bonus(view, cand, rule.keep_bonus)
    return cand[np.argmax(objective, axis=-1)]


def _observations(params: PointingParams, seed: int) -> np.ndarray:
    """Observations of 64 scenarios over 30 steps, half driven by the greedy rule (receivers on
    drones, views and fixes), half at random."""
    venv = StereoPointingVectorEnv(num_envs=64, params=params, max_episode_steps=12)
    obs, _ = venv.reset(seed=seed)
    rule, rng, seen = GreedyPointing(params), np.random.default_rng(seed), [obs]
    for step in range(30):
        if step % 2:
            action = rng.uniform(-1.0, 1.0, venv.action_space.shape)
        else:
            action = rule.predict(obs)[0]
        obs, *_ = venv.step(action)
        seen.append(obs)
    return np.concatenate(seen).astype(np.float64)


@pytest.mark.parametrize(
    "params",
    [
        PointingParams(),
        PointingParams(n_receivers=3, n_drones=3, sigma_ang=0.0),
        PointingParams(n_receivers=5, n_drones=2, cued_start=False, fov=0.5),
        PointingParams(n_receivers=6, n_drones=3, circle_radius=5.0),
    ],
)
def test_compiled_assignment_scores_choose_as_the_numpy_forms(params):
    obs = _observations(params, seed=params.n_receivers)
    view = rule_view(params, obs)
    orthogonal, greedy = OrthogonalPairs(params), GreedyPointing(params)
    np.testing.assert_array_equal(orthogonal.choose(view), _orthogonal_numpy(orthogonal, view))
    np.testing.assert_array_equal(greedy.choose(view), _greedy_numpy(greedy, view))
