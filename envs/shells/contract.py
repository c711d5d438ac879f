"""The one contract every environment's simulation follows, and the adapter the shells step.

An environment's physics lives in one module, ``envs/<env>/simulation.py``: pure functions
over frozen, batched values (leading axis ``B`` = scenario), in the gymnax style. Every such
module defines the same six functions with the same signatures and return conventions
(:class:`Simulation`); :class:`Core` binds one to its parameters, and the Gymnasium env, the
native vector env and the PettingZoo env (:mod:`.gym_env`, :mod:`.vector_env`,
:mod:`.parallel_env`) are thin shells over a :class:`Core`. Scenario-wise selection for
autoreset (:func:`tree_where`) is generic: it needs nothing of the env.

Conventions shared by every env:

* a scenario is driven by ``n_agents`` agents (platforms, receivers) with one action each,
  ``(B, n_agents, agent action)`` in ``[−1, 1]`` (cores clip what lies outside; NaN raises);
  the single-agent Gymnasium env acts with the flattened joint action;
* ``observe`` is the single-agent (joint) view ``(B, obs_dim)``; ``observe_agents`` the
  per-agent views ``(B, n_agents, agent obs_dim)`` of the PettingZoo env and of
  parameter-sharing training; both are float32 and clipped to ``[−OBS_CLIP, OBS_CLIP]``;
* one team reward per scenario; an episode ends for all agents together; the time limit is
  the shells' business (``max_episode_steps`` lives only in the env's registration);
* autoreset draws fresh scenarios only for those that ended (:func:`tree_scatter`).
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import importlib
import math
from dataclasses import dataclass
from types import ModuleType
from typing import Any, Protocol, TypeVar

import numpy as np
from gymnasium import spaces
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
ParamsT = TypeVar("ParamsT")

#: every observation entry is clipped to ``[−OBS_CLIP, OBS_CLIP]`` (a diverged tracker or a far
#: object reads as ±10 instead of an unbounded number)
OBS_CLIP = 10.0

#: ``max_episode_steps`` default of the vector and PettingZoo shells: the env's registration
#: (the one place an episode length is set)
REGISTERED = "registered"


@dataclass(frozen=True)
class EnvSpaces:
    """The spaces of one env: the joint (single-agent) view and the per-agent view."""

    agents: tuple[str, ...]
    """Agent names, in the order of the agent axis."""
    observation: spaces.Box
    """Joint observation ``Box(−OBS_CLIP, OBS_CLIP, (obs_dim,))``."""
    action: spaces.Box
    """Joint action ``Box(−1, 1, (n_agents · agent action,))``, flattened in agent order."""
    agent_observation: spaces.Box
    """One agent's observation."""
    agent_action: spaces.Box
    """One agent's action ``Box(−1, 1, (agent action,))``."""

    @classmethod
    def build(
        cls, prefix: str, n_agents: int, obs_dim: int, agent_obs_dim: int, agent_action_dim: int
    ) -> EnvSpaces:
        """Agents ``prefix_0 … prefix_{n−1}``, observations clipped to ``±OBS_CLIP``, actions in
        ``[−1, 1]`` (SB3 policies handle one-dimensional Box spaces everywhere)."""
        return cls(
            agents=tuple(f"{prefix}_{k}" for k in range(n_agents)),
            observation=spaces.Box(-OBS_CLIP, OBS_CLIP, (obs_dim,), np.float32),
            action=spaces.Box(-1.0, 1.0, (n_agents * agent_action_dim,), np.float32),
            agent_observation=spaces.Box(-OBS_CLIP, OBS_CLIP, (agent_obs_dim,), np.float32),
            agent_action=spaces.Box(-1.0, 1.0, (agent_action_dim,), np.float32),
        )

    @property
    def n_agents(self) -> int:
        """Number of agents per scenario."""
        return len(self.agents)


