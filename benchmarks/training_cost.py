"""Put a shipped run's training cost on the record by training it again.

For each shipped run folder given (``train/policies/<env>/<run>/``) this trains the run once
more from its saved ``config.yaml`` (algorithm, seed, env params, the resolved hyperparameter
set) into a temporary folder with today's ``sensorgym train``, then compares the new weights
with the shipped ones tensor by tensor, bit for bit (the safetensors header is compared as a
mapping: its metadata's order varies from save to save). Only when every tensor is identical
does the retraining measure the shipped run's cost: its ``cost.json`` (:mod:`sensorgym.train.cost`)
is copied into the shipped folder with a ``reproduced`` note, and the ``wall_s``/``eval_s`` of its
curve points (and ARS iterations) are merged into the shipped ``curve.json`` (``search.json``),
whose ``curve.png`` is redrawn. When the weights are identical but the curve's points are not
(a run trained before the curve's points and evaluation seed were fixed), the retraining's
``curve.json``, ``curve.png``, ``evaluation.json`` (and ``search.json``) replace the shipped
ones: the same weights, now with a clock and evaluated on the tuning seed. When the weights
differ it reports by how much, records that (and the retraining's own cost) in
``benchmarks/results/training_cost_unreproducible.json`` and writes nothing into the run.

``--estimate`` trains nothing: for every shipped run without a cost record it prints the
samples it trained on and a time estimate from ``benchmarks/results/training.json``'s PPO fps
for its env (samples / fps), and that estimate scaled by what the recorded runs took against
their own such estimate (the fps benchmark has no imitation, wrappers, curve evaluations or
rollout-heavy policies, so the plain quotient is a floor).

    python benchmarks/training_cost.py train/policies/sensorgym__BearingsManeuverBook-v0/*/
    python benchmarks/training_cost.py --estimate
"""

from __future__ import annotations

import argparse
import json
import shutil
import struct
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import yaml

ROOT = Path(__file__).resolve().parents[1]
TRAINING = ROOT / "benchmarks" / "results" / "training.json"
#: shipped runs whose retraining from config.yaml gave other weights (the env changed since)
UNREPRODUCIBLE = ROOT / "benchmarks" / "results" / "training_cost_unreproducible.json"


def read_safetensors(path: Path) -> tuple[dict[str, Any], dict[str, bytes]]:
    """The header (a mapping) and every tensor's raw bytes of a safetensors file."""
    data = Path(path).read_bytes()
    (n,) = struct.unpack("<Q", data[:8])
    header = json.loads(data[8 : 8 + n])
    body = data[8 + n :]
    tensors = {
        name: body[slice(*entry["data_offsets"])]
        for name, entry in header.items()
        if name != "__metadata__"
    }
    return header, tensors


def compare_weights(shipped: Path, retrained: Path) -> dict[str, Any]:
    """``identical`` (every tensor's bytes and the header mapping), and per differing tensor
    its largest absolute difference and the share of elements that differ."""
    from safetensors.numpy import load_file

    head_a, raw_a = read_safetensors(shipped)
    head_b, raw_b = read_safetensors(retrained)
    report: dict[str, Any] = {"identical": head_a == head_b and raw_a == raw_b, "tensors": {}}
    if report["identical"]:
        return report
    a, b = load_file(shipped), load_file(retrained)
    for name in sorted(set(a) | set(b)):
        if name not in a or name not in b or a[name].shape != b[name].shape:
            report["tensors"][name] = "missing or of another shape"
        elif raw_a[name] != raw_b[name]:
            diff = abs(a[name].astype("float64") - b[name].astype("float64"))
            report["tensors"][name] = {
                "max_abs_diff": float(diff.max()),
                "differing_share": float((diff > 0).mean()),
                "max_abs_value": float(abs(a[name]).max()),
            }
    if head_a != head_b:
        report["header"] = "the headers differ (shapes, dtypes or metadata)"
    return report


def _merge_clock(rows: list[dict], new_rows: list[dict], key: str) -> list[dict] | None:
    """``rows`` with ``wall_s``/``eval_s`` of ``new_rows`` matched on ``key`` (``None`` when
    the two do not pair up row for row)."""
    if [r[key] for r in rows] != [r[key] for r in new_rows]:
        return None
    clock = ("wall_s", "eval_s")
    return [
        {**r, **{k: n[k] for k in clock if k in n}} for r, n in zip(rows, new_rows, strict=True)
    ]


