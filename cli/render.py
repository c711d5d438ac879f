"""``sensorgym render``: watch a rule (or a trained model) play one episode of an env.

Runs one seeded episode of the Gymnasium env with ``render_mode="rgb_array"`` and writes the
frames: an animated ``.gif`` (every ``--every``-th step), or the last frame as ``.png``.
Prints the episode return and length.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from sensorgym.cli.benchmark import UNSAFE_PICKLE_HELP

HELP = "Play one seeded episode with a rule or trained model and save it as GIF or PNG."


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--env", default="sensorgym/BearingsManeuver-v0", help="env id")
    parser.add_argument("--rule", default=None, help="rule name (default: the env's last rule)")
    parser.add_argument(
        "--model",
        type=Path,
        default=None,
        help="a `sensorgym train` run folder (policy.safetensors + config.yaml)",
    )
    parser.add_argument("--unsafe-pickle", action="store_true", help=UNSAFE_PICKLE_HELP)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--every", type=int, default=1, help="keep every N-th frame in the GIF")
    parser.add_argument("--fps", type=float, default=5.0)
    parser.add_argument("--out", type=Path, default=Path("results/render/episode.gif"))


def run(args: argparse.Namespace) -> int:
    import gymnasium as gym
    import numpy as np
    from PIL import Image

    import sensorgym.envs  # noqa: F401  (registers the ids)
    from sensorgym.agents.registry import rules_for
    from sensorgym.train.models import RunFolderError, check_run_folder, load_model

    if args.out.suffix.lower() not in (".gif", ".png"):
        raise SystemExit("--out must end in .gif or .png")
    if args.every < 1 or args.fps <= 0:
        raise SystemExit("--every must be >= 1 and --fps > 0")
    if args.env not in gym.registry:
        raise SystemExit(f"--env: {args.env!r} is not a registered id")
    if args.model is not None:
        try:
            config = check_run_folder(args.model, args.unsafe_pickle)
        except RunFolderError as exc:
            raise SystemExit(f"--model: {exc}") from None
        trained_on = config["env"]
        if trained_on != args.env:
            raise SystemExit(f"--model {args.model}: trained on {trained_on}, not on {args.env}")
    env = gym.make(args.env, render_mode="rgb_array")
    core_env = env.unwrapped
    if args.model is not None:
        try:
            policy = load_model(args.model, unsafe_pickle=args.unsafe_pickle)
        except RunFolderError as exc:
            raise SystemExit(f"--model: {exc}") from None
        name = f"model {args.model}"
        if config.get("agents", False):  # parameter sharing: the policy acts per agent
            policy = SharedPolicy(policy, core_env)
    else:
        rules = rules_for(args.env, core_env.params, lambda: core_env.simulator_state)
        name = args.rule or list(rules)[-1]
        if name not in rules:
            raise SystemExit(f"--rule: one of {sorted(rules)}, got {name!r}")
        policy = rules[name]
    obs, _ = env.reset(seed=args.seed)
    frames, total, steps, state, start = [env.render()], 0.0, 0, None, np.array([True])
    done = False
    while not done:
        action, state = policy.predict(obs, state=state, episode_start=start, deterministic=True)
        start = np.array([False])
        obs, reward, terminated, truncated, _ = env.step(action)
        total, steps, done = total + reward, steps + 1, terminated or truncated
        if steps % args.every == 0 or done:
            frames.append(env.render())
    env.close()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    images = [Image.fromarray(f) for f in frames]
    if args.out.suffix.lower() == ".png":
        images[-1].save(args.out)
    else:
        duration = int(1000 / args.fps)
        images[0].save(args.out, save_all=True, append_images=images[1:], duration=duration, loop=0)
    print(f"{args.env}, {name}, seed {args.seed}: return {total:.3f} over {steps} steps")
    print(f"wrote {args.out} ({len(images)} frames)")
    return 0


class SharedPolicy:
    """A parameter-sharing model (``sensorgym train --agents``) driving a single env: each step
    it acts on every agent's own observation of the env's current state and returns the joint
    action (the agents' actions in agent order)."""

    def __init__(self, model: Any, core_env: Any):
        self.model, self.core_env = model, core_env

    def predict(self, observation: Any, **kwargs: Any) -> tuple[Any, Any]:
        per_agent = self.core_env.core.observe_agents(self.core_env.simulator_state)[0]
        actions, state = self.model.predict(per_agent, **kwargs)
        return actions.reshape(-1), state