class Simulation(Protocol):
    """What every ``envs/<env>/simulation.py`` module defines (module-level functions)."""

    def spaces(self, params: Any) -> EnvSpaces:
        """The env's spaces for ``params``."""
        ...

    def reset(self, params: Any, rng: np.random.Generator, batch: int, like: Any = None) -> Any:
        """``batch`` fresh scenarios drawn from ``rng``. ``like`` is the running batch they will
        be swapped into (a core whose scenarios share state, e.g. a tracker clock, matches it)."""
        ...

    def step(
        self, params: Any, state: Any, action: FloatArray, rng: np.random.Generator
    ) -> tuple[Any, FloatArray, BoolArray]:
        """``(state, reward (B,), terminated (B,))`` after the joint ``action``
        ``(B, n_agents, agent action)``."""
        ...

    def observe(self, params: Any, state: Any) -> NDArray[np.float32]:
        """Joint observations ``(B, obs_dim)``."""
        ...

    def observe_agents(self, params: Any, state: Any) -> NDArray[np.float32]:
        """Per-agent observations ``(B, n_agents, agent obs_dim)``."""
        ...

    def info(self, params: Any, state: Any) -> dict[str, FloatArray]:
        """Diagnostics ``{key: (B,) array}`` (may hold ground truth: never for the policy)."""
        ...


def clip_observation(obs: ArrayLike) -> NDArray[np.float32]:
    """``obs`` clipped to ``[−OBS_CLIP, OBS_CLIP]``, as float32."""
    return np.clip(obs, -OBS_CLIP, OBS_CLIP).astype(np.float32)


def with_agent_index(obs: NDArray[np.float32], n_agents: int) -> NDArray[np.float32]:
    """Per-agent views of a shared observation ``(B, d)``: ``(B, n, d + n)``, the shared
    observation followed by a one-hot of the agent's index, so that one shared policy knows
    which agent it drives."""
    B = obs.shape[0]
    shared = np.broadcast_to(obs[:, None, :], (B, n_agents, obs.shape[1]))
    one_hot = np.broadcast_to(np.eye(n_agents, dtype=np.float32), (B, n_agents, n_agents))
    return np.concatenate([shared, one_hot], axis=-1)


def tree_where(mask: ArrayLike, new: Any, old: Any) -> Any:
    """Scenario-wise select over a state: ``new`` where ``mask`` ``(B,)`` is True, else ``old``.

    States are frozen dataclasses (nested freely) whose arrays carry the scenario axis first;
    a scalar field (e.g. a clock all scenarios share) must be equal in both, else
    ``ValueError`` (reset the fresh scenarios ``like`` the running batch).
    """
    m = np.asarray(mask, dtype=bool)

    def pick(a: Any, b: Any, name: str) -> Any:
        if dataclasses.is_dataclass(a):
            if type(a) is not type(b):
                raise ValueError(f"{name}: {type(a).__name__} vs {type(b).__name__}")
            parts = {
                f.name: pick(getattr(a, f.name), getattr(b, f.name), f"{name}.{f.name}")
                for f in dataclasses.fields(a)
            }
            return type(a)(**parts)
        if isinstance(a, np.ndarray) and a.ndim >= 1:
            if a.shape[0] != m.shape[0]:
                raise ValueError(f"mask: {m.shape[0]} entries for a batch of {a.shape[0]} ({name})")
            if a.shape != b.shape:
                raise ValueError(f"{name}: shapes {a.shape} and {b.shape} differ")
            return np.where(m.reshape((-1,) + (1,) * (a.ndim - 1)), a, b)
        if not np.array_equal(a, b):
            raise ValueError(f"{name}: shared value {a!r} differs from {b!r}")
        return b

    if m.ndim != 1:
        raise ValueError(f"mask: expected shape (B,), got {m.shape}")
    return pick(new, old, "state")


