"""The plan-fix-first rule: on the episode's first step every receiver stays on the drone it was
cued to, so that each track gets its first fix before the plan re-pairs; from then on it is
plan-acquire-share exactly."""

from __future__ import annotations

import numpy as np
import pytest

from sensorgym.agents.registry import rules_for
from sensorgym.agents.stereo_pointing import aimed_drone, rule_view
from sensorgym.agents.stereo_pointing_horizon import PlanHorizon
from sensorgym.agents.stereo_pointing_sharing import Sharing, shared_aims
from sensorgym.envs.stereo_pointing import simulation
from sensorgym.envs.stereo_pointing.simulation import PointingParams, slew_actions

ENV_ID = "sensorgym/StereoPointing-v0"


def test_the_first_step_holds_the_cue_pairs_and_later_steps_are_plan_acquire_share():
    """On 64 seeded scenarios the first action slews every receiver onto the drone it is aimed
    at, the cue's drone ``k mod m`` for receiver ``k`` unless both drones are in its field of
    view (aimed between two drones where they fit, as plan-acquire-share aims), which
    plan-acquire-share does not do in every scenario (it re-pairs on the cue); on the next 20
    steps the two rules act alike on the same observations."""
    params = PointingParams()
    rules = rules_for(ENV_ID, params, lambda: None)
    first, share = rules["plan-fix-first"], rules["plan-acquire-share"]
    B = 64
    rng = np.random.default_rng(500)
    state = simulation.reset(params, rng, B)
    obs = simulation.observe(params, state)
    view = rule_view(params, obs.astype(np.float64))
    cue = np.broadcast_to(np.arange(params.n_receivers) % params.n_drones, (B, params.n_receivers))
    held = aimed_drone(view.aimed)
    both = view.aimed.all(axis=-1)
    np.testing.assert_array_equal(held[~both], cue[~both])
    assert np.all(held >= 0) and both.mean() < 0.2
    points, index = shared_aims(params, view, held, Sharing())
    want = slew_actions(params, view.azimuth, view.elevation, points, index)
    start = np.ones(B, dtype=bool)
    action, steps = first.predict(obs, None, start)
    np.testing.assert_allclose(action, want.astype(np.float32))
    assert np.any(share.predict(obs, None, start)[0] != action)
    for _ in range(20):
        state, _, _ = simulation.step(params, state, action, rng)
        obs = simulation.observe(params, state)
        action, after = first.predict(obs, steps, None)
        np.testing.assert_array_equal(share.predict(obs, steps, None)[0], action)
        steps = after


def test_a_receiver_aimed_at_no_drone_follows_the_plan_while_the_cue_is_held():
    """With random initial pointing (no receiver on the cue) the first step is
    plan-acquire-share's: there is nothing to hold."""
    params = PointingParams(cued_start=False)
    first = PlanHorizon(params, acquisition=True, sharing=Sharing(), cue_steps=1)
    share = PlanHorizon(params, acquisition=True, sharing=Sharing())
    obs = simulation.observe(params, simulation.reset(params, np.random.default_rng(3), 32))
    view = rule_view(params, obs.astype(np.float64))
    free = np.all(aimed_drone(view.aimed) < 0, axis=1)
    assert free.sum() >= 8
    start = np.ones(32, dtype=bool)
    np.testing.assert_array_equal(
        first.predict(obs, None, start)[0][free], share.predict(obs, None, start)[0][free]
    )


@pytest.mark.parametrize("bad", [-1, 1.5, True])
def test_cue_steps_must_be_a_count(bad):
    with pytest.raises(ValueError, match="cue_steps"):
        PlanHorizon(cue_steps=bad)
