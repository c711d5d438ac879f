"""The plan-acquire-share rule: a receiver aims between its drone and another one when both fit
in its field of view, and then sees both; it keeps its drone's prediction otherwise; with
sharing off the rule is plan-acquire exactly."""

from __future__ import annotations

import numpy as np
import pytest

from sensorgym.agents.registry import rules_for
from sensorgym.agents.stereo_pointing import rule_view
from sensorgym.agents.stereo_pointing_horizon import PlanHorizon
from sensorgym.agents.stereo_pointing_sharing import Sharing, share_logits, shared_aims
from sensorgym.envs.stereo_pointing import simulation
from sensorgym.envs.stereo_pointing.simulation import PointingParams, slew_actions
from sensorgym.trackers.geometry import unit_from_angles

ENV_ID = "sensorgym/StereoPointing-v0"


def _two_drones(params: PointingParams, separation_deg: float):
    """Two drones 120 m from receiver 0, ``separation_deg`` apart in azimuth seen from it;
    receivers all pointing at drone 0; a near-exact cue (track RMS about 0.2 m)."""
    r0 = params.receiver_positions[0]
    az0, el = 0.4, 0.35
    drones = np.stack([
        r0 + 120.0 * unit_from_angles(az0, el),
        r0 + 120.0 * unit_from_angles(az0 + np.deg2rad(separation_deg), el),
    ])[None]  # fmt: skip
    los = drones[0, 0] - params.receiver_positions
    azimuth = np.arctan2(los[:, 0], los[:, 2])[None]
    elevation = np.arctan2(los[:, 1], np.hypot(los[:, 0], los[:, 2]))[None]
    state = simulation.start(params, drones, np.zeros((1, 2, 3)), azimuth, elevation,
                             np.random.default_rng(1))  # fmt: skip
    return state, rule_view(params, simulation.observe(params, state).astype(np.float64))


@pytest.mark.parametrize("separation", [4.0, 12.0, 25.0])
def test_a_receiver_holds_two_drones_exactly_when_they_fit(separation):
    params = PointingParams(cue_sigma=(0.1, 0.1))
    state, view = _two_drones(params, separation)
    target = np.zeros((1, params.n_receivers), dtype=np.int64)  # every receiver on drone 0
    points, index = shared_aims(params, view, target, Sharing())
    fits = np.deg2rad(separation) < 2 * params.fov * Sharing().fraction
    assert (index[0, 0] >= params.n_drones) == fits
    # slewed there (within a few steps at the gimbal's rate), receiver 0 sees what it aims at
    for _ in range(8):
        action = slew_actions(params, view.azimuth, view.elevation, points, index)
        state, _, _ = simulation.step(params, state, action, np.random.default_rng(2))
        view = rule_view(params, simulation.observe(params, state).astype(np.float64))
        points, index = shared_aims(params, view, target, Sharing())
    assert state.seen[0, 0, 0]
    assert state.seen[0, 0, 1] == fits  # the second drone only when shared
    # a receiver left on drone 0 by the bisector rule still sees drone 0 whenever it shares
    assert np.all(state.seen[0, index[0] >= params.n_drones, 0])


def test_an_uncertain_track_is_not_shared():
    params = PointingParams(cue_sigma=(5.0, 2.0))  # the cue: RMS about 8.7 m > max_rms 3 m
    _, view = _two_drones(params, 4.0)
    target = np.zeros((1, params.n_receivers), dtype=np.int64)
    _, index = shared_aims(params, view, target, Sharing())
    np.testing.assert_array_equal(index, target)


def test_sharing_settings_are_validated():
    for bad in ({"margin": -1.0}, {"fraction": 1.5}, {"max_rms": float("nan")}):
        with pytest.raises(ValueError):
            Sharing(**bad)


def test_the_rule_is_plan_acquire_where_no_pair_fits_and_differs_where_some_do():
    """With a zero share of the field of view nothing fits and the rule's actions are
    plan-acquire's on every step of 8 registered scenarios; the registered setting aims
    between drones on some of those steps."""
    params = PointingParams()
    rules = rules_for(ENV_ID, params, lambda: None)
    plain, share = rules["plan-acquire"], rules["plan-acquire-share"]
    never = PlanHorizon(params, acquisition=True, sharing=Sharing(fraction=0.0))
    rng = np.random.default_rng(500)
    state = simulation.reset(params, rng, 8)
    differ, steps = 0, None
    for t in range(150):
        obs = simulation.observe(params, state)
        start = np.full(8, t == 0)
        a, next_steps = plain.predict(obs, steps, start)
        np.testing.assert_array_equal(never.predict(obs, steps, start)[0], a)
        b, _ = share.predict(obs, steps, start)
        differ += int(np.any(a != b))
        steps = next_steps
        state, _, _ = simulation.step(params, state, b, rng)
    assert differ > 0


def _scenario_views(params: PointingParams, seed: int, batch: int, steps: int):
    """Views and plan-acquire assignments of ``steps`` steps of seeded scenarios played by the
    plan-acquire-share rule."""
    rule = PlanHorizon(params, acquisition=True, sharing=Sharing())
    rng = np.random.default_rng(seed)
    state = simulation.reset(params, rng, batch)
    out, t = [], None
    for k in range(steps):
        obs = simulation.observe(params, state)
        view = rule_view(params, obs.astype(np.float64))
        out.append((view, rule.choose(view, np.full(batch, k)), k))
        action, t = rule.predict(obs, t, np.full(batch, k == 0))
        state, _, _ = simulation.step(params, state, action, rng)
    return out


def test_the_share_logits_are_positive_exactly_where_the_stated_test_holds():
    """On 40 steps of 16 seeded scenarios and three settings, ``share_logits > 0`` is the
    docstring's test ``∠ + 2 q max(σ̂_j/r_kj, σ̂_t/r_kt) < 2 f fov`` with both tracks' RMS
    below ``max_rms``, for another drone in sight; some pairs pass and some fail."""
    params = PointingParams()
    passed = failed = 0
    for view, target, _ in _scenario_views(params, 7, 16, 40):
        for sharing in (Sharing(), Sharing(0.0, 1.0, 6.0), Sharing(1.0, 0.5, 1.0)):
            logits = share_logits(params, view, target, sharing)
            for k in range(params.n_receivers):
                rows = np.arange(16)
                u = view.los[rows, k, target[:, k]]
                for j in range(params.n_drones):
                    angle = np.arccos(np.clip(np.sum(u * view.los[:, k, j], axis=1), -1, 1))
                    rms = np.maximum(
                        view.sigma[:, j] / view.ranges[:, k, j],
                        view.sigma[rows, target[:, k]] / view.ranges[rows, k, target[:, k]],
                    )
                    expect = (
                        (angle + 2 * sharing.margin * rms < 2 * params.fov * sharing.fraction)
                        & (view.sigma[:, j] < sharing.max_rms)
                        & (view.sigma[rows, target[:, k]] < sharing.max_rms)
                        & (target[:, k] != j)
                    )
                    np.testing.assert_array_equal(logits[:, k, j] > 0, expect)
                    passed, failed = passed + expect.sum(), failed + (~expect).sum()
    assert passed > 0 and failed > 0
