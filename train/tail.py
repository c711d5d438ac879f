"""The tail in physical units: per env, the accuracy measures a user of that sensor quotes.

Returns are log-ratios and their mean hides the few episodes that go badly. Each env declares
one or two measures in :data:`TAIL_MEASURES`, read per episode from the diagnostics of its
simulation's ``info`` (ground truth allowed there: evaluation only, never the policy's
observation); :func:`~sensorgym.train.evaluation.evaluate` collects them per episode in the
order of the returns and :func:`tail_summary` gives each one's median, p90 and CVaR₅ % (the
mean of the worst 5 % of the episodes, worst = largest for a lower-is-better measure) beside
the return's p10.

| env | measure | unit | per episode |
|-----|---------|------|-------------|
| BearingsManeuver, Book | ``final_error`` | m | the env's tracker's position error at the end |
| | ``final_bound`` | m | the position RMS bound ``√(P_xx + P_yy)`` (PCRLB) at the end |
| StereoPointing, Crowded, StereoPlacement | ``fix_sigma`` | m | mean CRLB ``σ_pos`` over the fixed drone-steps |
| | ``no_fix_share`` | share | drone-steps without a fix / all drone-steps |
| StereoScanning | ``gospa`` | m | mean over periods of GOSPA (``c = truth_gate``, ``p = 2``, ``α = 2``) |
| GimbalTracking | ``pointing_error`` | mrad | mean over the frames of the angle between the boresight and the target |
| | ``in_view_share`` | share | frames with the target in the field of view / frames (higher is better) |
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

#: how a measure is read: ``final`` the value of ``key`` in the info of the step that ended
#: the episode; ``mean`` the mean of ``key`` over the episode's steps; ``ratio`` the sum of
#: ``key`` over the steps divided by the sum of ``per``
Reading = Literal["final", "mean", "ratio"]


@dataclass(frozen=True)
class Measure:
    """One tail measure of an env: how it is read per episode from the env's ``info``."""

    name: str
    """The measure's name in results (``tails[name]``)."""
    unit: str
    """``"m"`` (metres), ``"mrad"`` (milliradians) or ``"share"`` (a fraction in [0, 1])."""
    key: str
    """The ``info`` entry it is read from."""
    reading: Reading = "final"
    """How the per-step entries make the episode's value (:data:`Reading`)."""
    per: str | None = None
    """The denominator's ``info`` entry of a ``ratio`` (summed over the steps)."""
    lower_is_better: bool = True
    """Whether a smaller value is better (the worst 5 % are then the largest)."""
    description: str = ""
    """One line for tables and docs."""
    scale: float = 1.0
    """The ``info`` entry times this is the measure in :attr:`unit` (1000 for radians read as
    milliradians)."""

    def __post_init__(self) -> None:
        if (self.reading == "ratio") != (self.per is not None):
            raise ValueError(f"{self.name}: a 'ratio' reading needs `per`, no other does")

    @property
    def per_step(self) -> bool:
        """Whether the measure accumulates over the episode's steps."""
        return self.reading != "final"


_BEARINGS = (
    Measure(
        "final_error", "m", "position_error",
        description="the env's tracker's position error at the episode end",
    ),
    Measure(
        "final_bound", "m", "position_bound",
        description="the position RMS bound sqrt(P_xx + P_yy) (PCRLB) at the episode end",
    ),
)  # fmt: skip
_STEREO = (
    Measure(
        "fix_sigma", "m", "fixed_sigma_sum", "ratio", "fixed_sigma_count",
        description="mean CRLB position sigma over the drone-steps with a fix",
    ),
    Measure(
        "no_fix_share", "share", "unfixed_share", "mean",
        description="share of the drone-steps without a fix",
    ),
)  # fmt: skip

