"""A learnable re-acquisition search for ``sensorgym/GimbalTracking-v0``: the policy scores where
the lost target is, the wrapper hops the boresight there first.

:class:`~sensorgym.agents.gimbal_search.FeedForwardSearch` hops over fixed rings about paper
001's prediction in a fixed order. Where a lost target is depends on what it did before the
loss (a turn bends its path to one side); aiming at the true direction while the gate searches
is worth far more than the rule gets from its fixed order (``research/gimbal_learning/``). With
:class:`SearchOrderAction` the policy's action is a score per position of a wider pattern
(``rings`` hexagonal rings of one half-gate spacing), and each hop goes to the unvisited
position of highest score, back to the prediction between two hops, ``dwell`` frames each —
the rule's structure with a learned order. The zero action keeps the pattern's own order:
:class:`~sensorgym.agents.gimbal_search.FeedForwardSearch` with ``rings`` rings, exactly.

:class:`TruthHop` is the teacher for imitation: while the gate searches, each position scores
``exp(−d²/2) − 1`` with ``d`` its distance from the target's true direction in half-gates (a
gate-wide kernel: 0 on the target, −1 far off), so a student fitted by least squares learns
the expected kernel given its observations — a smoothed posterior of where the lost target is
— and the wrapper's hop order follows it. (A one-hot label on the nearest position orders the
hops worse: ``research/gimbal_learning/``.)
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray
from stable_baselines3.common.vec_env import VecEnv

from sensorgym.agents.gimbal_search import search_offsets
from sensorgym.agents.gimbal_tracking import (
    CarrierFeedForward,
    TruthServo,
    frames_since_detection,
    rate_action,
)
from sensorgym.envs.gimbal_tracking.simulation import GimbalParams
from sensorgym.train.wrappers import ObservedActionWrapper, find_wrapper

FloatArray = NDArray[np.float64]

#: the pattern's rings by default (60 positions out to four half-gates: the gate's positions
#: then tile the field of view's inner ±5 half-gates)
SEARCH_RINGS = 4


class SearchOrderAction(ObservedActionWrapper):
    """Action ``a ∈ [−1, 1]^P``, one score per position of :func:`search_offsets`'s ``rings``
    rings (``P = 3 rings (rings + 1)``). While the tracking gate tracks, the boresight follows
    :class:`~sensorgym.agents.gimbal_tracking.CarrierFeedForward` and the action is unused; once
    it searches (``search_after`` frames without a detection), every other hop of ``dwell``
    frames goes to the unvisited position of highest score (ties: the pattern's order), the
    others to the prediction. All positions visited: the pattern starts over; a detection ends
    the search and clears the visits."""

    def __init__(self, venv: VecEnv, rings: int = SEARCH_RINGS, dwell: int = 2):
        for name, value, least in (("rings", rings, 1), ("dwell", dwell, 1)):
            if isinstance(value, bool) or not isinstance(value, int) or value < least:
                raise ValueError(f"{name}: need an integer >= {least}, got {value!r}")
        params: GimbalParams = venv.get_attr("params")[0]
        if params.n_gimbals != 1:
            raise ValueError(
                f"n_gimbals: the search order drives one gimbal, got {params.n_gimbals}"
            )
        half_gate = 0.5 * params.gate_pixels * params.pixel_pitch
        self.positions: FloatArray = search_offsets(half_gate, rings)[1::2]
        """The pattern's positions ``(P, 2)``: body-frame offsets from the prediction, rad."""
        p = len(self.positions)
        super().__init__(venv, spaces.Box(-1.0, 1.0, (p,), np.float32))
        self.params = params
        self.half_gate = half_gate
        self.dwell = dwell
        self.servo = CarrierFeedForward(params)
        self.visited = np.zeros((self.num_envs, p), dtype=bool)
        """Positions visited in each slot's current search."""
        self.current = np.zeros(self.num_envs, dtype=np.int64)
        """Each slot's position of its current hop."""

    def searching(self, obs: FloatArray) -> NDArray[np.bool_]:
        """Whether each slot's gate searches ``(n,)``."""
        return frames_since_detection(self.params, obs) >= self.params.search_after

    def env_action(self, actions: NDArray[Any], obs: NDArray[Any]) -> NDArray[Any]:
        score = np.asarray(actions, dtype=np.float64).reshape(self.num_envs, -1)
        if score.shape[1] != len(self.positions):
            raise ValueError(
                f"actions: need {len(self.positions)} scores per env, got {score.shape}"
            )
        if not np.all(np.isfinite(score)):
            raise ValueError("actions: contain NaN or infinite values")
        view = np.asarray(obs, dtype=np.float64)
        into = (
            frames_since_detection(self.params, view) - self.params.search_after
        )  # frames into the search (< 0: none)
        searching = into >= 0
        hop = np.maximum(into, 0) // self.dwell
        outward = searching & (hop % 2 == 1)  # even hops: back at the prediction
        choose = outward & (np.maximum(into, 0) % self.dwell == 0)  # a hop's first frame
        self.visited[~searching] = False
        if choose.any():
            self.visited[self.visited.all(axis=1)] = False  # pattern done: start over
            ranked = np.where(self.visited, -np.inf, np.clip(score, -1.0, 1.0))
            best = np.argmax(ranked, axis=1)  # the first of equal scores: the pattern's order
            self.current = np.where(choose, best, self.current)
            self.visited[np.flatnonzero(choose), best[choose]] = True
        offset = np.where(outward[:, None], self.positions[self.current], 0.0)
        return rate_action(self.params, self.servo.change(view) + offset)


def search_order(venv: VecEnv, **kwargs: Any) -> VecEnv:
    """The ``gimbal-search-order`` wrapper factory (``sensorgym.train.wrappers.WRAPPERS``)."""
    return SearchOrderAction(venv, **kwargs)


class TruthHop:
    """The teacher of :class:`SearchOrderAction`: while the gate searches, each position's
    score ``exp(−d²/2) − 1``, ``d`` its distance (in half-gates) from the target's true offset
    from the servo's aim; −1 for all while the gate tracks."""

    def __init__(self, state_fn: Any, wrapper: SearchOrderAction):
        self.wrapper = wrapper
        self.truth = TruthServo(wrapper.params, state_fn)

    def predict(
        self,
        observation: NDArray[Any],
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[NDArray[np.float32], None]:
        """SB3's ``predict``: the teacher's scores ``(N, P)`` for the simulator's scenarios (the
        observation is the student's; the teacher reads the wrapper's latest)."""
        w = self.wrapper
        obs = np.asarray(w.last_obs, dtype=np.float64)
        offset = self.truth.change(obs) - w.servo.change(obs)  # the target's, from the aim
        d = np.linalg.norm(w.positions[None] - offset[:, None], axis=-1) / w.half_gate
        label = np.where(w.searching(obs)[:, None], np.expm1(-0.5 * d * d), -1.0)
        return label.astype(np.float32), None


def truth_hop(env: VecEnv) -> TruthHop:
    """The ``gimbal-truth-hop`` expert factory (``sensorgym.train.experts.EXPERTS``):
    :class:`TruthHop` for the :class:`SearchOrderAction` in ``env``'s wrapper stack."""
    from sensorgym.train.evaluation import simulator_state

    return TruthHop(simulator_state(env), find_wrapper(env, SearchOrderAction))