def tree_scatter(
    mask: ArrayLike, fresh: Any, old: Any, *, in_place: bool = False, keep: Any = ()
) -> Any:
    """``old`` with the scenarios where ``mask`` ``(B,)`` is True replaced, in order, by the
    ``k = mask.sum()`` scenarios of ``fresh`` (a batch of ``k``): autoreset draws only the
    scenarios that ended. Shared scalar fields must be equal, as for :func:`tree_where`.

    ``in_place=True`` writes the fresh rows into ``old``'s own arrays instead of copying them
    (what autoreset does with the state a step has just allocated: only ``k`` rows move). An
    array of ``old`` that shares memory with anything in ``keep`` (states, observations or
    infos already handed out: dataclasses, dicts, tuples and arrays, searched through) or is
    read-only is copied as without ``in_place``, so nothing handed out changes. The merged
    dataclasses are new objects that hold only their fields (nothing cached on ``old``).
    """
    m = np.asarray(mask, dtype=bool)
    if m.ndim != 1:
        raise ValueError(f"mask: expected shape (B,), got {m.shape}")
    rows = np.flatnonzero(m)
    k = rows.shape[0]
    kept = _memory_roots(keep) if in_place else set()

    def put(a: Any, b: Any, name: str) -> Any:
        names = _field_names(type(b))
        if names is not None:
            if type(a) is not type(b):
                raise ValueError(f"{name}: {type(a).__name__} vs {type(b).__name__}")
            merged = {f: put(getattr(a, f), getattr(b, f), f"{name}.{f}") for f in names}
            # the merged value of valid states is valid: bypass the constructor's checks
            if in_place and hasattr(b, "__dict__"):
                # only the fields: a value cached on ``b`` (keyed by its fields' identity,
                # which writing in place keeps) would be stale
                out = object.__new__(type(b))
                out.__dict__.update(merged)
                return out
            out = copy.copy(b)
            for f, value in merged.items():
                object.__setattr__(out, f, value)
            return out
        if isinstance(b, np.ndarray) and b.ndim >= 1:
            if b.shape[0] != m.shape[0]:
                raise ValueError(f"mask: {m.shape[0]} entries for a batch of {b.shape[0]} ({name})")
            if a.shape != (k, *b.shape[1:]):
                raise ValueError(f"{name}: fresh shape {a.shape}, expected {(k, *b.shape[1:])}")
            out = b
            if not (in_place and b.flags.writeable and id(_memory_root(b)) not in kept):
                out = b.copy()
            out[rows] = a
            return out
        if not (a is b or a == b if isinstance(b, float) else np.array_equal(a, b)):
            raise ValueError(f"{name}: shared value {a!r} differs from {b!r}")
        return b

    return put(fresh, old, "state")


@functools.cache
def _field_names(cls: type) -> tuple[str, ...] | None:
    """The field names of a dataclass type, else ``None`` (cached: autoreset is a hot path)."""
    if not dataclasses.is_dataclass(cls):
        return None
    return tuple(f.name for f in dataclasses.fields(cls))


def _memory_root(a: np.ndarray) -> np.ndarray:
    """The array that owns ``a``'s memory (``a`` itself unless it is a view)."""
    while isinstance(a.base, np.ndarray):
        a = a.base
    return a


def _memory_roots(tree: Any) -> set[int]:
    """``id`` of the memory owner of every array in ``tree`` (:func:`tree_arrays`)."""
    return {id(_memory_root(a)) for a in tree_arrays(tree)}


def tree_arrays(tree: Any) -> list[np.ndarray]:
    """Every array in ``tree`` (dataclasses, dicts, tuples and lists, searched through), in
    field order."""
    found: list[np.ndarray] = []

    def visit(x: Any) -> None:
        if isinstance(x, np.ndarray):
            found.append(x)
        elif isinstance(x, dict):
            for v in x.values():
                visit(v)
        elif isinstance(x, (tuple, list)):
            for v in x:
                visit(v)
        else:
            for f in _field_names(type(x)) or ():
                visit(getattr(x, f))

    visit(tree)
    return found


def resolve_params(params_type: type[ParamsT], params: ParamsT | None, **fields: Any) -> ParamsT:
    """``params`` (default ``params_type()``) with ``fields`` replaced: every door (``gym.make``,
    ``gym.make_vec``, ``parallel_env``) takes the params' fields as keyword arguments.

    Unknown keywords raise ``TypeError`` naming the known fields.
    """
    base = params_type() if params is None else params
    if not isinstance(base, params_type):
        raise TypeError(f"params: expected {params_type.__name__}, got {type(params).__name__}")
    known = {f.name for f in dataclasses.fields(params_type)}  # type: ignore[arg-type]
    unknown = sorted(set(fields) - known)
    if unknown:
        raise TypeError(
            f"unexpected keyword arguments {unknown}; {params_type.__name__} fields: "
            f"{sorted(known)}"
        )
    return dataclasses.replace(base, **fields) if fields else base  # type: ignore[type-var]


