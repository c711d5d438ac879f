"""A stand-off shield for the platform-manoeuvre envs — lab code of issue 37 item 3 (negative:
see README.md, "A stand-off shield"). Not part of the package.

Run the sensorgym CLI with the ``standoff-shield`` wrapper registered (training and probes)::

    PYTHONPATH=research/book_training python research/book_training/shield.py train \
        --env sensorgym/BearingsManeuverBook-v0 --algo ppo --seed 0 --out RUNS --no-progress \
        --hyperparam "wrappers=[{name: standoff-shield, kappa: 0.5, max_episode_steps: 32},
                                {name: time-feature, max_episode_steps: 32}]" \
        --hyperparam "training_wrappers=[{name: termination-penalty, penalty: 5.0}]"
    PYTHONPATH=research/book_training python research/book_training/shield.py probe NAME=RUN ...

The shield is a safety filter between any policy and the env
(``sensorgym/BearingsManeuver-v0``, ``sensorgym/BearingsManeuverBook-v0``).
Coming within ``min_range`` of the target ends the episode with a penalty. A policy that learns
to fly close (where the bearings say most about range) meets the stand-off now and then: the
closer the pass, the more a small error of the estimate matters. The shield keeps the
policy's command whenever it can prove, on the tracker's estimate, that a way out remains, and
otherwise takes the admissible turn nearest to the one asked for (Alshiekh et al., "Safe
reinforcement learning via shielding", AAAI 2018; the backup-policy form of Hobbs et al.,
"Runtime assurance for safety-critical systems", 2023).

The proof, per scenario, on the estimated world (:func:`sensorgym.agents.bearings_maneuver.estimate_frame`;
the target moves on at its estimated velocity)::

    fly one step with the command, then fly the escape law for the remaining steps
    (at most ``horizon``): turn at full rate towards the heading straight away from the
    estimated target, at full speed;
    the command is admissible when every step end keeps  r_t ≥ min_range + margin + κ σ_r

``σ_r`` is the estimate's largest position standard deviation one step ahead
(:func:`sensorgym.agents.bearings_mpc.standoff_range`, the ``mpc-estimate`` rule's margin). The env checks the
stand-off at step ends, so the proof does too; steps after the episode's end are not checked
(at the last step only the step itself must keep the stand-off). When no command on the grid is
admissible the shield takes the one with the largest clearance.

The shield reads only the observation and the time left: a shielded policy is as fieldable as
the policy. It is a deterministic function of its inputs.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray
from stable_baselines3.common.vec_env import VecEnv

from sensorgym.agents.bearings_maneuver import estimate_frame, platform_views
from sensorgym.agents.bearings_mpc import standoff_range
from sensorgym.envs.bearings_maneuver.simulation import ManeuverParams
from sensorgym.envs.worlds.platform import fly
from sensorgym.train.wrappers import WRAPPERS, EpisodeSteps, ObservedActionWrapper, time_limit_of

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class StandoffShield:
    """Filter a policy's commands so that, on the estimate, the stand-off can always be kept
    (module docstring). Single platform only (``params.platforms == 1``)."""

    params: ManeuverParams = field(default_factory=ManeuverParams)
    """Env settings (kinematics, normalisation scales, ``min_range``)."""
    margin: float = 0.0
    """Kept beyond ``min_range`` on the estimated path (m)."""
    kappa: float = 2.0
    """Standard deviations ``σ_r`` of the estimated range kept beyond that."""
    horizon: int = 8
    """Steps of the escape law checked after the commanded step."""
    turns: int = 41
    """Turn commands on the grid ``linspace(−1, 1, turns)`` the shield may substitute."""

    def __post_init__(self) -> None:
        if self.params.platforms != 1:
            raise ValueError(
                f"StandoffShield: one platform only, got platforms={self.params.platforms}"
            )
        for name in ("horizon", "turns"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
                raise ValueError(f"{name}: must be an integer >= 1, got {value!r}")
        if self.turns < 2:
            raise ValueError(f"turns: the grid needs at least 2 commands, got {self.turns}")
        for name in ("margin", "kappa"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float) or not (
                np.isfinite(value) and value >= 0.0
            ):  # fmt: skip
                raise ValueError(f"{name}: must be a finite number >= 0, got {value!r}")

    def clearance(self, observation: NDArray, commands: NDArray, steps_left: NDArray) -> FloatArray:
        """The smallest ``r_t − (min_range + margin + κ σ_r)`` over the commanded step and the
        escape that follows, ``(N, C)`` m, for observations ``(N, obs_dim)``, commands
        ``(N, C, 2)`` in ``[−1, 1]`` and the steps left in each episode ``(N,)`` (≥ 1)."""
        p, w = self.params, self.params.world
        obs = np.asarray(observation, dtype=np.float64)
        n, C = commands.shape[:2]
        pos, heading, speed, target, L = estimate_frame(p, platform_views(p, obs))
        need = standoff_range(p, L, self.margin, self.kappa)[:, None]  # (N, 1)
        x = np.broadcast_to(pos[:, 0][:, None], (n, C, 2))
        h = np.broadcast_to(heading[:, 0][:, None], (n, C))
        v = np.broadcast_to(speed[:, 0][:, None], (n, C))
        x, h, v = fly(x, h, v, np.clip(commands, -1.0, 1.0), w)
        tx = target[:, None, :2] + w.dt * target[:, None, 2:]
        worst = np.hypot(*np.moveaxis(tx - x, -1, 0)) - need
        left = np.asarray(steps_left, dtype=np.int64)[:, None]
        escape = np.empty((n, C, 2))
        for t in range(1, self.horizon + 1):
            # the escape law: full rate towards the heading away from the target, full speed
            dx, dy = np.moveaxis(x - tx, -1, 0)
            off = np.angle(np.exp(1j * (np.arctan2(dx, dy) - h)))
            escape[..., 0] = off / (w.max_turn_rate * w.dt) if w.max_turn_rate > 0.0 else 0.0
            escape[..., 1] = 1.0
            x, h, v = fly(x, h, v, np.clip(escape, -1.0, 1.0), w)
            tx = tx + w.dt * target[:, None, 2:]
            r = np.hypot(*np.moveaxis(tx - x, -1, 0)) - need
            worst = np.where(left > t, np.minimum(worst, r), worst)
        return worst

    def filter(self, observation: NDArray, actions: NDArray, steps_left: NDArray) -> FloatArray:
        """The shielded actions ``(N, 2)``: each row's own action when it is admissible, else
        the admissible grid turn nearest to its turn (its speed command kept), else the grid
        turn with the largest clearance."""
        a = np.clip(np.asarray(actions, dtype=np.float64).reshape(-1, 2), -1.0, 1.0)
        n = a.shape[0]
        grid = np.linspace(-1.0, 1.0, self.turns)
        commands = np.empty((n, self.turns + 1, 2))
        commands[:, 0] = a
        commands[:, 1:, 0] = grid
        commands[:, 1:, 1] = a[:, 1:2]
        clear = self.clearance(observation, commands, steps_left)
        out = a.copy()
        for i in np.flatnonzero(clear[:, 0] < 0.0):
            ok = clear[i, 1:] >= 0.0
            if ok.any():
                distance = np.where(ok, np.abs(grid - a[i, 0]), np.inf)
                out[i, 0] = grid[int(np.argmin(distance))]
            else:
                out[i, 0] = grid[int(np.argmax(clear[i, 1:]))]
        return out


class ShieldedAction(ObservedActionWrapper):
    """The policy's action, filtered by :class:`StandoffShield` with ``margin`` (m), ``kappa``,
    ``horizon`` and ``turns`` (its fields); the time left comes from ``max_episode_steps``
    (default: the env's time limit)."""

    def __init__(
        self,
        venv: VecEnv,
        margin: float = 0.0,
        kappa: float = 2.0,
        horizon: int = 8,
        turns: int = 41,
        max_episode_steps: int | None = None,
    ):
        super().__init__(venv, venv.action_space)
        limit = max_episode_steps or time_limit_of(venv)
        if not isinstance(limit, int | np.integer) or limit < 1:
            raise ValueError(f"standoff-shield: needs an env with a time limit, got {limit!r}")
        self.limit = int(limit)
        params = venv.get_attr("params")[0]
        self.shield = StandoffShield(params, margin, kappa, horizon, turns)
        self._steps = EpisodeSteps(venv.num_envs)
        self.replaced = 0
        """How many actions the shield has replaced since the wrapper was made."""

    def env_action(self, actions: NDArray[Any], obs: NDArray[Any]) -> NDArray[Any]:
        a = np.asarray(actions, dtype=np.float64).reshape(self.num_envs, 2)
        out = self.shield.filter(obs, a, np.maximum(self.limit - self._steps.t, 1))
        self.replaced += int(np.count_nonzero(np.any(out != np.clip(a, -1.0, 1.0), axis=1)))
        return out

    def reset(self) -> np.ndarray:
        self._steps.reset()
        return super().reset()

    def step_wait(self) -> Any:
        obs, rewards, dones, infos = super().step_wait()
        self._steps.step(dones)
        return obs, rewards, dones, infos


WRAPPERS["standoff-shield"] = "shield:ShieldedAction"

if __name__ == "__main__":
    if sys.argv[1:2] == ["probe"]:
        import probe

        sys.argv = [sys.argv[0], *sys.argv[2:]]
        probe.main()
    else:
        from sensorgym.cli.main import main

        sys.exit(main(sys.argv[1:]))
