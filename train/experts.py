"""Experts for imitation pre-training, and behaviour cloning (with DAgger) before RL.

A run's ``pretrain`` (a run key of ``hyperparams/<algo>.yml``) names an expert of
:data:`EXPERTS` and how long to imitate it:

====================  =====================================================================
key                   meaning
====================  =====================================================================
``expert``            a name in :data:`EXPERTS`, or ``rule:<name>``: a rule registered for
                      the env (:mod:`sensorgym.agents.registry`; acts in the env's own
                      action space, so only for runs without an action wrapper)
``steps``             transitions collected per round (over all slots of the training env)
``rounds``            data-collection rounds (default 1: plain behaviour cloning). Round 1
                      follows the expert; every later round follows the current student and
                      labels the states it visits with the expert's action (DAgger, Ross,
                      Gordon & Bagnell 2011), aggregating all rounds' data
``epochs``            passes over the aggregated data after each round (default 10)
``batch_size``        minibatch size (default 256)
``learning_rate``     Adam step size (default 1e-3)
``fit_log_std``       also fit a Gaussian policy's log standard deviation (default false: it
                      keeps its initial value, so RL fine-tuning still explores)
====================  =====================================================================

The policy's action distribution is fitted by maximum likelihood of the expert's actions
(for SAC: its deterministic action to the expert's, in squashed units) and an actor-critic's
value head to the discounted returns of the collected episodes, so RL starts from the expert's
behaviour with a matching critic.

An expert factory takes the (wrapped) SB3 training env and returns a predictor with SB3's
``predict(obs, state=None, episode_start=None, deterministic=True)`` acting in that env's
spaces. A teacher may see the truth (``evaluation.simulator_state(env)()``): the student sees only
its observation, so what it learns is a fieldable policy.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from functools import partial
from importlib import import_module
from typing import Any

import numpy as np
import torch as th
from stable_baselines3 import SAC
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.policies import ActorCriticPolicy
from stable_baselines3.common.vec_env import VecEnv

from sensorgym.train.wrappers import base_env, base_observation

#: expert name → ``"sensorgym.<module>:<factory>"``, factory ``(env: VecEnv) -> predictor``
EXPERTS: dict[str, str] = {
    "pointing-truth-plan": "sensorgym.train.env_wrappers.stereo_pointing:truth_plan_expert",
    "pointing-plan-estimate": "sensorgym.train.env_wrappers.stereo_pointing:plan_estimate_expert",
    "pointing-orthogonal-pairs": "sensorgym.train.env_wrappers.stereo_pointing:orthogonal_pairs_expert",
    "plan-choice-estimate": "sensorgym.train.env_wrappers.stereo_pointing:plan_choice_expert",
    "plan-horizon-choice": "sensorgym.train.env_wrappers.stereo_pointing:PlanHorizonExpert",
    "placement-truth-target": "sensorgym.train.env_wrappers.stereo_placement:truth_target",
    "scan-entry-search": "sensorgym.train.env_wrappers.stereo_scanning:entry_search_expert",
    "gimbal-truth-aim": "sensorgym.train.env_wrappers.gimbal_tracking:truth_aim",
    "gimbal-truth-centre": "sensorgym.train.env_wrappers.gimbal_tracking:truth_centre",
    "gimbal-truth-hop": "sensorgym.train.env_wrappers.gimbal_search:truth_hop",
}

#: an expert named ``rule:<name>`` is the rule registered as ``<name>`` for the env
RULE_PREFIX = "rule:"


def _registered_rule(rule: str, env: VecEnv) -> Any:
    """The rule registered as ``rule`` for the env under ``env`` (built like the benchmark's)."""
    from sensorgym.agents.registry import RULES
    from sensorgym.train.evaluation import env_params, simulator_state

    env_id = env.get_attr("env_id")[0]
    if rule not in RULES.get(env_id, {}):
        known = sorted(RULES.get(env_id, {}))
        raise KeyError(f"pretrain: no rule {rule!r} for {env_id}; known: {known}")
    if env.action_space != base_env(env).action_space:
        raise ValueError(
            f"pretrain: rule {rule!r} acts in {env_id}'s own action space, but the run's "
            f"wrappers change it to {env.action_space}: register an expert for the wrapper"
        )
    return _OnBaseView(RULES[env_id][rule](env_params(env), simulator_state(env)), env)


class _OnBaseView:
    """A rule acting on the env's own observation under observation wrappers."""

    def __init__(self, rule: Any, env: VecEnv):
        self.rule, self.env = rule, env

    def predict(self, observation: np.ndarray, **kwargs: Any) -> tuple[np.ndarray, Any]:
        return self.rule.predict(base_observation(self.env, observation), **kwargs)


@dataclass(frozen=True)
class Pretrain:
    """A checked ``pretrain`` entry (see the module docstring for the keys)."""

    expert: str
    """A name in :data:`EXPERTS`, or ``rule:<name>`` (a registered rule of the env)."""
    steps: int
    """Transitions collected per round."""
    rounds: int = 1
    """Collection rounds (1: behaviour cloning; more: DAgger)."""
    epochs: int = 10
    """Passes over the aggregated data after each round."""
    batch_size: int = 256
    """Minibatch size."""
    learning_rate: float = 1e-3
    """Adam step size."""
    fit_log_std: bool = False
    """Also fit a Gaussian policy's log standard deviation."""

    @classmethod
    def from_config(cls, entry: Any) -> Pretrain:
        """A :class:`Pretrain` from a config mapping, or ``ValueError`` saying what is wrong."""
        if not isinstance(entry, Mapping):
            raise ValueError(f"pretrain: expected a mapping, got {entry!r}")
        unknown = set(entry) - set(cls.__dataclass_fields__)
        if unknown:
            raise ValueError(f"pretrain: unknown keys {sorted(unknown)}")
        try:
            p = cls(**entry)
        except TypeError as exc:
            raise ValueError(f"pretrain: {exc}") from None
        if not isinstance(p.expert, str) or not (
            p.expert in EXPERTS or p.expert.startswith(RULE_PREFIX)
        ):
            raise ValueError(
                f"pretrain: expert {p.expert!r} is neither one of {sorted(EXPERTS)} nor "
                f"{RULE_PREFIX}<registered rule>"
            )
        for key in ("steps", "rounds", "epochs", "batch_size"):
            if not isinstance(getattr(p, key), int) or getattr(p, key) < 1:
                raise ValueError(
                    f"pretrain: {key} must be an integer >= 1, got {getattr(p, key)!r}"
                )
        if not p.learning_rate > 0:
            raise ValueError(f"pretrain: learning_rate must be > 0, got {p.learning_rate!r}")
        return p


def expert_factory(name: str) -> Callable[[VecEnv], Any]:
    """The factory registered as ``name`` in :data:`EXPERTS`, or for ``rule:<rule>`` one that
    builds that registered rule for the env; ``KeyError`` lists the names."""
    if name.startswith(RULE_PREFIX):
        return partial(_registered_rule, name.removeprefix(RULE_PREFIX))
    if name not in EXPERTS:
        raise KeyError(f"expert {name!r} is not one of {sorted(EXPERTS)}")
    module, _, attr = EXPERTS[name].partition(":")
    return getattr(import_module(module), attr)


@dataclass(frozen=True)
class Demonstrations:
    """Observations visited, the expert's actions there, and discounted returns-to-go."""

    observations: np.ndarray
    actions: np.ndarray
    returns: np.ndarray


def collect(
    env: VecEnv,
    expert: Any,
    steps: int,
    gamma: float,
    student: BaseAlgorithm | None = None,
) -> Demonstrations:
    """Roll out ``student`` (or, without one, ``expert``) on ``env`` for at least ``steps``
    transitions and label every visited observation with the expert's deterministic action.

    Returns-to-go are discounted sums of the rewards of the policy that acted, cut at episode
    ends; an episode still running when collection stops is bootstrapped with zero (its last
    steps' value targets are short: a small bias the RL phase corrects)."""
    n = env.num_envs
    horizon = -(-steps // n)
    obs = env.reset()
    start = np.ones(n, dtype=bool)
    expert_state = student_state = None
    observations, actions, rewards, dones = [], [], [], []
    for _ in range(horizon):
        label, expert_state = expert.predict(
            obs, state=expert_state, episode_start=start, deterministic=True
        )
        act = label
        if student is not None:
            act, student_state = student.predict(
                obs, state=student_state, episode_start=start, deterministic=False
            )
        observations.append(np.array(obs, copy=True))
        actions.append(np.array(label, copy=True))
        obs, reward, done, _ = env.step(act)
        rewards.append(np.asarray(reward, dtype=np.float64))
        dones.append(np.asarray(done, dtype=bool))
        start = dones[-1]
    returns = np.zeros((horizon, n))
    running = np.zeros(n)
    for t in range(horizon - 1, -1, -1):
        running = rewards[t] + gamma * running * ~dones[t]
        returns[t] = running
    return Demonstrations(
        np.concatenate(observations),
        np.concatenate(actions),
        returns.reshape(-1),
    )


def fit(model: BaseAlgorithm, data: Demonstrations, config: Pretrain, seed: int) -> float:
    """Fit ``model``'s policy to ``data`` for ``config.epochs`` passes; the last epoch's mean
    loss (negative log-likelihood, or squared error for SAC, plus the value loss)."""
    policy = model.policy
    policy.set_training_mode(True)
    params = [p for name, p in policy.named_parameters() if config.fit_log_std or name != "log_std"]
    if isinstance(model, SAC):
        params = list(policy.actor.parameters())
    optimizer = th.optim.Adam(params, lr=config.learning_rate)
    rng = np.random.default_rng(seed)
    obs_t = th.as_tensor(data.observations, dtype=th.float32)
    act_np = data.actions
    if isinstance(model, SAC):
        act_np = policy.scale_action(
            np.clip(act_np, model.action_space.low, model.action_space.high)
        )
    act_t = th.as_tensor(act_np)
    ret_t = th.as_tensor(data.returns, dtype=th.float32)
    size = len(obs_t)
    last = float("nan")
    for _ in range(config.epochs):
        order = rng.permutation(size)
        losses = []
        for lo in range(0, size, config.batch_size):
            idx = th.as_tensor(order[lo : lo + config.batch_size])
            obs, act = obs_t[idx], act_t[idx]
            if isinstance(policy, ActorCriticPolicy):
                values, log_prob, _ = policy.evaluate_actions(obs, act)
                loss = -log_prob.mean() + 0.5 * ((values.flatten() - ret_t[idx]) ** 2).mean()
            elif isinstance(model, SAC):
                loss = ((policy.actor(obs, deterministic=True) - act.float()) ** 2).mean()
            else:
                raise ValueError(f"pretrain: {type(model).__name__} is not supported")
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
            losses.append(loss.item())
        last = float(np.mean(losses))
    policy.set_training_mode(False)
    return last


def pretrain(model: BaseAlgorithm, env: VecEnv, config: Pretrain, seed: int) -> list[float]:
    """Behaviour cloning (``rounds`` = 1) or DAgger of ``config.expert`` into ``model`` on
    ``env``; the loss after each round."""
    expert = expert_factory(config.expert)(env)
    gamma = float(getattr(model, "gamma", 0.99))
    parts: list[Demonstrations] = []
    losses = []
    for round_ in range(config.rounds):
        student = None if round_ == 0 else model
        parts.append(collect(env, expert, config.steps, gamma, student))
        data = Demonstrations(
            np.concatenate([p.observations for p in parts]),
            np.concatenate([p.actions for p in parts]),
            np.concatenate([p.returns for p in parts]),
        )
        losses.append(fit(model, data, config, seed + round_))
    return losses
