"""Augmented Random Search (Mania, Guy & Recht 2018, "Simple random search provides a
competitive approach to reinforcement learning", algorithm V1-t) over a policy's small search
vector, every perturbation scored on the same seeded scenarios: the ``ars`` algorithm of
``sensorgym train``.

Each iteration draws a scenario seed (from the run's seed, in ``[SCENARIO_SEEDS)``: never a
held-out benchmark seed nor a tuning seed) and ``n_directions`` Gaussian directions ``δ``, and
plays ``episodes`` episodes of the training env under ``θ + ν δ`` and under ``θ − ν δ``, all
with that seed. A seed replays the same scenarios and the same measurement noise under any
policy (StereoPointing draws its noise whatever the action), so the difference ``r₊ − r₋`` of
a direction is paired episode by episode (common random numbers): it is exactly zero on every
episode where the two policies act alike, and the spread of scenario to scenario, which is
far larger than the effect of a small change of policy, cancels. The update keeps the
``top_directions`` directions with the best ``max(r₊, r₋)`` and steps

    θ ← θ + α / (b σ_R) Σ_b (r₊ − r₋) δ,

``α`` the ``learning_rate``, ``σ_R`` the standard deviation of the ``2b`` returns kept (no
step when they are all equal). The policy must have a ``search_parameter()`` (the
:class:`~sensorgym.train.candidate_policy.CandidatePolicy` with ``residual: linear``: zero is
the prior rule); its other weights are never changed. The model is an SB3
:class:`~stable_baselines3.common.base_class.BaseAlgorithm`, so ``sensorgym train`` saves it
(``policy.safetensors``, no pickle) and ``benchmark``/``render --model`` load it like a PPO run.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.policies import BasePolicy
from stable_baselines3.common.type_aliases import MaybeCallback

from sensorgym.train.candidate_policy import CandidatePolicy
from sensorgym.train.cost import RunClock
from sensorgym.train.evaluation import evaluate

#: scenario seeds of the iterations are drawn from this range: above the tuning seeds (500,
#: 600) and below the held-out benchmark seeds (10000, 31337)
SCENARIO_SEEDS = (1000, 10000)


class ARS(BaseAlgorithm):
    """Augmented Random Search with paired perturbations (see the module docstring).

    ``learning_rate``: the step size ``α``; ``n_directions``: directions per iteration;
    ``top_directions``: directions used in the update (``None``: all); ``noise_std``: ``ν``;
    ``episodes``: episodes per perturbation (a multiple of the env's scenarios). An
    iteration costs ``2 · n_directions · episodes`` episodes; training runs whole iterations
    until ``total_timesteps`` env steps are spent (at least one)."""

    policy_aliases: ClassVar[dict[str, type[BasePolicy]]] = {"CandidatePolicy": CandidatePolicy}

    def __init__(
        self,
        policy: str | type[BasePolicy],
        env: Any,
        learning_rate: float = 0.02,
        n_directions: int = 8,
        top_directions: int | None = None,
        noise_std: float = 0.3,
        episodes: int = 64,
        policy_kwargs: dict[str, Any] | None = None,
        tensorboard_log: str | None = None,
        verbose: int = 0,
        seed: int | None = None,
        device: str = "cpu",
        _init_setup_model: bool = True,
    ):
        super().__init__(
            policy,
            env,
            learning_rate,
            policy_kwargs=policy_kwargs,
            tensorboard_log=tensorboard_log,
            verbose=verbose,
            device=device,
            support_multi_env=True,
            seed=seed,
            supported_action_spaces=(spaces.Discrete, spaces.MultiDiscrete),
        )
        if not (isinstance(n_directions, int) and n_directions >= 1):
            raise ValueError(f"n_directions: must be an integer >= 1, got {n_directions!r}")
        top = n_directions if top_directions is None else top_directions
        if not (isinstance(top, int) and 1 <= top <= n_directions):
            raise ValueError(f"top_directions: must lie in [1, {n_directions}], got {top!r}")
        if not (np.isfinite(noise_std) and noise_std > 0.0):
            raise ValueError(f"noise_std: must be finite and > 0, got {noise_std!r}")
        if not (isinstance(learning_rate, float | int) and learning_rate > 0.0):
            raise ValueError(f"learning_rate: must be a number > 0, got {learning_rate!r}")
        if not (isinstance(episodes, int) and episodes >= 1):
            raise ValueError(f"episodes: must be an integer >= 1, got {episodes!r}")
        if self.env is not None and episodes % self.env.num_envs:
            raise ValueError(
                f"episodes: {episodes} is not a multiple of the env's {self.env.num_envs} "
                "scenarios (every perturbation must meet the same episodes)"
            )
        self.n_directions, self.top_directions = n_directions, top
        self.noise_std, self.episodes = float(noise_std), episodes
        self.history: list[dict[str, float]] = []
        """Per iteration: its scenario seed, the mean return of the perturbations kept, the
        mean paired difference ``r₊ − r₋``, the step's norm and ``wall_s``, the seconds on
        :attr:`clock` when the iteration ended."""
        self.clock: RunClock | None = None
        """The run's clock (``sensorgym train`` sets it; else one starts with learning)."""
        if _init_setup_model:
            self._setup_model()

    def _setup_model(self) -> None:
        self._setup_lr_schedule()
        self.set_random_seed(self.seed)
        self.policy = self.policy_class(  # type: ignore[assignment]
            self.observation_space, self.action_space, self.lr_schedule, **self.policy_kwargs
        ).to(self.device)
        search = getattr(self.policy, "search_parameter", None)
        if search is None:
            raise ValueError(
                f"policy: ARS needs a policy with a search_parameter(), got {self.policy_class}"
            )
        search()  # ValueError when this policy has no search vector (a CandidatePolicy's MLP)
        self.policy.set_training_mode(False)

    @property
    def theta(self) -> np.ndarray:
        """The search vector (a copy, float64)."""
        return self.policy.search_parameter().detach().cpu().numpy().ravel().astype(np.float64)

    def set_theta(self, theta: np.ndarray) -> None:
        """Write ``theta`` into the policy's search parameter."""
        param = self.policy.search_parameter()
        with th.no_grad():
            param.copy_(th.as_tensor(np.asarray(theta), dtype=param.dtype).reshape(param.shape))

    def returns(self, theta: np.ndarray, seed: int) -> np.ndarray:
        """Per-episode returns ``(episodes,)`` of the policy at ``theta`` on the scenarios of
        ``seed`` (the search vector is restored afterwards; the steps count as training's)."""
        saved = self.theta
        self.set_theta(theta)
        try:
            stats = evaluate(self, self.env, self.episodes, seed)
            self.num_timesteps += round(stats.episodes * stats.mean_length)
            return np.array(stats.returns)
        finally:
            self.set_theta(saved)

    def learn(
        self,
        total_timesteps: int,
        callback: MaybeCallback = None,
        log_interval: int = 1,
        tb_log_name: str = "ARS",
        reset_num_timesteps: bool = True,
        progress_bar: bool = False,
    ) -> ARS:
        total_timesteps, callback = self._setup_learn(
            total_timesteps, callback, reset_num_timesteps, tb_log_name, progress_bar
        )
        if self.clock is None or self.clock.origin is None:
            self.clock = RunClock()
            self.clock.start()
        callback.on_training_start(locals(), globals())
        rng = np.random.default_rng(self.seed)
        while True:
            self._iterate(rng)
            for key in ("mean_return", "paired_difference", "step_norm"):
                self.logger.record(f"ars/{key}", self.history[-1][key])
            self.logger.dump(self.num_timesteps)
            callback.update_locals({"dones": np.zeros(0, dtype=bool), "infos": []})
            if not callback.on_step() or self.num_timesteps >= total_timesteps:
                break
        callback.on_training_end()
        return self

    def _iterate(self, rng: np.random.Generator) -> None:
        """One ARS iteration (scenario seed, directions, paired returns, step)."""
        seed = int(rng.integers(*SCENARIO_SEEDS))
        theta = self.theta
        deltas = rng.standard_normal((self.n_directions, theta.size))
        plus, minus = [], []
        for d in deltas:
            plus.append(self.returns(theta + self.noise_std * d, seed).mean())
            minus.append(self.returns(theta - self.noise_std * d, seed).mean())
        r_plus, r_minus = np.array(plus), np.array(minus)
        top = np.argsort(-np.maximum(r_plus, r_minus), kind="stable")[: self.top_directions]
        sigma = float(np.concatenate([r_plus[top], r_minus[top]]).std())
        step = np.zeros_like(theta)
        if sigma > 0.0:
            alpha = float(self.lr_schedule(1.0 - self._current_progress_remaining))
            step = alpha / (len(top) * sigma) * ((r_plus[top] - r_minus[top]) @ deltas[top])
        self.set_theta(theta + step)
        if self._total_timesteps > 0:  # within learn()
            self._update_current_progress_remaining(self.num_timesteps, self._total_timesteps)
        row = {
            "iteration": len(self.history),
            "timesteps": self.num_timesteps,
            "scenario_seed": seed,
            "mean_return": float(np.concatenate([r_plus[top], r_minus[top]]).mean()),
            "paired_difference": float(np.mean(r_plus - r_minus)),
            "step_norm": float(np.linalg.norm(step)),
            **({} if self.clock is None else {"wall_s": round(self.clock.elapsed(), 3)}),
            **{f"theta_{i}": float(v) for i, v in enumerate(theta + step)},
        }
        self.history.append(row)
