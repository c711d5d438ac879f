"""StereoScanning-v0: the rules' search schedule and the ``scan-modes`` action wrapper."""

from __future__ import annotations

import numpy as np
import pytest
from gymnasium import spaces

from sensorgym.agents import stereo_scanning as rules
from sensorgym.envs.stereo_scanning.simulation import (
    ScanningParams,
    local_angles,
    sector_action,
    split_observation,
)
from sensorgym.train.env_wrappers.stereo_scanning import (
    MODES,
    EntrySearchModes,
    ScanModes,
    entry_search_expert,
    mode_sectors,
)
from sensorgym.train.evaluation import evaluate, make_sb3_env

ENV_ID = "sensorgym/StereoScanning-v0"
PARAMS = ScanningParams()


def one_track_observation(params: ScanningParams = PARAMS) -> np.ndarray:
    """An observation with one confirmed track 10 m from the scene centre, moving at 3 m/s."""
    obs = np.zeros((1, params.obs_dim), np.float32)
    obs[0, 0] = 1.0
    obs[0, 1:4] = np.array([10.0, 0.0, 0.0]) / params.length_scale
    obs[0, 4:7] = np.array([0.0, 0.0, 3.0]) / params.speed_scale
    return obs


def widths(rule, obs: np.ndarray, periods: int) -> np.ndarray:
    """The sector widths (rad, receiver 0) ``rule`` chooses on ``obs`` for ``periods`` periods."""
    state, out = None, []
    for k in range(periods):
        action, state = rule.predict(obs, state, np.array([k == 0]))
        out.append(action[0, 2])
    lo, hi = PARAMS.sector_width
    return lo + 0.5 * (np.asarray(out) + 1.0) * (hi - lo)


@pytest.mark.parametrize("make", [rules.CueFollowing, rules.GreedyInformation])
def test_rules_search_with_two_consecutive_sweeps_every_sweep_every_periods(make):
    w = widths(make(PARAMS), one_track_observation(), 2 * rules.SWEEP_EVERY + 2)
    swept = np.flatnonzero(np.isclose(w, PARAMS.sector_width[1]))
    e = rules.SWEEP_EVERY
    np.testing.assert_array_equal(swept, [0, 1, e, e + 1, 2 * e, 2 * e + 1])
    assert np.all(w[[2, e - 1, e + 2]] < np.deg2rad(30.0))


def test_a_rule_without_search_sweeps_only_at_the_start():
    w = widths(rules.CueFollowing(PARAMS, sweep_every=rules.NEVER), one_track_observation(), 25)
    np.testing.assert_array_equal(np.flatnonzero(np.isclose(w, PARAMS.sector_width[1])), [0, 1])


def test_the_search_beats_no_search_and_single_sweeps():
    """A single sweep cannot confirm a new drone (its tentative track must be continued the
    next period): the two-sweep search finds the late drone and earns more, same scenarios."""
    env = make_sb3_env(ENV_ID, 16, 77)
    scores = {
        name: evaluate(rule, env, 32, 77).mean
        for name, rule in {
            "search": rules.CueFollowing(PARAMS),
            "single": rules.CueFollowing(PARAMS, sweep_periods=1),
            "never": rules.CueFollowing(PARAMS, sweep_every=rules.NEVER),
        }.items()
    }
    env.close()
    assert scores["search"] > scores["single"] + 3.0
    assert scores["search"] > scores["never"]


def test_entry_search_covers_the_entry_region_and_the_tracks_narrower_than_a_sweep():
    o = split_observation(PARAMS, one_track_observation())
    sectors = rules.entry_sectors(PARAMS, o, 0)
    w = sectors[:, 2]
    assert np.all(w < np.deg2rad(60.0)) and np.all(w > np.deg2rad(40.0))
    points = np.concatenate([rules.entry_points(PARAMS), o["position"][0, :1]])
    ang = local_angles(PARAMS, points)  # (9, n, 3)
    assert np.all(np.abs(ang[..., :2] - sectors[None, :, :2]) <= 0.5 * w[None, :, None] + 1e-9)
    # the rule searches with these sectors on its search periods, even before any track
    rule = rules.CueFollowing(PARAMS, search="entry")
    action, _ = rule.predict(np.zeros((1, PARAMS.obs_dim), np.float32), None, np.array([True]))
    np.testing.assert_allclose(action[0, 2], sector_action(PARAMS, sectors)[0, 2], atol=0.05)
    with pytest.raises(ValueError, match="search"):
        rules.CueFollowing(PARAMS, search="spiral")


