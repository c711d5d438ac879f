"""What every registered env promises, checked over every id (STYLE: API conformance over every
registered id): the Gymnasium and SB3 checkers, seeding, the shells against each other, both
autoreset modes, bad actions, rendering, pickling, and the rules' ``predict`` contract."""

from __future__ import annotations

import dataclasses
import pickle

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

from sensorgym.agents.protocol import PolicyPredictor
from sensorgym.agents.registry import RULES, rules_for
from sensorgym.envs import ENV_IDS
from tests.kernel_signatures import kernel_signatures


def _vector(env_id: str, num_envs: int, **kwargs):
    return gym.make_vec(
        env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", **kwargs
    )


def _actions(env: gym.Env, count: int, seed: int = 0) -> np.ndarray:
    shape = (count, *env.action_space.shape)
    return np.random.default_rng(seed).uniform(-1, 1, shape).astype(np.float32)


def _episode(env: gym.Env, seed: int, actions: np.ndarray) -> np.ndarray:
    obs, _ = env.reset(seed=seed)
    out = [obs]
    for a in actions:
        obs, r, term, trunc, _ = env.step(a)
        out.append(np.concatenate([obs, [r, term, trunc]]))
        if term or trunc:
            break
    return np.concatenate(out)


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_gymnasium_and_sb3_checkers_pass(env_id):
    check_env(gym.make(env_id, render_mode="rgb_array").unwrapped, skip_render_check=False)
    sb3_check_env(gym.make(env_id), warn=True)


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_registration_gives_a_time_limit_and_a_native_vector_env(env_id):
    env = gym.make(env_id)
    steps = env.spec.max_episode_steps
    assert steps is not None and steps > 1
    venv = _vector(env_id, 3)
    assert venv.unwrapped.max_episode_steps == steps
    obs, info = venv.reset(seed=1)
    assert obs.shape == (3, *env.observation_space.shape) and obs.dtype == np.float32
    assert all(value.shape == (3,) for key, value in info.items() if not key.startswith("_"))


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_same_seed_same_episode_other_seed_another(env_id):
    env = gym.make(env_id)
    actions = _actions(env, 25)
    a, b = _episode(gym.make(env_id), 7, actions), _episode(gym.make(env_id), 7, actions)
    c = _episode(gym.make(env_id), 8, actions)
    np.testing.assert_array_equal(a, b)
    assert a.shape != c.shape or not np.array_equal(a, c)


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_vector_env_of_one_reproduces_the_single_env_across_autoreset(env_id):
    """Gymnasium's vector-equivalence pattern: same seed, same actions, step by step, over three
    episodes (the NEXT_STEP autoreset step is matched by an explicit reset of the single env)."""
    single = gym.make(env_id, max_episode_steps=5)
    vector = _vector(env_id, 1, max_episode_steps=5)
    obs_s, _ = single.reset(seed=3)
    obs_v, _ = vector.reset(seed=3)
    np.testing.assert_array_equal(obs_v[0], obs_s)
    done, restarts = False, 0
    for a in _actions(single, 17, seed=1):
        obs_v, r_v, term_v, trunc_v, _ = vector.step(a[None])
        if done:  # the vector env restarts on this step; the single env is reset by hand
            obs_s, _ = single.reset()
            assert r_v[0] == 0.0 and not term_v[0] and not trunc_v[0]
            done, restarts = False, restarts + 1
        else:
            obs_s, r_s, term_s, trunc_s, _ = single.step(a)
            assert (r_v[0], term_v[0], trunc_v[0]) == (r_s, term_s, trunc_s)
            done = term_s or trunc_s
        np.testing.assert_array_equal(obs_v[0], obs_s)
    assert restarts >= 2


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_same_step_autoreset_is_next_step_shifted_by_one(env_id):
    """SAME_STEP returns at the ending step what NEXT_STEP returns one step later, and keeps the
    ending observation in ``final_obs``."""
    same = _vector(env_id, 2, max_episode_steps=3, autoreset_mode="SameStep")
    nxt = _vector(env_id, 2, max_episode_steps=3)
    same.reset(seed=2)
    nxt.reset(seed=2)
    a = np.tile(_actions(gym.make(env_id), 1)[0], (2, 1))
    for _ in range(2):
        o_s, r_s, *_ = same.step(a)
        o_n, r_n, *_ = nxt.step(a)
        np.testing.assert_array_equal(o_s, o_n)
        np.testing.assert_array_equal(r_s, r_n)
    o_s, r_s, term_s, trunc_s, info_s = same.step(a)
    o_n, r_n, term_n, trunc_n, _ = nxt.step(a)
    np.testing.assert_array_equal(r_s, r_n)
    assert (trunc_s | term_s).all() and (trunc_n | term_n).all()
    np.testing.assert_array_equal(info_s["final_obs"], o_n)
    assert info_s["_final_obs"].all()
    o_n, *_ = nxt.step(a)  # NEXT_STEP restarts now
    np.testing.assert_array_equal(o_s, o_n)


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_bad_actions_raise_and_out_of_range_actions_are_clipped(env_id):
    a, b = gym.make(env_id), gym.make(env_id)
    a.reset(seed=6)
    b.reset(seed=6)
    shape = a.action_space.shape
    oa = a.step(np.full(shape, 5.0))
    ob = b.step(np.ones(shape))
    np.testing.assert_array_equal(oa[0], ob[0])
    assert oa[1] == ob[1]
    with pytest.raises(ValueError, match="action: contains NaN"):
        a.step(np.full(shape, np.nan))
    with pytest.raises(ValueError, match="action: expected shape"):
        a.step(np.zeros(shape[0] + 1))
    with pytest.raises(RuntimeError, match="reset"):
        gym.make(env_id).unwrapped.step(np.zeros(shape))
    venv = _vector(env_id, 2)
    with pytest.raises(RuntimeError, match="reset"):
        venv.step(np.zeros((2, *shape)))
    venv.reset(seed=0)
    with pytest.raises(ValueError, match="action: expected shape"):
        venv.step(np.zeros((3, *shape)))


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_render_draws_the_episode(env_id):
    env = gym.make(env_id, render_mode="rgb_array")
    env.reset(seed=0)
    first = env.render()
    for a in _actions(env, 3):
        env.step(a)
    second = env.render()
    assert first.ndim == 3 and first.shape[2] == 3 and first.dtype == np.uint8
    assert not np.array_equal(first, second)
    with pytest.raises(ValueError, match="render_mode"):
        type(env.unwrapped)(render_mode="ansi")


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_pickle_round_trip_mid_episode(env_id):
    """A pickled env continues exactly as the original (SubprocVecEnv and checkpoints need it),
    with the kernels the original uses: its params pickle without their read-only derived
    arrays, which would come back writable, a new argument type for numba (the first step of
    the copy compiled every kernel again, a minute for StereoScanning)."""
    env = gym.make(env_id)
    env.reset(seed=5)
    actions = _actions(env, 4)
    env.step(actions[0])
    env.step(actions[1])
    twin = pickle.loads(pickle.dumps(env))
    params = twin.unwrapped.params
    assert set(params.__getstate__()) == {f.name for f in dataclasses.fields(params)}
    compiled = kernel_signatures()
    for a in actions[2:]:
        o1, r1, *_ = env.step(a)
        o2, r2, *_ = twin.step(a)
        np.testing.assert_array_equal(o1, o2)
        assert r1 == r2
    assert kernel_signatures() == compiled


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_every_env_has_rules_that_follow_the_sb3_predict_protocol(env_id):
    assert env_id in RULES
    venv = _vector(env_id, 3)
    obs, _ = venv.reset(seed=0)
    core_env = venv.unwrapped
    rules = rules_for(env_id, core_env.params, lambda: core_env.simulator_state)
    assert len(rules) >= 3
    for name, rule in rules.items():
        assert isinstance(rule, PolicyPredictor), name
        action, _ = rule.predict(obs, episode_start=np.ones(3, dtype=bool))
        assert action.shape == venv.action_space.shape and action.dtype == np.float32, name
        assert np.all(np.abs(action) <= 1.0), name
        venv.step(action)
    with pytest.raises(ValueError, match="observation"):
        next(iter(rules.values())).predict(np.zeros(3))
