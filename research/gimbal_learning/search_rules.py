"""Probe: does a blind search pattern (a rosette around the coasting prediction once the
target has been undetected for a while) recover the targets carrier-feedforward loses?

Prints the mean return, the lost share and the paired difference to the rule on 48 scenarios
(seed 700) for four pattern settings.

    python research/gimbal_learning/search_rules.py
"""

import gymnasium as gym
import numpy as np

import sensorgym.envs  # noqa: F401  (registers the ids)
from sensorgym.agents.gimbal_tracking import CarrierFeedForward, rate_action

ENV = "sensorgym/GimbalTracking-v0"
B = 48


class Rosette(CarrierFeedForward):
    start = 25
    R = 12e-3
    P = 10

    def act(self, obs):
        p = self.params
        change = self.change(obs)
        sd = np.rint(obs[:, 20 + p.n_channels] * (p.reacquire_limit + 1))
        j = np.maximum(sd - self.start, 0.0)
        petal = np.floor(j / self.P)
        ph = (j % self.P) / self.P
        r = self.R * np.sin(np.pi * ph) * np.minimum(1.0, (petal + 1) / 3)
        th = petal * 2.39996
        off = np.stack([r * np.cos(th), r * np.sin(th)], -1)
        off = np.where((sd >= self.start)[:, None], off, 0.0)
        return rate_action(p, change + off)


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
print("cff", c.mean(), cl.mean())
for st, R, P in [(25, 12e-3, 10), (40, 12e-3, 10), (25, 10e-3, 16), (60, 14e-3, 10)]:
    Rosette.start = st
    Rosette.R = R
    Rosette.P = P
    s, sl = run(lambda env: Rosette(env.params))
    print(
        "rosette",
        st,
        R,
        P,
        round(s.mean(), 1),
        sl.mean(),
        "paired",
        round((s - c).mean(), 1),
        np.median(s - c),
    )
