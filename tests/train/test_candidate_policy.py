"""The candidate-scoring policy: its untrained mode is the plan-horizon rule, its learned score
of a candidate depends on that candidate's features only, and a run folder rebuilds it from
``config.yaml`` and safetensors (no pickle)."""

from __future__ import annotations

import numpy as np
import pytest
import torch as th

from sensorgym.agents.stereo_pointing_horizon import PlanHorizon
from sensorgym.envs.stereo_pointing.simulation import PointingParams
from sensorgym.train.candidate_policy import CandidatePolicy
from sensorgym.train.config import load_hyperparams, split_run_settings
from sensorgym.train.evaluation import evaluate, make_sb3_env
from sensorgym.train.models import build_model, load_model, save_run

ENV_ID = "sensorgym/StereoPointing-v0"


def _config(seed: int = 0) -> dict:
    hp = load_hyperparams("ppo", ENV_ID)
    hp.pop("agents")
    return {"env": ENV_ID, "algo": "ppo", "seed": seed, "agents": False, "hyperparams": hp}


def _env(config: dict, n: int = 8):
    run, _ = split_run_settings(config["hyperparams"])
    return make_sb3_env(ENV_ID, n, 0, wrappers=run["wrappers"])


def test_the_untrained_mode_is_the_plan_horizon_rule():
    config = _config()
    assert config["hyperparams"]["policy"] == "CandidatePolicy"
    model = build_model(config, _env(config))
    assert isinstance(model.policy, CandidatePolicy)
    trained = evaluate(model, _env(config), 8, 21)
    rule = evaluate(PlanHorizon(PointingParams()), make_sb3_env(ENV_ID, 8, 0), 8, 21)
    np.testing.assert_allclose(trained.returns, rule.returns, rtol=1e-6, atol=1e-6)


def test_a_candidates_learned_score_reads_its_own_features_only():
    """Perturbing candidate 3's features changes its learned score and no other's."""
    config = _config()
    policy = build_model(config, _env(config)).policy
    nets = policy.mlp_extractor
    th.nn.init.normal_(nets.score_out.weight)  # a non-zero residual
    obs = th.as_tensor(_env(config).reset())
    x, prior, _, _ = nets.inputs(obs)
    residual = nets.score_out(nets.scorer(x)).squeeze(-1)
    x2 = x.clone()
    x2[:, 3] += 0.5
    residual2 = nets.score_out(nets.scorer(x2)).squeeze(-1)
    changed = (residual2 - residual).abs() > 1e-7
    assert changed[:, 3].all() and not changed[:, np.r_[0:3, 4:16]].any()
    assert th.allclose(prior.max(dim=1).values, th.zeros(len(obs)))


def test_a_run_folder_rebuilds_the_policy_from_config_and_weights(tmp_path):
    config = _config(seed=3)
    env = _env(config, 4)
    model = build_model(config, env)
    with th.no_grad():
        for p in model.policy.parameters():
            p.add_(0.05 * th.randn_like(p))
    save_run(model, tmp_path, config)
    assert not (tmp_path / "model.zip").exists()
    loaded = load_model(tmp_path)
    assert isinstance(loaded.policy, CandidatePolicy)
    obs = env.reset()
    a, _ = model.predict(obs, deterministic=True)
    b, _ = loaded.predict(obs, deterministic=True)
    np.testing.assert_array_equal(a, b)
    for key, value in model.policy.state_dict().items():
        assert th.equal(value, loaded.policy.state_dict()[key])


def test_the_policy_refuses_a_layout_it_cannot_read():
    config = _config()
    config["hyperparams"]["policy_kwargs"]["prior_horizon"] = 70
    with pytest.raises(ValueError, match="prior_horizon"):
        build_model(config, _env(config, 2))
