"""Probe: which missing knowledge would let a student order the search better?

``order_fit.py`` found every student's best-scored position holding about 0.55 of the
teacher's kernel, whatever the loss or the data. Here the same student (least squares on the
searching frames) is given, beside its observation, pieces of the truth no tracker has:

* ``occlusion``: whether the target is occluded, and the frames until the occlusion ends;
* ``turn``: the target's turn rate, whether it is turning, frames since the turn began;
* ``range``: the target's range and speed (m, m/s; a passive tracker has neither);
* ``all``: the three together;
* ``offset``: the true offset itself (half-gates): a check that the student can learn the
  order when it has what decides it.

If one lifts the first hop towards the oracle's, that knowledge is what the order lacks.
Offline only: fitted on tuning seeds 100–103 (the fixed order), measured on seed 110.

    python research/gimbal_learning/order_information.py   # → order_information.json
"""

import json
from pathlib import Path

import numpy as np
import torch as th
from order_fit import ENV, N_ENVS, WRAPPERS, Zero, first_hop, fit

from sensorgym.train.env_wrappers.gimbal_search import SearchOrderAction, truth_hop
from sensorgym.train.evaluation import make_sb3_env, simulator_state
from sensorgym.train.wrappers import find_wrapper

STEPS = 256_000
HERE = Path(__file__).parent


def truth(s):
    """Truth columns per scenario: occlusion (2), turn (3), range and speed (2)."""
    f = np.asarray(s.frame, np.float64)
    occluded = np.asarray(s.occluded, np.float64)
    until = np.where(occluded > 0, np.asarray(s.occlusion_end) - f, 0.0)
    turning = ((f > s.turn_start) & (f <= s.turn_end)).astype(np.float64)
    since_turn = np.clip(f - s.turn_start, 0.0, 200.0) / 100.0
    rng = np.linalg.norm(s.target_position, axis=1) / 10_000.0
    speed = np.linalg.norm(s.target_velocity, axis=1) / 100.0
    return np.stack(
        [occluded, until / 60.0, np.asarray(s.turn_rate) * 10.0, turning, since_turn, rng, speed], 1
    )


COLUMNS = {
    "none": [], "occlusion": [0, 1], "turn": [2, 3, 4], "range": [5, 6], "all": list(range(7)),
    "offset": [7, 8],
}  # fmt: skip


def collect(seed):
    env = make_sb3_env(ENV, N_ENVS, seed, wrappers=WRAPPERS)
    wrapper = find_wrapper(env, SearchOrderAction)
    teacher, state, zero = truth_hop(env), simulator_state(env), Zero(env.action_space.shape[0])
    obs = env.reset()
    xs, ts, ys, ms = [], [], [], []
    for _ in range(STEPS // N_ENVS):
        label, _ = teacher.predict(obs)
        xs.append(obs.astype(np.float32))
        view = np.asarray(wrapper.last_obs, np.float64)
        offset = (teacher.truth.change(view) - wrapper.servo.change(view)) / wrapper.half_gate
        ts.append(np.hstack([truth(state()), np.clip(offset, -10, 10)]).astype(np.float32))
        ys.append(label)
        ms.append(wrapper.searching(np.asarray(wrapper.last_obs, np.float64)))
        obs, *_ = env.step(zero.predict(obs)[0])
    env.close()
    return [np.concatenate(a) for a in (xs, ts, ys, ms)]


def main():
    parts = [collect(s) for s in (100, 101, 102, 103)]
    x, t, y, m = (np.concatenate(a) for a in zip(*parts, strict=True))
    xv, tv, yv, mv = collect(110)
    out = {"searching frames": int(m.sum()), "first hop": {}}
    out["first hop"]["zero scores"] = first_hop(np.zeros_like(yv), yv, mv)
    out["first hop"]["oracle"] = float(np.mean(yv[mv].max(axis=1) + 1.0))  # the nearest
    for name, cols in COLUMNS.items():
        net = fit("search", np.hstack([x, t[:, cols]]), y, m)
        with th.no_grad():
            s = net(th.as_tensor(np.hstack([xv, tv[:, cols]]))).numpy()
        out["first hop"][name] = first_hop(s, yv, mv)
        print(f"{name}: {out['first hop'][name]:.3f}", flush=True)
    (HERE / "order_information.json").write_text(json.dumps(out, indent=1) + "\n")


if __name__ == "__main__":
    main()
