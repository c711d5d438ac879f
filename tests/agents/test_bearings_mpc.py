"""The receding-horizon planner ``mpc-estimate`` and the tuned book plan ``book-plan-tuned``:
deterministic, row by row, reset by ``episode_start``, the stand-off kept, at least as good as
``lookahead-estimate`` on tuning scenarios, bad input refused."""

from __future__ import annotations

import numpy as np
import pytest

from sensorgym.agents.bearings_maneuver import EstimateLookahead
from sensorgym.agents.bearings_mpc import BOOK_ID, MANEUVER_ID, RecedingPlan
from sensorgym.agents.book_maneuver import BOOK_TUNED_TURNS, OpenLoop
from sensorgym.agents.registry import RULES
from sensorgym.train.evaluation import env_params, evaluate, make_sb3_env, simulator_state

#: a tuning seed (held-out seeds 10000 and 31337 are never used to choose or check a setting)
TUNING_SEED = 500


def _rule(env_id: str, n: int, seed: int = TUNING_SEED, name: str = "mpc-estimate"):
    env = make_sb3_env(env_id, n, seed, episode_streams=True)
    return env, RULES[env_id][name](env_params(env), simulator_state(env))


def _trajectory(env_id: str, n: int, steps: int) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """The observations and actions of ``steps`` steps of ``mpc-estimate`` on ``n`` seeded
    scenarios."""
    env, rule = _rule(env_id, n)
    env.seed(TUNING_SEED)
    obs, state, start = env.reset(), None, np.ones(n, dtype=bool)
    seen, played = [], []
    for _ in range(steps):
        action, state = rule.predict(obs, state=state, episode_start=start)
        seen.append(obs.copy())
        played.append(action)
        obs, _, start, _ = env.step(action)
    env.close()
    return seen, played


@pytest.mark.parametrize("env_id", [MANEUVER_ID, BOOK_ID])
def test_mpc_is_deterministic(env_id):
    first = _trajectory(env_id, 3, 3)
    second = _trajectory(env_id, 3, 3)
    for a, b in zip(first[1], second[1], strict=True):
        np.testing.assert_array_equal(a, b)


def test_batched_rule_equals_the_rule_row_by_row():
    env, rule = _rule(MANEUVER_ID, 4)
    env.seed(TUNING_SEED)
    obs, state, start = env.reset(), None, np.ones(4, dtype=bool)
    # one observation alone (no batch axis) is the same row
    single, _ = rule.predict(obs[1])
    np.testing.assert_array_equal(single, rule.predict(obs)[0][1])
    rows = [None] * 4
    for _ in range(3):
        action, state = rule.predict(obs, state=state, episode_start=start)
        for i in range(4):
            a, rows[i] = rule.predict(obs[i : i + 1], state=rows[i], episode_start=start[i : i + 1])
            np.testing.assert_array_equal(a[0], action[i])
            np.testing.assert_array_equal(rows[i].plan[0], state.plan[i])
        obs, _, start, _ = env.step(action)
    env.close()


def test_episode_start_resets_the_plan():
    env, rule = _rule(MANEUVER_ID, 3)
    env.seed(TUNING_SEED)
    obs = env.reset()
    fresh, memory = rule.predict(obs)
    for _ in range(2):
        obs = env.step(fresh)[0]
        fresh, memory = rule.predict(obs, state=memory)
    assert np.all(memory.step == 3)
    # a row whose episode starts now plans as if it had no memory; the others keep theirs
    start = np.array([True, False, True])
    action, reset = rule.predict(obs, state=memory, episode_start=start)
    alone, _ = rule.predict(obs)
    np.testing.assert_array_equal(action[start], alone[start])
    np.testing.assert_array_equal(reset.step, [1, 4, 1])
    kept, _ = rule.predict(obs, state=memory)
    np.testing.assert_array_equal(action[~start], kept[~start])
    env.close()


@pytest.mark.parametrize("env_id", [MANEUVER_ID, BOOK_ID])
def test_mpc_keeps_the_standoff_and_matches_the_lookahead(env_id):
    """On 8 episodes of a tuning seed: no episode ends at the stand-off, and the paired mean
    return is at least ``lookahead-estimate``'s less 0.1 (a log-factor: ≈ 10 % of the final
    bound; on these episodes it is above it: +0.91 and +0.61 measured)."""
    episodes = 8
    env, mpc = _rule(env_id, episodes)
    steps = mpc.steps
    ours = evaluate(mpc, env, episodes, TUNING_SEED, record_actions=True)
    assert all(len(a) == steps for a in ours.actions), "an episode broke the stand-off"
    base = evaluate(EstimateLookahead(env_params(env)), env, episodes, TUNING_SEED)
    env.close()
    diff = np.asarray(ours.returns) - np.asarray(base.returns)
    assert diff.mean() >= -0.1, diff


def test_book_plan_tuned_keeps_the_standoff():
    env, rule = _rule(BOOK_ID, 16, name="book-plan-tuned")
    assert isinstance(rule, OpenLoop) and rule.turns == BOOK_TUNED_TURNS
    stats = evaluate(rule, env, 32, TUNING_SEED, record_actions=True)
    env.close()
    assert all(len(a) == 32 for a in stats.actions)


def test_mpc_refuses_bad_input():
    env, rule = _rule(MANEUVER_ID, 2)
    obs = env.reset()
    env.close()
    with pytest.raises(ValueError, match="observation: expected shape"):
        rule.predict(obs[:, :5])
    bad = obs.copy()
    bad[1, 3] = np.nan
    with pytest.raises(ValueError, match="observation: contains NaN"):
        rule.predict(bad)
    with pytest.raises(ValueError, match="state: expected None or the PlanMemory"):
        rule.predict(obs, state=np.zeros(2))
    _, memory = rule.predict(obs[:1])
    with pytest.raises(ValueError, match="state: expected None or the PlanMemory"):
        rule.predict(obs, state=memory)  # a memory of one row for two
    params = rule.params
    for field, value in (("steps", 0), ("maxiter", 0), ("restarts", -1), ("polish", True)):
        with pytest.raises(ValueError, match=f"{field}: must be an integer"):
            RecedingPlan(params, **{field: value})
    for field, value in (("kappa", -1.0), ("margin", float("nan"))):
        with pytest.raises(ValueError, match=f"{field}: must be a finite number"):
            RecedingPlan(params, **{field: value})