def test_mode_sectors_are_the_rules_plans():
    obs = np.repeat(one_track_observation(), 4, axis=0)
    sectors = mode_sectors(PARAMS, obs, np.array([0, 1, 2, 3]))
    np.testing.assert_allclose(sectors[0, :, :2], 0.0)
    np.testing.assert_allclose(sectors[0, :, 2], PARAMS.sector_width[1])
    cue = rules.CueFollowing(PARAMS).sectors(split_observation(PARAMS, obs), 1)
    np.testing.assert_allclose(sectors[1], cue)
    np.testing.assert_allclose(sectors[2, :, :2], cue[:, :2])
    np.testing.assert_allclose(sectors[2, :, 2], np.minimum(2 * cue[:, 2], PARAMS.sector_width[1]))
    entry = rules.entry_sectors(PARAMS, split_observation(PARAMS, obs), 3)
    np.testing.assert_allclose(sectors[3], entry)
    # without a confirmed track cue and cue-wide sweep
    empty = mode_sectors(PARAMS, np.zeros((3, PARAMS.obs_dim)), np.array([0, 1, 2]))
    np.testing.assert_allclose(empty, np.repeat(sectors[:1], 3, axis=0))
    with pytest.raises(ValueError, match="modes"):
        mode_sectors(PARAMS, obs[:1], np.array([len(MODES)]))


class Constant:
    """SB3 ``predict`` of one fixed action."""

    def __init__(self, action):
        self.action = action

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        return np.full(len(observation), self.action), None


def test_scan_modes_keeps_the_scenarios_and_rewards():
    """Always ``cue`` through the wrapper scores exactly what cue-following without search
    scores on the raw env (same seed, same scenarios)."""
    wrapped = ScanModes(make_sb3_env(ENV_ID, 8, 5))
    assert wrapped.action_space == spaces.Discrete(len(MODES))
    raw = make_sb3_env(ENV_ID, 8, 5)
    rule = rules.CueFollowing(PARAMS, sweep_every=rules.NEVER, sweep_periods=1)
    a = evaluate(Constant(1), wrapped, 16, 5)
    b = evaluate(rule, raw, 16, 5)
    assert a.mean == pytest.approx(b.mean, abs=1e-9)
    assert evaluate(Constant(0), wrapped, 16, 5).mean == pytest.approx(
        evaluate(rules.FullSweep(PARAMS), raw, 16, 5).mean, abs=1e-9
    )
    wrapped.close()
    raw.close()


def test_scan_modes_refuses_other_envs():
    with pytest.raises(ValueError, match="StereoScanning"):
        ScanModes(make_sb3_env("sensorgym/StereoPlacement-v0", 2, 0))


def test_the_entry_search_expert_is_the_rule_in_scan_modes_actions():
    """The imitation expert acting through scan-modes scores exactly what cue-entry-search
    scores on the raw env (same seed, same scenarios)."""
    wrapped = ScanModes(make_sb3_env(ENV_ID, 8, 9))
    raw = make_sb3_env(ENV_ID, 8, 9)
    a = evaluate(entry_search_expert(wrapped), wrapped, 16, 9)
    b = evaluate(rules.CueFollowing(PARAMS, search="entry"), raw, 16, 9)
    assert a.mean == pytest.approx(b.mean, abs=1e-9)
    with pytest.raises(ValueError, match="scan-modes"):
        entry_search_expert(raw)
    wrapped.close()
    raw.close()


def test_scan_modes_and_its_expert_are_registered_for_training():
    from sensorgym.train.experts import expert_factory
    from sensorgym.train.wrappers import apply_wrappers

    env = apply_wrappers(make_sb3_env(ENV_ID, 2, 0), [{"name": "scan-modes"}])
    assert isinstance(env, ScanModes)
    assert isinstance(expert_factory("scan-entry-search")(env), EntrySearchModes)
    env.close()
