"""Drawing of a receiver-placement episode (``render_mode="rgb_array"``): a top view of scenario 0
on one figure kept for the episode (:class:`~sensorgym.envs.shells.rendering.Canvas`)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from sensorgym.envs.shells.rendering import Canvas, sigma_ellipse, status_line
from sensorgym.envs.stereo_placement.simulation import PlacementParams, PlacementState

#: colours of the receivers (cycled)
_COLOURS = ("tab:blue", "tab:green", "tab:orange", "tab:purple", "tab:brown", "tab:pink")
#: the estimate's 2σ circle is drawn this many times its size
ELLIPSE_SCALE = 5.0
#: the view widens by this factor whenever the drone would leave it
_ZOOM_OUT = 1.5
#: height of the legend strip below the axes, pixels
_LEGEND_PX = 48
#: a circle of unit radius, a closed ring
_RING = sigma_ellipse(np.eye(2), k=1.0, points=49)


class Scene:
    """The figure of one params' episodes, top view (world X right, Z up the page): the
    permitted disc, each receiver's track and its line of sight of the last period, the true
    drone track, the tracker's estimate with a circle of ``2σ_pos`` (the step's bound, the root
    of the trace of the position covariance, so the circle bounds the top view's ellipse;
    × :data:`ELLIPSE_SCALE`), a legend and a status line (step, time, the step's reward and the
    return so far, the bound in metres, the drone's altitude). The view is the disc and widens
    by ``_ZOOM_OUT`` whenever the drone would leave it."""

    def __init__(self, params: PlacementParams, size: int = 480):
        from matplotlib.lines import Line2D
        from matplotlib.patches import Circle

        self.params = params
        self.canvas = Canvas((size, size + _LEGEND_PX))
        fig, moving = self.canvas.figure, self.canvas.moving
        bottom = (_LEGEND_PX + 40) / (size + _LEGEND_PX)
        self.ax = ax = fig.add_axes((0.18, bottom, 0.77, 1.0 - bottom - 0.08))
        ax.set_aspect("equal")
        ax.set_xlabel("X (m)")
        ax.set_ylabel("Z (m)")
        ax.add_patch(Circle((0.0, 0.0), params.arena_radius, fill=False, ls="--", color="0.6"))
        self.view = 0.0
        self.tracks, self.heads, self.sights = [], [], []
        for k in range(params.n_receivers):
            c = _COLOURS[k % len(_COLOURS)]
            self.tracks.append(moving(ax.plot([], [], "-", c=c, lw=1)[0]))
            self.heads.append(moving(ax.plot([], [], "s", c=c, ms=6)[0]))
            self.sights.append(moving(ax.plot([], [], ":", c=c, lw=1)[0]))
        self.drone = moving(ax.plot([], [], "-", c="tab:red", lw=1)[0])
        self.drone_now = moving(ax.plot([], [], "x", c="tab:red", ms=8)[0])
        self.estimate = moving(ax.plot([], [], "+", c="k", ms=12, mew=1.5)[0])
        self.circle = moving(ax.plot([], [], "-", c="k", lw=0.8)[0])
        self.title = moving(ax.set_title(" ", fontsize=8))
        proxies = [
            Line2D([], [], c="tab:blue", marker="s", lw=1, label="receiver, track"),
            Line2D([], [], c="tab:blue", ls=":", lw=1, label="line of sight"),
            Line2D([], [], c="0.6", ls="--", label="permitted disc"),
            Line2D([], [], c="tab:red", marker="x", lw=1, label="drone, true track"),
            Line2D([], [], ls="", marker="+", ms=10, mew=1.5, c="k", label="estimate"),
            Line2D([], [], c="k", lw=0.8, label=f"2σ circle × {ELLIPSE_SCALE:g}"),
        ]
        fig.legend(handles=proxies, loc="lower center", ncol=3, fontsize=7, frameon=False)

    def draw(
        self, history: Sequence[PlacementState], rewards: Sequence[float] = ()
    ) -> NDArray[np.uint8]:
        """The RGB frame ``(size + 48, size, 3)`` of the episode so far (``rewards``: one per
        step, for the status line)."""
        params, now = self.params, history[-1]
        tracks = np.array([s.receivers[0] for s in history])  # (T, n, 3)
        drone = np.array([s.drone_position[0] for s in history])  # (T, 3)
        # the view is a function of the whole episode so far, so every path draws the same frame
        base = 1.1 * params.arena_radius
        far = float(np.abs(drone[:, [0, 2]]).max()) / (0.95 * base)
        view = base * (_ZOOM_OUT ** int(np.ceil(np.log(far) / np.log(_ZOOM_OUT))) if far > 1 else 1)
        if view != self.view:
            self.view = view
            self.ax.set_xlim(-view, view)
            self.ax.set_ylim(-view, view)
            self.canvas.redraw_still()
        for k in range(params.n_receivers):
            self.tracks[k].set_data(tracks[:, k, 0], tracks[:, k, 2])
            self.heads[k].set_data([tracks[-1, k, 0]], [tracks[-1, k, 2]])
            o = now.geometry.origins[0, k]
            end = o + now.geometry.los[0, k] * now.geometry.ranges[0, k]
            self.sights[k].set_data([o[0], end[0]], [o[2], end[2]])
        self.drone.set_data(drone[:, 0], drone[:, 2])
        self.drone_now.set_data([drone[-1, 0]], [drone[-1, 2]])
        est = now.estimate[0]
        self.estimate.set_data([est[0]], [est[2]])
        bound = float(now.bound[0])
        radius = 2.0 * bound * ELLIPSE_SCALE if np.isfinite(bound) else np.nan
        self.circle.set_data(est[0] + radius * _RING[0], est[2] + radius * _RING[1])
        text = "degenerate" if now.fix.degenerate[0] else f"bound σ {bound:.3g} m"
        self.title.set_text(
            f"{status_line(float(now.t[0]), rewards)}\n{text}   altitude {drone[-1, 1]:.0f} m"
        )
        return self.canvas.frame()


def draw(
    params: PlacementParams,
    history: Sequence[PlacementState],
    rewards: Sequence[float] = (),
    size: int = 480,
) -> NDArray[np.uint8]:
    """The frame of :class:`Scene` on a figure of its own: an RGB image ``(size + 48, size, 3)``
    of scenario 0 of the episode ``history`` (the states since the reset)."""
    return Scene(params, size).draw(history, rewards)
