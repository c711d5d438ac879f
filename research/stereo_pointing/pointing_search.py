"""Find the drones the rules of ``sensorgym/StereoPointing-v0`` never fix: search along the line of
sight of the one receiver that sees them.

``python research/stereo_pointing/pointing_search.py [--seeds 500 600] [--episodes 512]`` plays the same
seeded scenarios with ``plan-fix-first`` and with ``plan-fix-first`` plus the epipolar search of
:mod:`sensorgym.agents.stereo_pointing_search` at several settings: the other receivers sent to
a lost drone (track RMS above ``lost_rms``) that exactly one receiver sees aim along that
receiver's boresight ray, swept in range from step to step. The diagnosis that led here: about
2 % of ``plan-fix-first``'s episodes have a drone that is never fixed (a return near −400), and
in 42 % of the drone-steps without a fix one receiver sees the drone. Writes
``research/stereo_pointing/results/pointing_search.json``: per setting the paired difference to
``plan-fix-first`` (per episode, the same scenarios and noise), the share of drone-steps without
a fix and the number of drones never fixed. It chose the ``plan-search`` rule's setting:
first ``lost_rms`` and ``width`` of the range sweep alone, then the seeing receiver's anchor
and a sweep across the ray, which find the drones that the range sweep still missed (one seen
at the edge of its receiver's cone, off the ray). Tuning seeds only.
"""

from __future__ import annotations

import time
from pathlib import Path

from pointing_cue_hold import paired_rows
from pointing_sharing import tuning_args, write_rows

from sensorgym.agents.stereo_pointing_horizon import PlanHorizon
from sensorgym.agents.stereo_pointing_search import EpipolarSearch
from sensorgym.agents.stereo_pointing_sharing import Sharing
from sensorgym.envs.stereo_pointing.simulation import PointingParams

RESULTS = Path(__file__).resolve().parent / "results" / "pointing_search.json"

#: the range sweep before the anchor and the sweep across the ray (the first ``plan-search``)
RANGE_SWEEP = {"sweep": (0, 1, -1, 2, -2, 3, -3), "across": (0.0,), "anchor": False}
#: the :class:`EpipolarSearch` settings measured; None is plan-fix-first (no search). The first
#: four chose ``lost_rms`` and ``width`` for the range sweep alone (seeds 500, 600); the rest
#: add the seeing receiver's anchor and the sweep across the ray (chosen on 500 and 600,
#: confirmed on 700 and 800): the last is the default, ``plan-search`` as registered
SETTINGS: tuple[dict | None, ...] = (
    None,
    {"lost_rms": 2.0, "width": 1.6, **RANGE_SWEEP},
    {"lost_rms": 4.0, "width": 1.6, **RANGE_SWEEP},
    {"lost_rms": 8.0, "width": 1.6, **RANGE_SWEEP},
    {"lost_rms": 4.0, "width": 1.0, **RANGE_SWEEP},
    {"sweep": RANGE_SWEEP["sweep"], "across": (0.0,), "anchor": True},
    {"sweep": RANGE_SWEEP["sweep"], "across": (0.0, 0.7, -0.7), "anchor": True},
    {"sweep": (0, 1, -1, 2, -2), "across": (0.0, 0.7, -0.7), "anchor": True},
    {},
)


def fields(setting: dict | None) -> dict:
    """A results row's description of a setting (every field of :class:`EpipolarSearch`)."""
    search = None if setting is None else EpipolarSearch(**setting)
    return {
        "lost_rms_m": None if search is None else search.lost_rms,
        "width_fov": None if search is None else search.width,
        "sweep": None if search is None else list(search.sweep),
        "across": None if search is None else list(search.across),
        "anchor": None if search is None else search.anchor,
    }


def main() -> None:
    args = tuning_args(__doc__, RESULTS, [500, 600, 700, 800], episodes=512)
    params = PointingParams()
    start = time.perf_counter()
    variants = [
        (
            fields(setting),
            PlanHorizon(
                params,
                acquisition=True,
                sharing=Sharing(),
                cue_steps=1,
                search=None if setting is None else EpipolarSearch(**setting),
            ),
        )
        for setting in SETTINGS
    ]
    rows = paired_rows(args, params, variants, "plan_fix_first")
    write_rows(args.out, {"rule": "plan-fix-first", "episodes": args.episodes}, rows, start)


if __name__ == "__main__":
    main()
