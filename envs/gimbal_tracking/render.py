"""Drawing of a gimbal-tracking episode (``render_mode="rgb_array"``)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from sensorgym.envs.gimbal_tracking.reference import (
    body_to_level,
    carrier_attitude,
    tangent_offsets,
)
from sensorgym.envs.gimbal_tracking.simulation import GimbalParams, GimbalState
from sensorgym.trackers.geometry import unit_from_zup_angles


def _body_offsets(params: GimbalParams, state: GimbalState, direction: np.ndarray) -> np.ndarray:
    """Image offsets (mrad) of level-frame ``direction (3,)`` from scenario 0's boresight."""
    attitude, _ = carrier_attitude(params, state.carrier_phase[:1], state.frame[:1])
    u_body = body_to_level(attitude)[0].T @ direction
    return 1000.0 * tangent_offsets(u_body, state.gimbal_angles[0])


def draw(
    params: GimbalParams, history: Sequence[GimbalState], size: int = 480
) -> NDArray[np.uint8]:
    """An RGB image ``(size, size, 3)`` of scenario 0: the field of view around the boresight
    (mrad), the target's recent track in it (red; hollow while occluded), the tracker's
    estimate (black +) and its next-frame prediction (blue x); the frame, ``σ_LOS`` and the
    channels the target stands out in, in the title."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.patches import Rectangle

    fig = Figure(figsize=(size / 100, size / 100), dpi=100)
    canvas = FigureCanvasAgg(fig)  # no pyplot: no global state, no display needed
    ax = fig.add_subplot()
    now = history[-1]
    h = 1000.0 * params.half_field
    ax.add_patch(Rectangle((-h, -h), 2 * h, 2 * h, fill=False, ls="--", color="0.5"))
    track = []
    for s in history[-25:]:
        los = s.target_position[0] / np.linalg.norm(s.target_position[0])
        track.append(_body_offsets(params, now, los))
    track = np.array(track)
    ax.plot(track[:, 0], track[:, 1], "-", c="tab:red", lw=1)
    face = "none" if now.occluded[0] else "tab:red"
    ax.plot(*track[-1], "o", mec="tab:red", mfc=face, ms=8)
    for angles, marker, colour in (
        (now.estimate[0], "+", "k"),
        (now.predicted[0], "x", "tab:blue"),
    ):
        u = unit_from_zup_angles(angles[0], angles[1])
        ax.plot(*_body_offsets(params, now, u), marker, c=colour, ms=12, mew=1.5)
    reach = 1.6 * h
    ax.set_xlim(-reach, reach)
    ax.set_ylim(-reach, reach)
    ax.set_xlabel("azimuth offset (mrad)")
    ax.set_ylabel("elevation offset (mrad)")
    ax.set_aspect("equal")
    seen = int(now.visible[0].sum())
    sigma = 1000.0 * float(now.sigma_los[0])
    ax.set_title(
        f"frame {int(now.frame[0])}   σ_LOS {sigma:.3g} mrad   seen in {seen} channel(s)",
        fontsize=9,
    )
    fig.tight_layout()
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3].copy()
