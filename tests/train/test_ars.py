"""The ``ars`` trainer: its untrained policy is the best rule, plan-search, a search from a
policy made worse on purpose climbs back on its paired training scenarios, and a run folder
written by ``sensorgym train`` reloads (no pickle) to the same actions."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch as th

from sensorgym.agents.registry import RULES
from sensorgym.agents.stereo_pointing_horizon import PlanHorizon
from sensorgym.agents.stereo_pointing_search import EpipolarSearch
from sensorgym.agents.stereo_pointing_sharing import Sharing
from sensorgym.envs.stereo_pointing.simulation import PointingParams
from sensorgym.train.ars import ARS, SCENARIO_SEEDS
from sensorgym.train.candidate_policy import CandidatePolicy
from sensorgym.train.config import ALGORITHMS, load_hyperparams, split_run_settings
from sensorgym.train.env_wrappers.stereo_pointing import PlanAction, _find
from sensorgym.train.evaluation import evaluate, make_sb3_env
from sensorgym.train.models import load_model
from sensorgym.train.trainer import SEARCH_FILE, train

ENV_ID = "sensorgym/StereoPointing-v0"


def _model(n_envs: int = 4, **overrides) -> ARS:
    hp = load_hyperparams("ars", ENV_ID)
    hp.update(overrides)
    run, kwargs = split_run_settings(hp)
    env = make_sb3_env(ENV_ID, n_envs, 0, wrappers=run["wrappers"])
    return ALGORITHMS["ars"](run["policy"], env, seed=0, **kwargs)


def _share_wrappers(sharing, **plan) -> list:
    """The ars.yml entry's wrappers (the shipped runs') with ``pointing-plan`` given only
    ``sharing`` (and the ``plan`` keywords)."""
    wrappers = load_hyperparams("ars", ENV_ID)["wrappers"]
    assert wrappers[0]["name"] == "pointing-plan"
    return [{"name": "pointing-plan", "sharing": sharing, **plan}, *wrappers[1:]]


def test_the_untrained_policy_is_the_plan_search_rule_and_without_its_aims_plan_acquire():
    """The ars.yml entry (the shipped runs') aims through ``pointing-plan`` with ``sharing``,
    ``cue_steps: 1`` and ``search``: its untrained policy scores exactly as the registered
    ``plan-search`` on 4 seeded episodes; with the plain ``pointing-plan`` (one drone per
    receiver, no hold, no search) exactly as ``plan-acquire``."""
    model = _model(episodes=4)
    assert isinstance(model.policy, CandidatePolicy)
    assert np.array_equal(model.theta, np.zeros(9))
    plan = _find(model.env, PlanAction, "pointing-plan")
    assert plan.sharing == Sharing() and plan.cue_steps == 1 and plan.search == EpipolarSearch()
    rule = RULES[ENV_ID]["plan-search"](PointingParams(), lambda: None)
    theirs = evaluate(rule, make_sb3_env(ENV_ID, 4, 0), 4, 21)
    assert evaluate(model, model.env, 4, 21).returns == theirs.returns
    plain = _model(episodes=4, wrappers=_share_wrappers(None))
    assert _find(plain.env, PlanAction, "pointing-plan").cue_steps == 0
    rule = PlanHorizon(PointingParams(), acquisition=True)
    theirs = evaluate(rule, make_sb3_env(ENV_ID, 4, 0), 4, 21)
    assert evaluate(plain, plain.env, 4, 21).returns == theirs.returns
    assert theirs.returns != evaluate(model, model.env, 4, 21).returns


def test_the_search_climbs_back_from_a_worse_policy():
    """A weight of -5 on the 15-step plan's best-plan flag (-50 return units on the candidate
    the short plan likes best) loses drones; on the training scenarios the search's vector
    scores above its start, paired, and the weight has moved up."""
    model = _model(n_envs=2, episodes=2, n_directions=4, learning_rate=2.0, noise_std=2.0)
    start = np.zeros(9)
    start[4] = -5.0
    model.set_theta(start)
    seed = 1234
    before = model.returns(start, seed)
    rng = np.random.default_rng(0)
    for _ in range(2):
        model._iterate(rng)
    after = model.returns(model.theta, seed)
    assert model.theta[4] > start[4]
    assert after.mean() > before.mean() + 50.0
    assert all(SCENARIO_SEEDS[0] <= h["scenario_seed"] < SCENARIO_SEEDS[1] for h in model.history)


def _tiny_run(out, seed: int, hyperparams: dict):
    """One ARS iteration of ``sensorgym train`` on two scenarios, saved under ``out``."""
    return train(ENV_ID, "ars", seed=seed, timesteps=1, n_envs=2, out=out, eval_episodes=2,
                 progress=False, curve_points=0, hyperparams=hyperparams)  # fmt: skip


def _same_actions(model, loaded, env, shape: tuple[int, ...]) -> None:
    """``model`` and ``loaded`` act alike on three steps of ``env``."""
    obs = env.reset()
    for _ in range(3):
        a, _ = model.predict(obs, deterministic=True)
        b, _ = loaded.predict(obs, deterministic=True)
        assert a.shape == shape
        np.testing.assert_array_equal(a, b)
        obs, *_ = env.step(a)


def test_a_run_reloads_to_the_same_actions(tmp_path):
    hp = {"episodes": 2, "n_directions": 2, "noise_std": 2.0, "learning_rate": 1.0}
    result = _tiny_run(tmp_path, 3, hp)
    history = json.loads((result.run_dir / SEARCH_FILE).read_text())
    assert len(history) == 1 and history[0]["timesteps"] == 2 * 2 * 2 * 150
    assert not (result.run_dir / "model.zip").exists()
    loaded = load_model(result.run_dir)
    assert isinstance(loaded, ARS)
    np.testing.assert_array_equal(loaded.theta, result.model.theta)
    env = make_sb3_env(
        ENV_ID, 8, 5, wrappers=split_run_settings(load_hyperparams("ars", ENV_ID))[0]["wrappers"]
    )
    _same_actions(result.model, loaded, env, (8,))


def test_bad_settings_are_refused():
    with pytest.raises(ValueError, match="multiple"):
        _model(n_envs=4, episodes=6)
    with pytest.raises(ValueError, match="top_directions"):
        _model(n_directions=2, top_directions=3)
    with pytest.raises(ValueError, match="noise_std"):
        _model(noise_std=0.0)
    with pytest.raises(ValueError, match="search_parameter"):
        _model(
            policy_kwargs={**load_hyperparams("ars", ENV_ID)["policy_kwargs"], "residual": "mlp"}
        )


def test_the_linear_features_are_the_plan_gaps_flags_and_kept_receivers():
    model = _model(episodes=4)
    nets = model.policy.mlp_extractor
    obs = th.as_tensor(model.env.reset())
    x = nets.linear_features(obs)
    _, loss, _, kept, _ = nets.layout.split(obs)
    assert x.shape == (4, 16, 9)
    th.testing.assert_close(x[..., 2], 100.0 * loss[..., 2])
    th.testing.assert_close(x[..., 3], 150.0 * loss[..., 3])  # the time left at step 0
    assert th.equal(x[..., 4:8].amax(dim=1), th.full((4, 4), 10.0))
    th.testing.assert_close(x[..., 8], 4.0 * kept)


@pytest.mark.parametrize(("cue_steps", "search"), [(0, False), (1, False), (1, True)])
def test_with_sharing_the_untrained_policy_acts_as_the_rule(cue_steps, search):
    """With ``pointing-plan``'s ``sharing`` the untrained policy's env actions are the
    plan-acquire-share rule's on every step of two episodes of four seeded scenarios; with
    ``cue_steps`` 1 as well they are the plan-fix-first rule's, the wrapper's step count
    restarting with each episode, and with ``search`` too the plan-search rule's. The
    registered setting shares some receiver-steps (without it the actions differ), and the cue
    hold changes some first steps (without it the actions differ there)."""
    if cue_steps:
        extra = {"search": True} if search else {}
        model = _model(n_envs=4, episodes=4, wrappers=_share_wrappers(True, cue_steps=1, **extra))
    else:
        model = _model(n_envs=4, episodes=4, wrappers=_share_wrappers(True))
    plain = _model(n_envs=4, episodes=4, wrappers=_share_wrappers(None))
    no_cue = _model(n_envs=4, episodes=4, wrappers=_share_wrappers(True))
    plan = _find(model.env, PlanAction, "pointing-plan")
    straight = _find(plain.env, PlanAction, "pointing-plan")
    uncued = _find(no_cue.env, PlanAction, "pointing-plan")
    assert plan.sharing == Sharing() and straight.sharing is None
    assert plan.cue_steps == cue_steps and uncued.cue_steps == 0
    assert (plan.search == EpipolarSearch()) if search else plan.search is None
    rule = PlanHorizon(
        PointingParams(),
        acquisition=True,
        sharing=Sharing(),
        cue_steps=cue_steps,
        search=plan.search,
    )
    name = "plan-search" if search else "plan-fix-first" if cue_steps else "plan-acquire-share"
    assert rule == RULES[ENV_ID][name](PointingParams(), lambda: None)
    model.env.seed(21)
    obs = model.env.reset()
    state, start = None, np.ones(4, dtype=bool)
    differs, held = 0, 0
    for step in range(2 * 150):
        action, _ = model.predict(obs, deterministic=True)
        ours = plan.env_action(action, plan.last_obs).astype(np.float32)
        theirs, state = rule.predict(plan.last_obs, state, start)
        np.testing.assert_array_equal(ours, theirs)
        differs += int(np.any(ours != straight.env_action(action, plan.last_obs)))
        if cue_steps and step % 150 == 0:
            held += int(np.any(ours != uncued.env_action(action, plan.last_obs)))
        obs, _, start, _ = model.env.step(action)
    assert differs > 0
    assert held == (2 if cue_steps else 0)


def test_bad_sharing_settings_are_refused():
    with pytest.raises(ValueError, match="unknown fields"):
        _model(wrappers=_share_wrappers({"margin": 0.5, "width": 1.0}))
    with pytest.raises(ValueError, match="fraction"):
        _model(wrappers=_share_wrappers({"fraction": 1.5}))
    with pytest.raises(ValueError, match="mapping"):
        _model(wrappers=_share_wrappers("yes"))
    for bad in (-1, 1.5, "1", True):
        with pytest.raises(ValueError, match="cue_steps"):
            _model(wrappers=_share_wrappers(True, cue_steps=bad))
    for bad, match in (({"bogus": 1}, "unknown"), ("yes", "mapping"), ({"lost_rms": -1}, "lost")):
        with pytest.raises(ValueError, match=match):
            _model(wrappers=_share_wrappers(True, search=bad))
