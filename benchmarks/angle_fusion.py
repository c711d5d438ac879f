"""Throughput of the paper 001 angle predictors and the paper 004 fused tracker, batched.

Run: ``.venv/bin/python benchmarks/angle_fusion.py [--repeat 5]``. Prints a table of
track-steps per second (one track advanced by one frame) for batches of 1, 64 and 1024 tracks,
and writes ``benchmarks/results/angle_fusion.json``.

What the environments need: a gimbal-pointing env steps every environment of a vector env
once per frame, so each step runs one predictor update (and a prediction for the command)
over the whole batch; a multi-channel env runs one fused-tracker update per frame.
"""

from __future__ import annotations

import argparse

import numpy as np
from timing import RESULTS, best_rate, write_results

from sensorgym.envs.worlds.gimbal import StraightTrajectory
from sensorgym.envs.worlds.imaging import ImagingScene
from sensorgym.reproduce.experiments.paper004_closed_loop import matched_model
from sensorgym.trackers.angles.baselines import AngleKalmanPredictor, LineFitPredictor
from sensorgym.trackers.angles.prediction import ABCPredictor
from sensorgym.trackers.fusion.tracker import FusionTracker

BATCHES = (1, 64, 1024)


def time_angle_predictor(predictor, batch: int, frames: int, repeat: int) -> float:
    """Best-of-``repeat`` track-steps per second of ``update`` + ``predict(state, 1)``."""
    th, ph = StraightTrajectory().angles(np.arange(frames))
    az = np.broadcast_to(th[:, None], (frames, batch)).copy()
    el = np.broadcast_to(ph[:, None], (frames, batch)).copy()

    def run(state):
        for t in range(frames):
            state = predictor.update(state, az[t], el[t])
            predictor.predict(state, 1.0)

    return best_rate(run, batch * frames, repeat, lambda: predictor.initial_state(batch))


def time_fusion(batch: int, frames: int, repeat: int) -> float:
    """Best-of-``repeat`` track-steps per second of one fused update (4 channels, 48 px)."""
    scene = ImagingScene()
    tracker = FusionTracker(matched_model(scene))
    rng = np.random.default_rng(0)
    angle, views = scene.initial_world(rng, batch)
    images = scene.render(rng, angle, np.zeros(batch), views)

    def run(state):
        for _ in range(frames):
            state = tracker.update(state, images)

    return best_rate(run, batch * frames, repeat, lambda: tracker.initial_state(batch))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5, help="best of this many runs (5)")
    parser.add_argument("--frames", type=int, default=200, help="frames per run (200)")
    args = parser.parse_args()
    cases = {
        "ABCPredictor update+predict": lambda b: time_angle_predictor(
            ABCPredictor(), b, args.frames, args.repeat
        ),
        "LineFitPredictor update+predict": lambda b: time_angle_predictor(
            LineFitPredictor(), b, args.frames, args.repeat
        ),
        "AngleKalmanPredictor update+predict": lambda b: time_angle_predictor(
            AngleKalmanPredictor(), b, args.frames, args.repeat
        ),
        "FusionTracker update (4 ch)": lambda b: time_fusion(b, args.frames, args.repeat),
    }
    rows = {name: {str(b): fn(b) for b in BATCHES} for name, fn in cases.items()}
    print(f"track-steps per second (best of {args.repeat}, {args.frames} frames)")
    print(f"  {'case':<38}" + "".join(f"{'B=' + str(b):>14}" for b in BATCHES))
    for name, r in rows.items():
        print(f"  {name:<38}" + "".join(f"{r[str(b)]:>14,.0f}" for b in BATCHES))
    write_results(
        RESULTS / "angle_fusion.json",
        rows,
        unit="track-steps per second",
        frames=args.frames,
        repeat=args.repeat,
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
