"""Which heuristic rules apply to which environment: what ``sensorgym benchmark`` scores.

``RULES[env_id][name]`` builds the rule from the env's parameters (rules that plan with the
env's kinematics need them); every rule implements :class:`~.protocol.PolicyPredictor`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from . import placement_rules, pointing_rules
from .maneuver_rules import GreedyInformation, Paper002Maneuver, StraightCourse
from .protocol import PolicyPredictor

RuleFactory = Callable[[Any], PolicyPredictor]

RULES: dict[str, dict[str, RuleFactory]] = {
    "sensorgym/BearingsManeuver-v0": {
        "straight-course": lambda params: StraightCourse(),
        "paper002": lambda params: Paper002Maneuver(params),
        "greedy-information": lambda params: GreedyInformation(params),
    },
    "sensorgym/StereoPointing-v0": {
        "hold-still": pointing_rules.HoldStill,
        "track-nearest": pointing_rules.TrackNearest,
        "orthogonal-pairs": pointing_rules.OrthogonalPairs,
        "greedy-information": pointing_rules.GreedyInformation,
    },
    "sensorgym/StereoPlacement-v0": {
        "hold-position": placement_rules.HoldPosition,
        "circle-placement": placement_rules.CirclePlacement,
        "greedy-information": placement_rules.GreedyInformation,
    },
}


def rules_for(env_id: str, params: Any) -> dict[str, PolicyPredictor]:
    """The rules registered for ``env_id``, built for ``params``; ``KeyError`` names known ids."""
    if env_id not in RULES:
        raise KeyError(f"no rules registered for {env_id!r}; known: {sorted(RULES)}")
    return {name: make(params) for name, make in RULES[env_id].items()}
