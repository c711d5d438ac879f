"""A simulated world never imports a tracker: trackers run on a world's output, not inside it."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

WORLDS = Path(__file__).resolve().parents[3] / "envs" / "worlds"
#: shared geometry, input checks, the kernels' input form and the bearings motion/measurement
#: model, not trackers
ALLOWED = {
    "sensorgym.trackers.geometry",
    "sensorgym.trackers.geometry_kernels",
    "sensorgym.trackers.kernel_args",
    "sensorgym.trackers.validation",
    "sensorgym.trackers.bearings.models",
}


@pytest.mark.parametrize("path", sorted(WORLDS.glob("*.py")), ids=lambda p: p.name)
def test_world_imports_no_tracker(path):
    imported = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module:
            imported.add(node.module)
        elif isinstance(node, ast.Import):
            imported.update(alias.name for alias in node.names)
    trackers = {m for m in imported if m.startswith("sensorgym.trackers")}
    assert trackers <= ALLOWED, f"{path.name} imports {sorted(trackers - ALLOWED)}"
