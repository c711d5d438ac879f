"""Wrappers, imitation pre-training, paired evaluation and learning curves of `sensorgym train`."""

from __future__ import annotations

import json

import numpy as np
import pytest
import yaml
from stable_baselines3 import PPO

from sensorgym.agents.bearings_maneuver import GreedyManeuver, StraightCourse
from sensorgym.cli.main import main
from sensorgym.envs import ENV_IDS
from sensorgym.envs.bearings_maneuver.simulation import OBS_DIM
from sensorgym.train.benchmark import best_rule, paired_difference, paired_to_best_rule, pool
from sensorgym.train.curves import (
    POLICY_COLOUR,
    WINDOW_MARGIN,
    curve_window,
    rule_colours,
    spread_labels,
    write_curve,
)
from sensorgym.train.evaluation import env_params, evaluate, make_sb3_env
from sensorgym.train.experts import Pretrain, collect, expert_factory, pretrain
from sensorgym.train.models import load_model
from sensorgym.train.trainer import VALIDATION_SEED, train
from sensorgym.train.wrappers import apply_wrappers, base_observation, check_wrappers
from tests.pending import having

ENV_ID = "sensorgym/BearingsManeuver-v0"


def test_time_feature_counts_down_per_slot_and_keeps_the_reward():
    plain = make_sb3_env(ENV_ID, 3, seed=4)
    timed = make_sb3_env(ENV_ID, 3, seed=4, wrappers=[{"name": "time-feature"}])
    assert timed.observation_space.shape == (OBS_DIM + 1,)
    o0, o1 = plain.reset(), timed.reset()
    np.testing.assert_array_equal(o1[:, :OBS_DIM], o0)
    np.testing.assert_array_equal(o1[:, OBS_DIM], 1.0)
    action = np.zeros((3, 2), dtype=np.float32)
    for t in range(1, 31):
        p, r0, _, _ = plain.step(action)
        w, r1, d1, infos = timed.step(action)
        np.testing.assert_array_equal(r0, r1)
        np.testing.assert_array_equal(w[:, :OBS_DIM], p)
        if t < 30:
            np.testing.assert_allclose(w[:, OBS_DIM], 1.0 - t / 30)
    assert d1.all()
    np.testing.assert_array_equal(w[:, OBS_DIM], 1.0)  # the next episode's first observation
    assert infos[0]["terminal_observation"][OBS_DIM] == pytest.approx(0.0)


def test_frame_stack_and_unknown_wrappers():
    specs = [{"name": "time-feature"}, {"name": "frame-stack", "n_stack": 3}]
    env = make_sb3_env(ENV_ID, 2, seed=0, wrappers=specs)
    plain = make_sb3_env(ENV_ID, 2, seed=0)
    assert env.observation_space.shape == (3 * (OBS_DIM + 1),)
    obs, base = env.reset(), plain.reset()
    np.testing.assert_array_equal(obs[:, : 2 * (OBS_DIM + 1)], 0.0)
    np.testing.assert_array_equal(base_observation(env, obs), base)
    obs, base = env.step(np.ones((2, 2)))[0], plain.step(np.ones((2, 2)))[0]
    np.testing.assert_array_equal(base_observation(env, obs), base)
    with pytest.raises(ValueError, match="not one of"):
        check_wrappers([{"name": "teleport"}])
    with pytest.raises(ValueError, match="does not take"):
        apply_wrappers(make_sb3_env(ENV_ID, 1, 0), [{"name": "frame-stack", "depth": 2}])
    with pytest.raises(ValueError, match="list"):
        check_wrappers("frame-stack")


def test_evaluation_orders_episodes_so_that_policies_pair_up():
    env = make_sb3_env(ENV_ID, 4, seed=0)
    a = evaluate(StraightCourse(), env, 12, seed=7)
    b = evaluate(GreedyManeuver(env_params(env)), env, 12, seed=7)
    assert len(a.returns) == len(b.returns) == 12
    assert a.mean == pytest.approx(np.mean(a.returns))
    # a straight course learns nothing about range: per scenario the greedy rule does better
    d = paired_difference(b.returns, a.returns)
    assert d["mean"] == pytest.approx(b.mean - a.mean)
    assert d["ci95"] < np.hypot(a.ci95, b.ci95)  # pairing removes the shared scenario spread
    assert d["mean"] - d["ci95"] > 0
    # chunks pooled in order keep the pairing
    parts = [evaluate(StraightCourse(), env, 4, seed=s).as_dict() for s in (1, 2)]
    assert pool(parts)["returns"] == parts[0]["returns"] + parts[1]["returns"]


