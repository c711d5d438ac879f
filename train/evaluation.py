"""Seeded evaluation of any SB3-style policy on a registered env, batched.

Rules and trained models are scored the same way: SB3's ``predict`` stepped over the env's
native vector env (through :class:`.sb3_vec_env.SB3VecEnv`), deterministic actions, a fixed
seed, so that two policies evaluated with one seed meet the same scenarios.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode
from stable_baselines3.common.vec_env import VecEnv, VecMonitor

import sensorgym.envs  # noqa: F401  (registers the ids)
from sensorgym.train.sb3_vec_env import SB3VecEnv
from sensorgym.train.tail import Measure, TailCollector, measures_for
from sensorgym.train.wrappers import apply_wrappers


@dataclass(frozen=True)
class EpisodeStats:
    """Returns of ``episodes`` evaluation episodes."""

    mean: float
    """Mean episode return."""
    std: float
    """Standard deviation of the episode returns."""
    ci95: float
    """Half-width of the normal 95 % confidence interval of the mean."""
    episodes: int
    """Number of episodes."""
    mean_length: float
    """Mean episode length (steps)."""
    returns: tuple[float, ...] = field(default=(), repr=False)
    """Every episode's return, in a fixed order: round ``k`` of every slot, slot by slot
    (episode ``k·B + i`` is slot ``i``'s ``k``-th): two policies evaluated with one seed and
    batch pair up episode by episode on the same scenarios."""
    bounds: tuple[float, ...] = field(default=(), repr=False)
    """Every episode's upper bound on the return (the env's ``episode_bound`` of the state the
    episode started in, :mod:`.bounds`), in the order of :attr:`returns`; empty for an env
    without one."""
    actions: tuple[np.ndarray, ...] = field(default=(), repr=False)
    """With ``record_actions``: every episode's actions as the env took them, ``(steps, *a)``
    with ``a`` a scenario's action shape, in the order of :attr:`returns` (not in
    :meth:`as_dict`)."""
    keys: tuple[tuple[int, int], ...] = field(default=(), repr=False)
    """With ``record_actions``: every episode's ``(scenario slot, episode number in it)``, in
    the order of :attr:`returns`: with one stream per episode the scenario is
    :func:`~sensorgym.envs.shells.streams.episode_generator` ``(seed, slot, number)``'s."""
    tails: dict[str, tuple[float, ...]] = field(default_factory=dict, repr=False)
    """The env's tail measures (:mod:`.tail`), name → every episode's value (NaN where the
    episode has none, e.g. no fix at all), in the order of :attr:`returns`; empty for an env
    without them."""

    def as_dict(self) -> dict[str, Any]:
        d = asdict(self)
        del d["actions"], d["keys"]
        d["returns"] = list(self.returns)
        if self.bounds:
            d["bounds"] = list(self.bounds)
        else:
            del d["bounds"]
        if self.tails:  # JSON has no NaN: an episode without a value reads null
            d["tails"] = {
                k: [x if np.isfinite(x) else None for x in v] for k, v in self.tails.items()
            }
        else:
            del d["tails"]
        return d


def make_sb3_env(
    env_id: str,
    n_envs: int,
    seed: int,
    agents: bool = False,
    wrappers: Any = (),
    episode_streams: bool = False,
    **env_kwargs: Any,
) -> VecEnv:
    """The env's native vector env of ``n_envs`` scenarios as an SB3 ``VecEnv`` (SAME_STEP
    autoreset, ``VecMonitor``); ``agents=True`` makes every agent of every scenario a slot
    (parameter sharing over the env's PettingZoo agents). ``wrappers``: a run's wrapper list
    (:mod:`.wrappers`), applied over the monitor. ``episode_streams``: one random stream per
    episode (:mod:`sensorgym.envs.shells.streams`; what scoring uses). ``env_kwargs``: params
    fields."""
    venv = gym.make_vec(
        env_id,
        num_envs=n_envs,
        vectorization_mode="vector_entry_point",
        autoreset_mode=AutoresetMode.SAME_STEP,
        agent_view=agents,
        episode_streams=episode_streams,
        **env_kwargs,
    )
    env = apply_wrappers(VecMonitor(SB3VecEnv(venv)), wrappers)
    env.seed(seed)
    return env


def env_params(env: VecEnv) -> Any:
    """The parameters dataclass of the vector env under an SB3 wrapper stack."""
    return env.get_attr("params")[0]


def simulator_state(env: VecEnv) -> Callable[[], Any]:
    """A function returning the current simulator state under ``env`` (the vector env's
    public ``simulator_state``), for truth-informed rules, which plan on the truth; the vector env is
    the one :func:`make_sb3_env` builds, whose batch matches the observations."""
    return lambda: env.get_attr("simulator_state")[0]


def env_id_of(env: VecEnv) -> str | None:
    """The registered id of the vector env under an SB3 wrapper stack (``None`` if it has no
    spec)."""
    spec = env.get_attr("spec")[0]
    return getattr(spec, "id", None)


def agents_per_scenario(env: VecEnv) -> int:
    """Slots per scenario of an SB3 env from :func:`make_sb3_env` (1 unless ``agents=True``)."""
    return int(getattr(env.unwrapped, "agents_per_scenario", 1))


