"""The package's layers point one way — trackers ← envs ← agents ← train ← cli and reproduce —
and no module imports another module's private (``_``-prefixed) name (issue 38)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: each subpackage's layer: a module may import its own layer and the layers below
LAYERS = {"trackers": 0, "envs": 1, "agents": 2, "train": 3, "cli": 4, "reproduce": 4}


def _imports(path: Path) -> list[tuple[int, str, list[str]]]:
    """``(line, module, names)`` of every ``sensorgym`` import in ``path``."""
    return _imports_of(path.read_text(), path)


def _imports_of(text: str, path: Path) -> list[tuple[int, str, list[str]]]:
    """:func:`_imports` of source ``text`` (``path`` names it in errors)."""
    found = []
    for node in ast.walk(ast.parse(text, filename=str(path))):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.append((node.lineno, node.module, [a.name for a in node.names]))
        elif isinstance(node, ast.Import):
            found += [(node.lineno, a.name, []) for a in node.names]
    return [f for f in found if f[1].split(".")[0] == "sensorgym"]


@pytest.mark.parametrize("package", sorted(LAYERS))
def test_a_package_imports_only_its_layer_and_those_below(package):
    upward = [
        f"{path.relative_to(ROOT)}:{line} imports {module}"
        for path in sorted((ROOT / package).rglob("*.py"))
        for line, module, _ in _imports(path)
        if LAYERS.get(module.split(".")[1] if "." in module else "", -1) > LAYERS[package]
    ]
    assert not upward, "\n".join(upward)


def _private_names(path: Path) -> list[str]:
    """The private names ``path`` imports from other modules. A package's private module
    (``reproduce/_cli.py``) may serve its siblings: that is not a crossing."""
    return _private_names_of(path.read_text(), path)


def _private_names_of(text: str, path: Path) -> list[str]:
    """:func:`_private_names` of source ``text`` as if it were the file at ``path``."""
    package = "sensorgym." + ".".join(path.relative_to(ROOT).parent.parts)
    found = []
    for line, module, names in _imports_of(text, path):
        parts = module.split(".")
        for k, part in enumerate(parts):
            if part.startswith("_") and ".".join(parts[:k]) != package:
                found.append(f"{line} {module}")
        found += [f"{line} {module}: {n}" for n in names if n.startswith("_")]
    return found


@pytest.mark.parametrize("package", sorted(LAYERS))
def test_no_module_imports_another_modules_private_name(package):
    private = [
        f"{path.relative_to(ROOT)}:{found}"
        for path in sorted((ROOT / package).rglob("*.py"))
        for found in _private_names(path)
    ]
    assert not private, "\n".join(private)


def test_the_checks_see_a_violation(tmp_path):
    bad = ROOT / "envs" / "bad.py"  # where a product module would sit (only parsed here)
    text = "from sensorgym.train.wrappers import _hidden\nimport sensorgym.cli.main\n"
    text += "from sensorgym.reproduce._cli import publish\nfrom sensorgym.envs._x import y\n"
    tmp = tmp_path / "bad.py"
    tmp.write_text(text)
    (_, module2, _) = _imports(tmp)[1]
    assert LAYERS[module2.split(".")[1]] > LAYERS["envs"]
    found = _private_names_of(text, bad)
    assert found == [
        "1 sensorgym.train.wrappers: _hidden",
        "3 sensorgym.reproduce._cli",
    ]  # a private module of another package crosses; one of its own (envs/_x.py) does not
