"""The hindsight optimum of the platform-manoeuvre envs: the per-episode bound on the return.

``sensorgym/BearingsManeuver-v0`` and ``sensorgym/BearingsManeuverBook-v0`` pay the shrinking of
the posterior Cramér–Rao bound on the *true* target state (:mod:`.simulation`)::

    P̄_k = F P_k Fᵀ + Q,   P_{k+1} = (P̄_k⁻¹ + Σ_platforms H_kᵀ H_k / σ²)⁻¹,   P_0 = P_prior
    H_k = n̂ᵀ / r  (the bearing's gradient at the true target, from platform position p_{k+1})
    reward_k = ln m(P_k) − ln m(P_{k+1}) − close_penalty · [some platform within min_range]

so an episode that keeps the stand-off returns ``G(u) = ln m(P_0) − ln m(P_T)``. Neither ``P_0``
(the prior from the first bearing at reset) nor the target's path depends on the actions (the
target's process noise is drawn in the same order and shapes whatever the platforms do), and
the bearings' *noise* never enters the bound. Given the episode's reset state and its target
path ``x_0 … x_T``, the return is a deterministic function of the action sequence
``u = (u_0 … u_{T−1})`` alone, through the platforms' flight (``fly_platform``: turn
``a₀ · ω_max``, speed change ``a₁ · Δv_max``, the speed clipped to ``[v_min, v_max]``, the exact
arc; actions clipped to ``[−1, 1]``).

The **hindsight optimum** of an episode is therefore ``G* = max_u G(u)`` over action sequences in
``[−1, 1]^{T×K×2}``, the stand-off counted exactly as the env counts it (the episode ends with
``−close_penalty`` at the first step where a platform is closer than ``min_range`` to the
target, checked at the bearings, i.e. after every step). No policy, closed loop or not, however
much it knows, can return more on that episode: whatever it observes, it ends up playing *some*
action sequence, and the return of that sequence is ``G(u) ≤ G*``.

What this module computes, and what is guaranteed
-------------------------------------------------
:func:`hindsight_optimum` maximises ``G`` numerically: SLSQP over the active action entries
(turns; speed changes when ``max_speed_change > 0``), the stand-off ``r_{k,j} ≥ min_range`` at
every step and platform as inequality constraints (aimed :data:`STANDOFF_SLACK` inside so that
rounding never puts an optimised point on the wrong side; the check of the result is the env's
own, exact), with central-difference gradients from one batched compiled rollout, multi-start:

* from every start given (e.g. the action sequences the benchmarked policies played on this
  episode) and from ``restarts`` random piecewise-constant sequences;
* it keeps the best point it evaluated, by the env's exact return (termination and penalty
  included), the starts themselves among them.

So ``value ≥ G(start)`` for every start given, **by construction** (up to nothing: the starts'
returns are computed by the same recursion as the env's, :func:`episode_returns`; the result
replays in the env within float rounding). The problem is non-convex, so ``value`` is a *lower
estimate* of the true hindsight optimum ``G*`` (a better sequence may exist that no start led
to) and an *upper reference* for every policy given as a start. Against a policy not given as a
start it is a reference, not a proof. ``gain`` says how much the optimiser added over the best
start.

The recursion is :func:`.kernels.step_kernel`'s, compiled from the same primitives
(``fly_platform``, ``bound_predict``, ``bound_update``, ``accuracy``), on the recorded target
path (:func:`target_paths` replays the env's draws). ``prior_factor`` swaps ``P_0`` for another
prior's square root (``sensorgym reproduce bot-control`` uses the book's prior): the same
optimiser then bounds that prior's final bound instead of the env's return.
"""

from __future__ import annotations

import contextlib
import copy
import ctypes
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import minimize

from sensorgym.envs.bearings_maneuver import simulation
from sensorgym.envs.bearings_maneuver.kernels import fly_step
from sensorgym.envs.bearings_maneuver.simulation import ManeuverParams, ManeuverState
from sensorgym.trackers.bearings.kernels import STATE_DIM, accuracy, bound_predict, bound_update
from sensorgym.trackers.stereo.kernels import copy2

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

