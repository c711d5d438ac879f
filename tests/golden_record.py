"""Seeded episodes of every env and every reproduction's report, recorded before a refactor.

``python tests/golden_record.py`` rewrites ``tests/golden/`` (``… ENV_ID`` only that env's
episodes); ``tests/test_golden.py`` replays
the same calls and demands identical observations, rewards and printed numbers.
"""

from __future__ import annotations

import contextlib
import io
import re
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np

GOLDEN = Path(__file__).parent / "golden"
SEEDS = (0, 7)
SINGLE_STEPS = 40
VECTOR_ENVS, VECTOR_STEPS = 3, 35
PARALLEL_STEPS = 20
REPRODUCTIONS = ("paper000", "paper001", "paper002", "paper003", "paper004", "bot-benchmark")
REPRODUCTION_RUNS = 4


def _actions(seed: int, steps: int, shape: tuple[int, ...]) -> np.ndarray:
    # beyond the Box on purpose: the clipping is part of the behaviour
    return np.random.default_rng(1000 + seed).uniform(-1.2, 1.2, (steps, *shape))


def single_episodes(env_id: str, seed: int) -> dict[str, np.ndarray]:
    """Reset with ``seed``, then seeded actions; a new episode (reset, no seed) after an end."""
    env = gym.make(env_id)
    obs, _ = env.reset(seed=seed)
    out = {"obs": [obs], "reward": [], "terminated": [], "truncated": []}
    for a in _actions(seed, SINGLE_STEPS, env.action_space.shape):
        obs, reward, terminated, truncated, _ = env.step(a)
        if terminated or truncated:
            obs, _ = env.reset()
        out["obs"].append(obs)
        out["reward"].append(reward)
        out["terminated"].append(terminated)
        out["truncated"].append(truncated)
    return {k: np.asarray(v) for k, v in out.items()}


def _vector_run(env, obs, actions) -> dict[str, np.ndarray]:
    out = {"obs": [obs], "reward": [], "terminated": [], "truncated": []}
    for a in actions:
        obs, reward, terminated, truncated, _ = env.step(a)
        out["obs"].append(obs)
        out["reward"].append(reward)
        out["terminated"].append(terminated)
        out["truncated"].append(truncated)
    return {k: np.asarray(v) for k, v in out.items()}


def vector_episodes(env_id: str, seed: int) -> dict[str, np.ndarray]:
    """``VECTOR_ENVS`` scenarios of the native vector env (NEXT_STEP autoreset)."""
    env = gym.make_vec(env_id, num_envs=VECTOR_ENVS, vectorization_mode="vector_entry_point")
    obs, _ = env.reset(seed=seed)
    return _vector_run(env, obs, _actions(seed, VECTOR_STEPS, env.action_space.shape))


def full_sweep(env) -> np.ndarray:
    """The papers' full sweep of every receiver (``FullSweep``): scanning's random sectors
    never confirm a track, the sweep confirms most drones within a few periods."""
    from sensorgym.agents.stereo_scanning import FullSweep

    return FullSweep(env.params).predict(np.zeros(env.observation_space.shape))[0]


def hold_still(env) -> np.ndarray:
    """The gimbal's drives at rest: random rates slew the narrow field of view off the target
    within a frame or two, at rest it stays in view long enough for the tracker to fuse."""
    return np.zeros(env.action_space.shape, dtype=np.float32)


#: envs whose random-action episodes miss their tracker: one vector episode more under a fixed
#: action that does not read the observation (so no float difference feeds back into it)
FIXED_ACTIONS = {
    "sensorgym/StereoScanning-v0": full_sweep,
    "sensorgym/GimbalTracking-v0": hold_still,
}
FIXED_ACTION_ENVS = tuple(FIXED_ACTIONS)


def fixed_action(env) -> np.ndarray:
    """The fixed action of ``env``'s id (:data:`FIXED_ACTIONS`)."""
    return FIXED_ACTIONS[env.spec.id](env)


def fixed_action_episodes(env_id: str, seed: int) -> dict[str, np.ndarray]:
    """``VECTOR_ENVS`` scenarios of the native vector env under :func:`fixed_action`."""
    env = gym.make_vec(env_id, num_envs=VECTOR_ENVS, vectorization_mode="vector_entry_point")
    obs, _ = env.reset(seed=seed)
    return _vector_run(env, obs, [fixed_action(env)] * VECTOR_STEPS)


