"""Which heuristic rules apply to which environment: what ``sensorgym benchmark`` scores.

``RULES[env_id][name](params, state_fn)`` builds the rule from the env's parameters (rules that
plan with the env's kinematics need them) and a function returning the simulator's current
state (only oracles use it: they are ceilings, not fieldable policies). Every rule implements
:class:`~.protocol.PolicyPredictor`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from sensorgym.agents import stereo_placement as placement_rules
from sensorgym.agents import stereo_pointing as pointing_rules
from sensorgym.agents.bearings_maneuver import GreedyInformation, Paper002Maneuver, StraightCourse
from sensorgym.agents.bearings_maneuver_oracle import OracleLookahead
from sensorgym.agents.protocol import PolicyPredictor

StateFn = Callable[[], Any]
RuleFactory = Callable[[Any, StateFn], PolicyPredictor]

RULES: dict[str, dict[str, RuleFactory]] = {
    "sensorgym/BearingsManeuver-v0": {
        "straight-course": lambda params, _: StraightCourse(),
        "paper002": lambda params, _: Paper002Maneuver(params),
        "greedy-information": lambda params, _: GreedyInformation(params),
        "oracle-lookahead": lambda params, state_fn: OracleLookahead(state_fn, params),
    },
    "sensorgym/StereoPointing-v0": {
        "hold-still": lambda params, _: pointing_rules.HoldStill(params),
        "track-nearest": lambda params, _: pointing_rules.TrackNearest(params),
        "orthogonal-pairs": lambda params, _: pointing_rules.OrthogonalPairs(params),
        "greedy-information": lambda params, _: pointing_rules.GreedyInformation(params),
    },
    "sensorgym/StereoPlacement-v0": {
        "hold-position": lambda params, _: placement_rules.HoldPosition(params),
        "circle-placement": lambda params, _: placement_rules.CirclePlacement(params),
        "greedy-information": lambda params, _: placement_rules.GreedyInformation(params),
    },
}


def rules_for(env_id: str, params: Any, state_fn: StateFn) -> dict[str, PolicyPredictor]:
    """The rules registered for ``env_id``, built for ``params`` and the simulator behind
    ``state_fn``; ``KeyError`` names the known ids."""
    if env_id not in RULES:
        raise KeyError(f"no rules registered for {env_id!r}; known: {sorted(RULES)}")
    return {name: make(params, state_fn) for name, make in RULES[env_id].items()}