#: the optimiser aims this far inside the stand-off (m, relative to ``min_range``: 1 mm per km)
#: so that rounding never lands an optimised point a hair inside it; the result is checked
#: against ``min_range`` exactly, as the env checks it
STANDOFF_SLACK = 1e-6
#: central-difference step on the actions (in ``[−1, 1]`` units)
FD_STEP = 1e-6

_JIT = {"cache": True, "nogil": True, "error_model": "numpy", "boundscheck": False}


@njit(**_JIT)
def returns_kernel(settings, pos0, heading0, speed0, L0, acc0, path, actions, ret, log_final, ranges,
                   ended):  # fmt: skip
    """The env's episode under each action sequence ``actions (S, T, K, 2)`` from one reset
    state (platforms ``pos0 (K, 2)``, ``heading0``, ``speed0`` ``(K,)``, the bound's square root
    ``L0 (4, 4)`` with accuracy ``acc0``) on the recorded target path ``path (T + 1, 4)``:
    :func:`.kernels.step_kernel`'s flight, bound recursion, reward and termination, row by row.
    Writes the exact return ``ret (S,)`` (rewards summed until the episode ends, the penalty
    included), ``ln m(P_T)`` of the full horizon ignoring termination ``log_final (S,)``, every
    range ``ranges (S, T, K)`` and the step count at the end ``ended (S,)`` (``T`` when the
    stand-off was kept); ``settings`` is the params' record (:data:`.kernels.SETTINGS`)."""
    p = settings[0]
    S, T, K = actions.shape[0], actions.shape[1], actions.shape[2]
    dt, q_tilde, sigma = p.dt, p.q_tilde, p.sigma
    L = np.empty((STATE_DIM, STATE_DIM))
    L_pred = np.empty((STATE_DIM, STATE_DIM))
    A_pred = np.empty((2 * STATE_DIM, STATE_DIM))
    A_update = np.empty((STATE_DIM + 1, STATE_DIM + 1))
    px, py = np.empty(K), np.empty(K)
    h, v = np.empty(K), np.empty(K)
    for s in range(S):
        copy2(L0, L)
        for k in range(K):
            px[k], py[k], h[k], v[k] = pos0[k, 0], pos0[k, 1], heading0[k], speed0[k]
        acc = acc0
        total = 0.0
        end = T
        for t in range(T):
            # fly: (a₀ ω_max, a₁ Δv_max), a clipped to [−1, 1], the exact arc
            for k in range(K):
                a0 = min(max(actions[s, t, k, 0], -1.0), 1.0)
                a1 = min(max(actions[s, t, k, 1], -1.0), 1.0)
                px[k], py[k], h[k], v[k] = fly_step(
                    p, px[k], py[k], h[k], v[k], a0 * p.max_turn, a1 * p.max_dv
                )
            tx, ty = path[t + 1, 0], path[t + 1, 1]
            # P̄ = F P Fᵀ + Q, then each platform's bearing on the true target, in turn
            bound_predict(L, dt, q_tilde, L_pred, A_pred)
            for k in range(K):
                bound_update(L_pred, tx, ty, px[k], py[k], sigma, L, A_update)
                if k + 1 < K:
                    copy2(L, L_pred)
            m = accuracy(p.relative_range, L, tx, ty, px[0], py[0], p.floor)
            close = False
            for k in range(K):
                r = math.hypot(tx - px[k], ty - py[k])
                ranges[s, t, k] = r
                if r < p.min_range:
                    close = True
            if end == T:
                # reward_k = ln m_k − ln m_{k+1} − penalty · [a platform within min_range]
                total += math.log(acc) - math.log(m)
                if close:
                    total -= p.penalty
                    end = t + 1
            acc = m
        ret[s] = total
        log_final[s] = math.log(acc)
        ended[s] = end


