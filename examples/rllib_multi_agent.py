"""Train one policy shared by every agent of a PettingZoo env with RLlib's PPO, then score it
with ``sensorgym benchmark --model`` beside the env's rules.

RLlib is the path to a Ray cluster: ``--address HOST:PORT`` joins one (the env runners spread
over its nodes), without it a Ray instance of its own starts here. Install RLlib first:

    pip install 'sensorgym[rllib]'    # Ray with RLlib's requirements (or: pip install 'ray[rllib]')

What this script does:

1. trains RLlib's PPO (its new API stack) on ``<env>.parallel_env()`` through RLlib's
   ``ParallelPettingZooEnv``, every agent mapped to one module (parameter sharing, as
   ``sensorgym train --agents``) with SB3's default actor-critic layout (two tanh layers of 64
   for the policy, two for the value, a state-independent log-std), so that the weights fit
   the run format;
2. prints each iteration's **team return**: every agent receives the env's one team reward, so
   RLlib's episode return (the sum over agents) counts it once per agent; divided by the
   number of agents it is the env's return, the number ``sensorgym benchmark`` reports;
3. exports the module's weights into a ``sensorgym train`` run folder (``policy.safetensors``
   and ``config.yaml`` with ``agents: true``; no pickle), checks that the exported policy acts
   exactly as the RLlib module's mean action, and scores it with ``sensorgym benchmark --model``.

Run: ``python examples/rllib_multi_agent.py [--env stereo_placement] [--iterations 5]
[--address HOST:PORT] [--out results/rllib]`` (a few minutes on 2 CPUs).
"""

from __future__ import annotations

import argparse
import importlib
from pathlib import Path

import numpy as np
import torch

from sensorgym.cli.main import main as sensorgym
from sensorgym.train.models import build_model, save_run

#: RLlib module parameter -> SB3 ActorCriticPolicy parameter (two hidden layers each)
RLLIB_TO_SB3 = {
    "encoder.actor_encoder.net.mlp.0": "mlp_extractor.policy_net.0",
    "encoder.actor_encoder.net.mlp.2": "mlp_extractor.policy_net.2",
    "encoder.critic_encoder.net.mlp.0": "mlp_extractor.value_net.0",
    "encoder.critic_encoder.net.mlp.2": "mlp_extractor.value_net.2",
    "pi.net.mlp.0": "action_net",
    "vf.net.mlp.0": "value_net",
}
#: the layers both sides have: SB3's MlpPolicy default
HIDDEN = [64, 64]


def train(module_name: str, iterations: int, seed: int, address: str | None, runners: int):
    """RLlib's PPO trained ``iterations`` times on the env package ``module_name``; returns the
    algorithm and the number of agents."""
    import ray
    from ray.rllib.algorithms.ppo import PPOConfig
    from ray.rllib.core.rl_module.default_model_config import DefaultModelConfig
    from ray.rllib.core.rl_module.multi_rl_module import MultiRLModuleSpec
    from ray.rllib.core.rl_module.rl_module import RLModuleSpec
    from ray.rllib.env.wrappers.pettingzoo_env import ParallelPettingZooEnv
    from ray.tune.registry import register_env

    package = importlib.import_module(f"sensorgym.envs.{module_name}")
    n_agents = len(package.parallel_env().possible_agents)
    if address:  # a cluster started elsewhere (`ray start --head`): its CPUs, its token
        ray.init(address=address, log_to_driver=False)
    else:  # always a Ray of its own: never a stale cluster left on this machine
        ray.init(address="local", num_cpus=max(2, runners + 1), include_dashboard=False,
                 log_to_driver=False)  # fmt: skip
    register_env("sensorgym-pz", lambda cfg: ParallelPettingZooEnv(package.parallel_env(**cfg)))
    model = DefaultModelConfig(
        fcnet_hiddens=HIDDEN, fcnet_activation="tanh", vf_share_layers=False, free_log_std=True
    )
    steps = package.parallel_env().max_episode_steps
    config = (
        PPOConfig()
        .environment("sensorgym-pz", env_config={})
        .env_runners(num_env_runners=runners)
        .learners(num_learners=0)
        .multi_agent(policies={"shared"}, policy_mapping_fn=lambda agent, *_, **__: "shared")
        .rl_module(
            rl_module_spec=MultiRLModuleSpec(
                rl_module_specs={"shared": RLModuleSpec(model_config=model)}
            )
        )
        # a batch of whole episodes of every agent; small, so that an iteration takes seconds
        .training(
            train_batch_size_per_learner=2 * steps * n_agents,
            minibatch_size=steps,
            num_epochs=4,
            lr=3e-4,
            gamma=0.95,
        )
        .debugging(seed=seed)
    )
    algo = config.build_algo()
    print(f"{'iteration':>9} {'samples':>8} {'team return':>12}")
    for i in range(1, iterations + 1):
        result = algo.train()
        runners_info = result["env_runners"]
        # RLlib sums the agents' rewards: the team reward once per agent
        team = runners_info.get("episode_return_mean", np.nan) / n_agents
        print(f"{i:>9} {runners_info.get('num_env_steps_sampled_lifetime', 0):>8} {team:>12.3f}")
    return algo, n_agents


