"""How much can any choice of pairing still gain over ``plan-search`` on
``sensorgym/StereoPointing-v0``? A rollout bound on tuning seeds (issue 13).

``python research/stereo_pointing/pointing_rollout.py [--seeds 500 600] [--episodes 128]`` writes
``research/stereo_pointing/results/pointing_rollout.json`` with two measurements.

**One-step deviations in hindsight.** At each decision step ``t`` of :data:`DECISION_STEPS`,
the episodes are branched: every one of the ``mⁿ`` assignments (which drone each receiver is
sent to; 16 with the defaults) is played on step ``t``, aimed as the rule aims
(:func:`~sensorgym.agents.stereo_pointing_horizon.plan_aims`: cue hold, sharing, search), and
``plan-search`` plays the rest of the episode. A seed replays the same scenario and the same
measurement noise under any policy (every step draws a fixed block of noise whatever the
action), so each branch's return to go is paired episode by episode with the rule's own. The
mean over episodes of the best branch minus the rule's is the most that changing the pairing on
step ``t`` could gain *with knowledge of the future noise and of the true drones*; a policy that
sees only the tracker (a trained pairing policy, a learned correction of the planner's values,
a one-step rollout of the rule) gains at most this in expectation. It bounds every
assignment-level learner from above: this is the improvement step of policy iteration, with a
perfect value function.

**The instantaneous bound.** On every step of the rule's own episodes, the best mean drone
reward any pointing could give at that instant on the true drones
(:func:`sensorgym.envs.stereo_pointing.bound.step_bound`, a proven upper bound; theory §11.3):
each receiver sees any set of drones that lie within ``2 · fov`` of each other from it, with
no slew limit and no tracking error (and, as a second number, with every receiver on at most
one drone: what a receiver seeing two drones at once adds). Its sum against the rule's return
splits what the rule loses into the first :data:`EARLY_STEPS` steps (the cue's hand-over and
the first re-pairing) and the rest (slewing, two receivers per drone, lost drones).

Each row also gives the shares of episodes that gain more than 1 and more than 5, the largest
single episode's gain and the mean without it: a lost drone that another pairing would have
found is worth about +400 in one episode and can carry the mean alone.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np
from pointing_sharing import paired_fields, tuning_args, write_rows

from sensorgym.agents.stereo_pointing import all_assignments, rule_view
from sensorgym.agents.stereo_pointing_horizon import PlanHorizon, plan_aims
from sensorgym.agents.stereo_pointing_search import EpipolarSearch
from sensorgym.agents.stereo_pointing_sharing import Sharing
from sensorgym.envs.stereo_pointing import simulation
from sensorgym.envs.stereo_pointing.bound import bound_path
from sensorgym.envs.stereo_pointing.simulation import PointingParams, PointingState, slew_actions

RESULTS = Path(__file__).resolve().parent / "results" / "pointing_rollout.json"
EPISODE_STEPS = 150
#: the steps at which the episodes are branched
DECISION_STEPS = (1, 2, 3, 5, 10, 20, 30, 50, 75, 100)
#: the steps counted as the hand-over phase in the instantaneous bound
EARLY_STEPS = 10


def plan_search(params: PointingParams) -> PlanHorizon:
    """The ``plan-search`` rule (as registered)."""
    return PlanHorizon(
        params, acquisition=True, sharing=Sharing(), cue_steps=1, search=EpipolarSearch()
    )


def act(rule: PlanHorizon, obs: np.ndarray, t: int, target: np.ndarray | None = None) -> np.ndarray:
    """The rule's gimbal rates at episode step ``t``; with ``target (B, n)`` the drone each
    receiver is sent to is that one instead of the plan's (aimed as the rule aims)."""
    p = rule.params
    view = rule_view(p, obs.astype(np.float64))
    steps = np.full(obs.shape[0], t)
    target = rule.choose(view, steps) if target is None else target
    points, index = plan_aims(p, view, target, steps, rule.cue_steps, rule.sharing, rule.search)
    return slew_actions(p, view.azimuth, view.elevation, points, index)


def clone(rng: np.random.Generator) -> np.random.Generator:
    out = np.random.default_rng()
    out.bit_generator.state = rng.bit_generator.state
    return out


