"""Drawing of a receiver-pointing episode (``render_mode="rgb_array"``)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from sensorgym.envs.stereo_pointing.simulation import PointingParams, PointingState

#: colours of the drones (cycled)
_COLOURS = ("tab:red", "tab:purple", "tab:orange", "tab:brown", "tab:pink", "tab:olive")


def draw(
    params: PointingParams, history: Sequence[PointingState], size: int = 480
) -> NDArray[np.uint8]:
    """An RGB image ``(size, size, 3)`` of scenario 0, top view (world X right, Z up the page):
    receivers with their field-of-view wedges (filled when they see a drone), the true drone
    tracks, the tracker's estimates, and the step's mean bound in the title."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.patches import Wedge

    fig = Figure(figsize=(size / 100, size / 100), dpi=100)
    canvas = FigureCanvasAgg(fig)  # no pyplot: no global state, no display needed
    ax = fig.add_subplot()
    now = history[-1]
    o = params.receiver_positions
    reach = 1.2 * params.start_distance[1]
    for k in range(params.n_receivers):
        # matplotlib angles run from +x counter-clockwise; azimuth runs from +Z towards +X
        centre = 90.0 - np.rad2deg(now.azimuth[0, k])
        half = np.rad2deg(params.fov)
        sees = bool(now.seen[0, k].any())
        ax.add_patch(
            Wedge(
                (o[k, 0], o[k, 2]), reach, centre - half, centre + half,
                alpha=0.35 if sees else 0.12, color="tab:blue", lw=0,
            )
        )  # fmt: skip
        ax.plot(o[k, 0], o[k, 2], "s", c="tab:blue", ms=6)
    truth = np.array([s.drone_position[0] for s in history])  # (T, m, 3)
    for j in range(params.n_drones):
        c = _COLOURS[j % len(_COLOURS)]
        ax.plot(truth[:, j, 0], truth[:, j, 2], "-", c=c, lw=1)
        ax.plot(truth[-1, j, 0], truth[-1, j, 2], "x", c=c, ms=8)
        est = now.track.position[0, j]
        ax.plot(est[0], est[2], "+", c=c, ms=12, mew=1.5)
    bound = now.bound[0]
    fixed = np.isfinite(bound)
    text = f"{bound[fixed].mean():.3g} m" if fixed.any() else "no fix"
    ax.set_title(f"t = {now.t[0]:.1f} s   bound {text}   fixed {int(fixed.sum())}", fontsize=9)
    ax.set_xlabel("X (m)")
    ax.set_ylabel("Z (m)")
    ax.set_xlim(-reach, reach)
    ax.set_ylim(-reach, reach)
    ax.set_aspect("equal")
    fig.tight_layout()
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3].copy()
