"""A candidate-scoring actor-critic for a choice among candidates described by their own
features: StereoPointing's candidate assignments under the ``plan-features`` and
``time-feature`` wrappers (:class:`~sensorgym.train.env_wrappers.stereo_pointing.PlanFeatures`).

The actor is permutation-equivariant: one small MLP, shared by every candidate, scores each
candidate from its own features (its per-step plan loss and best-plan flag at every horizon of
the features, the fraction of receivers it keeps on their drone, the time left) and the logits
of the ``Discrete`` action are the scores. To the learned score it adds ``alpha`` times a
*prior*: the ``plan-horizon`` rule's objective rebuilt from the same features (the planned
return over ``min(prior_horizon, steps left)`` plus ``prior_keep`` per receiver kept, relative
to the best candidate), ``alpha`` learned. The MLP's output layer starts at zero, so the
untrained policy's most likely action *is* the rule's choice (up to the features' float32
rounding): imitation and RL start from it and only have to learn where to deviate.

With ``residual="linear"`` the learned score is instead linear in a few named per-candidate
features (:meth:`CandidateNetworks.linear_features`: the planned-return gap to the best
candidate at every block, the best-plan flags, the receivers kept, and with ``schedule`` the
schedule block's re-acquisition evidence), its weights starting at zero: a small parameter vector whose zero point is the rule, what the ``ars`` trainer
(:mod:`sensorgym.train.ars`) searches.

The critic pools per-candidate embeddings (mean and max) and reads them with the env's own
observation and the time left.

It is an SB3 :class:`~stable_baselines3.common.policies.ActorCriticPolicy` whose extractor and
action head are replaced; :data:`sensorgym.train.config.POLICIES` registers it as
``CandidatePolicy``, so ``sensorgym train``, ``benchmark``, ``render --model`` and the shipped
policies rebuild it from a run's ``config.yaml`` (``policy`` and ``policy_kwargs``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3.common.policies import ActorCriticPolicy
from torch import nn

from sensorgym.agents.stereo_pointing_schedule import SCHEDULE_FEATURES

#: the learned score's forms: an MLP over the candidate's inputs, or linear in named features
RESIDUALS = ("mlp", "linear")
#: the linear residual's value of a best-plan flag (return units per unit weight)
LINEAR_FLAG_SCALE = 10.0


@dataclass(frozen=True)
class CandidateLayout:
    """Where each candidate's features lie in the flat observation ``[env observation |
    plan features | time left]`` of ``plan-features`` (with ``time_left``) and ``time-feature``
    over the env."""

    n_candidates: int
    """``C``: candidates (the ``Discrete`` action's size)."""
    horizons: tuple[int, ...]
    """The fixed horizons of the plan features (steps), in order; the time-left block follows."""
    base_dim: int
    """Size of the env's own observation (first in the vector)."""
    episode_steps: int
    """Episode length ``T`` (steps): the time feature ``1 − t/T`` gives ``T − t`` steps left."""
    schedule_inputs: int = 0
    """Inputs per candidate in the schedule block of ``plan-features`` with ``schedule``
    (:data:`~sensorgym.agents.stereo_pointing_schedule.SCHEDULE_FEATURES`, after the kept
    fractions; 0: none)."""

    @property
    def blocks(self) -> int:
        """Planning blocks: the fixed horizons and the time left."""
        return len(self.horizons) + 1

    @property
    def schedule_size(self) -> int:
        """Size of the schedule block."""
        return self.n_candidates * self.schedule_inputs

    @property
    def obs_dim(self) -> int:
        """Size of the observation this layout reads."""
        plan = self.n_candidates * (2 * self.blocks + 1)
        return self.base_dim + plan + self.schedule_size + 1

    def schedule_block(self, obs: th.Tensor) -> th.Tensor:
        """The schedule block ``(B, C, schedule_inputs)`` of observations ``(B, obs_dim)``."""
        start = self.base_dim + self.n_candidates * (2 * self.blocks + 1)
        block = obs[:, start : start + self.schedule_size]
        return block.reshape(obs.shape[0], self.n_candidates, self.schedule_inputs)

    def split(self, obs: th.Tensor) -> tuple[th.Tensor, th.Tensor, th.Tensor, th.Tensor, th.Tensor]:
        """``(base (B, base_dim), loss (B, C, H + 1), best (B, C, H + 1), kept (B, C),
        remaining (B, 1))`` of observations ``(B, obs_dim)``."""
        C, H = self.n_candidates, self.blocks
        b = obs.shape[0]
        plan = obs[:, self.base_dim : self.base_dim + 2 * H * C].reshape(b, H, 2, C)
        kept = obs[:, self.base_dim + 2 * H * C : self.base_dim + (2 * H + 1) * C]
        return (
            obs[:, : self.base_dim],
            plan[:, :, 0].transpose(1, 2),
            plan[:, :, 1].transpose(1, 2),
            kept,
            obs[:, -1:],
        )


class CandidateNetworks(nn.Module):
    """The actor's scores ``(B, C)`` and the critic's latent ``(B, hidden)``, SB3's
    ``mlp_extractor`` interface (``forward_actor``, ``forward_critic``, ``latent_dim_pi``,
    ``latent_dim_vf``)."""

    #: per-candidate inputs: loss and best flag per block, kept, time left, prior gap
    def __init__(
        self,
        layout: CandidateLayout,
        n_receivers: int,
        prior_horizon: int,
        prior_keep: float,
        hidden: int,
        alpha_init: float,
        residual: str = "mlp",
    ):
        super().__init__()
        if residual not in RESIDUALS:
            raise ValueError(f"residual: must be one of {RESIDUALS}, got {residual!r}")
        self.residual = residual
        if prior_horizon not in layout.horizons:
            raise ValueError(
                f"prior_horizon: {prior_horizon} must be one of the plan features' horizons "
                f"{list(layout.horizons)} (beyond the time left the prior plans over it)"
            )
        self.layout = layout
        self.n_receivers = n_receivers
        self.prior_horizon = prior_horizon
        self.prior_block = layout.horizons.index(prior_horizon)
        self.prior_keep = prior_keep
        n_in = 2 * layout.blocks + 3
        self.scorer = nn.Sequential(
            nn.Linear(n_in, hidden), nn.Tanh(), nn.Linear(hidden, hidden), nn.Tanh()
        )
        self.score_out = nn.Linear(hidden, 1)
        self.linear = (
            nn.Linear(2 * layout.blocks + 1 + layout.schedule_inputs, 1, bias=False)
            if residual == "linear"
            else None
        )
        self.log_alpha = nn.Parameter(th.tensor(float(np.log(alpha_init))))
        self.embed = nn.Sequential(nn.Linear(n_in, hidden), nn.Tanh())
        self.critic = nn.Sequential(
            nn.Linear(2 * hidden + layout.base_dim + 1, hidden),
            nn.Tanh(),
            nn.Linear(hidden, hidden),
            nn.Tanh(),
        )
        self.latent_dim_pi = layout.n_candidates
        self.latent_dim_vf = hidden

    def zero_residual(self) -> None:
        """Start the learned score at zero: the actor's mode is the prior's argmax."""
        nn.init.zeros_(self.score_out.weight)
        nn.init.zeros_(self.score_out.bias)
        if self.linear is not None:
            nn.init.zeros_(self.linear.weight)

    def prior(self, loss: th.Tensor, kept: th.Tensor, remaining: th.Tensor) -> th.Tensor:
        """The ``plan-horizon`` objective ``(B, C)``, relative to the best candidate: planned
        return over ``h = min(prior_horizon, steps left)`` (the per-step loss times ``h``)
        plus ``prior_keep`` per receiver kept."""
        left = self.steps_left(remaining)  # (B, 1)
        far = left >= self.prior_horizon
        h = th.where(far, th.full_like(left, float(self.prior_horizon)), left)
        per_step = th.where(far, loss[..., self.prior_block], loss[..., -1])
        g = h * per_step + self.prior_keep * self.n_receivers * kept
        return g - g.max(dim=1, keepdim=True).values

    def inputs(self, obs: th.Tensor) -> tuple[th.Tensor, th.Tensor, th.Tensor, th.Tensor]:
        """``(per-candidate inputs (B, C, F), prior (B, C), base (B, base_dim), remaining
        (B, 1))``."""
        base, loss, best, kept, remaining = self.layout.split(obs)
        prior = self.prior(loss, kept, remaining)
        C = self.layout.n_candidates
        x = th.cat(
            [
                loss,
                best,
                kept[..., None],
                remaining[:, None].expand(-1, C, 1),
                th.clamp(prior / 10.0, min=-10.0)[..., None],
            ],
            dim=-1,
        )
        return x, prior, base, remaining

    def steps_left(self, remaining: th.Tensor) -> th.Tensor:
        """Steps left ``(B, 1)`` (at least 1) of the time feature ``1 − t/T``."""
        return th.clamp(th.round(remaining * self.layout.episode_steps), min=1.0)

    def linear_features(self, obs: th.Tensor) -> th.Tensor:
        """The linear residual's per-candidate features ``(B, C, 2 H + 1 + S)``, each on a
        scale where a weight of 1 matters: per block (the fixed horizons, then the time left),
        the planned-return gap to the best candidate (the per-step loss times the block's
        horizon, return units); per block, ``LINEAR_FLAG_SCALE`` for the best candidate; the
        number of receivers the candidate keeps on their drone; with a schedule block
        (``S`` inputs), ``LINEAR_FLAG_SCALE`` times each of its features."""
        _, loss, best, kept, remaining = self.layout.split(obs)
        h = th.tensor([float(x) for x in self.layout.horizons], dtype=loss.dtype)
        h = th.cat([h.expand(loss.shape[0], -1), self.steps_left(remaining)], dim=1)  # (B, H)
        gap = loss * h[:, None, :]
        parts = [gap, LINEAR_FLAG_SCALE * best, self.n_receivers * kept[..., None]]
        if self.layout.schedule_inputs:
            parts.append(LINEAR_FLAG_SCALE * self.layout.schedule_block(obs))
        return th.cat(parts, dim=-1)

    def forward_actor(self, obs: th.Tensor) -> th.Tensor:
        x, prior, _, _ = self.inputs(obs)
        if self.linear is not None:
            residual = self.linear(self.linear_features(obs)).squeeze(-1)
        else:
            residual = self.score_out(self.scorer(x)).squeeze(-1)
        return th.exp(self.log_alpha) * prior + residual

    def forward_critic(self, obs: th.Tensor) -> th.Tensor:
        x, _, base, remaining = self.inputs(obs)
        e = self.embed(x)
        pooled = th.cat([e.mean(dim=1), e.max(dim=1).values, base, remaining], dim=-1)
        return self.critic(pooled)

    def forward(self, obs: th.Tensor) -> tuple[th.Tensor, th.Tensor]:
        return self.forward_actor(obs), self.forward_critic(obs)


class CandidatePolicy(ActorCriticPolicy):
    """SB3 actor-critic over a ``Discrete`` choice of candidates whose logits are the
    :class:`CandidateNetworks` scores (no action layer over them).

    ``policy_kwargs``: ``horizons`` (the plan features' fixed horizons), ``episode_steps``
    (the time feature's ``T``), ``n_receivers`` (the kept fraction's denominator),
    ``prior_horizon`` and ``prior_keep`` (the prior rule's settings), ``hidden`` (width of the
    shared MLPs), ``alpha_init`` (initial weight of the prior, per unit of return) and
    ``residual`` (``"mlp"`` or ``"linear"``: the learned score's form) and ``schedule`` (the
    observation holds the ``plan-features`` schedule block, which the linear residual weighs:
    :meth:`CandidateNetworks.linear_features`)."""

    def __init__(
        self,
        observation_space: spaces.Space,
        action_space: spaces.Space,
        lr_schedule: Any,
        horizons: tuple[int, ...] | list[int] = (15, 50, 100),
        episode_steps: int = 150,
        n_receivers: int = 4,
        prior_horizon: int = 100,
        prior_keep: float = 0.3,
        hidden: int = 64,
        alpha_init: float = 3.0,
        residual: str = "mlp",
        schedule: bool = False,
        **kwargs: Any,
    ):
        if not isinstance(action_space, spaces.Discrete):
            raise ValueError(f"CandidatePolicy: needs a Discrete action, got {action_space}")
        C = int(action_space.n)
        if not isinstance(observation_space, spaces.Box) or len(observation_space.shape) != 1:
            raise ValueError(
                f"CandidatePolicy: needs a flat Box observation, got {observation_space}"
            )
        H = len(horizons) + 1
        n_schedule = len(SCHEDULE_FEATURES) if schedule else 0
        base_dim = observation_space.shape[0] - C * (2 * H + 1) - C * n_schedule - 1
        self.layout = CandidateLayout(
            C, tuple(int(h) for h in horizons), base_dim, int(episode_steps), n_schedule
        )
        if base_dim < 0:
            raise ValueError(
                f"CandidatePolicy: an observation of {observation_space.shape[0]} cannot hold "
                f"{C} candidates' plan features at {H} horizons and the time feature"
            )
        if alpha_init <= 0.0:
            raise ValueError(f"alpha_init: must be > 0, got {alpha_init}")
        self._candidate_kwargs = dict(
            n_receivers=int(n_receivers),
            prior_horizon=int(prior_horizon),
            prior_keep=float(prior_keep),
            hidden=int(hidden),
            alpha_init=float(alpha_init),
            residual=str(residual),
        )
        super().__init__(observation_space, action_space, lr_schedule, **kwargs)

    def _build_mlp_extractor(self) -> None:
        self.mlp_extractor = CandidateNetworks(self.layout, **self._candidate_kwargs)

    def _build(self, lr_schedule: Any) -> None:
        super()._build(lr_schedule)
        # the scores are the logits: no action layer over them (built by SB3, dropped here,
        # and the optimizer rebuilt without its parameters)
        self.action_net = nn.Identity()
        self.mlp_extractor.zero_residual()
        self.optimizer = self.optimizer_class(
            self.parameters(), lr=lr_schedule(1), **self.optimizer_kwargs
        )

    def search_parameter(self) -> nn.Parameter:
        """The vector a direct policy search perturbs, zero the prior rule: the linear
        residual's weights ``(1, 2 H + 1 + S)`` (``residual="linear"``)."""
        linear = self.mlp_extractor.linear
        if linear is None:
            raise ValueError("search_parameter: the policy's residual is not linear")
        return linear.weight
