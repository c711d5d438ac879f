"""Where does carrier-feedforward lose the target that the truth-informed servo keeps?

Plays 48 scenarios (seed 700, tuning range) under both and prints, for the episodes the rule
loses, the gain the truth-informed servo makes there and, per lost episode, the last
detection, the last frame in view, the occlusion between and whether the target was turning.

    python research/gimbal_learning/where_targets_are_lost.py
"""

import gymnasium as gym
import numpy as np

import sensorgym.envs  # noqa: F401  (registers the ids)
from sensorgym.agents.registry import rules_for

ENV = "sensorgym/GimbalTracking-v0"
B = 48


def run(name):
    env = gym.make_vec(ENV, num_envs=B, vectorization_mode="vector_entry_point")
    obs, _ = env.reset(seed=700)
    rule = rules_for(ENV, env.params, lambda: env.simulator_state)[name]
    ret = np.zeros(B)
    live = np.ones(B, bool)
    st = None
    T = np.full(B, 500)
    pe = np.full((B, 500), np.nan)
    occ = np.zeros((B, 500))
    det = np.zeros((B, 500))
    turn = np.zeros((B, 500))
    sd = np.zeros((B, 500))
    for k in range(500):
        a, st = rule.predict(obs, st, episode_start=np.full(B, k == 0))
        s = env.simulator_state
        obs, r, te, tr, info = env.step(a)
        s = env.simulator_state
        ret[live] += r[live]
        pe[live, k] = info["pointing_error"][live]
        occ[live, k] = info["occluded"][live]
        det[live, k] = info["detected"][live]
        turn[live, k] = ((s.frame > s.turn_start) & (s.frame <= s.turn_end))[live]
        sd[live, k] = s.since_detection[live]
        T[te & live] = k
        live &= ~(te | tr)
    return ret, T, pe, occ, det, turn, sd


c = run("carrier-feedforward")
t = run("truth-servo")
lost = c[1] < 499
print(
    "cff lost",
    lost.sum(),
    "gain in lost eps",
    (t[0] - c[0])[lost].sum(),
    "gain elsewhere",
    (t[0] - c[0])[~lost].sum(),
)
h = np.deg2rad(0.75)
for b in np.flatnonzero(lost)[:12]:
    T = c[1][b]
    k0 = T - 50  # target left view at ~T-50
    # find first frame of the final out-of-view stretch
    pe = c[2][b]
    occ = c[3][b]
    det = c[4][b]
    turn = c[5][b]
    sd = c[6][b]
    # when did the last detection happen
    last = np.flatnonzero(det[:T] > 0.5)
    ld = last[-1] if len(last) else -1
    out = np.flatnonzero(pe[:T] < h)
    lastin = out[-1] if len(out) else -1
    print(
        f"ep {b}: end {T}, last det {ld}, last in view {lastin}, occluded at last det+1: {occ[ld + 1] if ld + 1 < 500 else -1}, occluded frames between: {occ[ld + 1 : lastin + 1].sum():.0f}, turning at lastdet: {turn[ld]}, pe at lastdet {pe[ld] * 1e3:.1f} mrad, pe at lastin {pe[lastin] * 1e3:.1f}"
    )
