"""``sensorgym compile``: pay numba's compile time once, on every core.

Every env's kernels and every registered rule's kernels are compiled on first use and written
to numba's disk cache (``cache=True``); from then on they load in milliseconds. Compiling is
single-threaded and takes minutes for all envs in one process (``benchmarks/cold_start.py``),
so this command compiles them in parallel: one process per env package (variants sharing a
package's kernels, such as ``BearingsManeuverBook-v0`` and ``StereoPointingCrowded-v0``, go
with it), each making the Gymnasium env and the native vector env, stepping both, and playing
one short episode of every registered rule, exactly as ``sensorgym benchmark`` will; then two
decisions of every rule at each params variant in the simulation module's ``COMPILE_VARIANTS``
(sizes or settings whose episodes take other compiled paths: degenerate periods, polynomial
searches at many receivers), so that no run stalls midway on them. With a warm cache it only
loads (seconds: the rules' episodes are played all the same); with ``--stamp FILE`` it does
nothing when FILE holds the digest of the current sources (:func:`source_digest`) — the set-up
scripts run it that way after every install — and when a kernel source changed since FILE was
written, it first deletes every cached kernel (:func:`clear_kernel_caches`: numba would keep a
caller compiled with an old callee from another file).
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path
from typing import Any

HELP = "compile every env's and rule's kernels into numba's disk cache, one process per env"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--env",
        action="append",
        default=None,
        metavar="ID",
        help="env id (repeatable; default: every registered env)",
    )
    parser.add_argument(
        "--jobs",
        type=int,
        default=None,
        help="processes at once (default: the CPUs this process may use)",
    )
    parser.add_argument(
        "--quiet",
        action="store_true",
        help="print nothing on success (default: a progress bar per env package on a terminal, "
        "a line per package as it finishes in a log)",
    )
    parser.add_argument(
        "--stamp",
        type=Path,
        default=None,
        metavar="FILE",
        help="skip if FILE holds the digest of the current sources; write it after compiling",
    )


#: the subpackages whose sources the compiled kernels come from
PACKAGES = ("envs", "agents", "trackers", "train")


def package_roots() -> list[Path]:
    """The source folders of :data:`PACKAGES`, found without importing them."""
    import importlib.util

    roots = []
    for name in PACKAGES:
        spec = importlib.util.find_spec(f"sensorgym.{name}")
        roots += [Path(r) for r in (spec.submodule_search_locations or ())] if spec else []
    return roots


def kernel_sources(roots: list[Path]) -> list[Path]:
    """The ``.py`` files under ``roots`` that define numba kernels (``@njit``)."""
    return [p for root in roots for p in sorted(root.rglob("*.py")) if "@njit" in p.read_text()]


def kernel_digest(roots: list[Path]) -> str:
    """SHA-256 of every kernel source under ``roots`` (:func:`kernel_sources`, path and bytes)."""
    import hashlib

    h = hashlib.sha256()
    for path in kernel_sources(roots):
        h.update(path.as_posix().encode())
        h.update(path.read_bytes())
    return h.hexdigest()


def clear_kernel_caches(roots: list[Path], cache_dir: str | None = None) -> int:
    """Delete numba's cached kernels (``*.nbi`` index and ``*.nbc`` code files) of the sources
    under ``roots`` — in the ``__pycache__`` folders beside them, or in ``cache_dir``'s mirror of
    their paths when numba caches there (``NUMBA_CACHE_DIR``). Returns how many files went.

    Numba keys a cached kernel on its own file only: after an edit to a kernel it calls in
    another file, the caller would load from the cache with the old callee compiled in. So when
    any kernel source changes, every kernel is compiled again."""
    removed = 0
    for root in roots:
        where = root.resolve()
        if cache_dir:
            where = Path(cache_dir) / where.relative_to(where.anchor)
        for pattern in ("*.nbi", "*.nbc"):
            for path in where.rglob(pattern) if where.is_dir() else ():
                path.unlink(missing_ok=True)
                removed += 1
    return removed


def source_digest() -> str:
    """SHA-256 of what decides whether the disk cache is current: sensorgym's and numba's
    versions, ``NUMBA_CACHE_DIR`` and every ``.py`` file of :data:`PACKAGES` (path and bytes).
    Found without importing them (importing ``sensorgym.envs`` alone takes seconds)."""
    import hashlib
    import importlib.util
    from importlib.metadata import version

    h = hashlib.sha256()
    h.update(
        f"{version('sensorgym')} {version('numba')} {os.environ.get('NUMBA_CACHE_DIR')}".encode()
    )
    for name in PACKAGES:
        spec = importlib.util.find_spec(f"sensorgym.{name}")
        roots = spec.submodule_search_locations if spec is not None else None
        for root in roots or ():
            for path in sorted(Path(root).rglob("*.py")):
                h.update(f"{name}/{path.relative_to(root).as_posix()}".encode())
                h.update(path.read_bytes())
    return h.hexdigest()


def groups(env_ids: list[str]) -> list[list[str]]:
    """``env_ids`` grouped by the package of their entry point (ids of one package share its
    kernels, so they compile in one process, one after the other), in registration order."""
    import gymnasium as gym

    out: dict[str, list[str]] = {}
    for env_id in env_ids:
        entry = gym.spec(env_id).entry_point
        package = (entry if isinstance(entry, str) else entry.__module__).rsplit(".", 1)[0]
        out.setdefault(package, []).append(env_id)
    return list(out.values())


def warm(env_ids: list[str], events: Any = None) -> tuple[list[str], float, int]:
    """Compile (or load) what ``env_ids`` use: the compiled normal draws of large batches
    (:mod:`sensorgym.envs.shells.normals`), the Gymnasium env, stepped once, then one episode
    of each registered rule on the native vector env of two scenarios (as ``sensorgym
    benchmark`` scores it); then, at each params variant the env's simulation module lists in
    ``COMPILE_VARIANTS`` (sizes or settings whose episodes take other compiled paths), two
    decisions of each rule that applies there (:func:`decide`). Returns the ids, the seconds
    taken and the number of rules played at the defaults.

    ``events`` (a queue, or ``None``) receives ``(first id, total, done, what)`` as the work
    goes: ``total`` the units of work (an env, a rule, a params variant), ``done`` those
    finished, ``what`` the one that comes next."""
    import gymnasium as gym
    import numpy as np
    from gymnasium.envs.registration import load_env_creator

    import sensorgym.envs  # noqa: F401  (registers the ids)
    from sensorgym.agents.registry import RULES
    from sensorgym.envs.shells.normals import COMPILED_MIN_DRAWS, standard_normal_rows
    from sensorgym.train.benchmark import NotApplicable, policies_for, score

    t0 = time.perf_counter()
    played = 0
    # every registered rule, ablations too: `benchmark --rule NAME` plays them compiled
    specs = {
        env_id: policies_for(env_id, shipped=False, rules=RULES.get(env_id, {}))
        for env_id in env_ids
    }
    variants = {  # read off the env class: making an env here would compile its kernels
        env_id: getattr(
            load_env_creator(gym.spec(env_id).entry_point).simulation, "COMPILE_VARIANTS", ()
        )
        for env_id in env_ids
    }
    total = sum(1 + len(specs[e]) + len(variants[e]) for e in env_ids)
    done = 0

    def report(what: str) -> None:
        if events is not None:
            events.put((env_ids[0], total, done, what))

    # the compiled normal draws, which only batches of many draws take
    report(f"{env_ids[0]}: normal draws")
    standard_normal_rows(np.random.default_rng(0), np.empty((1, COMPILED_MIN_DRAWS)), 0, 1)
    for env_id in env_ids:
        report(f"{env_id}: env step")
        env = gym.make(env_id)
        env.reset(seed=0)
        env.step(np.zeros(env.action_space.shape, env.action_space.dtype))
        env.close()
        done += 1
        for name, spec in specs[env_id].items():
            report(f"{env_id}: {name}")
            try:
                score(env_id, spec, episodes=1, n_envs=2, seed=0)
                played += 1
            except NotApplicable:
                pass
            done += 1
        for fields in variants[env_id]:
            report(f"{env_id}: rules at {fields}")
            decide(env_id, fields)
            done += 1
    report("done")
    return env_ids, time.perf_counter() - t0, played


def decide(env_id: str, fields: dict[str, Any], steps: int = 2) -> list[str]:
    """``steps`` decisions of every rule registered for ``env_id`` that applies at the params
    ``fields``, each followed by a step of the native vector env of two scenarios; returns the
    rules that decided."""
    from sensorgym.agents.registry import RULES
    from sensorgym.train.evaluation import env_params, make_sb3_env, simulator_state

    env = make_sb3_env(env_id, 2, 0, **fields)
    decided = []
    try:
        for name, make_rule in RULES.get(env_id, {}).items():
            try:
                rule = make_rule(env_params(env), simulator_state(env))
            except ValueError:  # a rule that does not apply at these params
                continue
            obs = env.reset()
            for _ in range(steps):
                action, _ = rule.predict(obs, deterministic=True)
                obs, *_ = env.step(action)
            decided.append(name)
    finally:
        env.close()
    return decided


def _compile_all(
    tasks: list[list[str]], jobs: int, show: bool
) -> list[tuple[list[str], float, int]]:
    """:func:`warm` every task, ``jobs`` processes at once (spawned: a fresh interpreter per
    worker, no forked numba or torch state). With ``show``: on a terminal a progress bar per
    task (what it compiles now), in a log a line per task as it finishes."""
    import multiprocessing
    import queue
    import sys
    from concurrent.futures import Future, ProcessPoolExecutor

    from sensorgym.cli.console import make_console

    console = make_console()
    live = show and console.is_terminal
    bars = _Bars(console, tasks) if live else None
    results: list[tuple[list[str], float, int]] = []

    def finished(ids: list[str], seconds: float, played: int) -> None:
        results.append((ids, seconds, played))
        if show and not live:
            print(f"{seconds:7.1f} s  {', '.join(ids)} (and {played} rules)", flush=True)

    try:
        if jobs == 1 or len(tasks) == 1:  # in this process, one task after the other
            for task in tasks:
                finished(*warm(task, bars))
        else:
            context = multiprocessing.get_context("spawn")
            with (
                context.Manager() as manager,
                ProcessPoolExecutor(min(jobs, len(tasks)), mp_context=context) as pool,
            ):
                events = manager.Queue() if live else None
                pending: set[Future] = {pool.submit(warm, task, events) for task in tasks}
                while pending:
                    done = {f for f in pending if f.done()}
                    for f in done:
                        finished(*f.result())  # a worker's exception surfaces here
                    pending -= done
                    if events is None:
                        time.sleep(0.2)
                        continue
                    try:
                        while True:
                            bars.put(events.get(timeout=0.1))
                    except queue.Empty:
                        pass
    finally:
        if bars is not None:
            bars.stop()
    if live:
        for ids, seconds, played in sorted(results, key=lambda d: -d[1]):
            print(f"{seconds:7.1f} s  {', '.join(ids)} (and {played} rules)")
    sys.stdout.flush()
    return results


class _Bars:
    """One rich progress bar per task of :func:`_compile_all`, keyed by its first env id."""

    def __init__(self, console: Any, tasks: list[list[str]]):
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn

        self.progress = Progress(
            TextColumn("{task.fields[label]:<32}"),
            BarColumn(),
            MofNCompleteColumn(),
            TextColumn("{task.description}"),
            console=console,
        )
        self.ids = {
            t[0]: self.progress.add_task("waiting", total=None, label=t[0].split("/")[-1])
            for t in tasks
        }
        self.progress.start()

    def put(self, event: tuple[str, int, int, str]) -> None:
        """Show one of :func:`warm`'s events (the queue's ``put``, so that :func:`warm` in this
        process reports to the bars directly)."""
        first_id, total, done, what = event
        self.progress.update(self.ids[first_id], total=total, completed=done, description=what)

    def stop(self) -> None:
        self.progress.stop()


def run(args: argparse.Namespace) -> int:
    if args.stamp is not None:
        digest = source_digest()
        recorded = args.stamp.read_text().split() if args.stamp.is_file() else []
        if recorded[:1] == [digest]:
            if not args.quiet:
                print(f"{args.stamp}: the sources are unchanged since the last compile")
            return 0
        roots = package_roots()
        kernels = kernel_digest(roots)
        if recorded[1:2] != [kernels]:
            removed = clear_kernel_caches(roots, os.environ.get("NUMBA_CACHE_DIR"))
            if removed and not args.quiet:
                print(f"kernel sources changed: {removed} cached kernel files removed")
    from sensorgym.train.benchmark import registered_envs

    known = registered_envs()
    env_ids = args.env or known
    unknown = [e for e in env_ids if e not in known]
    if unknown:
        raise SystemExit(f"--env: unknown id(s) {unknown}; registered: {known}")
    tasks = groups(env_ids)
    jobs = len(os.sched_getaffinity(0)) if args.jobs is None else args.jobs
    if jobs < 1:
        raise SystemExit(f"--jobs: expected at least 1, got {jobs}")
    t0 = time.perf_counter()
    _compile_all(tasks, jobs, show=not args.quiet)
    wall = time.perf_counter() - t0
    if not args.quiet:
        print(f"{wall:7.1f} s  wall, {min(jobs, len(tasks))} processes")
    if args.stamp is not None:
        args.stamp.write_text(f"{digest}\n{kernels}\n")
    return 0