def parallel_episodes(factory, seed: int) -> dict[str, np.ndarray]:
    """The PettingZoo env: joint observations ``(steps + 1, n_agents, obs)`` and team rewards."""
    env = factory()
    obs, _ = env.reset(seed=seed)
    agents = list(env.possible_agents)
    shape = env.action_space(agents[0]).shape
    out = {"obs": [np.stack([obs[a] for a in agents])], "reward": []}
    for joint in _actions(seed, PARALLEL_STEPS, (len(agents), *shape)):
        obs, rewards, _, _, _ = env.step(dict(zip(agents, joint, strict=True)))
        out["obs"].append(np.stack([obs[a] for a in agents]))
        out["reward"].append(rewards[agents[0]])
    return {k: np.asarray(v) for k, v in out.items()}


def normalised_report(text: str) -> str:
    """A reproduction's printed report without what may change between identical runs: run
    times, the files it wrote and the wording of document references."""
    lines = []
    timing_table = False
    for line in text.splitlines():
        if line.startswith("wrote ") or re.fullmatch(r"\s*[\d.]+ s", line):
            continue
        line = re.sub(r"took [\d.]+ s", "took _ s", line)
        line = re.sub(r"\(theory §[^)]*\)", "(ref)", line)
        if "time (s)" in line:
            timing_table = True
        elif not line.strip():
            timing_table = False
        elif timing_table:
            line = line.rsplit(None, 1)[0]
        lines.append(line.rstrip())
    return "\n".join(lines) + "\n"


def reproduction_report(name: str, out: Path) -> str:
    """The normalised report of ``sensorgym reproduce NAME --runs 4`` (no plots)."""
    from sensorgym.cli.main import main

    argv = ["reproduce", name, "--runs", str(REPRODUCTION_RUNS), "--out", str(out / name)]
    if name in ("paper001", "paper004"):
        argv.append("--no-plots")
    buffer = io.StringIO()
    with contextlib.redirect_stdout(buffer):
        main(argv)
    return normalised_report(buffer.getvalue())


def env_arrays(env_id: str) -> dict[str, np.ndarray]:
    """Every recording of one env, keyed ``NAME/KIND/SEED/FIELD``."""
    from tests.test_golden import PARALLEL_FACTORIES

    name = env_id.split("/")[1]
    arrays: dict[str, np.ndarray] = {}
    for seed in SEEDS:
        for kind, fn in (("single", single_episodes), ("vector", vector_episodes)):
            for key, value in fn(env_id, seed).items():
                arrays[f"{name}/{kind}/{seed}/{key}"] = value
        for key, value in parallel_episodes(PARALLEL_FACTORIES[env_id], seed).items():
            arrays[f"{name}/parallel/{seed}/{key}"] = value
        if env_id in FIXED_ACTION_ENVS:
            for key, value in fixed_action_episodes(env_id, seed).items():
                arrays[f"{name}/fixed/{seed}/{key}"] = value
    return arrays


def add_env(env_id: str) -> None:
    """Record one env (new, or changed with a stated reason) and keep every other recording."""
    with np.load(GOLDEN / "episodes.npz") as data:
        name = env_id.split("/")[1]
        arrays = {k: v for k, v in data.items() if not k.startswith(f"{name}/")}
    arrays.update(env_arrays(env_id))
    np.savez_compressed(GOLDEN / "episodes.npz", **arrays)
    print(f"recorded {env_id}; {len(arrays)} arrays in {GOLDEN / 'episodes.npz'}")


def record() -> None:
    import tempfile

    import sensorgym.envs as envs

    GOLDEN.mkdir(exist_ok=True)
    arrays: dict[str, np.ndarray] = {}
    for env_id in envs.ENV_IDS:
        arrays.update(env_arrays(env_id))
    np.savez_compressed(GOLDEN / "episodes.npz", **arrays)
    with tempfile.TemporaryDirectory() as tmp:
        for name in REPRODUCTIONS:
            (GOLDEN / f"{name}.txt").write_text(reproduction_report(name, Path(tmp)))
    print(f"recorded {len(arrays)} arrays and {len(REPRODUCTIONS)} reports in {GOLDEN}")


if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).parent.parent))
    if len(sys.argv) > 1:  # python tests/golden_record.py ENV_ID …: those envs only
        for env_id in sys.argv[1:]:
            add_env(env_id)
    else:
        record()
