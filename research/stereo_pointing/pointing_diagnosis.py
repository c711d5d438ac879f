"""Where the ``plan-horizon`` rule of ``sensorgym/StereoPointing-v0`` loses return (issue 13).

``python research/stereo_pointing/pointing_diagnosis.py [--seed 500] [--episodes 128]`` plays the same
seeded scenarios with ``plan-horizon``, ``plan-acquire`` (the fix this diagnosis led to),
``truth-plan`` and each of the ``m^n`` constant
assignments (receiver ``k`` held on drone ``c_k`` for the whole episode, slewed onto the
tracker's prediction by the env's slew controller), and writes
``research/stereo_pointing/results/pointing_diagnosis.json``:

* per policy the mean return, and per episode the best constant assignment in hindsight;
* for each run, how the drone-steps without a fix split: the drone had fewer than two receivers
  sent to it (*starved*), receivers sent to it were still slewing onto its prediction
  (*transit*), or the receivers sent to it pointed at its prediction and the drone was outside
  their field of view (*lost*: the tracker's estimate is off by more than the field of view);
  and how many drones were lost for good (no fix over the episode's last 50 steps);
* the planner's predicted return of the candidate it held against what the episode realised
  over the same steps, and at step 0 the plan's value of every constant assignment (on the
  estimate and on the truth) against the constant assignment's realised return.

Replaying a seed with another policy meets the same scenario and the same noise: the reset's
draws come first and do not depend on the policy, and every step draws a fixed
``(B, n, m, 3)`` block of measurement noise whatever the action (``simulation.step``: every
receiver-drone pair is measured, what is not seen is dropped). The script checks it: every
run must leave the generator in the same state and fly the same drones.
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from sensorgym.agents.stereo_pointing import (
    EPISODE_STEPS,
    TruthPlan,
    all_assignments,
    plan_values,
    rule_view,
)
from sensorgym.agents.stereo_pointing_horizon import PlanHorizon
from sensorgym.envs.stereo_pointing import simulation
from sensorgym.envs.stereo_pointing.simulation import PointingParams, boresights, lines_of_sight
from sensorgym.trackers.stereo.information import log_ratio_reward

RESULTS = Path(__file__).resolve().parent / "results" / "pointing_diagnosis.json"

#: ``(obs (B, obs_dim), step, state) -> drone per receiver (B, n)``
Chooser = Callable[[np.ndarray, int, Any], np.ndarray]


def play(params: PointingParams, choose: Chooser, seed: int, batch: int) -> dict[str, Any]:
    """One episode per scenario of ``batch`` seeded scenarios under ``choose``; the per-step
    record (rewards, per-drone rewards, who saw whom, the assignment, where the receivers
    pointed against the estimate) and the generator's end state."""
    rng = np.random.default_rng(seed)
    state = simulation.reset(params, rng, batch)
    obs = simulation.observe(params, state)
    T, n, m = EPISODE_STEPS, params.n_receivers, params.n_drones
    rec = {
        "reward": np.empty((batch, T)),
        "drone_reward": np.empty((batch, T, m)),
        "seen": np.empty((batch, T, n, m), dtype=bool),
        "target": np.empty((batch, T, n), dtype=np.int64),
        "on_estimate": np.empty((batch, T, n, m), dtype=bool),
    }
    positions = []
    cos_fov = np.cos(params.fov)
    for t in range(T):
        target = choose(obs, t, state)
        action = simulation.assignment_actions(params, obs, target)
        state, reward, _ = simulation.step(params, state, action, rng)
        obs = simulation.observe(params, state)
        rec["reward"][:, t] = reward
        rec["drone_reward"][:, t] = log_ratio_reward(
            state.bound, params.sigma_ref, params.reward_clip
        )
        rec["seen"][:, t] = state.seen
        rec["target"][:, t] = target
        # is receiver k's boresight within the field of view of drone j's current estimate?
        los, _ = lines_of_sight(params, state.track.x[..., :3])
        bore = boresights(state.azimuth, state.elevation)
        rec["on_estimate"][:, t] = np.einsum("bkjc,bkc->bkj", los, bore) >= cos_fov
        positions.append(state.drone_position.copy())
    rec["rng_state"] = rng.bit_generator.state
    rec["positions"] = np.stack(positions, 1)
    return rec


