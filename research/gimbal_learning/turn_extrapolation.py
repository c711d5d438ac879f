"""Probe: does aiming, through a loss, at a quadratic extrapolation of the last M detected
directions (the turn's curvature added to the straight-line prediction) keep the target?

    python research/gimbal_learning/turn_extrapolation.py [M]
"""

import sys

import gymnasium as gym
import numpy as np

import sensorgym.envs  # noqa: F401  (registers the ids)
from sensorgym.agents.gimbal_tracking import (
    ANGLE_SCALE,
    ATTITUDE,
    ATTITUDE_RATES,
    ESTIMATE_LEVEL,
    PREDICTED_LEVEL,
    CarrierFeedForward,
    aim_change,
    detected,
    rate_action,
)
from sensorgym.envs.gimbal_tracking.simulation import ATTITUDE_SCALE

ENV = "sensorgym/GimbalTracking-v0"
B = 48
M = int(sys.argv[1]) if len(sys.argv) > 1 else 40


class TurnAware(CarrierFeedForward):
    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        p = self.params
        n = obs.shape[0]
        if state is None:
            state = {"hist": np.full((n, M, 2), np.nan), "t": np.zeros(n), "since": np.zeros(n)}
        if episode_start is not None:
            st = np.asarray(episode_start, bool)
            state["hist"][st] = np.nan
        det = detected(p, obs)
        level = obs[:, ESTIMATE_LEVEL] * ANGLE_SCALE
        h = state["hist"]
        h[det] = np.roll(h[det], -1, axis=1)
        h[det, -1] = level[det]
        sd = np.rint(obs[:, 20 + p.n_channels] * (p.reacquire_limit + 1))
        T = p.frame_period
        ahead = (obs[:, ATTITUDE] + obs[:, ATTITUDE_RATES] * T) * ATTITUDE_SCALE
        aim = obs[:, PREDICTED_LEVEL] * ANGLE_SCALE
        ok = ~np.isnan(h[:, 0, 0]) & (sd > 0)
        if ok.any():
            t = np.arange(M) - (M - 1)
            for b in np.flatnonzero(ok):
                y = h[b].copy()
                y[:, 0] = np.unwrap(y[:, 0])
                tt = sd[b] + 1
                c = np.polyfit(t, y, 2)  # (3,2)
                ext = c[0] * tt**2 + c[1] * tt + c[2]
                lin = np.polyfit(t, y, 1)
                el = lin[0] * tt + lin[1]
                # add only the curvature part relative to the linear extrapolation
                aim[b] = aim[b] + (ext - el)
        return rate_action(p, aim_change(obs, aim, ahead)).astype(np.float32), state


def run(mk, seed=700):
    env = gym.make_vec(ENV, num_envs=B, vectorization_mode="vector_entry_point")
    obs, _ = env.reset(seed=seed)
    rule = mk(env)
    ret = np.zeros(B)
    live = np.ones(B, bool)
    st = None
    lost = np.zeros(B, bool)
    for k in range(500):
        a, st = rule.predict(obs, st, episode_start=np.full(B, k == 0))
        obs, r, te, tr, _info = env.step(a)
        ret[live] += r[live]
        lost |= te & live
        live &= ~(te | tr)
    return ret, lost


c, cl = run(lambda env: CarrierFeedForward(env.params))
s, sl = run(lambda env: TurnAware(env.params))
print(
    "M",
    M,
    "cff",
    c.mean(),
    cl.mean(),
    "turn",
    s.mean(),
    sl.mean(),
    "paired",
    (s - c).mean(),
    np.median(s - c),
)
