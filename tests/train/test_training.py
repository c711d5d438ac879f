"""SB3 on the native vector envs: the adapter, YAML hyperparameters, train / benchmark commands."""

from __future__ import annotations

import json
import re
from types import SimpleNamespace

import numpy as np
import pytest
import torch as th
from gymnasium.vector import AutoresetMode

from sensorgym.agents.bearings_maneuver import StraightCourse
from sensorgym.cli.main import main
from sensorgym.envs.bearings_maneuver.bearings_maneuver import BearingsManeuverVectorEnv
from sensorgym.envs.bearings_maneuver.simulation import OBS_DIM
from sensorgym.train.config import (
    apply_overrides,
    check_overrides,
    load_hyperparams,
    parse_override,
    split_run_settings,
)
from sensorgym.train.evaluation import evaluate, make_sb3_env
from sensorgym.train.models import WEIGHTS_FILE, load_model, read_config
from sensorgym.train.sb3_vec_env import SB3VecEnv
from sensorgym.train.shipped import shipped_policies
from sensorgym.train.trainer import train

ENV_ID = "sensorgym/BearingsManeuver-v0"


def test_sb3_adapter_reports_terminal_observations_and_time_limits():
    venv = SB3VecEnv(BearingsManeuverVectorEnv(3, max_episode_steps=4, autoreset_mode="SameStep"))
    venv.seed(5)
    venv.reset()
    for _ in range(4):
        obs, reward, dones, infos = venv.step(np.zeros((3, 2), dtype=np.float32))
        assert obs.shape == (3, OBS_DIM) and reward.dtype == np.float32
        assert all(isinstance(i["range"], float) for i in infos)
    assert dones.all()
    for info in infos:
        assert info["TimeLimit.truncated"] is True
        assert info["terminal_observation"].shape == (OBS_DIM,)
    with pytest.raises(ValueError, match="SAME_STEP"):
        SB3VecEnv(BearingsManeuverVectorEnv(2))


def test_evaluation_is_seeded_and_ranks_rules():
    env = make_sb3_env(ENV_ID, 4, seed=0)
    a = evaluate(StraightCourse(), env, 8, seed=3)
    b = evaluate(StraightCourse(), env, 8, seed=3)
    assert a == b and a.episodes == 8 and a.mean_length == 30.0


def test_hyperparameters_come_from_yaml():
    hp = load_hyperparams("ppo", ENV_ID)
    run, kwargs = split_run_settings(hp)
    assert run["policy"] == "MlpPolicy" and isinstance(run["n_timesteps"], int)
    assert isinstance(kwargs["learning_rate"], float) and kwargs["policy_kwargs"]["net_arch"]
    assert load_hyperparams("sac", ENV_ID)["policy"] == "MlpPolicy"
    with pytest.raises(KeyError, match="known"):
        load_hyperparams("ppo", "sensorgym/Nothing-v0")
    with pytest.raises(KeyError, match="algo"):
        load_hyperparams("dqn", ENV_ID)