def loss_split(params: PointingParams, rec: dict[str, Any]) -> dict[str, float]:
    """How the drone-steps of a run without a fix split (fractions of all drone-steps), the
    reward per step lost to each cause against the run's own mean fixed reward, and drones
    lost for good."""
    m = params.n_drones
    seen, target, on_est = rec["seen"], rec["target"], rec["on_estimate"]
    sent = target[..., None] == np.arange(m)  # (B, T, n, m)
    fixed = seen.sum(axis=2) >= 2  # (B, T, m)
    n_sent = sent.sum(axis=2)
    # a receiver sent to j that does not see it: still slewing (not on the estimate) or the
    # estimate is off (on it, drone outside the field of view)
    missing = sent & ~seen
    starved = ~fixed & (n_sent < 2)
    lost = ~fixed & ~starved & (missing & on_est).any(axis=2)
    transit = ~fixed & ~starved & ~lost
    total = fixed.size
    late = ~fixed[:, -50:].any(axis=1)  # (B, m): no fix over the last 50 steps
    ever = fixed.any(axis=1)
    return {
        "fixed": float(fixed.sum() / total),
        "starved": float(starved.sum() / total),
        "transit": float(transit.sum() / total),
        "lost": float(lost.sum() / total),
        "drones_lost_for_good": float(late.sum() / late.size),
        "drones_never_fixed": float((~ever).sum() / ever.size),
        "episodes_with_a_drone_lost_for_good": float(late.any(axis=1).mean()),
        "mean_fixed_drone_reward": float(rec["drone_reward"][fixed].mean()),
    }


