"""Action re-parameterisations of ``sensorgym/StereoScanning-v0`` for training (SB3 wrappers).

:class:`ScanModes` replaces the raw sector action (three sector centres and widths, 9 numbers)
by a choice among the sector plans the rules compute from the observation: a full sweep, or
sectors on the confirmed tracks (cue-following's cover, or that cover twice as wide).
A policy then learns *when* to search and how to dwell — the decisions the rules fix by a
schedule — while the geometry of a sector stays the rules' exact computation. The wrapper keeps
the env's scenarios and rewards (it only translates the action), so a wrapped policy is scored
against the rules on the same seeded scenarios. Registered in
:data:`sensorgym.train.wrappers.WRAPPERS` as ``scan-modes``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray
from stable_baselines3.common.vec_env import VecEnv

from sensorgym.agents import stereo_scanning as rules
from sensorgym.envs.stereo_scanning.simulation import (
    ScanningParams,
    sector_action,
    split_observation,
)
from sensorgym.train.wrappers import ObservedActionWrapper

#: the plans of :class:`ScanModes`, in action order
MODES = ("sweep", "cue", "cue-wide", "entry")


def mode_sectors(
    params: ScanningParams, obs: NDArray[Any], modes: NDArray[np.int64]
) -> NDArray[np.float64]:
    """Sectors ``(N, n, 3)`` (rad) of the plans ``modes (N,)`` (indices into :data:`MODES`)
    for observations ``(N, obs_dim)``: ``sweep`` every receiver's whole field of regard;
    ``cue`` :class:`~sensorgym.agents.stereo_scanning.CueFollowing`'s cover of the confirmed
    tracks and their motion; ``cue-wide`` the same centres at twice the width (a margin for
    uncertain tracks); ``entry`` one sector per receiver covering the region where drones
    enter the scene and the confirmed tracks
    (:func:`~sensorgym.agents.stereo_scanning.entry_sectors`) — a search at a finer
    noise than the sweep's. Without a confirmed track ``cue`` and ``cue-wide`` sweep."""
    m = np.asarray(modes, dtype=np.int64).reshape(-1)
    N = m.shape[0]
    if np.any((m < 0) | (m >= len(MODES))):
        raise ValueError(f"modes: must lie in [0, {len(MODES)}), got {m}")
    o = split_observation(params, np.asarray(obs, dtype=np.float64).reshape(N, -1))
    out = rules._full(params, N)
    cue = rules.CueFollowing(params)
    for i in range(N):
        if m[i] == 3:
            out[i] = rules.entry_sectors(params, o, i)
            continue
        if m[i] == 0 or not o["valid"][i].any():
            continue
        out[i] = cue.sectors(o, i)
        if m[i] == 2:
            out[i, :, 2] = np.minimum(2.0 * out[i, :, 2], params.sector_width[1])
    return out


class ScanModes(ObservedActionWrapper):
    """``Discrete(4)`` actions over the env's sector action: 0 sweep, 1 cue, 2 cue-wide, 3 entry
    (:func:`mode_sectors`, planned on the observation the policy acted on)."""

    def __init__(self, venv: VecEnv):
        params = venv.get_attr("params")[0]
        if not isinstance(params, ScanningParams):
            raise ValueError(f"scan-modes: needs a StereoScanning env, got {type(params).__name__}")
        self.params = params
        super().__init__(venv, spaces.Discrete(len(MODES)))

    def env_action(self, actions: NDArray[Any], obs: NDArray[Any]) -> NDArray[Any]:
        sectors = mode_sectors(self.params, obs, actions.reshape(-1))
        return sector_action(self.params, sectors).reshape(self.num_envs, -1)


class EntrySearchModes:
    """The ``cue-entry-search`` rule in :class:`ScanModes`' actions — ``entry`` on the first
    ``sweep_periods`` of every ``sweep_every`` periods, ``cue`` otherwise — with SB3's
    ``predict`` (its period counters are the state): the expert a policy imitates before RL."""

    def __init__(
        self,
        sweep_every: int = rules.SWEEP_EVERY,
        sweep_periods: int = rules.SWEEP_PERIODS,
    ):
        self.sweep_every = sweep_every
        self.sweep_periods = sweep_periods

    def predict(
        self,
        observation: NDArray[Any],
        state: Any = None,
        episode_start: NDArray[np.bool_] | None = None,
        deterministic: bool = True,
    ) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        N = len(observation)
        count = np.zeros(N, np.int64) if state is None else np.asarray(state, np.int64).copy()
        if episode_start is not None:
            count[np.asarray(episode_start, bool).reshape(-1)[:N]] = 0
        search = count % self.sweep_every < self.sweep_periods
        return np.where(search, MODES.index("entry"), MODES.index("cue")), count + 1


def entry_search_expert(env: VecEnv) -> EntrySearchModes:
    """The ``scan-entry-search`` expert factory (:class:`EntrySearchModes`; ``env`` must act
    through :class:`ScanModes`)."""
    if not isinstance(env.action_space, spaces.Discrete) or env.action_space.n != len(MODES):
        raise ValueError("scan-entry-search: the training env must act through scan-modes")
    return EntrySearchModes()


def scan_modes(venv: VecEnv) -> VecEnv:
    """The ``scan-modes`` wrapper factory (:class:`ScanModes`)."""
    return ScanModes(venv)


__all__ = [
    "MODES",
    "EntrySearchModes",
    "ScanModes",
    "entry_search_expert",
    "mode_sectors",
    "scan_modes",
]
