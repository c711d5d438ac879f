"""Probe: what limits the learned search order — the loss, the data or the information?

The shipped recipe imitates ``gimbal-truth-hop`` (a kernel about the true direction per
position of the four-ring search) by least squares on *every* frame, three DAgger rounds of
256k transitions: the frames where the scores act (the gate searches) are a small share of
them. Here the student is fitted offline on data from tuning seeds, in variants:

* ``all``: least squares on every frame (the recipe's loss, without DAgger);
* ``search``: least squares on the searching frames only;
* ``softmax``: cross-entropy of a softmax over the positions against the kernel normalised to
  a distribution, searching frames only (a classifier of where the target is).

Data: rollouts of the fixed order (zero scores) and of a shipped policy, tuning seeds 100+.
Offline measure on other tuning seeds: the kernel value at the best-scored position on the
searching frames (1 = the first hop lands on the target; the zero policy's is the pattern's
first position). Closed loop: the fitted students and the zero scores on tuning seed 502,
1024 episodes of 64 scenarios, paired to the zero scores, beside the shipped ``ppo_seed2``.

    python research/gimbal_learning/order_fit.py [transitions-per-seed]   # → order_fit.json
"""

import json
import sys
import time
from pathlib import Path

import numpy as np
import torch as th
from paired import paired

from sensorgym.train.env_wrappers.gimbal_search import SearchOrderAction, truth_hop
from sensorgym.train.evaluation import evaluate, make_sb3_env
from sensorgym.train.models import load_model
from sensorgym.train.wrappers import find_wrapper

th.set_num_threads(1)
ENV = "sensorgym/GimbalTracking-v0"
WRAPPERS = [{"name": "gimbal-search-order"}] + [
    {"name": "gimbal-turn-memory", "window": w} for w in (20, 40, 80)
]
SHIPPED = Path("train/policies/sensorgym__GimbalTracking-v0/ppo_seed2")
N_ENVS, EVAL_SEED, EVAL_EPISODES = 64, 502, 1024
HERE = Path(__file__).parent


class Zero:
    """Zero scores: the pattern's fixed order (``feedforward-search`` with four rings)."""

    def __init__(self, n_positions):
        self.n = n_positions

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        return np.zeros((len(obs), self.n), np.float32), None


class Student:
    """A fitted network's scores as an SB3 predictor."""

    def __init__(self, net):
        self.net = net

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        with th.no_grad():
            return self.net(th.as_tensor(obs, dtype=th.float32)).numpy(), None


def collect(seed, steps, policy_fn):
    env = make_sb3_env(ENV, N_ENVS, seed, wrappers=WRAPPERS)
    wrapper = find_wrapper(env, SearchOrderAction)
    teacher = truth_hop(env)
    policy = policy_fn(env)
    obs = env.reset()
    xs, ys, ms = [], [], []
    for _ in range(steps // N_ENVS):
        label, _ = teacher.predict(obs)
        xs.append(obs.astype(np.float32))
        ys.append(label)
        ms.append(wrapper.searching(np.asarray(wrapper.last_obs, np.float64)))
        action, _ = policy.predict(obs, deterministic=True)
        obs, *_ = env.step(action)
    env.close()
    return np.concatenate(xs), np.concatenate(ys), np.concatenate(ms)


def network(n_in, n_out):
    return th.nn.Sequential(
        th.nn.Linear(n_in, 128), th.nn.Tanh(), th.nn.Linear(128, 128), th.nn.Tanh(),
        th.nn.Linear(128, n_out),
    )  # fmt: skip


def fit(kind, x, y, m, epochs=20, seed=0):
    th.manual_seed(seed)
    if kind != "all":
        x, y = x[m], y[m]
    net = network(x.shape[1], y.shape[1])
    opt = th.optim.Adam(net.parameters(), lr=1e-3)
    xt, yt = th.as_tensor(x), th.as_tensor(y)
    target = (yt + 1.0) / (yt + 1.0).sum(1, keepdim=True).clamp_min(1e-12)
    rng = np.random.default_rng(seed)
    for _ in range(epochs):
        for idx in np.array_split(rng.permutation(len(xt)), max(1, len(xt) // 512)):
            out = net(xt[idx])
            if kind == "softmax":
                loss = -(target[idx] * th.log_softmax(out, 1)).sum(1).mean()
            else:
                loss = ((out - yt[idx]) ** 2).mean()
            opt.zero_grad()
            loss.backward()
            opt.step()
    return net


def first_hop(scores, y, m):
    """Mean kernel value (label + 1) at the best-scored position over searching frames."""
    best = np.argmax(scores[m], 1)
    return float(np.mean(y[m][np.arange(m.sum()), best] + 1.0))


def closed_loop(policy_fn):
    env = make_sb3_env(ENV, N_ENVS, EVAL_SEED, wrappers=WRAPPERS, episode_streams=True)
    stats = evaluate(policy_fn(env), env, EVAL_EPISODES, EVAL_SEED, tails=())
    env.close()
    return np.asarray(stats.returns)


def main():
    per_seed = int(sys.argv[1]) if len(sys.argv) > 1 else 128_000
    t0 = time.time()

    def zero(env):
        return Zero(env.action_space.shape[0])

    def shipped(env):
        return load_model(SHIPPED, env)

    parts = [collect(s, per_seed, zero) for s in (100, 101)]
    parts += [collect(s, per_seed, shipped) for s in (102, 103)]
    x, y, m = (np.concatenate(a) for a in zip(*parts, strict=True))
    xv, yv, mv = collect(110, per_seed, zero)
    n_pos = y.shape[1]
    print(f"data: {len(x)} frames, {m.sum()} searching; {time.time() - t0:.0f} s", flush=True)
    out = {"transitions": len(x), "searching": int(m.sum()), "offline": {}, "closed": {}}
    zero_scores = np.zeros((len(xv), n_pos), np.float32)
    out["offline"]["zero"] = first_hop(zero_scores, yv, mv)
    nets = {}
    for kind in ("all", "search", "softmax"):
        nets[kind] = fit(kind, x, y, m)
        with th.no_grad():
            s = nets[kind](th.as_tensor(xv)).numpy()
        out["offline"][kind] = first_hop(s, yv, mv)
        print(f"offline {kind}: {out['offline'][kind]:.3f}", flush=True)
    base = closed_loop(zero)
    out["closed"]["zero"] = {"mean": float(base.mean())}
    runs = {"shipped ppo_seed2": shipped} | {k: (lambda env, k=k: Student(nets[k])) for k in nets}
    for name, fn in runs.items():
        r = closed_loop(fn)
        out["closed"][name] = {"mean": float(r.mean()), "vs zero": paired(r, base)}
        print(f"closed {name}: {out['closed'][name]}", flush=True)
    (HERE / "order_fit.json").write_text(json.dumps(out, indent=1) + "\n")


if __name__ == "__main__":
    main()
