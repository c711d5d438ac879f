"""Probe: how much does the *order* of the search's hops matter, if the hops went first where
the target is? The room a learned search-order policy could take over ``feedforward-search``.

``feedforward-search`` visits its ring positions in a fixed order, back to the prediction
between every two. Here, at each ring hop, the next position is the unvisited one that scores
highest: *oracle* scores by nearness to the target's true offset (an upper bound for any
ordering), *fixed* by the pattern's own order (two rings: the rule itself). Beside them: aiming
at the true direction while the gate searches (what any search could get), and the oracle
order without the return to the prediction between hops.

Tuning seeds 20–23 (64 scenarios each, 500 frames, the core's own loop).

    python research/gimbal_learning/search_order.py
"""

import json
import sys
from pathlib import Path

import numpy as np
from paired import compare
from search_patterns import HALF_GATE, B, params, play, servo  # one loop, the same batch

from sensorgym.agents.gimbal_search import FeedForwardSearch, search_offsets
from sensorgym.agents.gimbal_tracking import TruthServo, rate_action

SEEDS = range(20, 24)
rule = FeedForwardSearch(params)


class Ordered:
    """Ring hops in score order (unvisited first), the centre between (unless not
    ``between``: then the centre is one more position), ``dwell`` frames each."""

    def __init__(self, ring, score, dwell=2, between=True):
        self.ring, self.score, self.dwell, self.between = ring, score, dwell, between

    def reset(self):
        self.visited = np.zeros((B, len(self.ring)), bool)
        self.current = np.zeros(B, np.int64)

    def __call__(self, obs, state):
        since = np.asarray(state.since_detection).reshape(B)
        searching = since >= params.search_after
        hop = np.maximum(since - params.search_after, 0) // self.dwell
        ring_hop = searching & ((hop % 2 == 1) | (not self.between))
        first = ring_hop & ((since - params.search_after) % self.dwell == 0)
        self.visited[~searching] = False
        if first.any():
            s = self.score(obs, state)  # (B, P)
            full = self.visited.all(1)
            self.visited[full] = False
            s = np.where(self.visited, -np.inf, s)
            choice = np.argmax(s, 1)
            self.current = np.where(first, choice, self.current)
            self.visited[np.flatnonzero(first), choice[first]] = True
        offset = np.where(ring_hop[:, None], self.ring[self.current], 0.0)
        return rate_action(params, servo.change(obs) + offset)


def truth_offset(obs, state):
    return TruthServo(params, lambda: state).change(obs) - servo.change(obs)


def oracle_score(ring):
    def score(obs, state):
        d = truth_offset(obs, state)
        return -np.linalg.norm(ring[None] - d[:, None], axis=-1)

    return score


def truth_while_searching(obs, state):
    searching = state.since_detection.reshape(B) >= params.search_after
    truth = TruthServo(params, lambda: state).change(obs)
    return rate_action(params, np.where(searching[:, None], truth, rule.change(obs)))


def fixed_score(ring):
    def score(obs, state):
        return np.broadcast_to(-np.arange(len(ring), dtype=float), (B, len(ring)))

    return score


if __name__ == "__main__":
    base = np.concatenate([play(lambda o, s: rule.act(o), seed) for seed in SEEDS])
    results = {"feedforward-search": {"mean": base.mean()}}
    candidates = {"truth aim while searching": truth_while_searching}
    for rings in [int(r) for r in (sys.argv[1:] or ["2", "3", "4", "5"])]:
        ring = search_offsets(HALF_GATE, rings)[1::2]
        candidates[f"fixed order, {rings} rings"] = Ordered(ring, fixed_score(ring))
        candidates[f"oracle order, {rings} rings"] = Ordered(ring, oracle_score(ring))
    ring = np.concatenate([np.zeros((1, 2)), search_offsets(HALF_GATE, 4)[1::2]])
    candidates["oracle order, 4 rings, no centre between"] = Ordered(
        ring, oracle_score(ring), between=False
    )
    results |= compare(candidates, base, play, SEEDS)
    out = Path(__file__).with_name("search_order.json")
    out.write_text(json.dumps({"seeds": list(SEEDS), "scenarios": B, "results": results}, indent=2))
    print("wrote", out)