@dataclass(frozen=True)
class EpisodeReturns:
    """Action sequences evaluated on one episode (:func:`episode_returns`), ``S`` of them."""

    value: FloatArray
    """The env's return ``(S,)``: rewards summed until the episode ends, penalty included."""
    log_final: FloatArray
    """``ln m(P_T)`` ``(S,)`` after all ``T`` steps, whether or not the stand-off was kept."""
    ranges: FloatArray
    """Platform–target range at every step ``(S, T, K)`` (m)."""
    ended: NDArray[np.int64]
    """Steps played ``(S,)``: ``T`` unless a platform came within ``min_range``."""

    @property
    def standoff_ok(self) -> BoolArray:
        """Whether each sequence kept the stand-off at every step ``(S,)``."""
        return self.ended == self.ranges.shape[1]


def target_paths(
    params: ManeuverParams,
    state: ManeuverState,
    steps: int,
    rng: np.random.Generator | None = None,
) -> FloatArray:
    """The true target states ``(B, steps + 1, 4)`` the env will produce from ``state``: the
    env's own steps replayed on a copy of ``rng`` (the generator as it stood at ``state``; the
    draws do not depend on the actions). ``rng`` may be omitted when ``world.q_tilde = 0`` (the
    path is then ``x_{k+1} = F x_k``). In a vector env the batch shares one generator and an
    autoreset draws from it, so this is the batch's path only until a row's episode ends."""
    if steps < 1:
        raise ValueError(f"steps: must be >= 1, got {steps}")
    if rng is None:
        if params.world.q_tilde > 0.0:
            raise ValueError("rng: needed when world.q_tilde > 0 (the target's path is random)")
        rng = np.random.default_rng(0)  # only the bearings' noise is drawn from it
    else:
        rng = copy.deepcopy(rng)
    s = state
    out = [s.target]
    zero = np.zeros((s.batch_size, s.heading.shape[1], 2))
    for _ in range(steps):
        s, _, _ = simulation.step(params, s, zero, rng)
        out.append(s.target)
    return np.stack(out, axis=1)


def _row(state: ManeuverState, b: int, prior_factor: FloatArray | None, params: ManeuverParams,
         path: FloatArray) -> tuple[FloatArray, ...]:  # fmt: skip
    """Scenario ``b``'s reset quantities for :func:`returns_kernel`."""
    L0 = state.bound_factor[b] if prior_factor is None else prior_factor[b]
    L0 = np.ascontiguousarray(L0, dtype=np.float64)
    acc0 = float(simulation.accuracy_of(params, L0, path[0], state.platform_position[b, 0]))
    return (
        np.ascontiguousarray(state.platform_position[b], dtype=np.float64),
        np.ascontiguousarray(state.heading[b], dtype=np.float64),
        np.ascontiguousarray(state.speed[b], dtype=np.float64),
        L0,
        acc0,
    )


def _evaluate(params: ManeuverParams, row: tuple[FloatArray, ...], path: FloatArray,
              actions: FloatArray) -> EpisodeReturns:  # fmt: skip
    S, T, K = actions.shape[:3]
    ret, log_final = np.empty(S), np.empty(S)
    ranges, ended = np.empty((S, T, K)), np.empty(S, dtype=np.int64)
    returns_kernel(
        params.kernel_constants, *row, np.ascontiguousarray(path), np.ascontiguousarray(actions),
        ret, log_final, ranges, ended,
    )  # fmt: skip
    return EpisodeReturns(ret, log_final, ranges, ended)


def _as_paths(params: ManeuverParams, state: ManeuverState, paths: ArrayLike | None,
              steps: int | None, rng: np.random.Generator | None) -> FloatArray:  # fmt: skip
    if paths is None:
        if steps is None:
            raise ValueError("steps: needed when paths is not given")
        return target_paths(params, state, steps, rng)
    p = np.asarray(paths, dtype=np.float64)
    if p.ndim != 3 or p.shape[0] != state.batch_size or p.shape[2] != STATE_DIM or p.shape[1] < 2:
        raise ValueError(f"paths: expected shape ({state.batch_size}, T + 1, 4), got {p.shape}")
    if not np.allclose(p[:, 0], state.target, rtol=0.0, atol=1e-9):
        raise ValueError("paths: the first target state is not the state's")
    return p