def test_hyperparameter_overrides_reach_inside_mappings_and_refuse_typos():
    hp = load_hyperparams("ppo", ENV_ID)
    assert parse_override("learning_rate=3e-4") == ("learning_rate", 3e-4)  # not PyYAML's str
    assert parse_override("policy_kwargs={lr: [1E5, 2.5e-3]}")[1] == {"lr": [1e5, 2.5e-3]}
    assert parse_override("pretrain.expert=rule:plan-search") == (
        "pretrain.expert",
        "rule:plan-search",
    )
    assert parse_override("policy_kwargs={net_arch: [64, 64]}") == (
        "policy_kwargs",
        {"net_arch": [64, 64]},
    )
    new = apply_overrides(hp, dict([parse_override("pretrain.steps=2000")]))
    assert (
        new["pretrain"]["steps"] == 2000 and new["pretrain"]["expert"] == hp["pretrain"]["expert"]
    )
    assert hp["pretrain"]["steps"] == 30000  # the loaded set is left as it was
    # null leaves an optional run setting out: no imitation phase
    run, _ = split_run_settings(apply_overrides(hp, {"pretrain": None}))
    assert "pretrain" not in run
    assert check_overrides("ppo", ENV_ID, {"gamma": 0.95})["gamma"] == 0.95
    with pytest.raises(KeyError, match=r"learnin_rate.*not a run setting"):
        check_overrides("ppo", ENV_ID, {"learnin_rate": 1e-4})
    with pytest.raises(KeyError, match="seed"):  # the trainer sets it: --seed
        check_overrides("ppo", ENV_ID, {"seed": 3})
    with pytest.raises(KeyError, match="not a mapping"):
        apply_overrides(hp, {"n_steps.size": 3})
    with pytest.raises(KeyError, match="not a mapping"):  # null is not a missing mapping
        apply_overrides(hp, {"pretrain": None, "pretrain.steps": 3})
    made = apply_overrides({"policy": "MlpPolicy"}, {"policy_kwargs.net_arch": [8]})
    assert made == {"policy": "MlpPolicy", "policy_kwargs": {"net_arch": [8]}}
    for bad in ("learning_rate", "=3", "pretrain..steps=1", "gamma=[0.9"):
        with pytest.raises(ValueError, match="--hyperparam"):
            parse_override(bad)


def test_train_saves_a_model_that_loads_and_acts_the_same(tmp_path):
    result = train(
        ENV_ID, "ppo", seed=1, timesteps=2048, out=tmp_path, eval_episodes=8, progress=False
    )
    assert (result.run_dir / WEIGHTS_FILE).is_file()
    assert not (result.run_dir / "model.zip").exists()  # no pickle: see test_model_files.py
    config = read_config(result.run_dir)
    assert config["env"] == ENV_ID and config["hyperparams"]["n_timesteps"] == 2048
    evaluation = json.loads((result.run_dir / "evaluation.json").read_text())["results"]
    assert {"trained", "straight-course", "paper002", "greedy-information"} <= set(evaluation)
    model = load_model(result.run_dir)
    size = model.observation_space.shape[0]  # the env's 10 and what the run's wrappers add
    obs = np.random.default_rng(0).uniform(-1, 1, (5, size)).astype(np.float32)
    again = load_model(result.run_dir / WEIGHTS_FILE)
    action = model.predict(obs, deterministic=True)[0]
    np.testing.assert_array_equal(action, again.predict(obs, deterministic=True)[0])
    assert np.all(np.abs(action) <= 1.0)


def test_benchmark_command_scores_every_rule(tmp_path, capsys):
    args = ["--env", ENV_ID, "--episodes", "8", "--n-envs", "4", "--out", str(tmp_path)]
    assert main(["benchmark", *args]) == 0
    doc = json.loads((tmp_path / "sensorgym__BearingsManeuver-v0.json").read_text())
    results = doc["results"]
    assert set(results) == {
        "straight-course",
        "paper002",
        "greedy-information",
        "lookahead-estimate",
        "mpc-estimate",
        "truth-lookahead",
        # the shipped policies, scored by default
        *(f"shipped:{run}" for run in shipped_policies(ENV_ID)),
    }
    assert results["truth-lookahead"]["mean"] > results["greedy-information"]["mean"]
    assert results["greedy-information"]["mean"] > results["straight-course"]["mean"]
    assert "greedy-information" in capsys.readouterr().out


def test_autoreset_mode_is_validated():
    with pytest.raises(ValueError, match="autoreset_mode"):
        BearingsManeuverVectorEnv(2, autoreset_mode=AutoresetMode.DISABLED)


