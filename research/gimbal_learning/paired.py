"""The probes' paired comparison: per-scenario return differences to a base on the same
scenarios, their mean and 95 % half-width (normal approximation)."""

import numpy as np


def paired(returns, base):
    """``{"paired": mean, "ci95": half-width}`` of ``returns − base`` (same scenarios)."""
    d = np.asarray(returns, np.float64) - np.asarray(base, np.float64)
    return {"paired": float(d.mean()), "ci95": float(1.96 * d.std(ddof=1) / np.sqrt(d.size))}


def compare(candidates, base, play, seeds):
    """Each of ``candidates`` (name → policy) played on ``seeds`` by ``play(policy, seed)``
    and paired to ``base`` (the concatenated returns of the same seeds); printed as it goes."""
    results = {}
    for name, policy in candidates.items():
        results[name] = paired(np.concatenate([play(policy, seed) for seed in seeds]), base)
        r = results[name]
        print(f"{name:34s} paired {r['paired']:+7.1f} ± {r['ci95']:5.1f}", flush=True)
    return results