def _as_actions(a: ArrayLike, B: int, T: int, K: int, name: str) -> FloatArray:
    """An action sequence as ``(B, T, K, 2)``: from ``(B, T', K, 2)``, ``(B, T', 2)`` (one
    platform, or the joint ``(B, T', 2K)``), or one shared ``(T', K, 2)`` / ``(T', 2)``;
    ``T' ≤ T`` (a policy whose episode ended early), padded with zeros; clipped to
    ``[−1, 1]`` (the env clips; the flight is the same)."""
    x = np.asarray(a, dtype=np.float64)
    if not np.all(np.isfinite(x)):
        raise ValueError(f"{name}: contains NaN or infinite values")
    if x.ndim == 2 and x.shape[1] == 2 * K:  # one joint sequence (T', 2K) for every scenario
        x = x.reshape(x.shape[0], K, 2)
    elif x.ndim == 3 and x.shape[0] == B and x.shape[2] == 2 * K:
        x = x.reshape(B, x.shape[1], K, 2)
    elif x.ndim == 3:
        x = np.broadcast_to(x[None], (B, *x.shape))
    if x.ndim != 4 or x.shape[0] != B or x.shape[2] != K or x.shape[3] != 2 or x.shape[1] > T:
        raise ValueError(f"{name}: expected ({B}, <= {T}, {K}, 2) or a shared sequence, got "
                         f"{np.shape(a)}")  # fmt: skip
    out = np.zeros((B, T, K, 2))
    out[:, : x.shape[1]] = np.clip(x, -1.0, 1.0)
    return out


def episode_returns(
    params: ManeuverParams,
    state: ManeuverState,
    actions: ArrayLike,
    paths: ArrayLike | None = None,
    steps: int | None = None,
    rng: np.random.Generator | None = None,
    prior_factor: ArrayLike | None = None,
) -> list[EpisodeReturns]:
    """The env's returns of action sequences ``actions (S, B, T, K, 2)`` (``S`` sequences per
    scenario; each as :func:`hindsight_optimum`'s starts) on the episodes that start at
    ``state`` with target ``paths (B, T + 1, 4)`` (or :func:`target_paths` of ``steps`` and
    ``rng``): one :class:`EpisodeReturns` per scenario."""
    p = _as_paths(params, state, paths, steps, rng)
    B, T, K = state.batch_size, p.shape[1] - 1, state.heading.shape[1]
    seqs = [_as_actions(a, B, T, K, "actions") for a in actions]
    L = _as_prior(prior_factor, B)
    out = []
    for b in range(B):
        acts = np.stack([s[b] for s in seqs]) if seqs else np.zeros((0, T, K, 2))
        out.append(_evaluate(params, _row(state, b, L, params, p[b]), p[b], acts))
    return out


def _as_prior(prior_factor: ArrayLike | None, B: int) -> FloatArray | None:
    if prior_factor is None:
        return None
    L = np.asarray(prior_factor, dtype=np.float64)
    try:
        return np.broadcast_to(L, (B, STATE_DIM, STATE_DIM))
    except ValueError:
        raise ValueError(f"prior_factor: expected (4, 4) or ({B}, 4, 4), got {L.shape}") from None


@contextlib.contextmanager
def one_blas_thread() -> Iterator[None]:
    """OpenBLAS on one thread (this thread only) while SLSQP runs: its least-squares steps on a
    few dozen variables are cheap, and OpenBLAS's thread hand-off on a loaded machine can cost
    more than the whole optimisation. Uses the wheels' bundled OpenBLAS
    ``openblas_set_num_threads_local``; a no-op where it is not found."""
    restore = []
    try:
        import numpy as _np
        import scipy as _sp

        for pkg in (_sp, _np):
            libs = Path(pkg.__file__).parent.parent / f"{pkg.__name__}.libs"
            for lib in libs.glob("*openblas*.so*"):
                f = getattr(ctypes.CDLL(str(lib)), "openblas_set_num_threads_local", None)
                if f is not None:
                    f.restype, f.argtypes = ctypes.c_int, [ctypes.c_int]
                    restore.append((f, f(1)))
    except OSError:  # pragma: no cover - a platform without the bundled library
        pass
    try:
        yield
    finally:
        for f, old in restore:
            f(old)


