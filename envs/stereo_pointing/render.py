"""Drawing of a receiver-pointing episode (``render_mode="rgb_array"``): a top view of scenario 0
on one figure kept for the episode (:class:`~sensorgym.envs.shells.rendering.Canvas`)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from sensorgym.envs.shells.rendering import Canvas, sigma_ellipse, status_line
from sensorgym.envs.stereo_pointing.simulation import PointingParams, PointingState

#: colours of the drones (cycled)
_COLOURS = ("tab:red", "tab:purple", "tab:orange", "tab:brown", "tab:pink", "tab:olive")
#: the tracks' 2σ ellipses are drawn this many times their size (decimetres on a 300 m view)
ELLIPSE_SCALE = 20.0
#: height of the legend strip below the axes, pixels
_LEGEND_PX = 64
#: the view widens by this factor whenever a drone leaves it
_ZOOM_OUT = 1.5


class Scene:
    """The figure of one params' episodes, top view (world X right, Z up the page): receivers
    with their field-of-view wedges (darker when they see a drone), each drone's true path and
    position (the view starts at 1.2 × the farthest start distance and widens by
    ``_ZOOM_OUT`` whenever a drone would leave it), the tracker's estimate with its 2σ position ellipse in X–Z (the marginal of its
    covariance, × :data:`ELLIPSE_SCALE`), a legend and a status line (step, time, the step's
    reward and the return so far, drones fixed, their mean bound ``σ_pos`` in metres)."""

    def __init__(self, params: PointingParams, size: int = 480):
        from matplotlib.lines import Line2D
        from matplotlib.patches import Patch, Wedge

        self.params = params
        self.canvas = Canvas((size, size + _LEGEND_PX))
        fig, moving = self.canvas.figure, self.canvas.moving
        bottom = (_LEGEND_PX + 40) / (size + _LEGEND_PX)
        self.ax = ax = fig.add_axes((0.15, bottom, 0.8, 1.0 - bottom - 0.08))
        self.reach = reach = 1.2 * params.start_distance[1]
        self._view(reach)
        ax.set_aspect("equal")
        ax.set_xlabel("X (m)")
        ax.set_ylabel("Z (m)")
        o = params.receiver_positions
        ax.plot(o[:, 0], o[:, 2], "s", c="tab:blue", ms=6)  # receivers do not move
        self.wedges = [
            moving(ax.add_patch(Wedge((o[k, 0], o[k, 2]), reach, 0.0, 1.0, color="tab:blue", lw=0)))
            for k in range(params.n_receivers)
        ]
        self.paths, self.truths, self.estimates, self.ellipses = [], [], [], []
        for j in range(params.n_drones):
            c = _COLOURS[j % len(_COLOURS)]
            self.paths.append(moving(ax.plot([], [], "-", c=c, lw=1)[0]))
            self.truths.append(moving(ax.plot([], [], "x", c=c, ms=8)[0]))
            self.ellipses.append(moving(ax.plot([], [], "-", c=c, lw=1)[0]))
            self.estimates.append(moving(ax.plot([], [], "+", c=c, ms=12, mew=1.5)[0]))
        self.title = moving(ax.set_title(" ", fontsize=8))
        proxies = [
            Line2D([], [], ls="", marker="s", c="tab:blue", label="receiver"),
            Patch(color="tab:blue", alpha=0.35, lw=0, label="field of view (dark: sees)"),
            Line2D([], [], c="0.3", lw=1, label="true path (colour: drone)"),
            Line2D([], [], ls="", marker="x", c="0.3", label="true position"),
            Line2D([], [], ls="", marker="+", ms=10, mew=1.5, c="0.3", label="track estimate"),
            Line2D([], [], c="0.3", lw=1, label=f"2σ ellipse × {ELLIPSE_SCALE:g}"),
        ]
        fig.legend(handles=proxies, loc="lower center", ncol=3, fontsize=7, frameon=False)

    def _view(self, reach: float) -> None:
        self.view = reach
        self.ax.set_xlim(-reach, reach)
        self.ax.set_ylim(-reach, reach)
        self.canvas.redraw_still()

    def draw(
        self, history: Sequence[PointingState], rewards: Sequence[float] = ()
    ) -> NDArray[np.uint8]:
        """The RGB frame ``(size + 64, size, 3)`` of the episode so far (``rewards``: one per
        step, for the status line)."""
        params, now = self.params, history[-1]
        truth = np.array([s.drone_position[0] for s in history])  # (T, m, 3)
        # the view is a function of the whole episode so far, so every path draws the same frame
        far = float(np.abs(truth[..., [0, 2]]).max()) / (0.98 * self.reach)
        zoom = _ZOOM_OUT ** int(np.ceil(np.log(far) / np.log(_ZOOM_OUT))) if far > 1.0 else 1.0
        if zoom * self.reach != self.view:
            self._view(zoom * self.reach)
        half = np.rad2deg(params.fov)
        for k, wedge in enumerate(self.wedges):
            # matplotlib angles run from +x counter-clockwise; azimuth runs from +Z towards +X
            centre = 90.0 - np.rad2deg(now.azimuth[0, k])
            wedge.set_theta1(centre - half)
            wedge.set_theta2(centre + half)
            wedge.set_radius(self.view)
            wedge.set_alpha(0.35 if now.seen[0, k].any() else 0.12)
        est, P = now.track.position[0], now.track.P[0]
        xz = np.ix_([0, 2], [0, 2])
        for j in range(params.n_drones):
            self.paths[j].set_data(truth[:, j, 0], truth[:, j, 2])
            self.truths[j].set_data([truth[-1, j, 0]], [truth[-1, j, 2]])
            self.estimates[j].set_data([est[j, 0]], [est[j, 2]])
            ring = sigma_ellipse(P[j][xz]) * ELLIPSE_SCALE
            self.ellipses[j].set_data(est[j, 0] + ring[0], est[j, 2] + ring[1])
        bound = now.bound[0]
        fixed = np.isfinite(bound)
        sigma = f"σ {bound[fixed].mean():.2f} m" if fixed.any() else "no fix"
        self.title.set_text(
            f"{status_line(float(now.t[0]), rewards)}\n"
            f"fixed {int(fixed.sum())}/{params.n_drones}   bound {sigma}"
        )
        return self.canvas.frame()


def draw(
    params: PointingParams,
    history: Sequence[PointingState],
    rewards: Sequence[float] = (),
    size: int = 480,
) -> NDArray[np.uint8]:
    """The frame of :class:`Scene` on a figure of its own: an RGB image ``(size + 64, size, 3)``
    of scenario 0 of the episode ``history`` (the states since the reset)."""
    return Scene(params, size).draw(history, rewards)
