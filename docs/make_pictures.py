"""Render the pictures of every registered env for its docs page: ``docs/assets/envs/<name>.png``
and ``docs/assets/envs/<name>.gif``.

Both show one seeded episode played by one of the env's rules, through ``sensorgym render``
(:mod:`sensorgym.cli.render`): the PNG its last frame (``render_mode="rgb_array"``), the GIF the
episode as an animation of about :data:`FRAMES` frames (every ``--every``-th step), scaled down
to half size with Pillow so that each GIF stays well under 1 MB. The docs build only reads the
committed files; run this after a change to an env's renderer or episodes::

    .venv/bin/python docs/make_pictures.py                      # every env, PNG and GIF
    .venv/bin/python docs/make_pictures.py StereoPointing-v0    # one env
    .venv/bin/python docs/make_pictures.py --only gif           # the GIFs only
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import gymnasium as gym

from sensorgym.cli.main import main
from sensorgym.envs import ENV_IDS

OUT = Path(__file__).resolve().parent / "assets" / "envs"
SEED = 0
#: about how many steps of the episode the GIF shows (its first state, then every N-th step)
FRAMES = 32
#: the GIF's frame size as a fraction of the env's frame
SCALE = 0.5
#: frames per second of the GIF
FPS = 6.0
#: the rule that plays each env's episode: a fieldable one whose frame shows the env's point
RULES = {
    "sensorgym/BearingsManeuver-v0": "greedy-information",
    "sensorgym/BearingsManeuverBook-v0": "book-leg-change",
    "sensorgym/StereoPointing-v0": "orthogonal-pairs",
    "sensorgym/StereoPointingCrowded-v0": "greedy-information",
    "sensorgym/StereoPlacement-v0": "greedy-information",
    "sensorgym/StereoScanning-v0": "greedy-information",
    "sensorgym/GimbalTracking-v0": "carrier-feedforward",
}


def _render(env_id: str, out: Path, *extra: str) -> None:
    argv = ["render", "--env", env_id, "--rule", RULES[env_id], "--seed", str(SEED), *extra]
    if main([*argv, "--out", str(out)]) != 0:
        raise SystemExit(f"sensorgym {' '.join(argv)} failed")


def picture(env_id: str) -> Path:
    """Render ``env_id``'s picture (the episode's last frame) and return its path."""
    out = OUT / f"{env_id.split('/', 1)[1]}.png"
    _render(env_id, out)
    return out


def every(env_id: str) -> int:
    """The GIF keeps every ``every``-th step: about :data:`FRAMES` over the time limit."""
    return max(1, round(gym.spec(env_id).max_episode_steps / FRAMES))


def animation(env_id: str) -> Path:
    """Render ``env_id``'s GIF (the episode, every :func:`every`-th step, at :data:`SCALE`)
    and return its path."""
    from PIL import Image, ImageSequence

    out = OUT / f"{env_id.split('/', 1)[1]}.gif"
    with tempfile.TemporaryDirectory() as tmp:
        full = Path(tmp) / "episode.gif"
        _render(env_id, full, "--every", str(every(env_id)), "--fps", str(FPS))
        with Image.open(full) as gif:
            frames = []
            for frame in ImageSequence.Iterator(gif):
                rgb = frame.convert("RGB")
                size = (round(rgb.width * SCALE), round(rgb.height * SCALE))
                small = rgb.resize(size, Image.Resampling.LANCZOS)
                frames.append(small.quantize(colors=128, method=Image.Quantize.MEDIANCUT))
    frames[0].save(
        out,
        save_all=True,
        append_images=frames[1:],
        duration=round(1000 / FPS),
        loop=0,
        optimize=True,
    )
    return out


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n", 1)[0])
    parser.add_argument("names", nargs="*", help="env names (StereoPointing-v0); default all")
    parser.add_argument("--only", choices=("png", "gif"), help="render only the PNGs or GIFs")
    args = parser.parse_args()
    missing = set(ENV_IDS) - set(RULES)
    if missing:
        raise SystemExit(f"no rule chosen for {sorted(missing)}: add it to RULES")
    for env_id in ENV_IDS:
        if args.names and env_id.split("/", 1)[1] not in args.names:
            continue
        if args.only != "gif":
            print(picture(env_id))
        if args.only != "png":
            path = animation(env_id)
            print(f"{path} ({path.stat().st_size / 1e3:.0f} kB)")