def test_best_rule_leaves_out_truth_informed_rules_and_models():
    results = {
        "truth-lookahead": {"mean": 5.0, "returns": [5.0, 5.0]},
        "shipped:ppo_seed0": {"mean": 4.0, "returns": [4.0, 4.2]},
        "greedy-information": {"mean": 3.0, "returns": [3.0, 3.0]},
        "straight-course": {"mean": 0.0, "returns": [0.0, 0.0]},
    }
    assert best_rule(results) == "greedy-information"
    best, paired = paired_to_best_rule(results)
    assert best == "greedy-information" and set(paired) == {
        "truth-lookahead",
        "shipped:ppo_seed0",
        "straight-course",
    }
    assert paired["shipped:ppo_seed0"]["mean"] == pytest.approx(1.1)
    # a plan fixed in advance from prior knowledge only is a fieldable rule, the best one here
    results["book-optimised-plan"] = {"mean": 4.5, "returns": [4.5, 4.5]}
    assert best_rule(results) == "book-optimised-plan"
    with pytest.raises(ValueError, match="equally long"):
        paired_difference([1.0, 2.0], [1.0])


def test_behaviour_cloning_makes_the_policy_act_like_the_expert():
    env = make_sb3_env(ENV_ID, 8, seed=1)
    model = PPO("MlpPolicy", env, seed=0, device="cpu", policy_kwargs={"net_arch": [64, 64]})
    expert = expert_factory("rule:greedy-information")(env)
    held_out = collect(make_sb3_env(ENV_ID, 8, seed=99), expert, 240, gamma=0.99)

    def disagreement() -> float:
        actions, _ = model.predict(held_out.observations, deterministic=True)
        return float(np.mean(np.abs(actions - held_out.actions)))

    before = disagreement()
    config = Pretrain(expert="rule:greedy-information", steps=960, epochs=20, batch_size=64)
    losses = pretrain(model, env, config, seed=0)
    after = disagreement()
    assert len(losses) == 1 and np.isfinite(losses[0])
    assert after < 0.7 * before  # measured 0.55 (0.26 → 0.14 with 2400 samples)
    # the log std was left for RL to explore with
    assert float(model.policy.log_std.detach().abs().max()) == 0.0


def test_pretrain_entries_are_checked():
    with pytest.raises(ValueError, match="neither"):
        Pretrain.from_config({"expert": "nobody", "steps": 10})
    with pytest.raises(ValueError, match="unknown keys"):
        Pretrain.from_config({"expert": "rule:paper002", "steps": 10, "speed": 2})
    with pytest.raises(ValueError, match="steps"):
        Pretrain.from_config({"expert": "rule:paper002", "steps": 0})
    with pytest.raises(KeyError, match="no rule"):
        expert_factory("rule:nobody")(make_sb3_env(ENV_ID, 1, 0))