def registered_episode_steps(env_id: str) -> int | None:
    """``max_episode_steps`` of ``env_id``'s registration (the one place it is set)."""
    import gymnasium as gym

    import sensorgym.envs  # noqa: F401  (registers the ids)

    return gym.spec(env_id).max_episode_steps


#: actions of at most this many entries are checked for finiteness element by element in Python
#: (on a two-entry action a numpy reduction's call overhead costs more than the loop)
_SMALL_ACTION = 64


def check_action(action: Any, shape: tuple[int, ...]) -> FloatArray:
    """The action as float64 of ``shape``; wrong shapes, NaN and inf raise ``ValueError``.

    Values outside the Box are not an error: cores clip them (the documented fallback).
    """
    try:
        a = np.asarray(action, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"action: cannot be read as floats ({exc})") from None
    if a.shape != shape:
        raise ValueError(f"action: expected shape {shape}, got {a.shape}")
    finite = (
        all(map(math.isfinite, a.ravel().tolist()))
        if a.size <= _SMALL_ACTION
        else bool(np.isfinite(a).all())
    )
    if not finite:
        raise ValueError("action: contains NaN or infinite values")
    return a


class Core:
    """A simulation module bound to its parameters: the one adapter every shell steps.

    ``Core(simulation, params)`` calls ``simulation.f(params, …)`` for each function of the
    :class:`Simulation` contract, reshapes flattened joint actions to the agent axis, and
    selects scenarios with :func:`tree_where`. It pickles by module name.
    """

    def __init__(self, simulation: ModuleType, params: Any):
        self.simulation = simulation
        self.params = params
        self.spaces: EnvSpaces = simulation.spaces(params)
        self._agent_axes = (self.spaces.n_agents, *self.spaces.agent_action.shape)
        self._joint_size = math.prod(self._agent_axes)

    def __reduce__(self) -> tuple[Any, tuple[str, Any]]:
        return _core_from_module_name, (self.simulation.__name__, self.params)

    @property
    def n_agents(self) -> int:
        """Agents per scenario."""
        return self.spaces.n_agents

    def reset(self, rng: np.random.Generator, batch: int, like: Any = None) -> Any:
        """``batch`` fresh scenarios (see :meth:`Simulation.reset`)."""
        return self.simulation.reset(self.params, rng, batch, like)

    def step(
        self, state: Any, action: FloatArray, rng: np.random.Generator
    ) -> tuple[Any, FloatArray, BoolArray]:
        """One step under ``action`` ``(B, n_agents · agent action)`` or
        ``(B, n_agents, agent action)``: ``(state, reward (B,), terminated (B,))``."""
        a = np.asarray(action)
        if a.ndim < 1 or a.size != a.shape[0] * self._joint_size:
            raise ValueError(
                f"action: expected (B, {self.n_agents} · {self.spaces.agent_action.shape}) "
                f"values, got shape {a.shape}"
            )
        joint = a.reshape(a.shape[0], *self._agent_axes)
        return self.simulation.step(self.params, state, joint, rng)

    def observe(self, state: Any) -> NDArray[np.float32]:
        """Joint observations ``(B, obs_dim)``."""
        return self.simulation.observe(self.params, state)

    def observe_agents(self, state: Any) -> NDArray[np.float32]:
        """Per-agent observations ``(B, n_agents, agent obs_dim)``."""
        return self.simulation.observe_agents(self.params, state)

    def info(self, state: Any) -> dict[str, FloatArray]:
        """Diagnostics ``{key: (B,) array}``."""
        return self.simulation.info(self.params, state)

    @staticmethod
    def where(mask: BoolArray, new: Any, old: Any) -> Any:
        """Scenario-wise select (:func:`tree_where`)."""
        return tree_where(mask, new, old)

    @staticmethod
    def scatter(
        mask: BoolArray, fresh: Any, old: Any, *, in_place: bool = False, keep: Any = ()
    ) -> Any:
        """``old`` with the masked scenarios replaced by ``fresh`` (:func:`tree_scatter`)."""
        return tree_scatter(mask, fresh, old, in_place=in_place, keep=keep)


def _core_from_module_name(name: str, params: Any) -> Core:
    return Core(importlib.import_module(name), params)
