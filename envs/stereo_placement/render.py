"""Drawing of a receiver-placement episode (``render_mode="rgb_array"``)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from sensorgym.envs.stereo_placement.simulation import PlacementParams, PlacementState

#: colours of the receivers (cycled)
_COLOURS = ("tab:blue", "tab:green", "tab:orange", "tab:purple", "tab:brown", "tab:pink")


def draw(
    params: PlacementParams, history: Sequence[PlacementState], size: int = 480
) -> NDArray[np.uint8]:
    """An RGB image ``(size, size, 3)`` of scenario 0, top view (world X right, Z up the page):
    the permitted disc, each receiver's track and its line of sight of the last period, the true
    drone track, the tracker's estimate, and the step's bound in the title."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.patches import Circle

    fig = Figure(figsize=(size / 100, size / 100), dpi=100)
    canvas = FigureCanvasAgg(fig)  # no pyplot: no global state, no display needed
    ax = fig.add_subplot()
    now = history[-1]
    ax.add_patch(Circle((0.0, 0.0), params.arena_radius, fill=False, ls="--", color="0.6"))
    tracks = np.array([s.receivers[0] for s in history])  # (T, n, 3)
    drone = np.array([s.drone_position[0] for s in history])  # (T, 3)
    for k in range(params.n_receivers):
        c = _COLOURS[k % len(_COLOURS)]
        ax.plot(tracks[:, k, 0], tracks[:, k, 2], "-", c=c, lw=1)
        ax.plot(tracks[-1, k, 0], tracks[-1, k, 2], "s", c=c, ms=6)
        o = now.geometry.origins[0, k]
        end = o + now.geometry.los[0, k] * now.geometry.ranges[0, k]
        ax.plot([o[0], end[0]], [o[2], end[2]], ":", c=c, lw=1)
    ax.plot(drone[:, 0], drone[:, 2], "-", c="tab:red", lw=1)
    ax.plot(drone[-1, 0], drone[-1, 2], "x", c="tab:red", ms=8)
    est = now.estimate[0]
    ax.plot(est[0], est[2], "+", c="k", ms=12, mew=1.5)
    bound = float(now.bound[0])
    text = "degenerate" if now.fix.degenerate[0] else f"bound {bound:.3g} m"
    ax.set_title(f"t = {now.t[0]:.0f} s   {text}   altitude {drone[-1, 1]:.0f} m", fontsize=9)
    reach = max(1.1 * params.arena_radius, 1.1 * float(np.abs(drone[-1, [0, 2]]).max()))
    ax.set_xlim(-reach, reach)
    ax.set_ylim(-reach, reach)
    ax.set_xlabel("X (m)")
    ax.set_ylabel("Z (m)")
    ax.set_aspect("equal")
    fig.tight_layout()
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3].copy()
