"""The paper 004 fused tracker in the loop: it points the channels of an imaging scene.

:mod:`sensorgym.envs.worlds.imaging` is the world (object motion, view chains, images);
:class:`~sensorgym.trackers.fusion.tracker.FusionTracker` is the tracker. This module joins
them for :mod:`sensorgym.reproduce.experiments.paper004`: the tracker's matched model of a
scene (:func:`matched_model`) and the closed-loop simulation (:func:`simulate_closed_loop`),
where each frame the optical axis is pointed where the tracker commands.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sensorgym.envs.worlds.imaging import ImagingScene
from sensorgym.trackers.fusion.tracker import FusionModel, FusionTracker

FloatArray = NDArray[np.float64]


def matched_model(
    scene: ImagingScene, channels: ArrayLike | None = None, **options: object
) -> FusionModel:
    """The tracker's model matched to ``scene``'s ``channels`` (default all): the scene's own
    templates, noise, view transitions and line-of-sight motion; ``options`` go to
    :class:`~sensorgym.trackers.fusion.tracker.FusionModel`."""
    s, ds = scene.templates()
    idx = np.arange(scene.channels) if channels is None else np.atleast_1d(channels)
    return FusionModel(
        templates=s[idx],
        template_slopes=ds[idx],
        noise_std=np.asarray(scene.noise_std, dtype=np.float64)[idx],
        transition=np.asarray(scene.transition, dtype=np.float64)[idx],
        correlation=scene.correlation,
        prior_std=scene.theta0,
        **options,  # type: ignore[arg-type]
    )


@dataclass(frozen=True)
class ClosedLoopRun:
    """Histories of a batch of closed-loop runs, each ``(T, B)`` (frames × scenarios)."""

    pointing_error: FloatArray
    """``λ_k − a_k``: the object's offset from the optical axis when frame k is taken (mrad)."""
    estimate_error: FloatArray
    """``λ_k − λ̂_k`` after the update (mrad)."""
    variance: FloatArray
    """The tracker's posterior variance ``d_k`` (mrad²)."""
    loop_open: NDArray[np.bool_]
    """True where the tracker coasted (no channel held the object)."""
    visible_channels: NDArray[np.int64]
    """Number of channels whose true view is not the background."""
    view_accuracy: FloatArray
    """Fraction of channels whose MAP view ``argmax P_k(ϑ)`` is the true view."""

    def lost(self, limit: float, frames: int) -> NDArray[np.bool_]:
        """``(B,)``: True where ``|λ − a| > limit`` for at least ``frames`` consecutive frames."""
        out = np.abs(self.pointing_error) > limit
        run = np.zeros(out.shape[1], dtype=np.int64)
        lost = np.zeros(out.shape[1], dtype=bool)
        for row in out:
            run = np.where(row, run + 1, 0)
            lost |= run >= frames
        return lost


def simulate_closed_loop(
    scene: ImagingScene,
    tracker: FusionTracker,
    rng: np.random.Generator,
    batch_size: int,
    frames: int,
    channels: ArrayLike | None = None,
) -> ClosedLoopRun:
    """Run the tracker in closed loop on ``batch_size`` independent scenarios for ``frames``.

    Each frame: the axis is pointed at ``tracker.command(state)``, the world advances, the
    images of ``channels`` (default all; the tracker's model must describe the same channels)
    are rendered and the tracker updates.
    """
    idx = np.arange(scene.channels) if channels is None else np.atleast_1d(channels)
    if tracker.model.channels != idx.size:
        raise ValueError("channels: the tracker's model describes a different number of channels")
    angle, views = scene.initial_world(rng, batch_size)
    # the operator designates the object on the axis to within about one pixel
    state = tracker.initial_state(batch_size, variance=scene.pixel_pitch**2)
    hist: dict[str, list[FloatArray]] = {k: [] for k in ClosedLoopRun.__dataclass_fields__}
    for _ in range(frames):
        axis = tracker.command(state)
        angle, views = scene.step_world(rng, angle, views)
        images = scene.render(rng, angle, axis, views)[:, idx]
        state = tracker.update(state, images)
        hist["pointing_error"].append(angle - axis)
        hist["estimate_error"].append(angle - state.estimate)
        hist["variance"].append(state.variance)
        hist["loop_open"].append(state.loop_open)
        hist["visible_channels"].append(np.sum(views[:, idx] > 0, axis=1))
        hist["view_accuracy"].append(
            np.mean(np.argmax(state.view_posterior, axis=-1) == views[:, idx], axis=1)
        )
    return ClosedLoopRun(**{k: np.stack(v) for k, v in hist.items()})
