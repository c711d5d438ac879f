"""Every compiled step reads like its reference: no function in ``envs/**/kernels*.py`` over
~120 lines or ~12 parameters (issue 38: kernels with a spine), and no kernel reads its settings
by ``C_*`` index."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
KERNEL_FILES = sorted((ROOT / "envs").rglob("kernels*.py"))
MAX_LINES, MAX_PARAMS = 120, 12


def test_there_are_kernel_files():
    assert len(KERNEL_FILES) >= 4


@pytest.mark.parametrize("path", KERNEL_FILES, ids=lambda p: str(p.relative_to(ROOT)))
def test_no_kernel_function_is_too_long_or_takes_too_many_parameters(path: Path):
    tree = ast.parse(path.read_text())
    too_big = [
        f"{node.name}: {node.end_lineno - node.lineno + 1} lines, {len(node.args.args)} params"
        for node in ast.walk(tree)
        if isinstance(node, ast.FunctionDef)
        and (node.end_lineno - node.lineno + 1 > MAX_LINES or len(node.args.args) > MAX_PARAMS)
    ]
    assert not too_big, too_big


@pytest.mark.parametrize("path", KERNEL_FILES, ids=lambda p: str(p.relative_to(ROOT)))
def test_settings_are_read_by_name(path: Path):
    assert not re.search(r"\[C_[A-Z_]+\]", path.read_text())