def test_the_curve_window_holds_the_band_and_the_best_rule_and_names_the_rest(tmp_path):
    points = [
        {"timesteps": 0, "mean": 60.0, "ci95": 10.0},
        {"timesteps": 8, "mean": 70.0, "ci95": 10.0},
    ]
    rules = {"best": 90.0, "near": 45.0, "still": -700.0, "low": 35.0}
    (lo, hi), shown, hidden = curve_window(points, rules)
    # the curve's band 50..80 and the best rule 90, widened by a quarter of their span
    assert (lo, hi) == pytest.approx((50 - WINDOW_MARGIN * 40, 90 + WINDOW_MARGIN * 40))
    assert shown == {"best": 90.0, "near": 45.0}
    assert hidden == {"still": -700.0, "low": 35.0}
    (lo, hi), shown, hidden = curve_window(points, {"best": 75.0, "still": -700.0})
    assert (lo, hi) == pytest.approx((50 - WINDOW_MARGIN * 30, 80 + WINDOW_MARGIN * 30))
    assert shown == {"best": 75.0} and hidden == {"still": -700.0}
    # the best fieldable rule stays in view under a truth-informed rule far above it
    (lo, hi), shown, hidden = curve_window(points, {"truth-x": 85.0, "rule": 20.0, "bad": -9.0})
    assert (lo, hi) == pytest.approx((20 - WINDOW_MARGIN * 65, 85 + WINDOW_MARGIN * 65))
    assert set(shown) == {"truth-x", "rule"} and set(hidden) == {"bad"}
    # a flat, exact curve with no rules still gets a window
    assert curve_window([{"timesteps": 0, "mean": 3.0, "ci95": 0.0}], {})[0] == (2.0, 4.0)
    # a diverged evaluation: the finite values set the range, a non-finite rule is named
    nan = float("nan")
    (lo, hi), shown, hidden = curve_window(
        [*points, {"timesteps": 9, "mean": nan, "ci95": 1.0}], {"best": 90.0, "broken": nan}
    )
    assert (lo, hi) == pytest.approx((50 - WINDOW_MARGIN * 40, 90 + WINDOW_MARGIN * 40))
    assert shown == {"best": 90.0} and list(hidden) == ["broken"]
    assert curve_window([], {})[0] == (-1.0, 1.0)
    assert curve_window([{"timesteps": 0, "mean": nan, "ci95": nan}], {"x": nan})[0] == (-1.0, 1.0)
    write_curve(tmp_path, "t", [{"timesteps": 0, "mean": nan, "ci95": nan}], {"x": nan})
    json_path, png_path = write_curve(tmp_path, "t", points, rules)
    assert json.loads(json_path.read_text()) == {"points": points, "rules": rules}
    assert png_path.stat().st_size > 1000


def test_spread_labels_keeps_the_order_and_the_gap_and_moves_least():
    y = np.array([10.0, 0.0, 10.5, 30.0, 9.8])
    a = spread_labels(y, 2.0)
    assert list(np.argsort(-a, kind="stable")) == list(np.argsort(-y, kind="stable"))
    assert np.all(-np.diff(np.sort(a)[::-1]) >= 2.0 - 1e-12)
    # labels far apart stay where they are; a crowded cluster is centred on its own mean
    assert a[3] == 30.0 and a[1] == 0.0
    cluster = np.sort(a[[0, 2, 4]])
    np.testing.assert_allclose(cluster, np.mean([10.0, 10.5, 9.8]) + np.array([-2.0, 0.0, 2.0]))
    np.testing.assert_array_equal(spread_labels(np.array([5.0, 1.0]), 2.0), [5.0, 1.0])


def test_train_with_wrappers_pretraining_and_a_learning_curve(tmp_path):
    hp = {
        "wrappers": [{"name": "time-feature"}],
        "pretrain": {"expert": "rule:greedy-information", "steps": 256, "epochs": 2},
        "n_steps": 32,
        "batch_size": 64,
    }
    result = train(
        ENV_ID,
        seed=0,
        timesteps=256,
        n_envs=4,
        out=tmp_path,
        eval_episodes=4,
        progress=False,
        hyperparams=hp,
        curve_points=2,
    )
    config = yaml.safe_load((result.run_dir / "config.yaml").read_text())
    assert config["hyperparams"]["wrappers"] == [{"name": "time-feature"}]
    curve = json.loads((result.run_dir / "curve.json").read_text())
    assert curve["points"][0]["timesteps"] == 0
    assert curve["points"][-1]["timesteps"] >= 256
    assert set(curve["rules"]) == {r for r in result.evaluation if r != "trained"}
    assert len(curve["pretrain_loss"]) == 1
    assert (result.run_dir / "curve.png").stat().st_size > 1000
    # the saved policy rebuilds its wrappers: benchmark scores it on the wrapped view, the same
    # scenarios as the rules
    wrappers = config["hyperparams"]["wrappers"]
    env = make_sb3_env(ENV_ID, 4, VALIDATION_SEED, wrappers=wrappers, episode_streams=True)
    stats = evaluate(load_model(result.run_dir, env), env, 4, VALIDATION_SEED)
    assert stats.mean == pytest.approx(result.evaluation["trained"]["mean"])
    out = tmp_path / "bench"
    argv = ["benchmark", "--env", ENV_ID, "--episodes", "4", "--n-envs", "4", "--seed", "3"]
    assert main([*argv, "--model", str(result.run_dir), "--no-chart", "--out", str(out)]) == 0
    doc = json.loads((out / "sensorgym__BearingsManeuver-v0.json").read_text())
    assert doc["best_rule"] == best_rule(doc["results"]) != "truth-lookahead"
    assert len(doc["results"]["model:ppo_seed0"]["returns"]) == 4
    assert "model:ppo_seed0" in doc["paired"]
    gif = tmp_path / "play.gif"
    assert main(["render", "--env", ENV_ID, "--model", str(result.run_dir), "--out", str(gif)]) == 0
    assert gif.stat().st_size > 0