#: env id → its tail measures, the first the main one (the printed table's)
TAIL_MEASURES: dict[str, tuple[Measure, ...]] = {
    "sensorgym/BearingsManeuver-v0": _BEARINGS,
    "sensorgym/BearingsManeuverBook-v0": _BEARINGS,
    "sensorgym/StereoPointing-v0": _STEREO,
    "sensorgym/StereoPointingCrowded-v0": _STEREO,
    "sensorgym/StereoPlacement-v0": _STEREO,
    "sensorgym/StereoScanning-v0": (
        Measure(
            "gospa", "m", "gospa", "mean",
            description="mean over the periods of GOSPA (c = truth_gate, p = 2, alpha = 2)",
        ),
    ),
    "sensorgym/GimbalTracking-v0": (
        Measure(
            "pointing_error", "mrad", "pointing_error", "mean", scale=1000.0,
            description="mean over the frames of the angle between the boresight and the target",
        ),
        Measure(
            "in_view_share", "share", "in_view", "mean", lower_is_better=False,
            description="share of the frames with the target in the field of view",
        ),
    ),
}  # fmt: skip

#: units of an error whose RMS over the episodes a tracking user quotes
ERROR_UNITS = frozenset({"m", "mrad"})

#: the share of the worst episodes the CVaR averages
CVAR_SHARE = 0.05


def measures_for(env_id: str | None) -> tuple[Measure, ...]:
    """The tail measures of ``env_id`` (none for an env without them)."""
    return TAIL_MEASURES.get(env_id or "", ())


class TailCollector:
    """Accumulates the tail measures of the episodes of ``slots`` vector-env slots."""

    def __init__(self, measures: Sequence[Measure], slots: int):
        self.measures = tuple(measures)
        self.sums = {m.name: np.zeros(slots) for m in self.measures if m.per_step}
        self.pers = {m.name: np.zeros(slots) for m in self.measures if m.reading == "ratio"}
        self.steps = np.zeros(slots)

    def step(self, infos: Sequence[Mapping[str, Any]], done: np.ndarray) -> None:
        """Add one step's diagnostics (``infos[i]["final_info"]`` for a slot whose episode
        ended on it, whose own info is already the next episode's)."""
        if not self.sums:
            return
        rows = [i.get("final_info", i) if d else i for i, d in zip(infos, done, strict=True)]
        self.steps += 1.0
        for m in self.measures:
            if m.per_step:
                self.sums[m.name] += m.scale * _column(rows, m.key)
            if m.per is not None:
                self.pers[m.name] += _column(rows, m.per)

    def episode(self, i: int, info: Mapping[str, Any]) -> dict[str, float]:
        """Slot ``i``'s values of the episode that just ended (``info``: its ``final_info``),
        after :meth:`step` has added its last step; then the slot's sums restart."""
        out = {}
        for m in self.measures:
            if m.reading == "final":
                value = m.scale * float(info.get(m.key, np.nan))
            elif m.reading == "mean":
                value = float(self.sums[m.name][i] / max(self.steps[i], 1.0))
            else:
                per = self.pers[m.name][i]
                value = float(self.sums[m.name][i] / per) if per > 0 else float("nan")
            out[m.name] = value
        for s in self.sums.values():
            s[i] = 0.0
        for s in self.pers.values():
            s[i] = 0.0
        self.steps[i] = 0.0
        return out


def _column(rows: Sequence[Mapping[str, Any]], key: str) -> np.ndarray:
    return np.array([float(r.get(key, np.nan)) for r in rows])


def quantile_summary(values: Sequence[float], lower_is_better: bool = True) -> dict[str, Any]:
    """``median``, ``p90`` and ``cvar5`` of the finite ``values`` (``p90``: the 90th
    percentile, or the 10th for a higher-is-better measure — the bad side; ``cvar5``: the mean
    of the worst ``⌈5 %⌉`` of them, at least one), for a lower-is-better measure its ``rms``
    ``√(mean x²)`` (an error's RMS, as a tracking user quotes it), and ``episodes`` (finite values) and
    ``missing`` (not finite: an episode without any fix has no ``fix_sigma``)."""
    x = np.asarray(values, dtype=np.float64)
    finite = x[np.isfinite(x)]
    out: dict[str, Any] = {"episodes": int(finite.size), "missing": int(x.size - finite.size)}
    if finite.size == 0:
        return {**out, "median": None, "p90": None, "cvar5": None, "rms": None}
    worst_q = 90.0 if lower_is_better else 10.0
    out["median"] = float(np.median(finite))
    out["p90"] = float(np.percentile(finite, worst_q))
    out["cvar5"] = cvar(finite, CVAR_SHARE, lower_is_better)
    out["rms"] = rms(finite) if lower_is_better else None
    return out


