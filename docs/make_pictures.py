"""Render the picture of every registered env for its docs page: ``docs/assets/envs/<name>.png``.

The last frame (``render_mode="rgb_array"``) of one seeded episode played by one of the env's
rules, through ``sensorgym render`` (:mod:`sensorgym.cli.render`). The docs build only reads
the committed PNGs; run this after a change to an env's renderer or episodes::

    .venv/bin/python docs/make_pictures.py            # every env
    .venv/bin/python docs/make_pictures.py StereoPointing-v0
"""

from __future__ import annotations

import sys
from pathlib import Path

from sensorgym.cli.main import main
from sensorgym.envs import ENV_IDS

OUT = Path(__file__).resolve().parent / "assets" / "envs"
SEED = 0
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


def picture(env_id: str) -> Path:
    """Render ``env_id``'s picture and return its path."""
    out = OUT / f"{env_id.split('/', 1)[1]}.png"
    argv = ["render", "--env", env_id, "--rule", RULES[env_id], "--seed", str(SEED)]
    if main([*argv, "--out", str(out)]) != 0:
        raise SystemExit(f"sensorgym {' '.join(argv)} failed")
    return out


if __name__ == "__main__":
    wanted = sys.argv[1:]
    missing = set(ENV_IDS) - set(RULES)
    if missing:
        raise SystemExit(f"no rule chosen for {sorted(missing)}: add it to RULES")
    for env_id in ENV_IDS:
        if not wanted or env_id.split("/", 1)[1] in wanted:
            print(picture(env_id))