def to_go(
    rule: PlanHorizon,
    state: PointingState,
    rng: np.random.Generator,
    t0: int,
    target: np.ndarray | None,
) -> np.ndarray:
    """Return ``(B,)`` from step ``t0`` to the episode's end: ``target`` on step ``t0`` (None:
    the rule's), the rule after."""
    p, total = rule.params, np.zeros(state.t.shape[0])
    obs = simulation.observe(p, state)
    for t in range(t0, EPISODE_STEPS):
        action = act(rule, obs, t, target if t == t0 else None)
        state, reward, _ = simulation.step(p, state, action, rng)
        obs = simulation.observe(p, state)
        total += reward
    return total


def deviations(rule: PlanHorizon, seed: int, batch: int) -> list[dict[str, Any]]:
    """One row per decision step: the rule's return to go and the best one-step deviation's, in
    hindsight, paired."""
    p = rule.params
    rng = np.random.default_rng(seed)
    state = simulation.reset(p, rng, batch)
    cands, rows, played = all_assignments(p), [], 0
    for t_dec in DECISION_STEPS:
        for t in range(played, t_dec):
            obs = simulation.observe(p, state)
            state, _, _ = simulation.step(p, state, act(rule, obs, t), rng)
        played = t_dec
        base = to_go(rule, state, clone(rng), t_dec, None)
        q = np.stack([
            to_go(rule, state, clone(rng), t_dec, np.broadcast_to(c, (batch, c.size)).copy())
            for c in cands
        ], axis=1)  # fmt: skip
        best = q.max(axis=1)
        rows.append({
            "seed": seed, "step": t_dec, "rule_to_go": float(base.mean()),
            "best_deviation_to_go": float(best.mean()),
            **paired_fields(best, base, "rule"),
            "episodes_gain_above_1": float((best - base > 1.0).mean()),
            "episodes_gain_above_5": float((best - base > 5.0).mean()),
            "largest_episode_gain": float((best - base).max()),
            "mean_gain_without_the_largest": float(np.sort(best - base)[:-1].mean()),
        })  # fmt: skip
        r = rows[-1]
        print(f"seed {seed} step {t_dec}: rule to go {r['rule_to_go']:.2f}, best deviation in "
              f"hindsight {r['paired_minus_rule']:+.2f} ± {r['paired_ci95']:.2f}", flush=True)  # fmt: skip
    return rows


def bound_rows(rule: PlanHorizon, seed: int, batch: int) -> dict[str, Any]:
    """The rule's return against the instantaneous bound, on the first :data:`EARLY_STEPS`
    steps and after."""
    p = rule.params
    rng = np.random.default_rng(seed)
    state = simulation.reset(p, rng, batch)
    obs = simulation.observe(p, state)
    # the drones' path is the policy's no matter: the bound of every step is known at the start
    bound = bound_path(p, state, EPISODE_STEPS)
    single = bound_path(p, state, EPISODE_STEPS, max_drones_per_receiver=1).sum(axis=1)
    real = np.zeros((batch, EPISODE_STEPS))
    never = np.ones((batch, p.n_drones), dtype=bool)
    for t in range(EPISODE_STEPS):
        state, real[:, t], _ = simulation.step(p, state, act(rule, obs, t), rng)
        obs = simulation.observe(p, state)
        never &= ~state.fixed
    e = EARLY_STEPS
    return {
        "seed": seed,
        "rule_return": float(real.sum(axis=1).mean()),
        "instant_bound": float(bound.sum(axis=1).mean()),
        "instant_bound_one_drone_per_receiver": float(single.mean()),
        f"rule_first_{e}_steps": float(real[:, :e].sum(axis=1).mean()),
        f"bound_first_{e}_steps": float(bound[:, :e].sum(axis=1).mean()),
        "rule_after": float(real[:, e:].sum(axis=1).mean()),
        "bound_after": float(bound[:, e:].sum(axis=1).mean()),
        "never_fixed_drones": int(never.sum()),
    }


def main() -> None:
    args = tuning_args(__doc__, RESULTS, [500, 600], episodes=128)
    start = time.perf_counter()
    rule = plan_search(PointingParams())
    rows, bounds = [], []
    for seed in args.seeds:
        bounds.append(bound_rows(rule, seed, args.episodes))
        print(bounds[-1], flush=True)
        rows += deviations(rule, seed, args.episodes)
    settings = {
        "seeds": args.seeds,
        "episodes": args.episodes,
        "rule": "plan-search",
        "decision_steps": list(DECISION_STEPS),
        "assignments_per_step": len(all_assignments(rule.params)),
        "instant_bound": bounds,
    }
    write_rows(args.out, settings, rows, start)


if __name__ == "__main__":
    main()
