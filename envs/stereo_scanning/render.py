"""Drawing of a scanning episode (``render_mode="rgb_array"``): a top view of scenario 0 on one
figure kept for the episode (:class:`~sensorgym.envs.shells.rendering.Canvas`)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from sensorgym.envs.shells.rendering import Canvas, sigma_ellipse, status_line
from sensorgym.envs.stereo_scanning import kernels
from sensorgym.envs.stereo_scanning.simulation import ScanningParams, ScanningState

#: colours of the receivers (cycled)
_COLOURS = ("tab:blue", "tab:green", "tab:orange", "tab:purple", "tab:brown", "tab:pink")
#: covariance circles are drawn this many times their 2σ radius (centimetres at 100 m scale)
ELLIPSE_SCALE = 10.0
#: height of the legend strip below the axes, pixels
_LEGEND_PX = 64
#: the fractions of the sector's reach at which its raster rows are drawn as arcs
_ROWS = (0.25, 0.5, 0.75)
#: points of a covariance circle of unit radius, a closed ring
_RING = sigma_ellipse(np.eye(2), k=1.0, points=49)


def _boresight_azimuth(params: ScanningParams, k: int) -> float:
    z = params.rotations[k][:, 2]
    return float(np.arctan2(z[0], z[2]))


class Scene:
    """The figure of one params' episodes, top view (world X right, Z up the page): each
    receiver's sector of the last period (a wedge, its raster rows as faint arcs), the rays of
    its fixes (dotted: a false detection) labelled with their fix times, the true paths of the
    drones in the scene, the confirmed tracks with ``2σ_pos`` covariance circles
    (× :data:`ELLIPSE_SCALE`; ``σ_pos`` is the root of the trace of the 3-D position
    covariance, so the circle bounds the ellipse of the top view), a legend and a status line
    (step, time, the step's reward and the return so far, drones present and tracked, false
    tracks, the tracked drones' mean ``σ_pos`` in metres)."""

    def __init__(self, params: ScanningParams, size: int = 520):
        from matplotlib.collections import LineCollection
        from matplotlib.lines import Line2D
        from matplotlib.patches import Patch, Wedge

        self.params = params
        self.canvas = Canvas((size, size + _LEGEND_PX))
        fig, moving = self.canvas.figure, self.canvas.moving
        bottom = (_LEGEND_PX + 40) / (size + _LEGEND_PX)
        self.ax = ax = fig.add_axes((0.14, bottom, 0.82, 1.0 - bottom - 0.08))
        reach = params.circle_radius + params.scene_half_width
        half = params.scene_half_width
        ax.plot([-half, half, half, -half, -half], [-half, -half, half, half, -half], "--", c="0.7")
        ax.set_xlim(-reach, reach)
        ax.set_ylim(-reach, reach)
        ax.set_aspect("equal")
        ax.set_xlabel("X (m)")
        ax.set_ylabel("Z (m)")
        self.sectors: list[list] = []
        r = 1.6 * params.circle_radius
        for k in range(params.n_receivers):
            c = _COLOURS[k % len(_COLOURS)]
            o = params.receivers[k]
            ax.plot(o[0], o[2], "s", c=c, ms=7)  # receivers do not move
            wedges = [Wedge((o[0], o[2]), r, 0.0, 1.0, alpha=0.08, color=c)]
            # the raster sweep: a few of its rows' ranges as arcs (the sweep runs row by row)
            wedges += [
                Wedge((o[0], o[2]), f * r, 0.0, 1.0, width=0.5, alpha=0.25, color=c) for f in _ROWS
            ]
            self.sectors.append([moving(ax.add_patch(w)) for w in wedges])
        self.rays = moving(ax.add_collection(LineCollection([], lw=0.6)))
        self.labels: list = []  # fix-time labels, a pool grown as needed
        self.paths = [
            moving(ax.plot([], [], "-", c="tab:red", lw=1)[0]) for _ in range(params.n_drones)
        ]
        self.truths = moving(ax.plot([], [], "x", ls="", c="tab:red", ms=6)[0])
        self.tracks = moving(ax.plot([], [], "+", ls="", c="k", ms=9, mew=1.2)[0])
        self.circles = moving(ax.add_collection(LineCollection([], colors="k", lw=0.6)))
        self.title = moving(ax.set_title(" ", fontsize=8))
        proxies = [
            Line2D([], [], ls="", marker="s", c="tab:blue", label="receiver (colour)"),
            Patch(color="tab:blue", alpha=0.15, lw=0, label="sector, raster rows"),
            Line2D([], [], c="tab:blue", lw=0.8, label="fix ray (time, s)"),
            Line2D([], [], c="tab:blue", lw=0.8, ls=":", label="false detection"),
            Line2D([], [], c="tab:red", lw=1, marker="x", label="drone, true path"),
            Line2D([], [], ls="", marker="+", ms=9, mew=1.2, c="k", label="confirmed track"),
            Line2D([], [], c="k", lw=0.6, label=f"2σ circle × {ELLIPSE_SCALE:g}"),
            Line2D([], [], c="0.7", ls="--", label="scene"),
        ]
        fig.legend(handles=proxies, loc="lower center", ncol=4, fontsize=7, frameon=False)

    def _label(self, i: int) -> object:
        while len(self.labels) <= i:
            self.labels.append(self.canvas.moving(self.ax.text(0.0, 0.0, "", fontsize=5)))
        return self.labels[i]

    def draw(
        self, history: Sequence[ScanningState], rewards: Sequence[float] = ()
    ) -> NDArray[np.uint8]:
        """The RGB frame ``(size + 64, size, 3)`` of the episode so far (``rewards``: one per
        step, for the status line)."""
        params, now = self.params, history[-1]
        rays, styles, colours, used = [], [], [], 0
        for k, wedges in enumerate(self.sectors):
            c = _COLOURS[k % len(_COLOURS)]
            o = params.receivers[k]
            az, _, w = now.sectors[0, k]
            # world azimuth of the sector centre (azimuth from +Z towards +X, theory §2.2)
            lo = 90.0 - np.rad2deg(_boresight_azimuth(params, k) + az + 0.5 * w)
            for wedge in wedges:
                wedge.set_visible(bool(w > 0))
                wedge.set_theta1(lo)
                wedge.set_theta2(lo + np.rad2deg(w))
            for f in range(now.fix_count[0, k]):
                end = o + now.fix_world[0, k, f] * 1.5 * params.circle_radius
                rays.append([(o[0], o[2]), (end[0], end[2])])
                styles.append("-" if now.fix_drone[0, k, f] >= 0 else ":")
                colours.append(c)
                label = self._label(used)
                label.set_text(f"{now.fix_time[0, k, f]:.2f}")
                label.set_position((end[0], end[2]))
                label.set_color(c)
                used += 1
        for i, label in enumerate(self.labels):
            label.set_visible(i < used)
        self.rays.set_segments(rays)
        self.rays.set_linestyles(styles or ["-"])
        self.rays.set_colors(colours or ["k"])
        paths = np.array([s.drone_position[0] for s in history])  # (T, m, 3)
        present = np.array([s.enter[0] <= s.t[0] for s in history]) & ~np.array(
            [s.exited[0] for s in history]
        )  # (T, m)
        ends = []
        for j, line in enumerate(self.paths):
            line.set_data(paths[present[:, j], j, 0], paths[present[:, j], j, 2])
            if present[:, j].any():
                ends.append(paths[present[:, j], j][-1])
        ends_xz = np.array(ends).reshape(-1, 3)
        self.truths.set_data(ends_xz[:, 0], ends_xz[:, 2])
        confirmed = np.flatnonzero(now.track_status[0] == kernels.CONFIRMED)
        dt = now.t[0] - now.track_t[0, confirmed]
        p = now.track_x[0, confirmed, :3] + now.track_x[0, confirmed, 3:] * dt[:, None]
        sig = np.hypot(now.track_sigma[0, confirmed, 0], now.track_sigma[0, confirmed, 1] * dt)
        self.tracks.set_data(p[:, 0], p[:, 2])
        radius = 2.0 * sig * ELLIPSE_SCALE
        self.circles.set_segments(
            [np.column_stack([x + rr * _RING[0], z + rr * _RING[1]]) for x, z, rr in
             zip(p[:, 0], p[:, 2], radius, strict=True)]
        )  # fmt: skip
        parts = now.parts[0]
        sigma = f"σ {parts[4]:.2f} m" if parts[1] > 0 and np.isfinite(parts[4]) else "no track"
        self.title.set_text(
            f"{status_line(float(now.t[0]), rewards)}\n"
            f"drones {parts[0]:.0f}, tracked {parts[1]:.0f} ({sigma}), false tracks {parts[2]:.0f}"
        )
        return self.canvas.frame()


def draw(
    params: ScanningParams,
    history: Sequence[ScanningState],
    rewards: Sequence[float] = (),
    size: int = 520,
) -> NDArray[np.uint8]:
    """The frame of :class:`Scene` on a figure of its own: an RGB image ``(size + 64, size, 3)``
    of scenario 0 of the episode ``history`` (the states since the reset)."""
    return Scene(params, size).draw(history, rewards)
