"""Figures of ``sensorgym reproduce paper004``: pure functions of the result dict of
:func:`sensorgym.reproduce.experiments.paper004.reproduce`.

matplotlib (Agg backend) is imported inside :func:`write_figures`, so the reproduction's numbers
never depend on a plotting installation.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from sensorgym.reproduce.experiments.paper004 import FORMS
from sensorgym.reproduce.experiments.reporting import save_figure


def write_figures(result: dict, out: Path) -> list[Path]:
    """Fig. 2 (a, b), the variance recurrence and a closed-loop example, as PNG files."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    f, s = result["formulas"], result["synergy"]
    rt16 = f["rt16"]
    written = []

    def save(fig, name: str) -> None:
        written.append(save_figure(fig, out / name))

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for j, L in enumerate(rt16["ranges_km"]):
        for form, ls in zip(FORMS, ("-", "--"), strict=True):
            err = rt16[form]["error_m"][f"{L:g}"]
            label = f"L = {L:g} km" if form == "mixture" else None
            axes[0].plot(rt16["q"], err, ls, color=f"C{j}", label=label)
            axes[1].plot(rt16["P"], err, ls, color=f"C{j}", label=label)
    axes[0].set_xlabel("detection parameter q")
    axes[1].set_xlabel("detection probability P (F = 0.01)")
    axes[1].set_xlim(0.0, 1.0)
    for a, t in zip(axes, ("(a)", "(b)"), strict=True):
        a.set_ylabel("tracking error Δ, m")
        a.set_title(f"Fig. 2{t}: solid (11a), dashed (11b)")
        a.grid(True, alpha=0.3)
        a.legend()
    save(fig, "fig2_tracking_error.png")

    fig, ax = plt.subplots(figsize=(6, 4))
    for i, q in enumerate(f["rt15"]["q"]):
        ax.semilogy(f["rt15"]["mixture"]["history"][i], color=f"C{i}", label=f"q = {q:g}")
        ax.semilogy(f["rt15"]["information"]["history"][i], "--", color=f"C{i}")
    ax.set_xlabel("step k")
    ax.set_ylabel("relative posterior variance δ_k")
    ax.set_title("RT-15: recurrence (11), solid (a), dashed (b)")
    ax.legend()
    ax.grid(True, which="both", alpha=0.3)
    save(fig, "rt15_variance_recurrence.png")

    fig, axes = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    for name in ("fused (4 weak)", "channel 0 alone", "one strong channel"):
        axes[0].plot(s[name]["example_pointing_error_mrad"], lw=0.8, label=name)
    limit = 0.5 * s["_scene"]["object_size_mrad"]
    for y in (-limit, limit):
        axes[0].axhline(y, color="k", lw=0.5, ls=":")
    axes[0].set_ylabel("λ − axis, mrad")
    axes[0].legend(fontsize=8)
    axes[0].set_title("closed loop, run 0 (dotted: object half-size)")
    axes[1].step(
        np.arange(len(s["fused (4 weak)"]["example_visible_channels"])),
        s["fused (4 weak)"]["example_visible_channels"],
        where="mid",
    )
    axes[1].set_ylabel("channels seeing the object")
    axes[1].set_xlabel("frame")
    save(fig, "synergy_example.png")
    return written
