"""``sensorgym compile``: every env's and rule's kernels into numba's disk cache."""

from __future__ import annotations

import queue

import pytest

from sensorgym.cli.compile import (
    clear_kernel_caches,
    decide,
    groups,
    kernel_digest,
    kernel_sources,
    package_roots,
    source_digest,
    warm,
)
from sensorgym.cli.main import main
from sensorgym.train.benchmark import registered_envs


def test_env_ids_sharing_a_package_compile_in_one_process():
    found = groups(registered_envs())
    flat = [env_id for group in found for env_id in group]
    assert flat == registered_envs()  # every id once, in registration order
    assert ["sensorgym/BearingsManeuver-v0", "sensorgym/BearingsManeuverBook-v0"] in found
    assert ["sensorgym/StereoPointing-v0", "sensorgym/StereoPointingCrowded-v0"] in found
    assert ["sensorgym/StereoScanning-v0"] in found


def test_warm_steps_the_env_and_plays_every_registered_rule():
    from sensorgym.agents.registry import RULES
    from sensorgym.envs.bearings_maneuver import kernels

    env_id = "sensorgym/BearingsManeuver-v0"
    events = queue.Queue()
    ids, seconds, played = warm([env_id], events)
    assert ids == [env_id] and seconds > 0.0
    assert played == len(RULES[env_id])
    # the progress it reports: the env, each rule by name, then done, counting up to the total
    reported = [events.get() for _ in range(events.qsize())]
    assert {e[:2] for e in reported} == {(env_id, 1 + len(RULES[env_id]))}
    assert [e[2] for e in reported] == sorted(e[2] for e in reported)
    assert reported[-1][2:] == (1 + len(RULES[env_id]), "done")
    assert {f"{env_id}: {name}" for name in RULES[env_id]} <= {e[3] for e in reported}
    # the env's kernels are compiled (or loaded from the cache) in this process
    assert kernels.step_kernel.signatures and kernels.reset_kernel.signatures


def test_every_compile_variant_is_valid_and_every_rule_decides_there():
    import gymnasium as gym

    from sensorgym.agents.registry import RULES
    from sensorgym.envs.stereo_placement import kernels as placement
    from sensorgym.trackers.stereo import kernels as stereo

    found = 0
    for env_id in registered_envs():
        env = gym.make(env_id).unwrapped
        variants = getattr(env.simulation, "COMPILE_VARIANTS", ())
        for fields in variants:
            env.params_type(**fields)  # the params' own validation takes them
            assert decide(env_id, fields) == list(RULES[env_id]), (env_id, fields)
            found += 1
    assert found >= 4  # the crowded env takes StereoPointing's variant too
    # the paths they are there for were taken: the generic solve of degenerate periods, the
    # polynomial assignment solvers
    assert placement.period_systems.signatures and placement.period_finish.signatures
    assert stereo.assignment_ascent_batch.signatures and stereo.assignment_greedy_batch.signatures


def test_compile_command_runs_and_refuses_unknown_ids(capsys):
    assert main(["compile", "--env", "sensorgym/StereoPlacement-v0", "--jobs", "1"]) == 0
    printed = capsys.readouterr().out
    assert "sensorgym/StereoPlacement-v0 (and 5 rules)" in printed and "wall" in printed
    with pytest.raises(SystemExit, match="unknown id"):
        main(["compile", "--env", "sensorgym/NoSuchEnv-v0"])
    with pytest.raises(SystemExit, match="--jobs"):
        main(["compile", "--env", "sensorgym/StereoPlacement-v0", "--jobs", "0"])


def test_a_stamp_of_the_current_sources_skips_the_compile(tmp_path, capsys):

    stamp = tmp_path / "compiled"
    stamp.write_text(source_digest() + "\n")
    assert main(["compile", "--stamp", str(stamp)]) == 0
    assert "unchanged" in capsys.readouterr().out
    # another digest (sources edited since): compiles, then records the current one
    # (the kernels' digest kept: a changed one would clear the tree's cached kernels)
    stamp.write_text("0" * 64 + "\n" + kernel_digest(package_roots()) + "\n")
    env_id = "sensorgym/StereoPlacement-v0"
    assert main(["compile", "--env", env_id, "--jobs", "1", "--stamp", str(stamp)]) == 0
    assert env_id in capsys.readouterr().out
    digest, kernels = stamp.read_text().split()
    assert digest == source_digest() and kernels == kernel_digest(package_roots())


def test_a_changed_kernel_source_clears_every_cached_kernel(tmp_path, monkeypatch):
    # numba keys a cached kernel on its own file: a caller compiled with an old callee from
    # another file would load stale, so any kernel edit clears them all
    root = tmp_path / "pkg"
    (root / "sub" / "__pycache__").mkdir(parents=True)
    (root / "kernels.py").write_text("from numba import njit\n\n@njit\ndef f(x):\n    return x\n")
    (root / "plain.py").write_text("x = 1\n")
    cached = [root / "sub" / "__pycache__" / f"kernels.f-3.py311.{e}" for e in ("nbi", "1.nbc")]
    for path in cached:
        path.write_bytes(b"cache")
    other = root / "sub" / "__pycache__" / "plain.cpython-311.pyc"
    other.write_bytes(b"pyc")
    assert kernel_sources([root]) == [root / "kernels.py"]
    before = kernel_digest([root])
    (root / "plain.py").write_text("x = 2\n")
    assert kernel_digest([root]) == before  # a file without kernels does not count
    (root / "kernels.py").write_text((root / "kernels.py").read_text() + "\n# edited\n")
    assert kernel_digest([root]) != before
    assert clear_kernel_caches([root]) == 2
    assert not any(p.exists() for p in cached) and other.exists()
    # with NUMBA_CACHE_DIR numba mirrors the source path under it
    mirror = tmp_path / "cache" / root.resolve().relative_to(root.resolve().anchor) / "sub"
    mirror.mkdir(parents=True)
    (mirror / "kernels.f-3.py311.nbi").write_bytes(b"cache")
    assert clear_kernel_caches([root], str(tmp_path / "cache")) == 1


def test_the_digest_changes_with_any_source_file_and_only_with_sources(tmp_path, monkeypatch):
    import importlib.util
    from types import SimpleNamespace

    real = source_digest()
    assert len(real) == 64 and source_digest() == real
    (tmp_path / "kernels.py").write_text("x = 1\n")
    fake = SimpleNamespace(submodule_search_locations=[str(tmp_path)])
    monkeypatch.setattr(importlib.util, "find_spec", lambda name: fake)
    before = source_digest()
    assert before != real
    (tmp_path / "notes.txt").write_text("not a source")
    assert source_digest() == before
    (tmp_path / "kernels.py").write_text("x = 2\n")
    assert source_digest() != before
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    (tmp_path / "kernels.py").write_text("x = 1\n")
    assert source_digest() != before  # another cache directory holds other kernels
