"""The assignment action and its teachers are reachable by the names a run's hyperparameters
use: the wrapper stack of the shipped runs rebuilds, and every registered teacher answers in
its action space."""

from __future__ import annotations

import numpy as np

from sensorgym.train.evaluation import evaluate, make_sb3_env
from sensorgym.train.experts import EXPERTS, expert_factory

ENV_ID = "sensorgym/StereoPointing-v0"
STACK = [{"name": "pointing-assignment"}, {"name": "time-feature"}]


def test_the_run_wrappers_rebuild_and_every_pointing_teacher_answers_an_assignment():
    env = make_sb3_env(ENV_ID, 4, 0, wrappers=STACK)
    assert env.action_space.nvec.tolist() == [2, 2, 2, 2]
    assert env.observation_space.shape == (53,)  # the observation and the time left
    obs = env.reset()
    for name in (n for n in EXPERTS if n.startswith("pointing-")):
        action, _ = expert_factory(name)(env).predict(obs)
        assert action.shape == (4, 4) and set(np.unique(action)) <= {0, 1}, name


def test_a_teacher_through_the_wrappers_scores_as_its_rule():
    """The orthogonal-pairs teacher acting through the run's wrappers meets the rule's return
    on the same scenarios (the time feature changes only what a policy sees)."""
    from sensorgym.agents.stereo_pointing import OrthogonalPairs
    from sensorgym.envs.stereo_pointing.simulation import PointingParams

    env = make_sb3_env(ENV_ID, 4, 0, wrappers=STACK)
    teacher = expert_factory("pointing-orthogonal-pairs")(env)
    want = evaluate(OrthogonalPairs(PointingParams()), make_sb3_env(ENV_ID, 4, 0), 4, 9).mean
    assert abs(evaluate(teacher, env, 4, 9).mean - want) <= 1e-6 * max(abs(want), 1.0)