def constant(cand: np.ndarray) -> Chooser:
    return lambda obs, t, state: np.broadcast_to(cand, (obs.shape[0], cand.size)).copy()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, default=500)
    ap.add_argument("--episodes", type=int, default=128)
    ap.add_argument("--out", type=Path, default=RESULTS)
    args = ap.parse_args()
    params = PointingParams()
    B, T = args.episodes, EPISODE_STEPS
    cands = all_assignments(params)
    start = time.perf_counter()

    rule = PlanHorizon(params)
    planned: list[tuple[int, np.ndarray, np.ndarray]] = []  # (t, choice, predicted value)

    def horizon_rule(obs: np.ndarray, t: int, state: Any) -> np.ndarray:
        steps = np.full(obs.shape[0], t)
        choice = rule.assign(obs, steps)
        view = rule_view(params, obs.astype(np.float64))
        h = rule.planning_horizon(steps)
        v = plan_values(
            params, view.azimuth, view.elevation, view.position, view.velocity, h, rule.stride
        )
        index = np.ravel_multi_index(tuple(choice.T), (params.n_drones,) * params.n_receivers)
        planned.append((t, choice, v[np.arange(len(v)), index]))
        return choice

    runs = {"plan-horizon": play(params, horizon_rule, args.seed, B)}

    acquire = PlanHorizon(params, acquisition=True)
    runs["plan-acquire"] = play(
        params, lambda obs, t, state: acquire.assign(obs, np.full(obs.shape[0], t)), args.seed, B
    )

    holder: dict[str, Any] = {}

    def truth_rule(obs: np.ndarray, t: int, state: Any) -> np.ndarray:
        holder["state"] = state
        return truth_plan.assign(obs)

    truth_plan = TruthPlan(lambda: holder["state"], params)
    runs["truth-plan"] = play(params, truth_rule, args.seed, B)
    for c in cands:
        runs["constant " + "".join(map(str, c))] = play(params, constant(c), args.seed, B)

    # the same scenarios and noise for every policy
    ref = runs["plan-horizon"]
    for name, rec in runs.items():
        if rec["rng_state"] != ref["rng_state"] or not np.array_equal(
            rec["positions"], ref["positions"]
        ):
            raise RuntimeError(f"{name}: the replay met another scenario or noise")

    returns = {name: rec["reward"].sum(axis=1) for name, rec in runs.items()}
    const_names = [k for k in runs if k.startswith("constant")]
    const = np.stack([returns[k] for k in const_names], 1)  # (B, C)
    best = const.max(axis=1)
    ph = returns["plan-horizon"]
    diff = best - ph

    # step-0 plan values of every constant assignment: on the estimate and on the truth
    rng = np.random.default_rng(args.seed)
    s0 = simulation.reset(params, rng, B)
    v0 = rule_view(params, simulation.observe(params, s0).astype(np.float64))
    est0 = plan_values(
        params, v0.azimuth, v0.elevation, v0.position, v0.velocity, np.full(B, float(T)), 3
    )
    true0 = TruthPlan(lambda: s0, params).values(s0)

    def paired(a: np.ndarray) -> dict[str, float]:
        return {
            "mean": float(a.mean()),
            "ci95": float(1.96 * a.std(ddof=1) / np.sqrt(a.size)),
        }

    # predicted against realised over the planned steps, for the candidate plan-horizon held
    rew = ref["reward"]
    cum = np.concatenate([np.zeros((B, 1)), np.cumsum(rew, axis=1)], axis=1)
    pred_rows = []
    for t, _choice, pred in planned:
        h = int(min(rule.horizon, T - t))
        realised = cum[:, t + h] - cum[:, t]
        pred_rows.append((t, h, pred, realised))
    by_phase = []
    for lo, hi in ((0, 1), (1, 50), (50, 100), (100, 150)):
        sel = [(p, r, h) for t, h, p, r in pred_rows if lo <= t < hi]
        p = np.concatenate([s[0] / s[2] for s in sel])
        r = np.concatenate([s[1] / s[2] for s in sel])
        by_phase.append(
            {
                "steps": [lo, hi],
                "predicted_per_step": float(p.mean()),
                "realised_per_step": float(r.mean()),
                "over_prediction_per_step": float((p - r).mean()),
            }
        )
    switches = (np.diff(ref["target"], axis=1) != 0).any(axis=2).sum(axis=1)

    # which candidate wins in hindsight, and how plan-horizon's losses distribute
    worst = np.argsort(diff)[::-1][:10]
    out = {
        "settings": {
            "env": "sensorgym/StereoPointing-v0",
            "seed": args.seed,
            "episodes": B,
            "steps": T,
            "seconds": round(time.perf_counter() - start, 1),
            "same_scenarios_and_noise_checked": True,
        },
        "returns": {
            name: {"mean": float(r.mean()), "ci95": float(1.96 * r.std(ddof=1) / np.sqrt(B))}
            for name, r in returns.items()
        },
        "best_constant_in_hindsight": paired(best),
        "best_constant_minus_plan_horizon": paired(diff),
        "truth_plan_minus_plan_horizon": paired(returns["truth-plan"] - ph),
        "plan_acquire_minus_plan_horizon": paired(returns["plan-acquire"] - ph),
        "share_of_episodes_best_constant_above_plan_horizon": float((diff > 0).mean()),
        "best_constant_counts": {
            const_names[c]: int(k)
            for c, k in zip(*np.unique(const.argmax(axis=1), return_counts=True), strict=True)
        },
        "loss_split": {name: loss_split(params, rec) for name, rec in runs.items()},
        "plan_horizon_switch_steps_per_episode": float(switches.mean()),
        "plan_horizon_predicted_vs_realised": by_phase,
        "step0_plan_vs_realised_constant": {
            "estimate_plan_minus_realised": float((est0 - const).mean()),
            "truth_plan_minus_realised": float((true0 - const).mean()),
            "corr_estimate_plan_realised": float(
                np.mean([np.corrcoef(est0[b], const[b])[0, 1] for b in range(B)])
            ),
            "realised_of_estimate_argmax": float(const[np.arange(B), est0.argmax(axis=1)].mean()),
            "realised_of_truth_argmax": float(const[np.arange(B), true0.argmax(axis=1)].mean()),
        },
        "worst_episodes": [
            {
                "episode": int(b),
                "plan_horizon": float(ph[b]),
                "best_constant": float(best[b]),
                "best_constant_name": const_names[int(const[b].argmax())],
                "plan_horizon_switch_steps": int(switches[b]),
                "plan_horizon_drone_fixed_steps": ref["seen"][b]
                .sum(axis=1)
                .__ge__(2)
                .sum(0)
                .tolist(),
            }
            for b in worst
        ],
    }
    args.out.write_text(json.dumps(out, indent=1) + "\n")
    print(json.dumps({k: out[k] for k in list(out)[:8]}, indent=1))


if __name__ == "__main__":
    main()
