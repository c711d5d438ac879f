"""The plan-search rule: the other receivers sent to a lost drone that exactly one receiver sees
aim along that receiver's boresight ray, swept in range and across it, and the seeing receiver
holds its ray; otherwise it is plan-fix-first."""

from __future__ import annotations

import numpy as np
import pytest

from sensorgym.agents.registry import rules_for
from sensorgym.agents.stereo_pointing import RuleView, rule_view
from sensorgym.agents.stereo_pointing_horizon import PlanHorizon
from sensorgym.agents.stereo_pointing_search import EpipolarSearch, search_aims
from sensorgym.agents.stereo_pointing_sharing import Sharing
from sensorgym.envs.stereo_pointing import simulation
from sensorgym.envs.stereo_pointing.simulation import PointingParams, boresights

ENV_ID = "sensorgym/StereoPointing-v0"


def _lost_view(params: PointingParams, sigma: float, seen_by: tuple[int, ...]) -> RuleView:
    """One scenario: drone 0 predicted at ``x̂``, every receiver's boresight through a point 9 m
    from it (so the prediction is off), seen on the last step by the receivers ``seen_by``;
    drone 1 elsewhere, tracked to 5 cm."""
    rec = params.receiver_positions
    x_hat = np.array([[20.0, 60.0, 90.0], [-70.0, 40.0, -30.0]])
    truth = x_hat[0] + np.array([6.0, -3.0, 6.0])
    d = truth - rec
    azimuth = np.arctan2(d[:, 0], d[:, 2])
    elevation = np.arctan2(d[:, 1], np.hypot(d[:, 0], d[:, 2]))
    los = x_hat[None] - rec[:, None]
    ranges = np.linalg.norm(los, axis=-1)
    seen = np.zeros((params.n_receivers, params.n_drones))
    seen[list(seen_by), 0] = 1.0
    return RuleView(
        azimuth=azimuth[None], elevation=elevation[None], seen=seen[None], aimed=seen[None],
        position=x_hat[None], sigma=np.array([[sigma, 0.05]]), velocity=np.zeros((1, 2, 3)),
        los=(los / ranges[..., None])[None], ranges=ranges[None],
    )  # fmt: skip


def test_the_searching_receivers_aim_on_the_seeing_receivers_ray_swept_in_range():
    """Receivers 1 and 3 are sent to drone 0 (``target``), which only receiver 1 saw: receiver 3
    searches on
    receiver 1's boresight ray — at the ray's point nearest the prediction on a step whose
    sweep offset is 0, one sweep step further on the next — and receiver 1 keeps its aim;
    receivers sent to the tracked drone never search."""
    params = PointingParams()
    search = EpipolarSearch(across=(0.0,), anchor=False)
    view = _lost_view(params, sigma=10.0, seen_by=(1,))
    target = np.array([[1, 0, 1, 0]])
    origin = params.receiver_positions[1]
    ray = boresights(view.azimuth, view.elevation)[0, 1]
    rho = ray @ (view.position[0, 0] - origin)
    points, searching = search_aims(params, view, target, np.array([0]), search)
    np.testing.assert_array_equal(searching, [[False, False, False, True]])
    np.testing.assert_allclose(points[0, 3], origin + rho * ray, atol=1e-9)
    later, _ = search_aims(params, view, target, np.array([1]), search)
    step = later[0, 3] - points[0, 3]
    np.testing.assert_allclose(np.cross(step, ray), 0.0, atol=1e-9)  # along the ray
    mean_range = np.linalg.norm(origin + rho * ray - params.receiver_positions, axis=-1).mean()
    assert step @ ray == pytest.approx(search.sweep[1] * search.width * params.fov * mean_range)


