"""``sensorgym render``: watch a rule (or a trained model) play one episode of an env.

Runs one seeded episode of the Gymnasium env with ``render_mode="rgb_array"`` and writes the
frames: an animated ``.gif`` (every ``--every``-th step), or the last frame as ``.png``.
Prints the episode return and length. ``--model`` takes a run folder or the name of a policy
shipped for the env (``sensorgym benchmark`` lists them as ``shipped:<name>``); a model acts
through the wrappers its run recorded (:mod:`sensorgym.train.wrappers`).
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from sensorgym.cli import args as types
from sensorgym.cli.benchmark import UNSAFE_PICKLE_HELP
from sensorgym.cli.params import add_param_argument, params_from

HELP = "Play one seeded episode with a rule or trained model and save it as GIF or PNG."


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--env", default="sensorgym/BearingsManeuver-v0", help="env id")
    parser.add_argument("--rule", default=None, help="rule name (default: the env's last rule)")
    parser.add_argument(
        "--model",
        type=Path,
        default=None,
        help="a `sensorgym train` run folder (policy.safetensors + config.yaml), or the name "
        "of a policy shipped for --env (e.g. ppo_seed0 or shipped:ppo_seed0)",
    )
    parser.add_argument("--unsafe-pickle", action="store_true", help=UNSAFE_PICKLE_HELP)
    parser.add_argument("--seed", type=types.seed, default=0)
    parser.add_argument(
        "--every", type=types.positive_int, default=1, help="keep every N-th frame in the GIF"
    )
    lo, hi = types.FPS_RANGE
    parser.add_argument(
        "--fps", type=types.fps, default=5.0, help=f"GIF frames per second ({lo:g} to {hi:g})"
    )
    parser.add_argument("--out", type=Path, default=Path("results/render/episode.gif"))
    add_param_argument(parser)


def run(args: argparse.Namespace) -> int:
    import gymnasium as gym
    from PIL import Image
    from stable_baselines3.common.vec_env import DummyVecEnv, VecMonitor

    import sensorgym.envs  # noqa: F401  (registers the ids)
    from sensorgym.agents.registry import rules_for
    from sensorgym.train.models import (
        RunFolderError,
        check_model_params,
        check_run_folder,
        load_model,
        wrappers_of,
    )
    from sensorgym.train.wrappers import apply_wrappers

    if args.out.suffix.lower() not in (".gif", ".png"):
        raise SystemExit("--out must end in .gif or .png")
    if args.env not in gym.registry:
        raise SystemExit(f"--env: {args.env!r} is not a registered id")
    params = params_from(args.env, args.param)
    wrappers: list[dict[str, Any]] = []
    if args.model is not None:
        args.model = _model_folder(args.model, args.env)
        try:
            config = check_run_folder(args.model, args.unsafe_pickle)
            wrappers = wrappers_of(config)
        except RunFolderError as exc:
            raise SystemExit(f"--model: {exc}") from None
        trained_on = config["env"]
        if trained_on != args.env:
            raise SystemExit(f"--model {args.model}: trained on {trained_on}, not on {args.env}")
        try:
            check_model_params(config, params)
        except RunFolderError as exc:
            raise SystemExit(f"--model {args.model}: {exc}") from None
    types.output_file(args.out)  # before the episode: a bad --out fails now
    env = _Frames(gym.make(args.env, render_mode="rgb_array", **params), args.every)
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
    # one slot of SB3's VecEnv API, so a model meets the wrappers it was trained through
    try:
        venv = apply_wrappers(VecMonitor(DummyVecEnv([lambda: env])), wrappers)
    except ValueError as exc:  # a wrapper's values in the run's config.yaml
        raise SystemExit(f"--model {args.model}: {exc}") from None
    venv.seed(args.seed)
    obs = venv.reset()
    total, steps, state, start = 0.0, 0, None, np.array([True])
    done = False
    while not done:
        action, state = policy.predict(obs, state=state, episode_start=start, deterministic=True)
        obs, reward, dones, _ = venv.step(action)
        start = dones
        total, steps, done = total + float(reward[0]), steps + 1, bool(dones[0])
    venv.close()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    images = [Image.fromarray(f) for f in env.frames]
    if args.out.suffix.lower() == ".png":
        images[-1].save(args.out)
    else:
        duration = int(1000 / args.fps)
        images[0].save(args.out, save_all=True, append_images=images[1:], duration=duration, loop=0)
    print(f"{args.env}, {name}, seed {args.seed}: return {total:.3f} over {steps} steps")
    print(f"wrote {args.out} ({len(images)} frames)")
    return 0


def _model_folder(model: Path, env_id: str) -> Path:
    """``model`` itself when it exists, else the shipped policy of ``env_id`` it names."""
    from sensorgym.train.shipped import shipped_policies

    if Path(model).exists():
        return Path(model)
    shipped = shipped_policies(env_id)
    key = str(model).removeprefix("shipped:")
    if key in shipped:
        return shipped[key]
    raise SystemExit(
        f"--model: {str(model)!r} is neither a run folder nor a policy shipped for {env_id} "
        f"(shipped: {sorted(shipped) or 'none'})"
    )


class _Frames(gym.Wrapper):
    """Keeps the frames of the first episode: the first state, every ``every``-th step's and
    the last one's (drawn before any reset)."""

    def __init__(self, env: gym.Env, every: int):
        super().__init__(env)
        self.every, self.frames, self._steps, self._done = every, [], 0, False

    def reset(self, **kwargs: Any) -> Any:
        result = self.env.reset(**kwargs)
        if not self.frames:
            self.frames.append(self.env.render())
        return result

    def step(self, action: Any) -> Any:
        result = self.env.step(action)
        if not self._done:
            self._steps += 1
            self._done = bool(result[2] or result[3])
            if self._steps % self.every == 0 or self._done:
                self.frames.append(self.env.render())
        return result


class SharedPolicy:
    """A parameter-sharing model (``sensorgym train --agents``) driving a single env: each step
    it acts on every agent's own observation of the env's current state and returns the joint
    action (the agents' actions in agent order)."""

    def __init__(self, model: Any, core_env: Any):
        self.model, self.core_env = model, core_env

    def predict(self, observation: Any, **kwargs: Any) -> tuple[Any, Any]:
        per_agent = self.core_env.core.observe_agents(self.core_env.simulator_state)[0]
        actions, state = self.model.predict(per_agent, **kwargs)
        return actions.reshape(1, -1), state  # one slot of the VecEnv: the joint action
