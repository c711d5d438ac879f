"""The docs' speed tables, generated from the committed benchmark results (so they cannot drift).

``python benchmarks/tables.py`` rewrites every block between ``<!-- table:NAME -->`` and
``<!-- /table:NAME -->`` in README.md and docs/environments.md from
``benchmarks/results/*.json``; ``--check`` only reports (exit 1) blocks that differ — what
``tests/test_docs_tables.py`` runs.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"
DOCS = (ROOT / "README.md", ROOT / "docs" / "environments.md")
ENVS = ("bearings_maneuver", "stereo_pointing", "stereo_placement", "stereo_scanning")


def _rows(name: str) -> dict[str, dict]:
    doc = json.loads((RESULTS / f"{name}.json").read_text())
    return {row["case"]: row for row in doc["results"]}, doc["settings"]


def env_speed() -> str:
    """Single env and native vector env beside CartPole-v1, per env."""
    lines = [
        "| env | `gym.make`, steps/s | × CartPole-v1 | vector env, 1024 scenarios, scenario-steps/s | × CartPole-v1 | cold start, s |",
        "| --- | ---: | ---: | ---: | ---: | ---: |",
    ]
    for name in ENVS:
        rows, settings = _rows(name)
        single = rows["gym.make, 1 scenario"]
        vector = rows["native vector env, 1024"]
        cold = settings.get("cold_start_s")
        lines.append(
            f"| `{settings['env']}` | {single['per_s']:,.0f} | {single['vs_cartpole']:.2f} "
            f"| {vector['per_s']:,.0f} | {vector['vs_cartpole']:.2f} "
            f"| {'' if cold is None else f'{cold:.1f}'} |"
        )
    return "\n".join(lines)


def training_speed() -> str:
    """PPO fps through our adapter against SB3's DummyVecEnv, per env."""
    doc = json.loads((RESULTS / "training.json").read_text())
    n = doc["settings"]["n_envs"]
    lines = [
        f"| env | PPO fps, our adapter ({n} scenarios) | PPO fps, SB3 `DummyVecEnv` ({n} envs) | ratio |",
        "| --- | ---: | ---: | ---: |",
    ]
    for r in doc["results"]:
        lines.append(
            f"| `{r['env']}` | {r['adapter_fps']:,.0f} | {r['dummy_fps']:,.0f} | {r['ratio']:.0f}× |"
        )
    return "\n".join(lines)


SCORES = ROOT / "docs" / "scores"

#: what each scored policy is, for the score tables (``model:…`` rows are the PPO runs)
POLICY_LABELS = {
    "oracle-lookahead": "`OracleLookahead` (ceiling: knows the truth; best constant action over 5 steps on the true bound, receding horizon)",
    "paper002": "`Paper002Maneuver` (theory §10.5 OC-5: run along the bearing, then turn abeam at full speed)",
    "straight-course": "`StraightCourse` (no manoeuvre: range unobservable)",
    "orthogonal-pairs": "`OrthogonalPairs` (theory §10.1 OC-1: pair the receivers whose lines of sight are closest to 90°)",
    "track-nearest": "`TrackNearest` (each receiver on its nearest drone)",
    "hold-still": "`HoldStill` (stay on the cue until the drones leave the field of view)",
    "circle-placement": "`CirclePlacement` (theory §10.3 OC-3: circle of radius √2·ĥ around the estimated ground point)",
    "hold-position": "`HoldPosition` (stay in the 15 m start cluster)",
    "oracle-sectors": "`OracleSectors` (ceiling: the greedy sectors on the true drones)",
    "cue-following": "`CueFollowing` (sectors just covering the predicted tracks; a full sweep every fifth period)",
    "orthogonal-sectors": "`OrthogonalSectors` (theory §10.1 OC-1: narrow sectors on the tracks with the most orthogonal lines of sight)",
    "full-sweep": "`FullSweep` (the papers' fixed sweep of the whole field of regard)",
}


GREEDY_LABELS = {
    "BearingsManeuver-v0": "`GreedyManeuver` (one-step D-optimal, from the tracker's estimate)",
    "StereoPointing-v0": "`GreedyPointing` (assignment maximising Σ ln det of the predicted position information)",
    "StereoPlacement-v0": "`GreedyPlacement` (one-step move of every receiver maximising the env's reward predicted one period ahead)",
    "StereoScanning-v0": "`GreedyInformation` (the common width and centres maximising the expected covariance reward of the tracks)",
}


def scores(env: str) -> str:
    """Mean return ± 95 % of every policy of ``docs/scores/<env>.json``, best first."""
    doc = json.loads((SCORES / f"sensorgym__{env}.json").read_text())
    settings = doc["settings"]
    lines = [
        f"Seed {settings['seed']}, {settings['episodes']} episodes "
        f"(`docs/scores/sensorgym__{env}.json`):",
        "",
        "| policy | mean return | ± 95 % |",
        "| --- | ---: | ---: |",
    ]
    for name, r in sorted(doc["results"].items(), key=lambda kv: -kv[1]["mean"]):
        label = (
            GREEDY_LABELS[env] if name == "greedy-information" else POLICY_LABELS.get(name, name)
        )
        if name.startswith("model:"):
            label = f"PPO (`train/hyperparams/ppo.yml`, training seed 0), `{name[6:]}`"
        lines.append(f"| {label} | {r['mean']:.3f} | {r['ci95']:.3f} |")
    return "\n".join(lines)


def cold_start() -> str:
    """Seconds from a fresh interpreter to every env's first steps, with an empty and a warm
    numba cache (``benchmarks/cold_start.py``)."""
    doc = json.loads((RESULTS / "cold_start.json").read_text())
    lines = ["| | cold (empty cache), s | warm (cached kernels), s |", "| --- | ---: | ---: |"]
    for r in doc["results"]:
        case = r["case"] if r["case"] in ("import", "total") else f"`{r['case']}`"
        lines.append(f"| {case} | {r['cold_s']:.1f} | {r['warm_s']:.2f} |")
    return "\n".join(lines)


TABLES = {
    "env-speed": env_speed,
    "cold-start": cold_start,
    "training-speed": training_speed,
    "scores-bearings": lambda: scores("BearingsManeuver-v0"),
    "scores-pointing": lambda: scores("StereoPointing-v0"),
    "scores-placement": lambda: scores("StereoPlacement-v0"),
    "scores-scanning": lambda: scores("StereoScanning-v0"),
}


def render(text: str) -> str:
    """``text`` with every generated block replaced by its current table."""

    def block(match: re.Match) -> str:
        name = match.group(1)
        return f"<!-- table:{name} -->\n{TABLES[name]()}\n<!-- /table:{name} -->"

    pattern = r"<!-- table:([\w-]+) -->\n(?:.*?\n)?<!-- /table:\1 -->"
    return re.sub(pattern, block, text, flags=re.S)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--check", action="store_true", help="report stale tables, write none")
    args = parser.parse_args()
    stale = []
    for path in DOCS:
        text = path.read_text()
        new = render(text)
        if new != text:
            stale.append(path)
            if not args.check:
                path.write_text(new)
                print(f"wrote {path.relative_to(ROOT)}")
    if args.check and stale:
        print("stale tables in: " + ", ".join(str(p.relative_to(ROOT)) for p in stale))
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
