"""The env's tracker reproduces paper 000's targets under the fixed sweep (fast settings)."""

from __future__ import annotations

import numpy as np

from sensorgym.reproduce.experiments.paper000 import Scenario000
from sensorgym.reproduce.experiments.scanning000 import format_report, reproduce, run_cell


def test_proposed_tracker_through_the_env_has_the_maxwell_error_and_finds_every_object():
    o = run_cell(np.random.default_rng(0), Scenario000(), "proposed", 1, (0.3, 0.4), 150)
    # Maxwell(σ = 0.1): mean 0.160, std 0.067 (theory §5.7); 150 runs: ±0.01 / ±0.008
    assert 0.14 <= o["d_avg"] <= 0.18
    assert 0.055 <= o["d_std"] <= 0.08
    assert o["pr_m"] >= 0.95


def test_alternative_error_grows_with_the_scan_delay_and_its_detection_falls():
    sc = Scenario000()
    short = run_cell(np.random.default_rng(1), sc, "alternative", 1, (0.10,), 200)
    long = run_cell(np.random.default_rng(2), sc, "alternative", 1, (0.25,), 200)
    assert 1.9 <= long["d_avg"] / short["d_avg"] <= 3.1
    assert long["pr_m"] < short["pr_m"]


def test_the_report_prints_ours_beside_the_papers(capsys):
    result = reproduce(runs=6, seed=3)
    text = format_report(result)
    assert "Table 1" in text and "Table 2" in text and "RT-2" in text
    assert "1.25/0.89" in text  # the paper's number beside ours
    assert len(result["cells"]) == 8