def test_parameter_sharing_slots_are_the_pettingzoo_agents_of_every_scenario():
    from sensorgym.envs.bearings_maneuver import parallel_env

    # one scenario: its slots step exactly as the PettingZoo env with the same seed
    venv = make_sb3_env(ENV_ID, 1, seed=7, agents=True, platforms=2, max_episode_steps=3)
    assert venv.num_envs == 2  # 1 scenario × 2 platforms
    obs = venv.reset()
    pz = parallel_env(platforms=2, max_episode_steps=3)
    first, _ = pz.reset(seed=7)
    np.testing.assert_array_equal(obs[0], first["platform_0"])  # slot 0 = scenario 0, agent 0
    np.testing.assert_array_equal(obs[1], first["platform_1"])
    actions = np.random.default_rng(0).uniform(-1, 1, (3, 2, 2)).astype(np.float32)
    for k in range(3):
        obs, reward, dones, infos = venv.step(actions[k])
        pz_obs, rewards, *_ = pz.step({"platform_0": actions[k, 0], "platform_1": actions[k, 1]})
        assert reward[0] == reward[1] == np.float32(rewards["platform_0"])  # one team reward
        if k < 2:
            np.testing.assert_array_equal(obs[1], pz_obs["platform_1"])
    assert dones.all()
    assert all(
        i["TimeLimit.truncated"] and i["terminal_observation"].shape == (OBS_DIM + 2,)
        for i in infos
    )
    np.testing.assert_array_equal(infos[1]["terminal_observation"], pz_obs["platform_1"])
    # several scenarios: slot i is agent i mod n of scenario i div n
    venv = make_sb3_env(ENV_ID, 3, seed=7, agents=True, platforms=2)
    assert venv.reset().shape == (6, OBS_DIM + 2)
    _, reward, _, _ = venv.step(np.zeros((6, 2), dtype=np.float32))
    np.testing.assert_array_equal(reward[0::2], reward[1::2])


def test_parameter_sharing_steps_the_batched_simulation_once_per_step():
    venv = make_sb3_env("sensorgym/StereoPointing-v0", 4, seed=0, agents=True, n_receivers=3)
    venv.reset()
    inner = venv.unwrapped.venv
    calls = []
    step = inner.core.simulation.step

    def counting(*args, **kwargs):
        calls.append(args[1].batch_size)
        return step(*args, **kwargs)

    inner.core.simulation = SimpleNamespace(**{**vars(inner.core.simulation), "step": counting})
    venv.step(np.zeros((12, 2), dtype=np.float32))
    assert calls == [4]  # 12 agent slots, one call on the 4 scenarios


def test_ppo_trains_one_shared_policy_on_every_receiver():
    from stable_baselines3 import PPO

    venv = make_sb3_env("sensorgym/StereoPointing-v0", 1, 0, agents=True, n_receivers=3, n_drones=1)
    model = PPO("MlpPolicy", venv, n_steps=32, batch_size=48, n_epochs=1, seed=0, device="cpu")
    model.learn(96)
    action, _ = model.predict(venv.reset(), deterministic=True)
    assert action.shape == (3, 2)


@pytest.mark.parametrize(
    ("env_id", "size", "agents"),
    [
        ("sensorgym/StereoPointing-v0", {"n_receivers": 16, "n_drones": 10}, 16),
        ("sensorgym/StereoScanning-v0", {"n_receivers": 16, "n_drones": 10}, 16),
        ("sensorgym/StereoPlacement-v0", {"n_receivers": 6}, 6),
        ("sensorgym/BearingsManeuver-v0", {"platforms": 16}, 16),
    ],
)
def test_parameter_sharing_trains_at_the_scale_sizes(env_id, size, agents):
    """One policy shared by every agent of a scenario at the sizes of the scale issue (16
    receivers × 10 drones, 6 receiver vehicles, 16 platforms): PPO updates it, and it acts for
    every agent."""
    from stable_baselines3 import PPO

    venv = make_sb3_env(env_id, 1, 0, agents=True, **size)
    assert venv.num_envs == agents
    model = PPO("MlpPolicy", venv, n_steps=4, batch_size=agents * 4, n_epochs=1, seed=0,
                device="cpu")  # fmt: skip
    before = [p.detach().clone() for p in model.policy.parameters()]
    model.learn(4 * agents)
    assert any(not th.equal(a, b) for a, b in zip(before, model.policy.parameters(), strict=True))
    action, _ = model.predict(venv.reset(), deterministic=True)
    assert action.shape == (agents, *venv.action_space.shape)
    assert np.all(np.isfinite(action))


