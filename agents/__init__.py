"""Heuristic observation-control rules, one module per environment, all with SB3's ``predict``.

| env | module | rules |
|-----|--------|-------|
| ``sensorgym/BearingsManeuver-v0`` | :mod:`.bearings_maneuver` | :class:`StraightCourse`, :class:`Paper002Maneuver`, :class:`GreedyManeuver`, :class:`TruthLookahead` (truth-informed) |
| ``sensorgym/StereoPointing-v0`` | :mod:`.stereo_pointing` | :class:`HoldStill`, :class:`TrackNearest`, :class:`OrthogonalPairs`, :class:`GreedyPointing` |
| ``sensorgym/StereoPlacement-v0`` | :mod:`.stereo_placement` | :class:`HoldPosition`, :class:`CirclePlacement`, :class:`GreedyPlacement`, :class:`TruthGreedyPlacement` (truth-informed) |
| ``sensorgym/StereoScanning-v0`` | :mod:`.stereo_scanning` | :class:`FullSweep`, :class:`CueFollowing`, :class:`OrthogonalSectors`, :class:`GreedyInformation`, :class:`TruthSectors` (truth-informed) |

:mod:`.registry` maps env ids to rule factories (``default_rules`` is what ``sensorgym
benchmark`` scores unless ``--rule`` names others);
:mod:`.protocol` is the ``predict`` interface they share with trained models.
"""

from sensorgym.agents.bearings_maneuver import (
    GreedyManeuver,
    Paper002Maneuver,
    StraightCourse,
    TruthLookahead,
)
from sensorgym.agents.protocol import MemorylessRule, PolicyPredictor
from sensorgym.agents.registry import ABLATIONS, RULES, default_rules, rules_for
from sensorgym.agents.stereo_placement import (
    CirclePlacement,
    GreedyPlacement,
    HoldPosition,
    TruthGreedyPlacement,
)
from sensorgym.agents.stereo_pointing import (
    GreedyPointing,
    HoldStill,
    OrthogonalPairs,
    TrackNearest,
)
from sensorgym.agents.stereo_scanning import (
    CueFollowing,
    FullSweep,
    GreedyInformation,
    OrthogonalSectors,
    TruthSectors,
)

__all__ = [
    "ABLATIONS",
    "RULES",
    "CirclePlacement",
    "CueFollowing",
    "FullSweep",
    "GreedyInformation",
    "GreedyManeuver",
    "GreedyPlacement",
    "GreedyPointing",
    "HoldPosition",
    "HoldStill",
    "MemorylessRule",
    "OrthogonalPairs",
    "OrthogonalSectors",
    "Paper002Maneuver",
    "PolicyPredictor",
    "StraightCourse",
    "TrackNearest",
    "TruthGreedyPlacement",
    "TruthLookahead",
    "TruthSectors",
    "default_rules",
    "rules_for",
]
