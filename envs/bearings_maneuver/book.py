"""``sensorgym/BearingsManeuverBook-v0``: the textbook observer-control scenario.

BearingsManeuver with the bearings-only scenario of Ristic, Arulampalam & Gordon (*Beyond the
Kalman Filter*, 2004, ch. 6) as its default parameters (:class:`BookManeuverParams`): the same
simulation (:mod:`.simulation`), kernels, tracker and reward, only the scenario is fixed instead
of drawn. The observer flies at 5 kn and turns at most 30°/min; a bearing every 60 s with
σ = 1.5°, 32 steps (bearings at t = 0 … 32 min); the target starts at (4.92, 0.85) km
East/North of the observer, 4 kn on course −140°, with q̃ = 9·10⁻⁶ m²/s³; coming within 1 km
of it ends the episode (the stand-off). ``sensorgym reproduce bot-control`` compares
manoeuvres on it, the book's leg change (140° → 20° during minutes 13–16) among them.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from sensorgym.envs.bearings_maneuver.bearings_maneuver import (
    BearingsManeuverEnv,
    BearingsManeuverParallelEnv,
    BearingsManeuverVectorEnv,
)
from sensorgym.envs.bearings_maneuver.simulation import ManeuverParams
from sensorgym.envs.shells import aec_constructors
from sensorgym.envs.worlds.platform import PlatformWorldParams
from sensorgym.trackers.bearings.models import KNOT

BOOK_ENV_ID = "sensorgym/BearingsManeuverBook-v0"

#: the book's initial target position relative to the observer, East/North (m)
BOOK_TARGET_OFFSET = (4_920.0, 850.0)
#: its range (m) and bearing from North clockwise (rad)
BOOK_RANGE = float(np.hypot(*BOOK_TARGET_OFFSET))
BOOK_BEARING = float(np.arctan2(*BOOK_TARGET_OFFSET))
#: the book's prior range standard deviation (m): the bank's uniform range span has it
BOOK_RANGE_SIGMA = 2_000.0


def book_world() -> PlatformWorldParams:
    """The book's observer and sensor: 5 kn at most, held (no speed change), turns up to 30°/min, a
    bearing every 60 s with σ = 1.5°, target acceleration noise q̃ = 9·10⁻⁶ m²/s³."""
    return PlatformWorldParams(
        dt=60.0,
        max_turn_rate=np.deg2rad(30.0) / 60.0,
        min_speed=0.0,
        max_speed=5.0 * KNOT,
        max_speed_change=0.0,
        q_tilde=9e-6,
        sigma_bearing=np.deg2rad(1.5),
    )


def _fixed(value: float) -> tuple[float, float]:
    return (value, value)


@dataclass(frozen=True)
class BookManeuverParams(ManeuverParams):
    """:class:`~.simulation.ManeuverParams` whose defaults are the textbook scenario (every
    field keeps its meaning; only the defaults differ)."""

    world: PlatformWorldParams = field(default_factory=book_world)
    """The book's observer and sensor (:func:`book_world`)."""
    initial_range: tuple[float, float] = _fixed(BOOK_RANGE)
    """The book's initial range, about 4.99 km (fixed)."""
    target_speed: tuple[float, float] = _fixed(4.0 * KNOT)
    """4 kn (fixed)."""
    initial_platform_speed: float = 5.0 * KNOT
    """5 kn."""
    initial_heading: tuple[float, float] = _fixed(np.deg2rad(140.0))
    """Observer course 140° at the start (fixed)."""
    initial_bearing: tuple[float, float] = _fixed(BOOK_BEARING)
    """Bearing of the target at the start, about 80.2° (fixed)."""
    target_course: tuple[float, float] = _fixed(np.deg2rad(-140.0))
    """Target course −140° (fixed)."""
    bank_ranges: tuple[float, float] | None = (
        BOOK_RANGE - np.sqrt(3.0) * BOOK_RANGE_SIGMA,
        BOOK_RANGE + np.sqrt(3.0) * BOOK_RANGE_SIGMA,
    )
    """Uniform range prior around the true range with the book's range σ = 2 km."""
    prior_speed: tuple[float, float] | None = (4.0 * KNOT, 2.0 * KNOT)
    """The book's speed prior: 4 kn ± 2 kn."""
    min_range: float = 1_000.0
    """Stand-off: closer than 1 km ends the episode with ``close_penalty``."""


class BearingsManeuverBookEnv(BearingsManeuverEnv):
    """``sensorgym/BearingsManeuverBook-v0``: :class:`BearingsManeuverEnv` on the textbook
    scenario (:class:`BookManeuverParams`, module docstring); 32 steps of 60 s.

    Same spaces, rewards and episode ends as :class:`BearingsManeuverEnv` (its docstring is
    the spec). The speed action does nothing (the world holds 5 kn). The tracker's prior is
    the env's (range uniform over ``bank_ranges``, course uniform over the full circle), not
    the book's half-circle course prior: the reward's bound starts from it.

    ## Version History

    * v0: initial version (issue 13); observation revised in place (issues 13, 35; CHANGELOG.md)
    """

    params_type = BookManeuverParams
    env_id = BOOK_ENV_ID


class BearingsManeuverBookVectorEnv(BearingsManeuverVectorEnv):
    """``num_envs`` :class:`BearingsManeuverBookEnv` scenarios in one batched call."""

    params_type = BookManeuverParams
    env_id = BOOK_ENV_ID


class BearingsManeuverBookParallelEnv(BearingsManeuverParallelEnv):
    """The textbook scenario as a PettingZoo env: one observer unless ``platforms`` says
    otherwise (platforms 2… start within ``formation_radius`` of the first)."""

    metadata: ClassVar[dict[str, Any]] = {
        **BearingsManeuverParallelEnv.metadata,
        "name": "bearings_maneuver_book_v0",
    }
    params_type = BookManeuverParams
    env_id = BOOK_ENV_ID
    default_fields: ClassVar[dict[str, Any]] = {}


def parallel_env(**kwargs: Any) -> BearingsManeuverBookParallelEnv:
    """PettingZoo constructor of :class:`BearingsManeuverBookParallelEnv` (``params`` fields as
    keywords and ``max_episode_steps``)."""
    return BearingsManeuverBookParallelEnv(**kwargs)


#: PettingZoo's AEC constructors: ``env`` (order-checked) and ``raw_env``
env, raw_env = aec_constructors(parallel_env)