def export(algo, env_id: str, out: Path, seed: int) -> Path:
    """Write the shared module as a ``sensorgym train`` run folder under ``out`` and return it."""
    config = {
        "env": env_id,
        "algo": "ppo",
        "seed": seed,
        "agents": True,
        "hyperparams": {"policy": "MlpPolicy", "policy_kwargs": {"net_arch": HIDDEN}},
        "trained_with": "RLlib PPO (examples/rllib_multi_agent.py)",
    }
    model = build_model(config)  # the SB3 policy the run format describes, untrained
    module = algo.get_module("shared")
    rllib = {k: v.detach().cpu() for k, v in module.state_dict().items()}
    state = model.policy.state_dict()
    for src, dst in RLLIB_TO_SB3.items():
        for part in ("weight", "bias"):
            state[f"{dst}.{part}"] = rllib[f"{src}.{part}"].to(state[f"{dst}.{part}"].dtype)
    state["log_std"] = rllib["pi.log_std"].to(state["log_std"].dtype)
    model.policy.load_state_dict(state, strict=True)
    # the exported policy acts as RLlib's module does (its mean action, clipped to the Box)
    obs = torch.as_tensor(
        np.random.default_rng(seed).normal(size=(8, *model.observation_space.shape)),
        dtype=torch.float32,
    )
    with torch.no_grad():  # the distribution's inputs: the means, then the log-stds
        inputs = module.forward_inference({"obs": obs})["action_dist_inputs"]
    mean = inputs[:, : model.action_space.shape[0]].numpy()
    ours = model.policy.predict(obs.numpy(), deterministic=True)[0]
    np.testing.assert_allclose(ours, np.clip(mean, -1.0, 1.0), atol=1e-5)
    run_dir = out / env_id.replace("/", "__") / f"rllib_ppo_seed{seed}"
    save_run(model, run_dir, config)
    return run_dir


def main(argv: list[str] | None = None) -> Path:
    """Train, export and score; returns the run folder."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--env", default="stereo_placement", help="an env package of sensorgym.envs"
    )
    parser.add_argument("--iterations", type=int, default=5)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--address", default=None, help="a Ray cluster to join (HOST:PORT)")
    parser.add_argument("--env-runners", type=int, default=0, help="RLlib env runner actors")
    parser.add_argument("--episodes", type=int, default=64, help="benchmark episodes")
    parser.add_argument(
        "--rule",
        action="append",
        default=[],
        help="score this rule beside it (default: the env's set)",
    )
    parser.add_argument("--out", type=Path, default=Path("results/rllib"))
    args = parser.parse_args(argv)
    try:
        import ray
        import ray.rllib
    except ImportError as exc:
        raise SystemExit(f"RLlib does not import ({exc}): pip install 'sensorgym[rllib]'") from None

    package = importlib.import_module(f"sensorgym.envs.{args.env}")
    env_id = package.parallel_env().env_id
    try:
        algo, _ = train(args.env, args.iterations, args.seed, args.address, args.env_runners)
        run_dir = export(algo, env_id, args.out, args.seed)
        algo.stop()
    finally:
        ray.shutdown()
    print(f"wrote {run_dir}")
    # the env's return of the exported policy beside the env's rules, on paired episodes
    status = sensorgym(
        ["benchmark", "--env", env_id, "--model", str(run_dir), "--no-shipped", "--no-chart",
         "--episodes", str(args.episodes), "--n-envs", str(min(16, args.episodes)),
         "--out", str(args.out / "benchmark"), *[a for r in args.rule for a in ("--rule", r)]]
    )  # fmt: skip
    if status:
        raise SystemExit(status)
    return run_dir


if __name__ == "__main__":
    main()
