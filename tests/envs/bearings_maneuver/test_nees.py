"""The env's bank tells the truth about its error (theory §11.6, issue 35 item 6): the joint NEES
of its moment-matched estimate at reset, mid-episode and at the end of an episode, over 2,000
seeded scenarios under random actions (the policy that strains it most).

``benchmarks/results/nees.json`` (seed 0) records 3.95 / 3.97 / 4.19 for this policy; the bank
with first-order EKF members ended at 5.27. The bounds below are those numbers' 95 % bands
widened for another seed (the spread of a mean of 2,000 draws of χ²₄ is 0.06), and they hold
the end to the second-order members: the first-order ones fail them by far."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import sensorgym.envs  # noqa: F401  (registers the ids)

SCENARIOS = 2000


def _nees(state) -> np.ndarray:
    est = state.estimate
    e = est.x - state.target
    return np.einsum("bi,bi->b", e, np.linalg.solve(est.P, e[..., None])[..., 0])


@pytest.fixture(scope="module")
def profile() -> dict[str, np.ndarray]:
    env = gym.make_vec("sensorgym/BearingsManeuver-v0", num_envs=SCENARIOS,
                       vectorization_mode="vector_entry_point", episode_streams=True)  # fmt: skip
    env.reset(seed=12)
    rng = np.random.default_rng(13)
    out = {"reset": _nees(env.simulator_state)}
    live = np.ones(SCENARIOS, dtype=bool)
    last = out["reset"].copy()
    for k in range(1, 31):
        _, _, terminated, truncated, _ = env.step(rng.uniform(-1, 1, env.action_space.shape))
        nees = _nees(env.simulator_state)
        if k == 15:
            out["mid"] = nees[live]
        last = np.where(live, nees, last)
        live &= ~(terminated | truncated)
    out["end"] = last
    env.close()
    return out


@pytest.mark.parametrize(("when", "low", "high"), [("reset", 3.85, 4.15), ("mid", 3.85, 4.15),
                                                   ("end", 3.9, 4.35)])  # fmt: skip
def test_the_banks_nees_stays_near_its_dimension(profile, when, low, high):
    mean = float(profile[when].mean())
    assert low <= mean <= high, (when, mean)
    # the tail: the share above χ²₄'s 99 % quantile (13.28), 1 % for a consistent filter
    # (here 2.3 % mid-episode and 2.5 % at the end: the Gaussian sum's excess, theory §11.6)
    assert np.mean(profile[when] > 13.28) < 0.035, when
