"""Drawing of a platform-manoeuvre episode (``render_mode="rgb_array"``): scenario 0 on one figure
kept for the episode (:class:`~sensorgym.envs.shells.rendering.Canvas`)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from sensorgym.envs.bearings_maneuver.simulation import ManeuverParams, ManeuverState
from sensorgym.envs.shells.rendering import Canvas, sigma_ellipse, status_line

#: the view widens by this factor whenever the platform or the target would leave it
_ZOOM_OUT = 1.5
#: height of the legend strip below the axes, pixels
_LEGEND_PX = 48
_KM = 1e-3


class Scene:
    """The figure of one params' episodes (East right, North up, km): the platforms' and the
    target's tracks, the bearing lines of every step (to the true range), the tracker's
    estimate with its 2σ position ellipse, a legend and a status line (step, time, the step's
    reward and the return so far, the bound). The view is a square around the first step's
    platform and target that widens by ``_ZOOM_OUT`` whenever a track would leave it."""

    def __init__(self, params: ManeuverParams, size: int = 480):
        from matplotlib.collections import LineCollection

        self.params = params
        self.canvas = Canvas((size, size + _LEGEND_PX))
        fig, moving = self.canvas.figure, self.canvas.moving
        bottom = (_LEGEND_PX + 40) / (size + _LEGEND_PX)
        self.ax = ax = fig.add_axes((0.15, bottom, 0.8, 1.0 - bottom - 0.08))
        ax.set_aspect("equal")
        ax.set_xlabel("East (km)")
        ax.set_ylabel("North (km)")
        self.view: tuple[float, float, float] | None = None
        self.bearings = moving(ax.add_collection(LineCollection([], lw=0.5, colors="0.8")))
        self.platforms = []
        for k in range(params.platforms):
            label = "platform" if k == 0 else None
            colour = f"C{k % 10}" if k else "tab:blue"
            self.platforms.append(moving(ax.plot([], [], "-o", ms=2, c=colour, label=label)[0]))
        self.target = moving(ax.plot([], [], "-", c="tab:red", label="target")[0])
        self.target_now = moving(ax.plot([], [], "x", c="tab:red")[0])
        self.estimate = moving(ax.plot([], [], "+", ms=10, c="tab:green", label="estimate")[0])
        self.ellipse = moving(ax.plot([], [], c="tab:green", lw=1, label="2σ ellipse")[0])
        self.bearings.set_label("bearings")
        # below the axes, drawn once: nothing moves over it
        fig.legend(*ax.get_legend_handles_labels(), loc="lower center", ncol=3, fontsize=7,
                   frameon=False)  # fmt: skip
        self.title = moving(ax.set_title(" ", fontsize=8))

    def _fit(self, history: Sequence[ManeuverState], points: NDArray) -> None:
        """The view for the episode so far: a function of the whole history, so that every
        path of drawing gives the same frame."""
        first = history[0]
        start = np.vstack([first.platform_position[0], first.target[0, None, :2]]) * _KM
        centre = 0.5 * (start.min(axis=0) + start.max(axis=0))
        half0 = max(0.75 * float(np.ptp(start, axis=0).max()), 1.0)
        far = float(np.abs(points - centre).max()) / (0.95 * half0)
        half = half0 * (
            _ZOOM_OUT ** int(np.ceil(np.log(far) / np.log(_ZOOM_OUT))) if far > 1 else 1
        )
        view = (float(centre[0]), float(centre[1]), half)
        if view != self.view:
            self.view = view
            self.ax.set_xlim(centre[0] - half, centre[0] + half)
            self.ax.set_ylim(centre[1] - half, centre[1] + half)
            self.canvas.redraw_still()

    def draw(
        self, history: Sequence[ManeuverState], rewards: Sequence[float] = ()
    ) -> NDArray[np.uint8]:
        """The RGB frame ``(size + 48, size, 3)`` of the episode so far (``rewards``: one per step,
        for the status line)."""
        platforms = np.array([s.platform_position[0] for s in history]) * _KM  # (T, K, 2)
        target = np.array([s.target[0, :2] for s in history]) * _KM
        self._fit(history, np.vstack([platforms.reshape(-1, 2), target]))
        ends = []  # bearing lines from each platform position, to the true range
        for s in history:
            p, b, r = s.platform_position[0] * _KM, s.bearing[0], s.range[0] * _KM
            ends.append(np.stack([p, p + r[:, None] * np.stack([np.sin(b), np.cos(b)], -1)], 1))
        self.bearings.set_segments(np.concatenate(ends))
        for k, line in enumerate(self.platforms):
            line.set_data(platforms[:, k, 0], platforms[:, k, 1])
        self.target.set_data(target[:, 0], target[:, 1])
        self.target_now.set_data([target[-1, 0]], [target[-1, 1]])
        now = history[-1]
        x = now.estimate.position[0] * _KM
        self.estimate.set_data([x[0]], [x[1]])
        ring = sigma_ellipse(now.estimate.P[0, :2, :2] * _KM**2)
        self.ellipse.set_data(x[0] + ring[0], x[1] + ring[1])
        unit = " m" if self.params.metric == "position" else ""
        self.title.set_text(
            f"{status_line(float(now.t[0]), rewards)}\nbound {now.accuracy[0]:.3g}{unit}"
        )
        return self.canvas.frame()


def draw(
    params: ManeuverParams,
    history: Sequence[ManeuverState],
    rewards: Sequence[float] = (),
    size: int = 480,
) -> NDArray[np.uint8]:
    """The frame of :class:`Scene` on a figure of its own: an RGB image ``(size + 48, size, 3)``
    of scenario 0 of the episode ``history`` (the states since the reset)."""
    return Scene(params, size).draw(history, rewards)
