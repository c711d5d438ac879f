"""The tail in physical units: the statistics, every env's measures, GOSPA against Stone Soup."""

from __future__ import annotations

import datetime
import itertools

import numpy as np
import pytest

from sensorgym.agents.registry import RULES
from sensorgym.trackers.metrics import gospa
from sensorgym.train.evaluation import env_params, evaluate, make_sb3_env, simulator_state
from sensorgym.train.tail import TAIL_MEASURES, cvar, quantile_summary, tail_summary


def test_cvar_is_the_mean_of_the_worst_five_percent():
    x = np.random.default_rng(0).permutation(np.arange(1.0, 101.0))
    assert cvar(x) == pytest.approx(98.0)  # 96 … 100
    assert cvar(x, lower_is_better=False) == pytest.approx(3.0)  # 1 … 5
    assert cvar(np.arange(10.0)) == 9.0  # ⌈0.5⌉ = 1: the worst one
    assert cvar([2.0, 7.0], share=1.0) == pytest.approx(4.5)
    with pytest.raises(ValueError, match="share"):
        cvar(x, share=0.0)


def test_quantile_summary_skips_missing_values_and_reads_the_bad_side():
    x = np.r_[np.arange(1.0, 101.0), np.nan]
    s = quantile_summary(x)
    assert (s["episodes"], s["missing"]) == (100, 1)
    assert s["median"] == pytest.approx(50.5)
    assert s["p90"] == pytest.approx(np.percentile(np.arange(1.0, 101.0), 90))
    assert s["cvar5"] == pytest.approx(98.0)
    # RMS of 1..100: sqrt(sum k^2 / 100) = sqrt(101 * 201 / 6)
    assert s["rms"] == pytest.approx(np.sqrt(101 * 201 / 6), rel=1e-12)
    higher = quantile_summary(x, lower_is_better=False)
    assert higher["p90"] == pytest.approx(np.percentile(np.arange(1.0, 101.0), 10))
    assert higher["cvar5"] == pytest.approx(3.0)
    assert higher["rms"] is None  # an RMS only for an error
    assert quantile_summary([np.nan])["median"] is None


def test_tail_summary_gives_the_return_p10_and_every_measure():
    result = {"returns": list(np.arange(11.0)), "tails": {"gospa": [1.0, 2.0, 3.0]}}
    s = tail_summary(result, TAIL_MEASURES["sensorgym/StereoScanning-v0"])
    assert s["return_p10"] == pytest.approx(1.0)
    assert s["measures"]["gospa"]["unit"] == "m"
    assert s["measures"]["gospa"]["median"] == 2.0
    assert s["measures"]["gospa"]["cvar5"] == 3.0


@pytest.mark.parametrize("env_id", sorted(TAIL_MEASURES))
def test_every_env_gives_finite_measures_per_episode_in_the_order_of_the_returns(env_id):
    rule = next(iter(RULES[env_id]))
    env = make_sb3_env(env_id, 2, 0)
    try:
        policy = RULES[env_id][rule](env_params(env), simulator_state(env))
        stats = evaluate(policy, env, 3, 7)
        # by hand: slot 0's first episode (the first of the returns)
        env.seed(7)
        obs = env.reset()
        start, state, steps, sums = np.ones(2, bool), None, 0, {}
        while True:
            action, state = policy.predict(
                obs, state=state, episode_start=start, deterministic=True
            )
            obs, _, done, infos = env.step(action)
            info = infos[0]["final_info"] if done[0] else infos[0]
            steps += 1
            for key, value in info.items():
                if isinstance(value, float):
                    sums[key] = sums.get(key, 0.0) + value
            start = done
            if done[0]:
                break
    finally:
        env.close()
    measures = TAIL_MEASURES[env_id]
    assert set(stats.tails) == {m.name for m in measures}
    for m in measures:
        values = np.asarray(stats.tails[m.name])
        assert values.shape == (3,), m.name
        # a ratio is missing (NaN) in an episode where its denominator never counted: no fix
        # in the whole episode has no fix_sigma (quantile_summary leaves it out); hold-still,
        # the first crowded rule, loses every drone in some episodes
        finite = np.isfinite(values)
        assert np.all(finite | (m.reading == "ratio")), m.name
        assert np.all(values[finite] >= 0.0), m.name
        if m.unit == "share":
            assert np.all(values[finite] <= 1.0), m.name
        want = (
            m.scale
            * {
                "final": info[m.key],
                "mean": sums[m.key] / steps,
                "ratio": (sums[m.key] / sums[m.per] if sums[m.per] > 0 else np.nan)
                if m.per
                else 0.0,
            }[m.reading]
        )
        assert values[0] == pytest.approx(want, rel=1e-12, nan_ok=True), m.name
    d = stats.as_dict()
    assert set(d["tails"]) == set(stats.tails)
    bare = make_sb3_env(env_id, 2, 0)
    try:
        assert "tails" not in evaluate(policy, bare, 2, 7, tails=()).as_dict()
    finally:
        bare.close()