def retrain(run_dir: Path, write: bool = True) -> dict[str, Any]:
    """Retrain the shipped run ``run_dir`` in a temporary folder and, when its weights are
    bit-identical, put the retraining's cost on the shipped run's record (see the module
    docstring). Returns what was found."""
    from sensorgym.train.cost import COST_FILE, now_utc
    from sensorgym.train.curves import write_curve
    from sensorgym.train.trainer import SEARCH_FILE, train

    run_dir = Path(run_dir).resolve()
    config = yaml.safe_load((run_dir / "config.yaml").read_text())
    evaluation = json.loads((run_dir / "evaluation.json").read_text())
    curve_path = run_dir / "curve.json"
    curve = json.loads(curve_path.read_text()) if curve_path.is_file() else None
    report: dict[str, Any] = {"run": str(run_dir.relative_to(ROOT)), "recorded": False}
    with tempfile.TemporaryDirectory() as tmp:
        begin = time.perf_counter()
        result = train(
            config["env"], config["algo"], seed=config["seed"], out=Path(tmp), progress=False,
            agents=bool(config.get("agents", False)), params=config.get("params") or {},
            hyperparams=config["hyperparams"], eval_episodes=evaluation["episodes"],
        )  # fmt: skip
        report["seconds"] = time.perf_counter() - begin
        new_config = yaml.safe_load((result.run_dir / "config.yaml").read_text())
        if new_config["hyperparams"] != config["hyperparams"]:
            report["error"] = "today's YAML resolves to another hyperparameter set"
            return report
        weights = compare_weights(
            run_dir / "policy.safetensors", result.run_dir / "policy.safetensors"
        )
        report["weights"] = weights
        cost = json.loads((result.run_dir / COST_FILE).read_text())
        report["cost"] = cost
        if not weights["identical"]:
            if write:  # why the run has no cost record: on the record, beside the others
                record_unreproducible(report, cost)
            return report
        new_curve = json.loads((result.run_dir / "curve.json").read_text())
        points = (
            None
            if curve is None
            else _merge_clock(curve["points"], new_curve["points"], "timesteps")
        )
        # the same weights but other curve points (a run trained before the curve's points and
        # its evaluation seed were fixed): the retraining's whole record replaces the shipped
        # one, which is then evaluated on the tuning seed like every later run's
        replace = curve is not None and points is None
        search = None
        if (run_dir / SEARCH_FILE).is_file():
            old = json.loads((run_dir / SEARCH_FILE).read_text())
            new = json.loads((result.run_dir / SEARCH_FILE).read_text())
            search = _merge_clock(old, new, "iteration")
            replace = replace or search is None
        report["record_replaced"] = replace
        if not write:
            return report
        cost["reproduced"] = {
            "by": "benchmarks/training_cost.py",
            "date_utc": now_utc(),
            "note": "measured on a retraining from config.yaml whose weights are bit-identical "
            "to the shipped ones",
            "shipped_evaluation_seed": evaluation["seed"],
            "retraining_evaluation_seed": json.loads(
                (result.run_dir / "evaluation.json").read_text()
            )["seed"],
        }
        if replace:
            cost["reproduced"]["record_replaced"] = (
                "the shipped curve's points differed from the retraining's: curve.json, "
                "curve.png, evaluation.json (and search.json) are the retraining's"
            )
            for name in ("curve.json", "curve.png", "evaluation.json", SEARCH_FILE):
                if (result.run_dir / name).is_file():
                    shutil.copyfile(result.run_dir / name, run_dir / name)
            (run_dir / COST_FILE).write_text(json.dumps(cost, indent=2) + "\n")
            report["recorded"] = True
            return report
        (run_dir / COST_FILE).write_text(json.dumps(cost, indent=2) + "\n")
        if search is not None:
            (run_dir / SEARCH_FILE).write_text(json.dumps(search, indent=1) + "\n")
        if curve is not None:
            title = f"{config['algo']} on {config['env']}, seed {config['seed']}"
            write_curve(run_dir, title, points, curve["rules"], curve.get("pretrain_loss"))
        report["recorded"] = True
    return report


