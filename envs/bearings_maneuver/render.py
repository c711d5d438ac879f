"""Drawing of a platform-manoeuvre episode (``render_mode="rgb_array"``)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from sensorgym.envs.bearings_maneuver.simulation import ManeuverParams, ManeuverState


def draw(
    params: ManeuverParams, history: Sequence[ManeuverState], size: int = 480
) -> NDArray[np.uint8]:
    """An RGB image ``(size, size, 3)`` of scenario 0: platform and target tracks, the bearing
    lines, the tracker's estimate with its 2σ position ellipse, and the bound in the title."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(size / 100, size / 100), dpi=100)
    canvas = FigureCanvasAgg(fig)  # no pyplot: no global state, no display needed
    ax = fig.add_subplot()
    km = 1e-3
    platforms = np.array([s.platform_position[0] for s in history]) * km  # (T, K, 2)
    target = np.array([s.target[0, :2] for s in history]) * km
    now = history[-1]
    est = now.estimate
    for s in history:  # bearing lines from each platform position, to the true range
        for p, b, r in zip(s.platform_position[0] * km, s.bearing[0], s.range[0] * km, strict=True):
            ax.plot([p[0], p[0] + r * np.sin(b)], [p[1], p[1] + r * np.cos(b)], lw=0.5, c="0.8")
    for k in range(platforms.shape[1]):
        label = "platform" if k == 0 else None
        ax.plot(*platforms[:, k].T, "-o", ms=2, c=f"C{k % 10}" if k else "tab:blue", label=label)
    ax.plot(*target.T, "-", c="tab:red", label="target")
    ax.plot(*target[-1], "x", c="tab:red")
    x = est.position[0] * km
    ax.plot(*x, "+", ms=10, c="tab:green", label="estimate")
    # 2σ ellipse of the estimate: P = V diag(λ) Vᵀ
    lam, V = np.linalg.eigh(est.P[0, :2, :2] * km**2)
    u = np.linspace(0.0, 2.0 * np.pi, 64)
    ring = (V * (2.0 * np.sqrt(np.clip(lam, 0.0, None)))) @ np.stack([np.cos(u), np.sin(u)])
    ax.plot(x[0] + ring[0], x[1] + ring[1], c="tab:green", lw=1)
    unit = "m" if params.metric == "position" else ""
    ax.set_title(f"t = {now.t[0]:.0f} s   bound {now.accuracy[0]:.3g} {unit}", fontsize=9)
    ax.set_xlabel("East (km)")
    ax.set_ylabel("North (km)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(loc="upper right", fontsize=7)
    fig.tight_layout()
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3].copy()