@dataclass(frozen=True)
class HindsightOptimum:
    """:func:`hindsight_optimum` of ``B`` scenarios (see the module docstring for what is
    guaranteed)."""

    value: FloatArray
    """The best return found ``(B,)``: the env's exact return of :attr:`actions` (with
    ``prior_factor``, ``ln m(P_0) − ln m(P_T)`` of that prior). At least every start's."""
    actions: FloatArray
    """Its action sequence ``(B, T, K, 2)`` in ``[−1, 1]``: play it in the env."""
    start_values: FloatArray
    """The returns of the starts given ``(B, S)`` (``S`` may be 0)."""
    best_start: FloatArray
    """The best return over every starting point ``(B,)``: the starts given and the random
    restarts' initial sequences."""
    gain: FloatArray
    """``value − best_start`` ``(B,)``: what the optimisation added (≥ 0)."""
    standoff_ok: BoolArray
    """Whether :attr:`actions` keeps the stand-off at every step ``(B,)``."""
    closest: FloatArray
    """Its closest approach of a platform to the target over the steps ``(B,)`` (m)."""
    final_bound: FloatArray
    """``m(P_T)`` of :attr:`actions` after ``T`` steps ``(B,)`` (m for the position metric)."""
    initial_bound: FloatArray
    """``m(P_0)`` ``(B,)``."""


class _Probe:
    """The smooth problem at a point of the active variables: ``ln m(P_T)`` (minimised) and the
    stand-off margins ``(r − min_range (1 + slack)) / scale`` (≥ 0), with central-difference
    derivatives from one batched rollout of ``2n + 1`` sequences (cached per point, as SLSQP
    asks for both and both Jacobians there). Tracks the best exact return of every sequence it
    rolled out."""

    def __init__(self, params: ManeuverParams, row: tuple[FloatArray, ...], path: FloatArray,
                 base: FloatArray, mask: BoolArray) -> None:  # fmt: skip
        self.params, self.row, self.path = params, row, path
        self.base, self.mask = base, mask  # the fixed entries, which entries vary
        self.floor = params.min_range * (1.0 + STANDOFF_SLACK)
        self.scale = max(params.min_range, 1.0)
        self.u: FloatArray | None = None
        self.best_value = -np.inf
        self.best_actions: FloatArray | None = None

    def _actions(self, U: FloatArray) -> FloatArray:
        A = np.broadcast_to(self.base, (U.shape[0], *self.base.shape)).copy()
        A[:, self.mask] = U
        return A

    def _run(self, U: FloatArray) -> EpisodeReturns:
        A = self._actions(U)
        res = _evaluate(self.params, self.row, self.path, A)
        i = int(np.argmax(res.value))
        if res.value[i] > self.best_value:
            self.best_value, self.best_actions = float(res.value[i]), A[i].copy()
        return res

    def at(self, u: FloatArray) -> _Probe:
        if self.u is None or not np.array_equal(u, self.u):
            res = self._run(u[None])
            self.u = u.copy()
            self.f = float(res.log_final[0])
            self.g = ((res.ranges[0] - self.floor) / self.scale).reshape(-1)
            self.df: FloatArray | None = None
            self.dg: FloatArray | None = None
        return self

    def slopes(self, u: FloatArray) -> _Probe:
        self.at(u)
        if self.df is None:
            n = u.size
            # the stencil stays inside [−1, 1]: actions are clipped there (a one-sided
            # difference at the bounds, not half the slope)
            up = np.minimum(u + FD_STEP, 1.0)
            dn = np.maximum(u - FD_STEP, -1.0)
            eye = np.eye(n, dtype=bool)
            U = np.concatenate([np.where(eye, up, u), np.where(eye, dn, u)])
            res = self._run(U)
            width = up - dn
            g = (res.ranges - self.floor).reshape(2 * n, -1) / self.scale
            self.df = (res.log_final[:n] - res.log_final[n:]) / width
            self.dg = ((g[:n] - g[n:]) / width[:, None]).T
        return self


