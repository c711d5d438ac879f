"""Figures of ``sensorgym reproduce paper001``: pure functions of the result dict of
:func:`sensorgym.reproduce.experiments.paper001.reproduce`.

matplotlib (Agg backend) is imported inside :func:`write_figures`, so the reproduction's numbers
never depend on a plotting installation.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from sensorgym.envs.worlds.gimbal import StraightTrajectory
from sensorgym.reproduce.experiments.reporting import save_figure


def write_figures(result: dict, out: Path) -> list[Path]:
    """Figures like the paper's 3–9 plus RMS error vs horizon, as PNG files in ``out``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ex = result["example"]
    loss, gate = result["loss_frame"], result["gate"]
    frames = np.asarray(ex["frames"])
    gate_frames = loss + np.asarray(result["horizons"])
    colours = {"abc": "C1", "linefit": "C2", "kalman": "C3"}
    written = []

    def save(fig, name: str) -> None:
        written.append(save_figure(fig, out / name))

    traj = StraightTrajectory()
    pos = traj.positions(np.arange(loss + gate + 1))
    fig = plt.figure(figsize=(6, 5))
    ax = fig.add_subplot(projection="3d")
    ax.plot(pos[:loss, 0], pos[:loss, 1], pos[:loss, 2], label="observed")
    ax.plot(pos[loss:, 0], pos[loss:, 1], pos[loss:, 2], "--", label="image lost")
    ax.scatter([0], [0], [0], c="k", label="carrier O")
    ax.set_xlabel("X, m")
    ax.set_ylabel("Y, m")
    ax.set_zlabel("Z, m")
    ax.legend()
    ax.set_title("Fig. 3 — object trajectory")
    save(fig, "fig3_trajectory.png")

    w = result["window"]
    for angle in ("azimuth", "elevation"):
        true_key = f"true_{angle}_deg"
        true = np.asarray(ex[true_key])
        # one-step-ahead (Figs. 4–5 for azimuth; the same for elevation)
        fig, axes = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
        ahead = frames[w:-1] + 1
        axes[0].plot(ahead, true[w + 1 :], label="true")
        abc1 = np.asarray(ex["predictors"]["abc"][f"one_step_{angle}_deg"])[w:-1]
        axes[0].plot(ahead, abc1, ":", label="A-B-C, predicted 1 frame ahead")
        axes[0].set_ylabel(f"{angle}, deg")
        axes[0].legend()
        for name, v in ex["predictors"].items():
            one = np.asarray(v[f"one_step_{angle}_deg"])[w:-1]
            axes[1].plot(ahead, one - true[w + 1 :], color=colours[name], lw=0.8, label=name)
        axes[1].set_xlabel("frame n")
        axes[1].set_ylabel("error, deg")
        axes[1].legend()
        axes[0].set_title(f"1-frame-ahead {angle} (cf. Figs. 4–5), one realisation")
        save(fig, f"fig4_5_{angle}_one_step.png")
        # prediction gate (Figs. 6–7 azimuth, 8–9 elevation)
        fig, axes = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
        gt = np.asarray(ex[f"gate_true_{angle}_deg"])
        axes[0].plot(frames, true, label="true (visible)")
        axes[0].plot(gate_frames, gt, label="true (lost)")
        for name, v in ex["predictors"].items():
            axes[0].plot(gate_frames, v[f"gate_{angle}_deg"], "--", color=colours[name], label=name)
            axes[1].plot(
                gate_frames,
                np.asarray(v[f"gate_{angle}_deg"]) - gt,
                color=colours[name],
                label=name,
            )
        for a in axes:
            a.axvspan(loss, loss + gate, color="0.9", zorder=0)
        axes[0].set_ylabel(f"{angle}, deg")
        axes[0].legend(fontsize=8)
        axes[1].set_ylabel("error, deg")
        axes[1].set_xlabel("frame n (grey: prediction gate)")
        axes[1].legend(fontsize=8)
        first = 6 if angle == "azimuth" else 8
        axes[0].set_title(f"{angle} through the loss (cf. Figs. {first}–{first + 1})")
        save(fig, f"fig{first}_{first + 1}_{angle}_gate.png")

    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    k = np.asarray(result["horizons"])
    for name, v in result["errors"].items():
        axes[0].semilogy(k, v["rms_azimuth_deg"], color=colours[name], label=name)
        axes[1].semilogy(k, v["rms_elevation_deg"], color=colours[name], label=name)
    for a, t in zip(axes, ("azimuth", "elevation"), strict=True):
        a.set_xlabel("frames since the loss, k")
        a.set_ylabel("RMS error, deg")
        a.set_title(f"{t}: {result['runs']} runs")
        a.grid(True, which="both", alpha=0.3)
        a.legend()
    save(fig, "rms_error_vs_horizon.png")
    return written
