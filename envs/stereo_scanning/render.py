"""Drawing of a scanning episode (``render_mode="rgb_array"``)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from sensorgym.envs.stereo_scanning import kernels
from sensorgym.envs.stereo_scanning.simulation import ScanningParams, ScanningState

#: colours of the receivers (cycled)
_COLOURS = ("tab:blue", "tab:green", "tab:orange", "tab:purple", "tab:brown", "tab:pink")
#: covariance circles are drawn this many times their 2σ radius (centimetres at 100 m scale)
ELLIPSE_SCALE = 10.0


def _boresight_azimuth(params: ScanningParams, k: int) -> float:
    z = params.rotations[k][:, 2]
    return float(np.arctan2(z[0], z[2]))


def draw(
    params: ScanningParams, history: Sequence[ScanningState], size: int = 520
) -> NDArray[np.uint8]:
    """An RGB image ``(size, size, 3)`` of scenario 0, top view (world X right, Z up the page):
    each receiver's sector of the last period (a wedge, its raster rows as faint arcs), the rays
    of its fixes labelled with their fix times, the true drone paths, and the confirmed tracks
    with ``2σ_pos`` covariance circles (× :data:`ELLIPSE_SCALE`)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.patches import Circle, Wedge

    fig = Figure(figsize=(size / 100, size / 100), dpi=100)
    canvas = FigureCanvasAgg(fig)  # no pyplot: no global state, no display needed
    ax = fig.add_subplot()
    now = history[-1]
    reach = params.circle_radius + params.scene_half_width
    half = params.scene_half_width
    ax.plot([-half, half, half, -half, -half], [-half, -half, half, half, -half], "--", c="0.7")
    for k in range(params.n_receivers):
        c = _COLOURS[k % len(_COLOURS)]
        o = params.receivers[k]
        ax.plot(o[0], o[2], "s", c=c, ms=7)
        az, _, w = now.sectors[0, k]
        if w > 0:
            # world azimuth of the sector centre (azimuth from +Z towards +X, theory §2.2)
            centre = _boresight_azimuth(params, k) + az
            lo = 90.0 - np.rad2deg(centre + 0.5 * w)
            ax.add_patch(Wedge((o[0], o[2]), 1.6 * params.circle_radius, lo, lo + np.rad2deg(w),
                               alpha=0.08, color=c))  # fmt: skip
            # the raster sweep: a few of its rows' ranges as arcs (the sweep runs row by row)
            for frac in (0.25, 0.5, 0.75):
                ax.add_patch(Wedge((o[0], o[2]), frac * 1.6 * params.circle_radius, lo,
                                   lo + np.rad2deg(w), width=0.5, alpha=0.25, color=c))  # fmt: skip
        for f in range(now.fix_count[0, k]):
            u = now.fix_world[0, k, f]
            end = o + u * 1.5 * params.circle_radius
            ls = "-" if now.fix_drone[0, k, f] >= 0 else ":"
            ax.plot([o[0], end[0]], [o[2], end[2]], ls, c=c, lw=0.6)
            ax.annotate(f"{now.fix_time[0, k, f]:.2f}", (end[0], end[2]), fontsize=5, color=c)
    paths = np.array([s.drone_position[0] for s in history])  # (T, m, 3)
    for j in range(params.n_drones):
        present = np.array([(s.enter[0, j] <= s.t[0]) and not s.exited[0, j] for s in history])
        if present.any():
            ax.plot(paths[present, j, 0], paths[present, j, 2], "-", c="tab:red", lw=1)
            ax.plot(paths[present, j, 0][-1], paths[present, j, 2][-1], "x", c="tab:red", ms=6)
    confirmed = np.flatnonzero(now.track_status[0] == kernels.CONFIRMED)
    for q in confirmed:
        dt = now.t[0] - now.track_t[0, q]
        p = now.track_x[0, q, :3] + now.track_x[0, q, 3:] * dt
        sig = float(np.hypot(now.track_sigma[0, q, 0], now.track_sigma[0, q, 1] * dt))
        ax.plot(p[0], p[2], "+", c="k", ms=9, mew=1.2)
        ax.add_patch(Circle((p[0], p[2]), 2 * sig * ELLIPSE_SCALE, fill=False, color="k", lw=0.6))
    parts = now.parts[0]
    ax.set_title(
        f"t = {now.t[0]:.0f} s   drones {parts[0]:.0f}, tracked {parts[1]:.0f}, false "
        f"{parts[2]:.0f}   (circles 2σ × {ELLIPSE_SCALE:g})",
        fontsize=8,
    )
    ax.set_xlim(-reach, reach)
    ax.set_ylim(-reach, reach)
    ax.set_xlabel("X (m)")
    ax.set_ylabel("Z (m)")
    ax.set_aspect("equal")
    fig.tight_layout()
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3].copy()
