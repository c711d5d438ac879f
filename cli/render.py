"""``sensorgym render`` (also ``enjoy`` and ``record``, rl-baselines3-zoo's names): watch a rule
or a trained model play seeded episodes of an env, and record them.

Runs ``--episodes`` seeded episodes (one after the other, as a ``VecEnv`` autoresets) of the
Gymnasium env with ``render_mode="rgb_array"`` and writes the frames of all of them: a video
``.mp4`` (where ``imageio`` and ``imageio-ffmpeg`` are installed, the ``video`` extra; else a
``.gif`` beside it, and a note says so), an animated ``.gif`` (every ``--every``-th step), or
the last frame as ``.png``. Prints each episode's return and length and their mean.
``--model`` takes a run folder or the name of a policy shipped for the env (``sensorgym
benchmark`` lists them as ``shipped:<name>``); a model acts through the wrappers its run
recorded (:mod:`sensorgym.train.wrappers`).
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

HELP = "Play seeded episodes with a rule or trained model; record them as MP4, GIF or PNG."
#: the other names of the command (rl-baselines3-zoo's ``enjoy`` and ``record_video``)
ALIASES = ["enjoy", "record"]
#: what ``--out`` may end in
SUFFIXES = (".mp4", ".gif", ".png")


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
    parser.add_argument("--seed", type=types.seed, default=0, help="seed of the first episode")
    parser.add_argument(
        "--episodes",
        type=types.positive_int,
        default=1,
        help="episodes to play, one after the other, all recorded",
    )
    parser.add_argument("--every", type=types.positive_int, default=1, help="keep every N-th frame")
    lo, hi = types.FPS_RANGE
    parser.add_argument(
        "--fps", type=types.fps, default=5.0, help=f"frames per second ({lo:g} to {hi:g})"
    )
    parser.add_argument(
        "--out",
        type=Path,
        default=Path("results/render/episode.mp4"),
        help="a .mp4 (needs the video extra; a .gif beside it otherwise), .gif or .png "
        "(the last frame)",
    )
    add_param_argument(parser)


def run(args: argparse.Namespace) -> int:
    import gymnasium as gym
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

    if args.out.suffix.lower() not in SUFFIXES:
        raise SystemExit(f"--out must end in {', '.join(SUFFIXES)}")
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
    env = _Frames(gym.make(args.env, render_mode="rgb_array", **params), args.every, args.episodes)
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
    returns: list[float] = []
    total, steps, state, start = 0.0, 0, None, np.array([True])
    while len(returns) < args.episodes:
        action, state = policy.predict(obs, state=state, episode_start=start, deterministic=True)
        obs, reward, dones, _ = venv.step(action)
        start = dones
        total, steps = total + float(reward[0]), steps + 1
        if dones[0]:
            returns.append(total)
            print(f"{args.env}, {name}, seed {args.seed}, episode {len(returns)}: "
                  f"return {total:.3f} over {steps} steps")  # fmt: skip
            total, steps = 0.0, 0
    venv.close()
    if args.episodes > 1:
        print(f"mean return {np.mean(returns):.3f} ± {np.std(returns):.3f} (std) over "
              f"{args.episodes} episodes")  # fmt: skip
    out = write_frames(env.frames, args.out, args.fps)
    print(f"wrote {out} ({len(env.frames)} frames)")
    return 0


def video_writer_missing() -> str | None:
    """Why an ``.mp4`` cannot be written here (``None``: it can): ``imageio`` and its ffmpeg
    plugin ``imageio-ffmpeg`` (the ``video`` extra) must both import."""
    import importlib.util

    missing = [m for m in ("imageio", "imageio_ffmpeg") if importlib.util.find_spec(m) is None]
    if missing:
        return f"{' and '.join(missing)} not installed: pip install 'sensorgym[video]'"
    return None


def write_frames(frames: list[np.ndarray], out: Path, fps: float) -> Path:
    """Write ``frames`` (``(H, W, 3)`` uint8) to ``out`` and return the path written: ``.png``
    the last frame; ``.gif`` all, looping; ``.mp4`` all as H.264 when
    :func:`video_writer_missing` says it can, else as a ``.gif`` beside ``out`` (with a note)."""
    from PIL import Image

    out.parent.mkdir(parents=True, exist_ok=True)
    suffix = out.suffix.lower()
    if suffix == ".png":
        Image.fromarray(frames[-1]).save(out)
        return out
    if suffix == ".mp4":
        why = video_writer_missing()
        if why is None:
            import imageio.v2 as imageio

            # H.264 in yuv420p wants even sides: pad odd ones with the frame's last row/column
            h, w = frames[0].shape[:2]
            pad = ((0, h % 2), (0, w % 2), (0, 0))
            with imageio.get_writer(out, fps=fps, codec="libx264", macro_block_size=1) as video:
                for frame in frames:
                    video.append_data(np.pad(frame, pad, mode="edge"))
            return out
        out = out.with_suffix(".gif")
        print(f"note: no MP4 ({why}): writing {out}")
    images = [Image.fromarray(f) for f in frames]
    duration = int(1000 / fps)
    images[0].save(out, save_all=True, append_images=images[1:], duration=duration, loop=0)
    return out


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
    """Keeps the frames of the first ``episodes`` episodes: each one's first state, every
    ``every``-th step's and its last one's (drawn before the reset that follows)."""

    def __init__(self, env: gym.Env, every: int, episodes: int = 1):
        super().__init__(env)
        self.every, self.episodes, self.frames = every, episodes, []
        self._steps, self._done, self._ended = 0, True, 0

    def reset(self, **kwargs: Any) -> Any:
        result = self.env.reset(**kwargs)
        if self._ended < self.episodes:
            self._steps, self._done = 0, False
            self.frames.append(self.env.render())
        return result

    def step(self, action: Any) -> Any:
        result = self.env.step(action)
        if not self._done:
            self._steps += 1
            self._done = bool(result[2] or result[3])
            self._ended += self._done
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