def _random_start(rng: np.random.Generator, T: int, K: int, legs: int = 4) -> FloatArray:
    """A random piecewise-constant sequence ``(T, K, 2)``: ``legs`` legs per platform and
    entry, uniform commands in ``[−1, 1]``."""
    out = np.empty((T, K, 2))
    for k in range(K):
        for j in range(2):
            n = min(legs, T)
            cuts = np.sort(rng.choice(np.arange(1, T), size=n - 1, replace=False)) if n > 1 else []
            out[:, k, j] = np.repeat(rng.uniform(-1.0, 1.0, n), np.diff([0, *cuts, T]))
    return out


def _polish(probe: _Probe, u0: FloatArray, standoff: bool, maxiter: int) -> None:
    """SLSQP from ``u0``: minimise ``ln m(P_T)`` in the box ``[−1, 1]`` subject to the
    stand-off at every step (when ``standoff``; the probe keeps the best point it sees)."""
    constraints = []
    if standoff:
        constraints = [
            {
                "type": "ineq",
                "fun": lambda u: probe.at(u).g,
                "jac": lambda u: probe.slopes(u).dg,
            }
        ]
    minimize(
        lambda u: probe.at(u).f,
        u0,
        jac=lambda u: probe.slopes(u).df,
        method="SLSQP",
        bounds=[(-1.0, 1.0)] * u0.size,
        constraints=constraints,
        options={"maxiter": maxiter, "ftol": 1e-10},
    )


def hindsight_optimum(
    params: ManeuverParams,
    state: ManeuverState,
    starts: Sequence[ArrayLike] = (),
    restarts: int = 4,
    seed: int = 0,
    paths: ArrayLike | None = None,
    steps: int | None = None,
    rng: np.random.Generator | None = None,
    polish: int | None = None,
    maxiter: int = 100,
    prior_factor: ArrayLike | None = None,
) -> HindsightOptimum:
    """The hindsight optimum of the episodes that start at ``state`` (a reset state, batch
    ``B``): the best action sequence of each, knowing its whole target path, under the env's
    own limits and stand-off (module docstring: what is guaranteed).

    ``starts``: action sequences to start from, each ``(B, T', K, 2)`` (or ``(B, T', 2K)``, or
    one ``(T', K, 2)`` / ``(T', 2)`` for every scenario; ``T' ≤ T``, padded with zeros), e.g.
    what each benchmarked policy played; the result is at least each one's return.
    ``restarts``: random piecewise-constant starts per scenario (``seed``). ``polish``: run the
    optimiser from only the ``polish`` best starts of each scenario (all: ``None``; every start
    is still evaluated and kept). The target's path: ``paths (B, T + 1, 4)``, or
    :func:`target_paths` of ``steps`` with ``rng`` (the env's generator at ``state``).
    ``prior_factor``: a square root ``(4, 4)`` or ``(B, 4, 4)`` of another prior ``P_0``
    (default the env's, ``state.bound_factor``)."""
    if restarts < 0:
        raise ValueError(f"restarts: must be >= 0, got {restarts}")
    p = _as_paths(params, state, paths, steps, rng)
    B, T, K = state.batch_size, p.shape[1] - 1, state.heading.shape[1]
    seqs = [_as_actions(a, B, T, K, f"starts[{i}]") for i, a in enumerate(starts)]
    if not seqs and restarts == 0:
        raise ValueError("starts: give at least one start or restarts >= 1")
    L = _as_prior(prior_factor, B)
    w = params.world
    # the entries that act: turns when ω_max > 0, speed changes when Δv_max > 0
    active = np.array([w.max_turn_rate > 0.0, w.max_speed_change > 0.0])
    mask = np.broadcast_to(active, (T, K, 2))
    gen = np.random.default_rng(seed)
    out = {n: [] for n in ("value", "actions", "start", "best_start", "ok", "closest",
                           "final", "initial")}  # fmt: skip
    for b in range(B):
        row = _row(state, b, L, params, p[b])
        given = np.stack([s[b] for s in seqs]) if seqs else np.zeros((0, T, K, 2))
        randoms = np.stack([_random_start(gen, T, K) for _ in range(restarts)]) if restarts else (
            np.zeros((0, T, K, 2)))  # fmt: skip
        randoms[:, ~mask] = 0.0
        every = np.concatenate([given, randoms])
        first = _evaluate(params, row, p[b], every)
        base = np.zeros((T, K, 2))
        probe = _Probe(params, row, p[b], base, mask)
        # the starts are points evaluated: the best of them is the floor of the result
        i0 = int(np.argmax(first.value))
        probe.best_value, probe.best_actions = float(first.value[i0]), every[i0].copy()
        # the smooth objective ranks the starts to polish: ln m(P_T), feasible ones first
        order = np.lexsort((first.log_final, ~first.standoff_ok))
        chosen = order if polish is None else order[:polish]
        for j in chosen:
            with one_blas_thread():
                _polish(probe, every[j][mask], params.min_range > 0.0, maxiter)
        best = probe.best_actions
        assert best is not None
        final = _evaluate(params, row, p[b], best[None])
        out["value"].append(float(final.value[0]))
        out["actions"].append(best)
        out["start"].append(first.value[: len(given)])
        out["best_start"].append(float(first.value.max()))
        out["ok"].append(bool(final.standoff_ok[0]))
        out["closest"].append(float(final.ranges[0].min()))
        out["final"].append(math.exp(final.log_final[0]))
        out["initial"].append(row[4])
    value = np.array(out["value"])
    best_start = np.array(out["best_start"])
    return HindsightOptimum(
        value=value,
        actions=np.stack(out["actions"]),
        start_values=np.stack(out["start"]) if seqs else np.zeros((B, 0)),
        best_start=best_start,
        gain=value - best_start,
        standoff_ok=np.array(out["ok"]),
        closest=np.array(out["closest"]),
        final_bound=np.array(out["final"]),
        initial_bound=np.array(out["initial"]),
    )


