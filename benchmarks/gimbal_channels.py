"""Paper 004's claim 4 through GimbalTracking-v0: more channels make up for weaker ones.

Run: ``.venv/bin/python benchmarks/gimbal_channels.py [--scenarios 48]``. Scores the
fieldable ``carrier-feedforward`` servo (a closed loop, as in the paper) over whole episodes of
the env with ``N = 1 … 4`` identical imaging channels at four contrasts, everything else at the
env's defaults (occlusions, turns, the carrier's motion). Each channel's detection parameter
``q`` (theory §9.4, the matched-filter SNR of its object view) and its detection probability
``P`` at a false-alarm probability of 0.01 (theory §9.4 eq. (9)) label the rows. Per cell: the
share of frames the tracker detects the target, the median and the 90th percentile of the
angle between the tracker's estimate and the target (frames played, mrad; a lost track's
coasting predictor can be radians off, so an RMS would only count those), the median ``σ_LOS`` (mrad), the share of episodes in
which the target is lost for good (terminated) and the mean return. Prints the table and writes
``benchmarks/results/gimbal_channels.json`` (the docs' table is generated from it).

Every cell plays the same scenarios (seed 700): the target's path, the carrier's motion and the
occlusions are drawn before the channels' views, so changing the channels leaves them alone.
"""

from __future__ import annotations

import argparse

import gymnasium as gym
import numpy as np
from timing import RESULTS, write_results

import sensorgym.envs  # noqa: F401  (registers the ids)
from sensorgym.agents.registry import rules_for
from sensorgym.trackers.fusion.detection_probability import detection_probability

ENV_ID = "sensorgym/GimbalTracking-v0"
SEED = 700
RULE = "carrier-feedforward"
FALSE_ALARM = 0.01
CHANNELS = (1, 2, 3, 4)
CONTRASTS = (0.6, 1.0, 1.3, 1.8)
#: each channel: its view lost 5 % of the frames, back at 20 %, bright/dark changes at 2 %
LOSE, RETURN, CHANGE = 0.05, 0.2, 0.02


def channel_fields(n: int, contrast: float) -> dict[str, tuple[float, ...]]:
    """The params fields of ``n`` identical channels of ``contrast`` (noise 1)."""
    return {
        "channel_contrast": (contrast,) * n,
        "channel_noise": (1.0,) * n,
        "lose_probability": (LOSE,) * n,
        "return_probability": (RETURN,) * n,
        "aspect_change_probability": (CHANGE,) * n,
    }


def run_cell(n: int, contrast: float, scenarios: int) -> dict[str, float]:
    """One episode of each of ``scenarios`` scenarios under the rule; the cell's row."""
    env = gym.make_vec(
        ENV_ID,
        num_envs=scenarios,
        vectorization_mode="vector_entry_point",
        **channel_fields(n, contrast),
    )
    obs, info = env.reset(seed=SEED)
    params = env.params
    q = float(params.fusion_tracker.model.detection_parameter[0, 1])
    rule = rules_for(ENV_ID, params, lambda: env.simulator_state)[RULE]
    memory = None
    live = np.ones(scenarios, dtype=bool)
    lost = np.zeros(scenarios, dtype=bool)
    returns = np.zeros(scenarios)
    detected, errors, sigmas = [], [], []
    steps = int(gym.spec(ENV_ID).max_episode_steps)
    for k in range(steps):
        action, memory = rule.predict(obs, memory, episode_start=np.full(scenarios, k == 0))
        obs, reward, terminated, truncated, info = env.step(action)
        returns[live] += reward[live]
        detected.append(info["detected"][live])
        errors.append(info["los_error"][live])
        sigmas.append(info["sigma_los"][live])
        lost |= terminated & live
        live &= ~(terminated | truncated)
        if not live.any():
            break
    env.close()
    error = np.concatenate(errors)
    return {
        "channels": n,
        "contrast": contrast,
        "q": q,
        "detection_probability": float(detection_probability(q, FALSE_ALARM)),
        "detected_share": float(np.concatenate(detected).mean()),
        "median_error_mrad": float(np.median(error) * 1e3),
        "p90_error_mrad": float(np.quantile(error, 0.9) * 1e3),
        "median_sigma_los_mrad": float(np.median(np.concatenate(sigmas)) * 1e3),
        "lost_share": float(lost.mean()),
        "mean_return": float(returns.mean()),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenarios", type=int, default=48, help="episodes per cell (48)")
    args = parser.parse_args()
    print(f"{RULE}, {args.scenarios} episodes a cell, seed {SEED}")
    print(f"  {'N':>2} {'c':>5} {'q':>5} {'P':>6} {'detected':>9} {'median':>7} {'p90':>7} "
          f"{'σ_LOS mrad':>11} {'lost':>6} {'return':>8}")  # fmt: skip
    rows = []
    for contrast in CONTRASTS:
        for n in CHANNELS:
            r = run_cell(n, contrast, args.scenarios)
            rows.append(r)
            print(
                f"  {n:>2} {contrast:>5.1f} {r['q']:>5.2f} {r['detection_probability']:>6.3f} "
                f"{r['detected_share']:>9.3f} {r['median_error_mrad']:>7.3f} {r['p90_error_mrad']:>7.3f} "
                f"{r['median_sigma_los_mrad']:>11.4f} {r['lost_share']:>6.2f} "
                f"{r['mean_return']:>8.1f}",
                flush=True,
            )
    write_results(
        RESULTS / "gimbal_channels.json",
        rows,
        env=ENV_ID,
        rule=RULE,
        seed=SEED,
        scenarios=args.scenarios,
        false_alarm=FALSE_ALARM,
        lose_probability=LOSE,
        return_probability=RETURN,
        aspect_change_probability=CHANGE,
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
