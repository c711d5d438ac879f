"""Train PPO on an env, then compare the trained policy with the rules on held-out scenarios.

The defaults train briefly (a policy worth having needs the YAML's 200 000+ steps:
``sensorgym train`` without ``--timesteps``).

    python examples/train_and_compare.py [--timesteps 20000] [--episodes 32] [--out results/examples]
        [--pretrain-steps N]

``--pretrain-steps`` shows how a recipe entry is overridden (``train(hyperparams=...)``, the
``--hyperparam`` option of ``sensorgym train``): the steps of the imitation phase that comes
before PPO (``pretrain.steps`` in ``train/hyperparams/ppo.yml``).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from sensorgym.agents.registry import rules_for
from sensorgym.train.evaluation import env_params, evaluate, make_sb3_env, simulator_state
from sensorgym.train.models import load_model, read_config
from sensorgym.train.trainer import train

ENV_ID = "sensorgym/BearingsManeuver-v0"


def main(argv: list[str] | None = None) -> dict[str, float]:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--timesteps", type=int, default=20_000)
    parser.add_argument("--episodes", type=int, default=32)
    parser.add_argument("--seed", type=int, default=0, help="training seed")
    parser.add_argument("--out", type=Path, default=Path("results/examples"))
    parser.add_argument("--pretrain-steps", type=int, default=None, help="default: the YAML's")
    args = parser.parse_args(argv)

    # train on seed `seed`; the run folder holds the weights (safetensors) and config.yaml
    overrides = {} if args.pretrain_steps is None else {"pretrain.steps": args.pretrain_steps}
    result = train(ENV_ID, "ppo", seed=args.seed, timesteps=args.timesteps, n_envs=16,
                   out=args.out, eval_episodes=16, progress=False,
                   hyperparams=overrides)  # fmt: skip
    print(f"trained {args.timesteps} steps, saved {result.run_dir}")

    # reload it (no pickle) and score it beside the rules on held-out scenarios
    eval_seed = 10_000 + args.seed
    env = make_sb3_env(ENV_ID, n_envs=min(16, args.episodes), seed=eval_seed)
    # the policy sees the env through the run's wrappers (e.g. the time left): same scenarios
    wrappers = read_config(result.run_dir)["hyperparams"].get("wrappers")
    model_env = make_sb3_env(ENV_ID, n_envs=env.num_envs, seed=eval_seed, wrappers=wrappers)
    policies = {"ppo (ours)": (load_model(result.run_dir, model_env), model_env)}
    rules = rules_for(ENV_ID, env_params(env), simulator_state(env))
    policies |= {name: (rule, env) for name, rule in rules.items()}
    scores = {}
    for name, (policy, venv) in policies.items():
        stats = evaluate(policy, venv, args.episodes, eval_seed)
        scores[name] = stats.mean
        print(f"{name:20s} {stats.mean:7.3f} ± {stats.ci95:.3f}")
    env.close()
    model_env.close()
    return scores


if __name__ == "__main__":
    main()