#: the benchmark's search per episode: random restarts beside the policies' own sequences, and
#: how many of all the starts SLSQP polishes (the best by the smooth objective)
BENCHMARK_RESTARTS = 2
BENCHMARK_POLISH = 2


def benchmark_episode(
    params: ManeuverParams, seed: int, slot: int, episode: int, steps: int
) -> tuple[ManeuverState, FloatArray]:
    """The reset state (batch 1) and the target path ``(1, steps + 1, 4)`` of a benchmark
    episode: slot ``slot``'s ``episode``-th under ``reset(seed=seed)`` of a vector env with one
    random stream per episode (:mod:`sensorgym.envs.shells.streams`), rebuilt from that
    stream alone — its reset's draws, then its steps' (which no action moves)."""
    from sensorgym.envs.shells.streams import RowGenerator, episode_generator

    rng = RowGenerator([episode_generator(seed, slot, episode)])
    state = simulation.reset(params, rng, 1)
    return state, target_paths(params, state, steps, rng)


def benchmark_bounds(
    params: ManeuverParams,
    seed: int,
    keys: Sequence[tuple[int, int]],
    played: Sequence[Sequence[ArrayLike]],
    steps: int,
    restarts: int = BENCHMARK_RESTARTS,
    polish: int | None = BENCHMARK_POLISH,
) -> tuple[FloatArray, FloatArray]:
    """The hindsight optimum of every benchmark episode ``keys[e] = (slot, number)`` (seed
    ``seed``, :func:`benchmark_episode`), started from every policy's own actions on it —
    ``played[p][e]``, ``(steps', K, 2)`` or ``(steps', 2K)`` as the env took them — and from
    ``restarts`` random sequences: ``(value, gain)``, each ``(E,)``. ``value`` is at least every
    policy's return on the episode, by construction (module docstring); ``gain`` is what the
    optimiser added over the best start."""
    value, gain = np.empty(len(keys)), np.empty(len(keys))
    for e, (slot, number) in enumerate(keys):
        state, path = benchmark_episode(params, seed, slot, number, steps)
        K = state.heading.shape[1]
        starts = [np.asarray(p[e], dtype=np.float64).reshape(1, -1, K, 2) for p in played]
        res = hindsight_optimum(
            params, state, starts, restarts=restarts, seed=seed + e, paths=path, polish=polish
        )
        value[e], gain[e] = res.value[0], res.gain[0]
    return value, gain
