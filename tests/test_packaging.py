"""The wheel holds only ``sensorgym/…``: no top-level ``envs``, ``train``, … and no file left out;
the build raises no setuptools warning about the data folders."""

from __future__ import annotations

import subprocess
import sys
import zipfile
from importlib.metadata import version
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
MAPPED = {"envs", "agents", "trackers", "train", "cli", "reproduce"}


def test_version_from_metadata():
    assert version("sensorgym")


def test_package_dirs_in_pyproject_cover_every_folder():
    import tomllib

    cfg = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    assert {k.split(".", 1)[1] for k in cfg["package-dir"]} == MAPPED
    # nested folders with Python files would need their own entry
    nested = {
        p.parent.relative_to(ROOT).as_posix()
        for d in MAPPED
        for p in (ROOT / d).rglob("*.py")
        if p.parent != ROOT / d and "__pycache__" not in p.parts
    }
    listed = {
        cfg["package-dir"].get(pkg, pkg.replace("sensorgym.", "").replace(".", "/"))
        for pkg in cfg["packages"]
    }
    assert nested <= listed, f"sub-packages missing from pyproject packages: {nested - listed}"


@pytest.mark.slow
def test_wheel_contains_only_sensorgym(tmp_path):
    build = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "-v", "-w", str(tmp_path), str(ROOT)],
        check=True,
        capture_output=True,
        text=True,
    )
    # setuptools is content with the data folders inside package folders (no "Package would
    # be ignored" warning about train/hyperparams or train/policies)
    log = build.stdout + build.stderr
    assert "absent from the `packages` configuration" not in log
    assert "would be ignored" not in log
    (wheel,) = tmp_path.glob("sensorgym-*.whl")
    names = zipfile.ZipFile(wheel).namelist()
    tops = {n.split("/", 1)[0] for n in names}
    assert tops == {"sensorgym", f"sensorgym-{version('sensorgym')}.dist-info"}
    assert "sensorgym/__init__.py" not in names  # implicit namespace package
    for d in MAPPED:
        for p in (ROOT / d).rglob("*.py"):
            if "__pycache__" in p.parts:
                continue
            rel = p.relative_to(ROOT / d).as_posix()
            assert f"sensorgym/{d}/{rel}" in names, f"{d}/{rel} missing from the wheel"
    # PEP 561: every subpackage of the namespace package carries the typed marker
    for d in MAPPED:
        assert f"sensorgym/{d}/py.typed" in names, f"{d}/py.typed missing from the wheel"
    # package data: the training hyperparameters
    for p in (ROOT / "train" / "hyperparams").glob("*.yml"):
        assert f"sensorgym/train/hyperparams/{p.name}" in names, f"{p.name} missing from the wheel"
    # package data: the shipped policies (run folders), every file of each
    policies = ROOT / "train" / "policies"
    shipped = [p for p in policies.rglob("*") if p.is_file()]
    assert shipped, "no shipped policy found"
    for p in shipped:
        rel = p.relative_to(policies).as_posix()
        assert f"sensorgym/train/policies/{rel}" in names, f"{rel} missing from the wheel"


@pytest.mark.slow
def test_sdist_holds_what_its_tests_read_and_not_the_lab(tmp_path):
    import tarfile

    subprocess.run(
        [sys.executable, "-m", "build", "--sdist", "-o", str(tmp_path), str(ROOT)],
        check=True,
        capture_output=True,
        text=True,
    )
    (sdist,) = tmp_path.glob("sensorgym-*.tar.gz")
    with tarfile.open(sdist) as tar:
        names = {n.split("/", 1)[1] for n in tar.getnames() if "/" in n}
    # the tests and every file of the repository they read (MANIFEST.in)
    wanted = ["tests/golden/episodes.npz", "tests/conftest.py", "docs/theory.md", "docs/conf.py",
              "benchmarks/tables.py", "scripts/docs.sh", ".ci/run", ".gitignore", "README.md",
              "CHANGELOG.md", "train/hyperparams/ppo.yml"]  # fmt: skip
    wanted += [p.relative_to(ROOT).as_posix() for p in (ROOT / "examples").glob("*.py")]
    wanted += [p.relative_to(ROOT).as_posix() for p in (ROOT / "tests").glob("test_*.py")]
    assert not [w for w in wanted if w not in names], "missing from the sdist"
    # not shipped: the lab, the docs site's build and generated pages, local runs, caches
    for top in ("research/", "docs/_build/", "docs/envs/", "results/", "build/"):
        assert not [n for n in names if n.startswith(top)], f"{top} in the sdist"
    assert not [n for n in names if "__pycache__" in n or n.endswith(".pyc")]