def rms(values: Sequence[float]) -> float:
    """``√(mean x²)`` of the finite ``values`` (NaN when there are none)."""
    x = np.asarray(values, dtype=np.float64)
    x = x[np.isfinite(x)]
    return float(np.sqrt(np.mean(x**2))) if x.size else float("nan")


def rms_ratio(
    values: Sequence[float],
    reference: Sequence[float],
    resamples: int = 4000,
    seed: int = 0,
) -> tuple[float, float, float]:
    """``(ratio, lo, hi)``: ``rms(values) / rms(reference)`` over the episodes where both are
    finite, and its 95 % paired percentile-bootstrap interval (episodes resampled together, so
    the scenario spread both share cancels; a fixed ``seed``, so a table regenerates
    identically). An RMS over a few hundred episodes is carried by its handful of worst ones: the
    interval says whether "worse RMS than the rule" is more than which episodes were drawn."""
    x = np.asarray(values, dtype=np.float64)
    y = np.asarray(reference, dtype=np.float64)
    if x.shape != y.shape or x.ndim != 1:
        raise ValueError(
            f"values, reference: expected two 1-D arrays of one length, got {x.shape}, {y.shape}"
        )
    keep = np.isfinite(x) & np.isfinite(y)
    x, y = x[keep], y[keep]
    if x.size == 0 or not np.any(y != 0.0):
        raise ValueError("reference: no finite, non-zero value to divide by")
    ratio = float(np.sqrt(np.mean(x**2) / np.mean(y**2)))
    idx = np.random.default_rng(seed).integers(0, x.size, (resamples, x.size))
    num, den = np.mean(x[idx] ** 2, axis=1), np.mean(y[idx] ** 2, axis=1)
    boot = np.sqrt(num[den > 0] / den[den > 0])
    lo, hi = np.quantile(boot, [0.025, 0.975])
    return ratio, float(lo), float(hi)


def cvar(values: Sequence[float], share: float = CVAR_SHARE, lower_is_better: bool = True) -> float:
    """The mean of the worst ``share`` of ``values`` (worst = largest if ``lower_is_better``,
    else smallest): the ``⌈share · n⌉`` worst values, at least one."""
    if not 0.0 < share <= 1.0:
        raise ValueError(f"share: must be in (0, 1], got {share}")
    x = np.sort(np.asarray(values, dtype=np.float64))
    if x.size == 0:
        raise ValueError("values: expected at least one")
    k = max(1, int(np.ceil(share * x.size - 1e-9)))
    worst = x[-k:] if lower_is_better else x[:k]
    return float(worst.mean())


def tail_summary(result: Mapping[str, Any], measures: Sequence[Measure] = ()) -> dict[str, Any]:
    """Tail statistics of one policy's result (:meth:`.evaluation.EpisodeStats.as_dict`):
    ``return_p10`` (the 10th percentile of the returns, the bad side) and per measure of its
    ``tails`` its unit, ``lower_is_better`` and :func:`quantile_summary`. ``measures``: their
    declarations (unit, direction); a measure not declared there is taken as metres, lower
    better."""
    declared = {m.name: m for m in measures}
    returns = np.asarray(result.get("returns", ()), dtype=np.float64)
    out: dict[str, Any] = {
        "return_p10": float(np.percentile(returns, 10.0)) if returns.size else None
    }
    stats: dict[str, Any] = {}
    for name, values in result.get("tails", {}).items():
        m = declared.get(name)
        lower = m.lower_is_better if m is not None else True
        stats[name] = {
            "unit": m.unit if m is not None else "m",
            "lower_is_better": lower,
            **quantile_summary(values, lower),
        }
    out["measures"] = stats
    return out