@pytest.mark.parametrize("anchor", [False, True])
@pytest.mark.parametrize(
    ("sigma", "seen_by"), [(1.0, (3,)), (10.0, ()), (10.0, (0, 3)), (10.0, (1,)), (10.0, (3,))]
)
def test_who_searches_depends_on_the_track_and_the_single_sighting(sigma, seen_by, anchor):
    """Receivers 0 and 3 are sent to drone 0. A track under ``lost_rms``, or a drone that no
    receiver or two receivers saw: nobody searches. Seen by receiver 3 alone: receiver 0
    searches, and receiver 3 holds its ray with the anchor; seen by receiver 1 alone (sent
    elsewhere): both search along its ray."""
    params = PointingParams()
    view = _lost_view(params, sigma, seen_by)
    target = np.array([[0, 1, 1, 0]])
    search = EpipolarSearch(anchor=anchor)
    _, searching = search_aims(params, view, target, np.array([4]), search)
    want = {(3,): [True, False, False, anchor], (1,): [True, False, False, True]}
    lost = sigma > search.lost_rms
    expected = want.get(seen_by, [False] * 4) if lost else [False] * 4
    np.testing.assert_array_equal(searching, [expected])


def test_the_seeing_receiver_holds_its_ray_advanced_by_the_estimated_velocity():
    """Receiver 1 alone saw the lost drone 0 and is sent to it: with the anchor it aims at its
    own ray's point nearest the prediction plus ``v̂ · dt`` (not at the prediction, 9 m off);
    without, it is not among the searching receivers (it aims at the prediction)."""
    params = PointingParams()
    view = _lost_view(params, sigma=10.0, seen_by=(1,))
    velocity = np.array([[[3.0, -1.0, 4.0], [0.0, 0.0, 0.0]]])
    view = RuleView(**{**view.__dict__, "velocity": velocity})
    target = np.array([[1, 0, 1, 0]])
    origin = params.receiver_positions[1]
    ray = boresights(view.azimuth, view.elevation)[0, 1]
    nearest = origin + (ray @ (view.position[0, 0] - origin)) * ray
    for t in (0, 5):
        points, searching = search_aims(params, view, target, np.array([t]), EpipolarSearch())
        assert searching[0, 1]
        np.testing.assert_allclose(points[0, 1], nearest + velocity[0, 0] * params.dt, atol=1e-9)
    _, searching = search_aims(params, view, target, np.array([0]), EpipolarSearch(anchor=False))
    assert not searching[0, 1]


def test_the_sweep_moves_across_the_ray_after_each_sweep_along_it():
    """With ``sweep (0, 1)`` and ``across (0, 0.7, −0.7)``: steps 0 and 1 stay on the ray; on
    steps 2 and 4 (along offset 0) the searching receiver's point lies ``±0.7 · fov · ρ`` off
    the nearest point along ``b × d``, perpendicular to the ray ``b`` and to that receiver's
    line of sight ``d``; step 6 is back on the ray."""
    params = PointingParams()
    search = EpipolarSearch(sweep=(0, 1), across=(0.0, 0.7, -0.7))
    view = _lost_view(params, sigma=10.0, seen_by=(1,))
    target = np.array([[1, 0, 1, 0]])
    origin, k = params.receiver_positions[1], params.receiver_positions[3]
    ray = boresights(view.azimuth, view.elevation)[0, 1]
    rho = ray @ (view.position[0, 0] - origin)
    nearest = origin + rho * ray
    off = {}
    for t in (0, 1, 2, 4, 6):
        points, _ = search_aims(params, view, target, np.array([t]), search)
        off[t] = points[0, 3] - nearest
    for t in (0, 1, 6):
        np.testing.assert_allclose(np.cross(off[t], ray), 0.0, atol=1e-9)
    across = np.cross(ray, nearest - k)
    across /= np.linalg.norm(across)
    for t, sign in ((2, 1.0), (4, -1.0)):
        np.testing.assert_allclose(off[t], sign * 0.7 * params.fov * rho * across, atol=1e-9)


