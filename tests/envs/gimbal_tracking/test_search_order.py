"""GimbalTracking-v0's learnable search order (``gimbal-search-order``) and its teacher
(``gimbal-truth-hop``)."""

from __future__ import annotations

import numpy as np
import pytest

from sensorgym.agents.gimbal_search import FeedForwardSearch
from sensorgym.train.env_wrappers.gimbal_search import SearchOrderAction, truth_hop
from sensorgym.train.evaluation import env_params, make_sb3_env

ENV_ID = "sensorgym/GimbalTracking-v0"


def _play(env, act, steps):
    obs = env.reset()
    total, live = np.zeros(env.num_envs), np.ones(env.num_envs, dtype=bool)
    searched = 0
    for _ in range(steps):
        obs, reward, done, _ = env.step(act(obs))
        total[live] += reward[live]
        live &= ~done
        if isinstance(env, SearchOrderAction):
            searched += int(env.searching(env.last_obs).sum())
    return total, searched


@pytest.mark.parametrize("rings", [1, 2, 4])
def test_zero_scores_are_the_search_rule_with_as_many_rings(rings):
    # 400 frames of 6 scenarios: occlusions long enough to search, and some searches that
    # go round the whole pattern (3 rings (rings + 1) hops)
    wrapped = SearchOrderAction(make_sb3_env(ENV_ID, 6, seed=3), rings=rings)
    plain = make_sb3_env(ENV_ID, 6, seed=3)
    rule = FeedForwardSearch(env_params(plain), rings=rings)
    p = 3 * rings * (rings + 1)
    assert wrapped.action_space.shape == (p,)
    zeros, searched = _play(wrapped, lambda obs: np.zeros((6, p), np.float32), 400)
    ruled, _ = _play(plain, lambda obs: rule.predict(obs)[0], 400)
    assert searched > 0
    np.testing.assert_array_equal(zeros, ruled)


def test_a_hop_goes_to_the_best_unvisited_position():
    env = SearchOrderAction(make_sb3_env(ENV_ID, 1, seed=0), rings=1)
    env.reset()
    since = 20 + env.params.n_channels
    obs = np.zeros((1, env.observation_space.shape[0]))
    score = np.array([[-1.0, -0.5, 0.0, -0.2, -1.0, -1.0]])
    order = []
    for frame in range(2 * 2 * 6):  # centre, position, … — dwell 2
        obs[0, since] = (env.params.search_after + frame) / (env.params.reacquire_limit + 1)
        env.env_action(score, obs)
        if frame % 4 == 2:
            order.append(int(env.current[0]))
    assert order == [2, 3, 1, 0, 4, 5]
    assert env.visited.all()
    obs[0, since] = 0.0  # a detection clears the visits
    env.env_action(score, obs)
    assert not env.visited.any()


def test_the_truth_hop_teacher_finds_targets_the_rule_loses():
    """Hopping first to the position nearest the true direction pays on the same scenarios."""
    wrapped = SearchOrderAction(make_sb3_env(ENV_ID, 12, seed=4))
    teacher = truth_hop(wrapped)
    labels = []

    def taught(obs):
        label = teacher.predict(obs)[0]
        labels.append(label)
        return label

    learned, _ = _play(wrapped, taught, 500)
    wrapped = SearchOrderAction(make_sb3_env(ENV_ID, 12, seed=4))
    zeros, _ = _play(wrapped, lambda obs: np.zeros((12, 60), np.float32), 500)
    assert learned.mean() > zeros.mean() + 20.0
    label = np.concatenate(labels)
    assert np.all((label >= -1.0) & (label <= 0.0))
    searching = label.max(axis=1) > -1.0
    assert 0 < searching.sum() < len(label)  # scores only while the gate searches


def test_bad_arguments_are_named():
    env = make_sb3_env(ENV_ID, 2, seed=0)
    with pytest.raises(ValueError, match="rings"):
        SearchOrderAction(env, rings=0)
    with pytest.raises(ValueError, match="dwell"):
        SearchOrderAction(env, dwell=True)
    wrapped = SearchOrderAction(env, rings=1)
    wrapped.reset()
    with pytest.raises(ValueError, match="actions"):
        wrapped.step(np.full((2, 6), np.nan, np.float32))
    with pytest.raises(ValueError, match="scores"):
        wrapped.step(np.zeros((2, 5), np.float32))
    with pytest.raises(ValueError, match="SearchOrderAction"):
        truth_hop(env)
