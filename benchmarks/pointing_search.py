"""Find the drones the rules of ``sensorgym/StereoPointing-v0`` never fix: search along the line of
sight of the one receiver that sees them.

``python benchmarks/pointing_search.py [--seeds 500 600] [--episodes 512]`` plays the same
seeded scenarios with ``plan-fix-first`` and with ``plan-fix-first`` plus the epipolar search of
:mod:`sensorgym.agents.stereo_pointing_search` at several settings: the other receivers sent to
a lost drone (track RMS above ``lost_rms``) that exactly one receiver sees aim along that
receiver's boresight ray, swept in range from step to step. The diagnosis that led here: about
2 % of ``plan-fix-first``'s episodes have a drone that is never fixed (a return near −400), and
in 42 % of the drone-steps without a fix one receiver sees the drone. Writes
``benchmarks/results/pointing_search.json``: per setting the paired difference to
``plan-fix-first`` (per episode, the same scenarios and noise), the share of drone-steps without
a fix and the number of drones never fixed. It chose the ``plan-search`` rule's setting.
Tuning seeds only.
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

#: (lost_rms in m, width in fields of view) measured; None is plan-fix-first (no search)
SETTINGS = (None, (2.0, 1.6), (4.0, 1.6), (8.0, 1.6), (4.0, 1.0))


def main() -> None:
    args = tuning_args(__doc__, RESULTS, [500, 600], episodes=512)
    params = PointingParams()
    start = time.perf_counter()
    variants = [
        (
            {
                "lost_rms_m": None if setting is None else setting[0],
                "width_fov": None if setting is None else setting[1],
            },
            PlanHorizon(
                params,
                acquisition=True,
                sharing=Sharing(),
                cue_steps=1,
                search=None if setting is None else EpipolarSearch(*setting),
            ),
        )
        for setting in SETTINGS
    ]
    rows = paired_rows(args, params, variants, "plan_fix_first")
    write_rows(args.out, {"rule": "plan-fix-first", "episodes": args.episodes}, rows, start)


if __name__ == "__main__":
    main()