def test_a_searching_receiver_on_the_seeing_receivers_ray_is_not_shifted_across():
    """Receiver 1's ray runs through receiver 3 (``b × d = 0``): on a step with an across
    offset, receiver 3's point stays on the ray (finite, no direction to shift in)."""
    params = PointingParams()
    view = _lost_view(params, sigma=10.0, seen_by=(1,))
    rec = params.receiver_positions
    d = rec[3] - rec[1]
    azimuth, elevation = view.azimuth.copy(), view.elevation.copy()
    azimuth[0, 1] = np.arctan2(d[0], d[2])
    elevation[0, 1] = np.arctan2(d[1], np.hypot(d[0], d[2]))
    view = RuleView(**{**view.__dict__, "azimuth": azimuth, "elevation": elevation})
    search = EpipolarSearch(sweep=(0,), across=(0.0, 0.7))
    target = np.array([[1, 0, 1, 0]])
    on_ray, _ = search_aims(params, view, target, np.array([0]), search)
    shifted, searching = search_aims(params, view, target, np.array([1]), search)
    assert searching[0, 3] and np.all(np.isfinite(shifted))
    np.testing.assert_allclose(shifted[0, 3], on_ray[0, 3], atol=1e-9)


def test_without_lost_drones_the_rule_is_plan_fix_first_and_the_registered_one_searches():
    """With ``lost_rms`` infinite the actions are plan-fix-first's on every step of 16 seeded
    scenarios; the registered plan-search differs on some steps of 64."""
    params = PointingParams()
    rules = rules_for(ENV_ID, params, lambda: None)
    first = rules["plan-fix-first"]
    never = PlanHorizon(
        params,
        acquisition=True,
        sharing=Sharing(),
        cue_steps=1,
        search=EpipolarSearch(lost_rms=np.inf),
    )
    for rule, batch in ((never, 16), (rules["plan-search"], 64)):
        rng = np.random.default_rng(500)
        state = simulation.reset(params, rng, batch)
        differ, steps = 0, None
        for t in range(60):
            obs = simulation.observe(params, state)
            start = np.full(batch, t == 0)
            a, next_steps = rule.predict(obs, steps, start)
            differ += int(np.any(a != first.predict(obs, steps, start)[0]))
            steps = next_steps
            state, _, _ = simulation.step(params, state, a, rng)
        assert (differ == 0) if rule is never else (differ > 0)


@pytest.mark.parametrize(
    "bad",
    [
        {"lost_rms": -1.0},
        {"width": float("nan")},
        {"sweep": ()},
        {"sweep": (0.5,)},
        {"across": ()},
        {"across": (0.0, float("inf"))},
        {"anchor": "yes"},
    ],
)
def test_bad_search_settings_are_refused(bad):
    with pytest.raises(ValueError, match=next(iter(bad))):
        EpipolarSearch(**bad)


def test_a_view_of_the_env_decodes_for_the_search():
    """The search runs on real observations (shapes and finite points)."""
    params = PointingParams()
    obs = simulation.observe(params, simulation.reset(params, np.random.default_rng(2), 8))
    view = rule_view(params, obs.astype(np.float64))
    target = np.tile(np.arange(4) % 2, (8, 1))
    points, searching = search_aims(params, view, target, np.zeros(8, np.int64), EpipolarSearch())
    assert points.shape == (8, 4, 3) and searching.shape == (8, 4)
    assert np.all(np.isfinite(points))


def test_the_wrappers_search_keyword_takes_every_field_as_yaml_gives_it():
    """``pointing-plan``'s ``search:`` mapping (lists and ints, as YAML gives them) builds the
    same :class:`EpipolarSearch`; a non-bool anchor is refused."""
    from sensorgym.train.env_wrappers.stereo_pointing import _search

    given = {"lost_rms": 2, "width": 1, "sweep": [0, 1], "across": [0, 0.5], "anchor": False}
    want = EpipolarSearch(lost_rms=2.0, width=1.0, sweep=(0, 1), across=(0.0, 0.5), anchor=False)
    assert _search(given) == want
    assert _search(True) == EpipolarSearch() and _search(None) is None
    with pytest.raises(ValueError, match="anchor"):
        _search({"anchor": "no"})