def record_unreproducible(report: dict[str, Any], cost: dict[str, Any]) -> None:
    """Merge into :data:`UNREPRODUCIBLE` the shipped run whose retraining gave other weights:
    the date, the largest weight difference and the retraining's own cost (the recipe's time
    on this machine, not the shipped run's), so that the training-cost table can say why the
    run has no cost of its own."""
    from sensorgym.train.cost import now_utc

    doc = json.loads(UNREPRODUCIBLE.read_text()) if UNREPRODUCIBLE.is_file() else {}
    tensors = report["weights"].get("tensors", {})
    doc[report["run"]] = {
        "date_utc": now_utc(),
        "weights_identical": False,
        "max_abs_weight_diff": max((t["max_abs_diff"] for t in tensors.values()), default=None),
        "retraining_cost": cost,
    }
    UNREPRODUCIBLE.write_text(json.dumps(dict(sorted(doc.items())), indent=1) + "\n")


def shipped_runs() -> list[Path]:
    from sensorgym.train.shipped import POLICIES_ROOT

    return sorted(p.parent for p in POLICIES_ROOT.glob("*/*/policy.safetensors"))


def run_samples(run_dir: Path) -> tuple[int, int]:
    """RL samples (the last curve point's, else the config's) and imitation samples of a run."""
    from sensorgym.train.cost import pretrain_samples

    config = yaml.safe_load((run_dir / "config.yaml").read_text())
    hp = config["hyperparams"]
    curve = run_dir / "curve.json"
    steps = (
        json.loads(curve.read_text())["points"][-1]["timesteps"]
        if curve.is_file()
        else hp["n_timesteps"]
    )
    pre = hp.get("pretrain")
    imitated = pretrain_samples(pre["steps"], pre.get("rounds", 1), hp["n_envs"]) if pre else 0
    return int(steps), imitated


def estimate() -> list[dict[str, Any]]:
    """For every shipped run: its samples, its recorded training seconds where there are any,
    else the fps estimate and the one scaled by the recorded runs' ratio."""
    from sensorgym.train.cost import read_cost

    fps = {r["env"]: r["adapter_fps"] for r in json.loads(TRAINING.read_text())["results"]}
    rows, ratios = [], []
    for run in shipped_runs():
        env = yaml.safe_load((run / "config.yaml").read_text())["env"]
        steps, imitated = run_samples(run)
        floor = (steps + imitated) / fps[env]
        cost = read_cost(run)
        row = {"run": str(run.relative_to(ROOT)), "samples": steps, "pretrain": imitated,
               "fps_estimate_s": floor}  # fmt: skip
        if cost is not None:
            row["recorded_s"] = cost["wall_s"]["total"]
            ratios.append(cost["wall_s"]["total"] / floor)
        rows.append(row)
    factor = max(ratios) if ratios else None
    for row in rows:
        if "recorded_s" not in row and factor is not None:
            row["scaled_estimate_s"] = row["fps_estimate_s"] * factor
            row["scale"] = factor
    return rows


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("runs", nargs="*", type=Path, help="shipped run folders")
    parser.add_argument("--estimate", action="store_true", help="estimate, train nothing")
    parser.add_argument("--dry-run", action="store_true", help="retrain and compare, write nothing")
    args = parser.parse_args()
    if args.estimate:
        for row in estimate():
            print(json.dumps(row))
        return 0
    failed = 0
    for run in args.runs:
        report = retrain(run, write=not args.dry_run)
        cost = report.get("cost", {})
        weights = report.get("weights", {})
        print(
            f"{report['run']}: weights {'bit-identical' if weights.get('identical') else 'DIFFER'}"
            f", training {cost.get('wall_s', {}).get('training', float('nan')):.1f} s of "
            f"{cost.get('wall_s', {}).get('total', float('nan')):.1f} s, "
            f"{cost.get('samples', {}).get('total')} samples; "
            f"{'recorded' if report['recorded'] else 'nothing recorded'}"
            + (f" ({report['error']})" if "error" in report else "")
        )
        if not weights.get("identical", False):
            print(json.dumps(weights.get("tensors", {}), indent=1))
        failed += not report["recorded"]
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
