"""Probe: how much of the room above carrier-feedforward is in where the boresight looks while the
gate searches, and which search pattern takes it?

1. *Oracle*: carrier-feedforward, but aiming at the true direction once the target has gone
   undetected for ``k`` frames (``k = 1, 25``: the gate searches at the boresight from 25).
2. *Patterns*: hops about the prediction once the gate searches — rings of one or two
   half-gates, with or without the centre between positions, ``dwell`` frames at each.

Tuning seeds 20–29 (64 scenarios each, 500 frames, the core's own loop); writes
``search_patterns.json`` beside this file.

    python research/gimbal_learning/search_patterns.py
"""

import json
from pathlib import Path

import numpy as np
from paired import compare

from sensorgym.agents.gimbal_search import FeedForwardSearch, search_offsets
from sensorgym.agents.gimbal_tracking import CarrierFeedForward, TruthServo, rate_action
from sensorgym.envs.gimbal_tracking import simulation as core
from sensorgym.envs.gimbal_tracking.simulation import GimbalParams

SEEDS, B, FRAMES = range(20, 30), 64, 500
params = GimbalParams()
HALF_GATE = 0.5 * params.gate_pixels * params.pixel_pitch


def play(policy, seed):
    """Returns of ``B`` scenarios under ``policy(obs, state) -> actions``."""
    rng = np.random.default_rng(seed)
    state = core.reset(params, rng, B)
    alive, total = np.ones(B, bool), np.zeros(B)
    if hasattr(policy, "reset"):  # a policy with memory starts each batch afresh
        policy.reset()
    for _ in range(FRAMES):
        action = policy(core.observe(params, state).astype(np.float64), state)
        state, reward, terminated = core.step(params, state, action[:, None, :], rng)
        total += np.where(alive, reward, 0.0)
        alive &= ~terminated
    return total


servo = CarrierFeedForward(params)


def oracle(after):
    def policy(obs, state):
        truth = TruthServo(params, lambda: state).change(obs)
        use = state.since_detection >= after
        return rate_action(params, np.where(use[:, None], truth, servo.change(obs)))

    return policy


class Pattern(FeedForwardSearch):
    """FeedForwardSearch with another pattern."""

    def __init__(self, pattern, dwell):
        object.__setattr__(self, "params", params)
        object.__setattr__(self, "dwell", dwell)
        object.__setattr__(self, "rings", 0)
        object.__setattr__(self, "pattern", pattern)

    @property
    def offsets(self):
        return self.pattern


def plain(rings):
    ring = search_offsets(HALF_GATE, rings)[1::2]
    return np.concatenate([np.zeros((1, 2)), ring])


if __name__ == "__main__":
    base = np.concatenate([play(lambda o, s: servo.act(o), seed) for seed in SEEDS])
    results = {"carrier-feedforward": {"mean": base.mean()}}
    candidates = {f"oracle after {k}": oracle(k) for k in (1, 25)}
    for name, pattern in {
        "one ring": plain(1),
        "two rings": plain(2),
        "one ring, centre between": search_offsets(HALF_GATE, 1),
        "two rings, centre between": search_offsets(HALF_GATE, 2),
    }.items():
        for dwell in (1, 2, 3):
            rule = Pattern(pattern, dwell)
            candidates[f"{name}, dwell {dwell}"] = lambda o, s, rule=rule: rule.act(o)
    results |= compare(candidates, base, play, SEEDS)
    out = Path(__file__).with_name("search_patterns.json")
    out.write_text(json.dumps({"seeds": list(SEEDS), "scenarios": B, "results": results}, indent=2))
    print("wrote", out)
