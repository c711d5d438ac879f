"""Open-loop manoeuvres of the textbook observer-control scenario (``BearingsManeuverBook-v0``).

:class:`OpenLoop` flies a fixed sequence of turn commands, one per step, whatever the bearings
say; :func:`book_leg_change` is the book's own manoeuvre (Ristic, Arulampalam & Gordon, ch. 6):
course 140° → 20° at 30°/min during minutes 13–16. On the book's fixed scenario it is the
baseline a reader asks a trained policy to beat. The numerically optimised sequence is made by
``sensorgym reproduce bot-control`` on the book's *nominal* target path (prior knowledge only,
no simulator truth), with a 500 m margin beyond the stand-off; its result for the default seed is
:data:`BOOK_OPTIMISED_TURNS`, flown by :func:`optimised_open_loop` (the ``book-optimised-plan``
rule — a fieldable rule like the leg change, scored as one — and the teacher of the trained
policies). :data:`BOOK_TUNED_TURNS` is the same optimiser's plan with the margin tuned on tuning
scenarios instead (``benchmarks/book_plan_margin.py``), flown by :func:`tuned_open_loop` (the
``book-plan-tuned`` rule).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sensorgym.trackers.validation import count

#: the book's leg change: minutes (steps) during which the observer turns at the full rate
LEG_CHANGE_STEPS = (12, 13, 14, 15)
#: its direction: −1 = full turn to port (140° → 20° at 30°/min)
LEG_CHANGE_TURN = -1.0
#: the open-loop turn commands (× 30°/min, + = to starboard) that minimise the book's PCRLB at
#: 32 min on the true, noise-free target path with 1.5 km kept at every bearing (stand-off +
#: margin): ``bot_control.optimise_open_loop(restarts=8, seed=10000)`` (its bound beside the
#: book's leg change: ``docs/reproduction/bot-control.md``). Planned on the book's nominal
#: target (prior knowledge, not the simulator's truth): a fieldable rule, not a bound.
BOOK_OPTIMISED_TURNS = (
    -0.9999999999997984,
    -0.690024302996851,
    0.129738179110129,
    0.6143642685724465,
    -0.48061840884745355,
    0.085476248217086,
    0.27907964915185485,
    0.23485970400520645,
    0.1865540525904501,
    0.15132817384352884,
    -0.020650528748882787,
    0.5986631449078397,
    0.24901576380171603,
    -0.025139556336533066,
    0.11596174178801182,
    0.1599853439855786,
    0.0013713521996187702,
    0.3214068000893553,
    0.9999999999999302,
    0.9999999999999997,
    0.9999999999999989,
    0.9999999999999987,
    0.9999999999999717,
    0.716717279804537,
    -0.21632400598708634,
    0.47104927051775014,
    0.6410430904632418,
    0.5636451899267759,
    0.6885392868813583,
    0.5808616908172873,
    0.6639268249787944,
    0.5152611221429044,
)
#: :data:`BOOK_OPTIMISED_TURNS`' optimiser with its stand-off margin tuned on tuning scenarios
#: (``book-plan-tuned``): ``python benchmarks/book_plan_margin.py`` (then ``--margin 450``)
#: re-optimised the plan on the book's nominal target path
#: (``bot_control.optimise_open_loop(restarts=8, seed=0, margin=m)``) for margins 0, 100, 200,
#: 300, 400, 450 and 500 m and flew each on 256 episodes of seeds 500 and 600; 500 m is the
#: smallest that broke no stand-off there, and so the best mean final PCRLB without a break
#: (``benchmarks/results/book_plan_margin.json``). Prior
#: knowledge only (no simulator truth): a fieldable rule, not a bound.
BOOK_TUNED_TURNS = (
    -0.9999999999999576,
    -0.3407396708111343,
    -0.04110559478007182,
    0.06695965611127527,
    0.10388963776923753,
    0.03534244081433072,
    0.16105774579471507,
    0.075464306776162,
    0.278808965665531,
    0.19011253465169392,
    0.21486964076162945,
    0.24681772675468638,
    0.21505396121271686,
    0.08011878189792696,
    0.13832748321144525,
    -0.006833856425209286,
    -0.03427013738852656,
    0.6341223776780995,
    0.9999999999999931,
    0.9999999999999901,
    0.9999999999999649,
    0.9999999999999476,
    0.9999999999999873,
    0.4288512373556715,
    -0.07456775168884985,
    0.5147315563308246,
    0.5967616927430505,
    0.601905910360452,
    0.6510601770192332,
    0.6185853555191426,
    0.6269686879809764,
    0.556032642862904,
)


@dataclass(frozen=True)
class OpenLoop:
    """A fixed sequence of turn commands ``a₀`` in ``[−1, 1]`` (× the world's turn limit), one
    per step, speed change 0; after the sequence, straight on. An SB3-style predictor whose
    ``state`` is the step count per env (reset by ``episode_start``), as SB3 does for recurrent
    policies. With ``platforms = K`` every platform flies the same sequence (action ``(2K,)``)."""

    turns: tuple[float, ...]
    """Turn command per step."""
    platforms: int = 1
    """Number of platforms ``K`` the action is for."""

    def __post_init__(self) -> None:
        u = np.asarray(self.turns, dtype=np.float64)
        if u.ndim != 1 or u.size == 0 or not np.all(np.isfinite(u)):
            raise ValueError(
                f"turns: need a non-empty sequence of finite numbers, got {self.turns}"
            )
        if np.any(np.abs(u) > 1.0):
            raise ValueError("turns: every command must lie in [-1, 1]")
        count(self.platforms, "platforms")

    def predict(
        self,
        observation: NDArray[Any],
        state: NDArray[np.int64] | None = None,
        episode_start: NDArray[np.bool_] | None = None,
        deterministic: bool = True,
    ) -> tuple[NDArray[np.float32], NDArray[np.int64]]:
        obs = np.asarray(observation)
        single = obs.ndim == 1
        n = 1 if single else obs.shape[0]
        k = np.zeros(n, dtype=np.int64) if state is None else np.asarray(state, dtype=np.int64)
        if episode_start is not None:
            k = np.where(np.asarray(episode_start, dtype=bool), 0, k)
        turns = np.append(np.asarray(self.turns, dtype=np.float64), 0.0)
        action = np.zeros((n, self.platforms, 2), dtype=np.float32)
        action[:, :, 0] = turns[np.minimum(k, turns.size - 1)][:, None]
        action = action.reshape(n, -1)
        return (action[0] if single else action), k + 1


def book_leg_change(steps: int = 32, platforms: int = 1) -> OpenLoop:
    """The book's manoeuvre over ``steps`` steps: straight on course 140°, a full turn to port
    (−30°/min) during minutes 13–16 (steps 12–15) to course 20°, straight again (by each of
    ``platforms`` platforms)."""
    turns = np.zeros(steps)
    turns[[k for k in LEG_CHANGE_STEPS if k < steps]] = LEG_CHANGE_TURN
    return OpenLoop(tuple(turns), platforms)


def optimised_open_loop(platforms: int = 1) -> OpenLoop:
    """The optimised open-loop manoeuvre :data:`BOOK_OPTIMISED_TURNS` (a fieldable rule: planned
    on the book's nominal target path with a 500 m stand-off margin, before any bearing; flown by
    each of ``platforms`` platforms)."""
    return OpenLoop(BOOK_OPTIMISED_TURNS, platforms)


def tuned_open_loop(platforms: int = 1) -> OpenLoop:
    """The book plan with its stand-off margin tuned on tuning scenarios,
    :data:`BOOK_TUNED_TURNS` (the ``book-plan-tuned`` rule: planned on the book's nominal
    target path before any bearing, like :func:`optimised_open_loop`; flown by each of
    ``platforms`` platforms)."""
    return OpenLoop(BOOK_TUNED_TURNS, platforms)