def test_train_command_with_parameter_sharing_then_benchmark_the_saved_run(tmp_path):
    args = ["--agents", "--timesteps", "128", "--n-envs", "2", "--eval-episodes", "2"]
    env = ["--env", "sensorgym/StereoPlacement-v0"]
    assert main(["train", *env, *args, "--out", str(tmp_path), "--no-progress"]) == 0
    run_dir = tmp_path / "sensorgym__StereoPlacement-v0" / "ppo-shared_seed0"
    assert read_config(run_dir)["agents"] is True
    evaluation = json.loads((run_dir / "evaluation.json").read_text())["results"]
    assert {"trained", "hold-position", "greedy-information"} <= set(evaluation)
    bench = [*env, "--episodes", "2", "--n-envs", "2", "--model", str(run_dir)]
    assert main(["benchmark", *bench, "--out", str(tmp_path / "bench")]) == 0
    results = json.loads((tmp_path / "bench" / "sensorgym__StereoPlacement-v0.json").read_text())
    assert "model:ppo-shared_seed0" in results["results"]


def test_train_command_with_sac_then_benchmark_the_saved_run(tmp_path, capsys):
    args = ["--algo", "sac", "--timesteps", "300", "--n-envs", "2", "--eval-episodes", "2"]
    small = ["--hyperparam", "policy_kwargs={net_arch: [32, 32]}", "--hyperparam", "tau=0.01"]
    assert main(["train", *args, *small, "--out", str(tmp_path), "--no-progress"]) == 0
    printed = capsys.readouterr().out  # the run beside the rules, paired to the best one
    assert "tuning seed 500" in printed and "paired IQM" in printed
    assert re.search(r"trained .* (best rule|[-+]\d)", printed)
    run_dir = tmp_path / "sensorgym__BearingsManeuver-v0" / "sac_seed0"
    config = read_config(run_dir)
    assert config["algo"] == "sac" and config["hyperparams"]["tau"] == 0.01
    assert config["hyperparams"]["policy_kwargs"]["net_arch"] == [32, 32]
    assert load_model(run_dir).actor.latent_pi[0].out_features == 32
    with pytest.raises(SystemExit, match=r"--hyperparam: .*tua"):
        main(["train", *args, "--hyperparam", "tua=0.01", "--out", str(tmp_path)])
    bench = ["--env", ENV_ID, "--episodes", "2", "--n-envs", "2", "--model", str(run_dir)]
    assert main(["benchmark", *bench, "--out", str(tmp_path / "bench")]) == 0
    results = json.loads((tmp_path / "bench" / "sensorgym__BearingsManeuver-v0.json").read_text())
    assert "model:sac_seed0" in results["results"]
    assert "model:sac_seed0" in capsys.readouterr().out


def test_infos_fast_path_equals_the_general_path():
    venv = make_sb3_env(ENV_ID, 3, seed=1, agents=True, platforms=2)
    venv.reset()
    inner = venv.unwrapped
    *_, infos = inner.venv.step(np.zeros((3, 2, 2), np.float32))
    fast = inner._split_infos(infos)
    partial = {**infos, "_range": np.array([True, True, False])}
    general = inner._split_infos(partial)
    assert len(fast) == 6 and all(isinstance(v, float) for v in fast[0].values())
    assert fast[:4] == general[:4] and "range" not in general[4]
    assert fast[4] == {**general[4], "range": fast[4]["range"]}


def test_training_runs_on_one_torch_thread_and_restores_the_setting(tmp_path, monkeypatch):
    import torch

    seen = []
    monkeypatch.setattr(
        "sensorgym.train.trainer._train", lambda *a, **k: seen.append(torch.get_num_threads())
    )
    before = torch.get_num_threads()
    train(ENV_ID, timesteps=1, out=tmp_path)
    train(ENV_ID, timesteps=1, out=tmp_path, torch_threads=2)
    assert seen == [1, 2] and torch.get_num_threads() == before
    with pytest.raises(ValueError, match="torch_threads"):
        train(ENV_ID, timesteps=1, out=tmp_path, torch_threads=0)