def evaluate(
    policy: Any,
    env: VecEnv,
    episodes: int,
    seed: int,
    episode_bound: Callable[[Any], np.ndarray] | None = None,
    tails: Sequence[Measure] | None = None,
    record_actions: bool = False,
) -> EpisodeStats:
    """Score ``policy`` (anything with SB3's ``predict``) over ``episodes`` episodes of ``env``,
    deterministic actions.

    ``env`` is reseeded with ``seed`` first, so policies evaluated with one seed and batch meet
    the same scenarios, in the same slots: exactly so, draw for draw, on an env made with
    ``episode_streams=True`` (as :func:`~.benchmark.score` makes it), however the policies
    end their episodes; with one generator for the batch, only while no episode ends early by
    a termination the policy caused. Slot ``i`` plays episodes until it has its share
    (``episodes // B``, one more for the last ``episodes % B`` slots, as SB3's
    ``evaluate_policy``); the returns are ordered
    by round, then slot (:attr:`EpisodeStats.returns`). On an env whose slots are agents
    (``make_sb3_env(..., agents=True)``) an episode is a scenario's, counted once: ``episodes``
    must then be a multiple of the number of scenarios.

    ``episode_bound``: the env's bound on an episode's return from the simulator state it
    starts in (one value per scenario, :mod:`.bounds`), read at the reset and after every step
    that ended an episode (the state then holds the next one's start); each episode's bound is
    kept beside its return (:attr:`EpisodeStats.bounds`).

    ``record_actions``: keep every episode's actions as the vector env took them (its
    ``last_action``, per scenario) and its key (:attr:`EpisodeStats.actions`,
    :attr:`EpisodeStats.keys`), for bounds that start from what each policy played.

    ``tails``: the accuracy measures read per episode from the env's diagnostics
    (:mod:`.tail`; the final ``info`` of an episode or its steps' ``info`` accumulated), kept
    beside the returns (:attr:`EpisodeStats.tails`); ``None``: the env's own
    (:data:`.tail.TAIL_MEASURES` of its id), ``()``: none.
    """
    if episodes < 1:
        raise ValueError(f"episodes: must be >= 1, got {episodes}")
    n = agents_per_scenario(env)
    slots = env.num_envs
    scenarios = slots // n
    if n > 1 and episodes % scenarios:
        raise ValueError(f"episodes: {episodes} is not a multiple of the {scenarios} scenarios")
    # SB3's split (evaluate_policy): scenario s plays (episodes + s) // scenarios episodes
    target = np.array([(episodes + s) // scenarios for s in range(scenarios)]).repeat(n)
    env.seed(seed)
    obs = env.reset()
    state_fn = simulator_state(env)
    measures = measures_for(env_id_of(env)) if tails is None else tuple(tails)
    collector = TailCollector(measures, slots) if measures else None
    done_tails: list[list[dict[str, float]]] = [[] for _ in range(slots)]

    def bounds_now() -> np.ndarray:  # per slot: the bound of the episode its scenario starts
        return np.repeat(np.asarray(episode_bound(state_fn()), dtype=np.float64), n)

    bound = bounds_now() if episode_bound is not None else np.zeros(slots)
    done_bounds: list[list[float]] = [[] for _ in range(slots)]
    start = np.ones(slots, dtype=bool)
    state = None
    running = np.zeros(slots)
    length = np.zeros(slots, dtype=np.int64)
    done_returns: list[list[float]] = [[] for _ in range(slots)]
    done_lengths: list[list[int]] = [[] for _ in range(slots)]
    played: list[list[np.ndarray]] = [[] for _ in range(slots)]  # this episode's actions
    done_actions: list[list[np.ndarray]] = [[] for _ in range(slots)]
    while any(len(done_returns[i]) < target[i] for i in range(slots)):
        action, state = policy.predict(obs, state=state, episode_start=start, deterministic=True)
        obs, reward, done, infos = env.step(action)
        if record_actions:
            taken = np.asarray(env.get_attr("last_action")[0])
            for i in range(slots):
                played[i].append(taken[i // n].copy())
        running += np.asarray(reward, dtype=np.float64)
        length += 1
        if collector is not None:
            collector.step(infos, done)
        for i in np.flatnonzero(done):
            values = collector.episode(i, infos[i].get("final_info", {})) if collector else {}
            if len(done_returns[i]) < target[i]:
                done_returns[i].append(float(running[i]))
                done_lengths[i].append(int(length[i]))
                done_bounds[i].append(float(bound[i]))
                done_tails[i].append(values)
                if record_actions:
                    done_actions[i].append(np.stack(played[i]))
            played[i] = []
        if episode_bound is not None and np.any(done):
            bound = np.where(done, bounds_now(), bound)
        running[done] = 0.0
        length[done] = 0
        start = np.asarray(done, dtype=bool)
    # one return per scenario: the agents of a scenario share its team return
    rounds = max(len(r) for r in done_returns)
    order = [
        (k, s) for k in range(rounds) for s in range(scenarios) if k < len(done_returns[s * n])
    ]
    r = np.array([[done_returns[s * n + a][k] for a in range(n)] for k, s in order])
    if not np.allclose(r, r[:, :1], rtol=1e-5, atol=1e-5):
        raise RuntimeError("evaluate: the agents of a scenario disagree on its team return")
    r = r[:, 0]
    lengths = np.array([done_lengths[s * n][k] for k, s in order], dtype=np.float64)
    bounds = [done_bounds[s * n][k] for k, s in order] if episode_bound is not None else []
    tail_values = {m.name: tuple(done_tails[s * n][k][m.name] for k, s in order) for m in measures}
    actions = tuple(done_actions[s * n][k] for k, s in order) if record_actions else ()
    keys = tuple((s, k) for k, s in order) if record_actions else ()
    std = float(r.std(ddof=1)) if r.size > 1 else 0.0
    return EpisodeStats(
        mean=float(r.mean()),
        std=std,
        ci95=float(1.96 * std / np.sqrt(r.size)),
        episodes=int(r.size),
        mean_length=float(np.mean(lengths)),
        returns=tuple(float(x) for x in r),
        bounds=tuple(bounds),
        actions=actions,
        keys=keys,
        tails=tail_values,
    )