def _brute_force_gospa(x: np.ndarray, y: np.ndarray, c: float, p: float) -> float:
    """GOSPA (α = 2) by its definition: every partial assignment, pairs closer than ``c``."""
    best = np.inf
    k, m = len(x), len(y)
    for n in range(min(k, m) + 1):
        for rows in itertools.combinations(range(k), n):
            for cols in itertools.permutations(range(m), n):
                d = [np.linalg.norm(x[i] - y[j]) for i, j in zip(rows, cols, strict=True)]
                if any(di >= c for di in d):
                    continue
                cost = sum(di**p for di in d) + c**p / 2 * (k + m - 2 * n)
                best = min(best, cost)
    return float(best ** (1 / p))


def _random_sets(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    k, m = rng.integers(0, 6, size=2)
    truths = rng.uniform(-5.0, 5.0, (m, 3))
    near = truths[rng.integers(0, max(m, 1), k)] if m else np.zeros((k, 3))
    tracks = near + rng.normal(0.0, 2.0, (k, 3))  # some within the cut-off, some not
    return tracks, truths


def test_gospa_matches_its_definition_over_every_assignment():
    rng = np.random.default_rng(1)
    for _ in range(150):
        x, y = _random_sets(rng)
        c, p = float(rng.uniform(0.5, 6.0)), float(rng.choice([1.0, 2.0, 3.0]))
        assert gospa(x, y, c, p) == pytest.approx(_brute_force_gospa(x, y, c, p), rel=1e-12)


def test_gospa_matches_stone_soup():
    pytest.importorskip("stonesoup")
    from stonesoup.metricgenerator.ospametric import GOSPAMetric
    from stonesoup.types.array import StateVector
    from stonesoup.types.state import State

    t = datetime.datetime(2025, 1, 1)
    rng = np.random.default_rng(2)
    for _ in range(200):
        x, y = _random_sets(rng)
        c = float(rng.uniform(0.5, 6.0))
        metric = GOSPAMetric(c=c, p=2)
        tracks = [State(StateVector(row), timestamp=t) for row in x]
        truths = [State(StateVector(row), timestamp=t) for row in y]
        if not tracks and not truths:  # Stone Soup needs a state to read the time off
            assert gospa(x, y, c, 2.0) == 0.0
            continue
        want = metric.compute_gospa_metric(tracks, truths)[0].value["distance"]
        assert gospa(x, y, c, 2.0) == pytest.approx(want, rel=1e-9, abs=1e-12)


def test_scanning_info_gospa_is_that_of_the_confirmed_tracks_and_present_drones():
    from sensorgym.envs.stereo_scanning import simulation as sim

    env = make_sb3_env("sensorgym/StereoScanning-v0", 2, 0)
    try:
        policy = RULES["sensorgym/StereoScanning-v0"]["full-sweep"](
            env_params(env), simulator_state(env)
        )
        obs, start, lstm = env.reset(), np.ones(2, bool), None
        params = env_params(env)
        for _ in range(12):
            action, lstm = policy.predict(obs, state=lstm, episode_start=start, deterministic=True)
            obs, _, start, infos = env.step(action)
        s = simulator_state(env)()
    finally:
        env.close()
    for b in range(2):
        confirmed = s.track_status[b] == 2
        x = s.track_x[b, confirmed]
        tracks = x[:, :3] + x[:, 3:6] * (s.t[b] - s.track_t[b, confirmed])[:, None]
        present = (s.enter[b] <= s.t[b] - params.period + 1e-9) & ~s.exited[b]
        want = gospa(tracks, s.drone_position[b, present], params.truth_gate)
        assert infos[b]["gospa"] == pytest.approx(want)
        assert sim.period_gospa(params, s)[b] == pytest.approx(want)


def test_rms_ratio_is_exact_on_scaled_errors_and_its_interval_is_paired():
    from sensorgym.train.tail import rms_ratio

    rng = np.random.default_rng(7)
    reference = np.abs(rng.standard_cauchy(256)) * 100.0  # heavy-tailed, like final errors
    ratio, lo, hi = rms_ratio(2.0 * reference, reference)
    assert (
        ratio == pytest.approx(2.0, rel=1e-12)
        and lo == pytest.approx(2.0)
        and hi == pytest.approx(2.0)
    )
    # an independent error of the same (light-tailed) law: the interval holds the ratio and 1
    other = np.abs(rng.normal(0.0, 100.0, 256))
    light = np.abs(rng.normal(0.0, 100.0, 256))
    r, lo, hi = rms_ratio(other, light)
    assert lo < r < hi and lo < 1.0 < hi and hi - lo < 0.5
    # a truly larger error of the same law is told apart
    assert rms_ratio(1.5 * other, light)[1] > 1.0
    assert rms_ratio(other, light) == (r, lo, hi)  # seeded: a table regenerates identically
    with_nan = np.append(other, np.nan)
    assert rms_ratio(with_nan, np.append(light, 5.0)) == (r, lo, hi)  # a pair with a NaN drops


@pytest.mark.parametrize(
    ("values", "reference", "match"),
    [
        ([1.0, 2.0], [1.0], "one length"),
        ([1.0], [0.0], "no finite, non-zero"),
        ([np.nan], [1.0], "no finite, non-zero"),
    ],
)
def test_rms_ratio_refuses_what_it_cannot_divide(values, reference, match):
    from sensorgym.train.tail import rms_ratio

    with pytest.raises(ValueError, match=match):
        rms_ratio(values, reference)
