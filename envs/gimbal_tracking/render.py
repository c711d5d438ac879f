"""Drawing of a gimbal-tracking episode (``render_mode="rgb_array"``): scenario 0's field of view
on one figure kept for the episode (:class:`~sensorgym.envs.shells.rendering.Canvas`)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from sensorgym.envs.gimbal_tracking.reference import (
    MRAD,
    body_to_level,
    carrier_attitude,
    gimbal_detections,
    measuring_gimbal,
    tangent_offsets,
)
from sensorgym.envs.gimbal_tracking.simulation import GimbalParams, GimbalState
from sensorgym.envs.shells.rendering import Canvas, sigma_ellipse, status_line
from sensorgym.trackers.geometry import unit_from_zup_angles

#: frames of the target's track drawn behind it
TRAIL = 25
#: height of the legend strip below the axes, pixels
_LEGEND_PX = 48


def shown_gimbal(state: GimbalState) -> int:
    """The gimbal drawn for scenario 0: the one whose fused direction the track measured (or
    would have: :func:`~.reference.measuring_gimbal`)."""
    detected = gimbal_detections(state.view_posterior[:1])
    return int(measuring_gimbal(state.fusion_variance[:1], detected)[0])


def image_offsets(
    params: GimbalParams, state: GimbalState, directions: np.ndarray, gimbal: int = 0
) -> np.ndarray:
    """Offsets (mrad) in scenario 0's image of level-frame ``directions (T, 3)``, seen through
    the boresight of ``state``'s gimbal ``gimbal``."""
    attitude, _ = carrier_attitude(params, state.carrier_phase[:1], state.frame[:1])
    u_body = directions @ body_to_level(attitude)[0]  # rows: Rᵀ u
    axis = np.broadcast_to(state.gimbal_angles[0, gimbal], (len(u_body), 2))
    return MRAD * tangent_offsets(u_body, axis)


class Scene:
    """The figure of one params' episodes: the field of view around the boresight (mrad; the
    axes move with the gimbal), the target and its recent track (hollow while occluded), the
    tracking gate, the tracker's estimate with its 2σ ellipse (paper 004's posterior variances)
    and its prediction for the next frame, a legend and a status line (step, time, the step's
    reward and the return so far, ``σ_LOS``, the channels the target stands out in). The view
    is fixed: 1.6 half fields around the boresight. With several gimbals it is the measuring
    gimbal's (:func:`shown_gimbal`), named in the status line."""

    def __init__(self, params: GimbalParams, size: int = 480):
        from matplotlib.lines import Line2D
        from matplotlib.patches import Rectangle

        self.params = params
        self.canvas = Canvas((size, size + _LEGEND_PX))
        fig, moving = self.canvas.figure, self.canvas.moving
        bottom = (_LEGEND_PX + 40) / (size + _LEGEND_PX)
        self.ax = ax = fig.add_axes((0.18, bottom, 0.77, 1.0 - bottom - 0.08))
        h = MRAD * params.half_field
        ax.add_patch(Rectangle((-h, -h), 2 * h, 2 * h, fill=False, ls="--", color="0.5"))
        ax.set_xlim(-1.6 * h, 1.6 * h)
        ax.set_ylim(-1.6 * h, 1.6 * h)
        ax.set_aspect("equal")
        ax.set_xlabel("azimuth offset (mrad)")
        ax.set_ylabel("elevation offset (mrad)")
        self.half_gate = 0.5 * params.gate_pixels * params.pixel_pitch * MRAD
        self.gate = moving(ax.plot([], [], "-", c="tab:green", lw=0.8)[0])
        self.track = moving(ax.plot([], [], "-", c="tab:red", lw=1)[0])
        self.target = moving(ax.plot([], [], "o", mec="tab:red", ms=8)[0])
        self.estimate = moving(ax.plot([], [], "+", c="k", ms=12, mew=1.5)[0])
        self.ellipse = moving(ax.plot([], [], "-", c="k", lw=0.8)[0])
        self.predicted = moving(ax.plot([], [], "x", c="tab:blue", ms=9, mew=1.5)[0])
        self.title = moving(ax.set_title(" ", fontsize=8))
        proxies = [
            Line2D([], [], c="0.5", ls="--", label="field of view"),
            Line2D([], [], c="tab:red", marker="o", lw=1, label="target, track"),
            Line2D([], [], c="tab:green", lw=0.8, label="tracking gate"),
            Line2D([], [], ls="", marker="+", ms=10, mew=1.5, c="k", label="estimate"),
            Line2D([], [], c="k", lw=0.8, label="2σ ellipse"),
            Line2D([], [], ls="", marker="x", ms=8, mew=1.5, c="tab:blue", label="prediction"),
        ]
        fig.legend(handles=proxies, loc="lower center", ncol=3, fontsize=7, frameon=False)

    def draw(
        self, history: Sequence[GimbalState], rewards: Sequence[float] = ()
    ) -> NDArray[np.uint8]:
        """The RGB frame ``(size + 48, size, 3)`` of the episode so far (``rewards``: one per
        step, for the status line)."""
        params, now = self.params, history[-1]
        k = shown_gimbal(now)
        trail = np.array([s.target_position[0] for s in history[-TRAIL:]])
        trail /= np.linalg.norm(trail, axis=-1, keepdims=True)
        track = image_offsets(params, now, trail, k)
        self.track.set_data(track[:, 0], track[:, 1])
        self.target.set_data([track[-1, 0]], [track[-1, 1]])
        self.target.set_markerfacecolor("none" if now.occluded[0] else "tab:red")
        angles = np.stack([now.reference[0, k], now.estimate[0], now.predicted[0]])
        gate, est, pred = image_offsets(
            params, now, unit_from_zup_angles(angles[:, 0], angles[:, 1]), k
        )
        g = self.half_gate
        self.gate.set_data(
            gate[0] + g * np.array([-1, 1, 1, -1, -1]), gate[1] + g * np.array([-1, -1, 1, 1, -1])
        )
        self.estimate.set_data([est[0]], [est[1]])
        ring = sigma_ellipse(np.diag(now.fusion_variance[0, k]))
        self.ellipse.set_data(est[0] + ring[0], est[1] + ring[1])
        self.predicted.set_data([pred[0]], [pred[1]])
        seen = int(now.visible[0, k].sum())
        t = float(now.frame[0]) * params.frame_period
        which = f"gimbal {k} of {params.n_gimbals}   " if params.n_gimbals > 1 else ""
        self.title.set_text(
            f"{status_line(t, rewards)}\n{which}σ_LOS {MRAD * float(now.sigma_los[0]):.3g} mrad   "
            f"seen in {seen} of {params.n_channels} channels"
            + ("   occluded" if now.occluded[0] else "")
        )
        return self.canvas.frame()


def draw(
    params: GimbalParams,
    history: Sequence[GimbalState],
    rewards: Sequence[float] = (),
    size: int = 480,
) -> NDArray[np.uint8]:
    """The frame of :class:`Scene` on a figure of its own: an RGB image ``(size + 48, size, 3)``
    of scenario 0 of the episode ``history`` (the states since the reset)."""
    return Scene(params, size).draw(history, rewards)