def test_parameter_sharing_runs_take_their_own_recipe():
    from sensorgym.train.config import for_mode, load_hyperparams

    hp = load_hyperparams("ppo", "sensorgym/StereoPlacement-v0")
    single, shared = for_mode(hp, agents=False), for_mode(hp, agents=True)
    assert "agents" not in single and "agents" not in shared
    assert single["wrappers"][0]["name"] == "placement-target" and "pretrain" in single
    assert "wrappers" not in shared and "pretrain" not in shared
    assert shared["policy_kwargs"] == {"net_arch": [128, 128]}
    assert single["gamma"] == shared["gamma"]


@pytest.mark.parametrize("env_id", having("ppo_recipe", ENV_IDS))
def test_every_parameter_sharing_recipe_builds_and_steps(env_id):
    """`sensorgym train --agents` on every env: the recipe's wrappers (and expert, if any) take
    one agent's own view and action (a joint-action wrapper on the agent view raised)."""
    from sensorgym.train.config import for_mode, load_hyperparams

    hp = for_mode(load_hyperparams("ppo", env_id), agents=True)
    env = make_sb3_env(env_id, 2, seed=0, agents=True, wrappers=hp.get("wrappers") or ())
    obs = env.reset()
    assert obs.shape == (env.num_envs, *env.observation_space.shape)
    if hp.get("pretrain"):
        expert = expert_factory(hp["pretrain"]["expert"])(env)
        actions, _ = expert.predict(obs, deterministic=True)
    else:
        env.action_space.seed(0)
        actions = np.stack([env.action_space.sample() for _ in range(env.num_envs)])
    obs, rewards, _, _ = env.step(actions)
    assert np.isfinite(obs).all() and np.isfinite(rewards).all()


def test_paired_iqm_is_robust_to_a_few_large_episodes_and_reproducible():
    # 250 episodes a steady 0.1 better, 6 episodes hundreds worse (a lost drone): the mean
    # difference is dragged below zero, the interquartile mean still reads the typical episode
    rng = np.random.default_rng(3)
    b = rng.normal(50.0, 30.0, 256)
    a = b + 0.1 + rng.normal(0.0, 0.01, 256)
    a[:6] -= 400.0
    d = paired_difference(list(a), list(b))
    assert d["mean"] < 0 and d["mean"] + d["ci95"] < 1.0
    lo, hi = d["iqm_ci95"]
    assert lo > 0.09 and hi < 0.11 and lo <= d["iqm"] <= hi
    assert d["iqm"] == pytest.approx(0.1, abs=0.005)
    assert (d["better"], d["worse"]) == (250, 6)
    assert paired_difference(list(a), list(b)) == d  # the bootstrap's generator is seeded
    # identical play: every episode ties, the interval collapses onto zero
    same = paired_difference(list(b), list(b))
    assert (same["iqm"], same["iqm_ci95"], same["better"], same["worse"]) == (0.0, [0.0, 0.0], 0, 0)
    with pytest.raises(ValueError, match="finite"):
        paired_difference([1.0, float("nan")], [1.0, 2.0])


def test_no_rule_line_takes_the_policys_colour():
    from matplotlib.colors import to_rgb

    palette = rule_colours()
    assert len(palette) >= 8  # tab10 without its orange
    policy = np.array(to_rgb(POLICY_COLOUR))
    assert min(np.linalg.norm(np.array(to_rgb(c)) - policy) for c in palette) >= 0.25
    assert "#ff7f0e" not in palette  # tab10's orange, the colour that clashed
