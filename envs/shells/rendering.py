"""Frames for the Gymnasium and PettingZoo shells: an env's renderer draws scenario 0 of the
states of the episode so far; ``"human"`` shows each frame in a matplotlib window.

An env names its renderer as a module path (``renderer = "sensorgym.envs.<env>.render"``, a
module with ``draw(params, history) -> (H, W, 3) uint8``), imported on the first frame so that
importing an env never imports matplotlib. A renderer that also has a ``Scene`` class
(``Scene(params)``, ``scene.draw(history, rewards) -> frame``) keeps one figure for the episode
and redraws only what moves (:class:`Canvas`); its ``draw`` is a fresh ``Scene``'s, so a frame
is the same pixels whichever path drew it.
"""

from __future__ import annotations

import importlib
from collections.abc import Sequence
from typing import Any

import gymnasium
import numpy as np
from numpy.typing import NDArray

#: the render modes of every env with a renderer
RENDER_MODES = ["human", "rgb_array"]
#: matplotlib backends that draw files, not windows (``"human"`` then shows nothing)
NON_INTERACTIVE = {"agg", "cairo", "pdf", "pgf", "ps", "svg", "template"}


def check_render_mode(render_mode: str | None, modes: list[str]) -> None:
    """``ValueError`` unless ``render_mode`` is ``None`` or one of ``modes``."""
    if render_mode not in (None, *modes):
        raise ValueError(f"render_mode: one of {modes}, got {render_mode!r}")


class Frames:
    """The states drawn so far in the episode and, for ``"human"``, the window they are shown in.

    ``mode`` ``None`` keeps nothing (no cost when nobody renders)."""

    def __init__(self, renderer: str | None, mode: str | None, fps: float):
        if mode is not None and renderer is None:
            raise ValueError(f"render_mode: {mode!r} needs a renderer; this env has none")
        self.renderer, self.mode, self.fps = renderer, mode, float(fps)
        self.history: list[Any] = []
        self.rewards: list[float] = []
        self._window: tuple[Any, Any] | None = None
        self._scene: tuple[Any, Any] | None = None  # (params, the renderer's Scene of them)

    def __getstate__(self) -> dict[str, Any]:
        # a figure or a window does not pickle; both are made again on the next frame
        return {**self.__dict__, "_window": None, "_scene": None}

    def start(self, state: Any) -> None:
        """A new episode from ``state``."""
        if self.mode is not None:
            self.history, self.rewards = [state], []

    def add(self, state: Any, reward: float | None = None) -> None:
        """The state after a step and the step's team reward (``None``: not known)."""
        if self.mode is not None:
            self.history.append(state)
            self.rewards.append(np.nan if reward is None else float(reward))

    def draw(self, params: Any) -> NDArray[np.uint8]:
        """The RGB frame of the episode so far."""
        if not self.history:
            raise RuntimeError("render: call reset() first")
        module = importlib.import_module(str(self.renderer))
        if not hasattr(module, "Scene"):
            return module.draw(params, self.history)
        if self._scene is None or self._scene[0] is not params:
            self._scene = (params, module.Scene(params))
        return self._scene[1].draw(self.history, self.rewards)

    def render(self, params: Any) -> NDArray[np.uint8] | None:
        """What a shell's ``render()`` returns: the frame for ``"rgb_array"``; for ``"human"``
        ``None`` after showing the frame in the window (where matplotlib has an interactive
        backend; elsewhere it is drawn and not shown); with no mode ``None`` and Gymnasium's
        warning. ``RuntimeError`` before the first reset."""
        if self.mode is None:
            gymnasium.logger.warn("render: no render_mode was given to the environment")
            return None
        frame = self.draw(params)
        if self.mode == "rgb_array":
            return frame
        self._show(frame)
        return None

    def _show(self, frame: NDArray[np.uint8]) -> None:
        import matplotlib.pyplot as plt

        if plt.get_backend().lower() in NON_INTERACTIVE:  # no display: nothing to show
            return
        if self._window is None or not plt.fignum_exists(self._window[0].number):
            fig, ax = plt.subplots(figsize=(frame.shape[1] / 100, frame.shape[0] / 100))
            ax.set_axis_off()
            fig.subplots_adjust(0, 0, 1, 1)
            self._window = (fig, ax.imshow(frame))
            fig.show()
        fig, image = self._window
        image.set_data(frame)
        fig.canvas.draw_idle()
        plt.pause(1.0 / self.fps)

    def close(self) -> None:
        """Close the window, if one was opened, and drop the figure."""
        self._scene = None
        if self._window is not None:
            import matplotlib.pyplot as plt

            plt.close(self._window[0])
            self._window = None


class Canvas:
    """One off-screen figure redrawn frame after frame: what does not move (axes, ticks,
    labels, fixed sites) is drawn once and kept as a bitmap; each frame restores it and draws
    only the artists registered with :meth:`moving` (matplotlib's blitting), so a frame costs a
    few milliseconds instead of a whole figure's layout and draw.

    ``size`` is ``(width, height)`` in pixels. Set the axes' limits, labels and layout before
    the first frame: they are part of the kept bitmap (change them, then :meth:`redraw_still`)."""

    def __init__(self, size: tuple[int, int], dpi: float = 100.0):
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        self.figure = Figure(figsize=(size[0] / dpi, size[1] / dpi), dpi=dpi)
        self.canvas = FigureCanvasAgg(self.figure)  # no pyplot: no global state, no display
        self._moving: list[Any] = []
        self._background: Any = None

    def moving(self, artist: Any) -> Any:
        """Register ``artist`` as redrawn every frame (in registration order) and return it."""
        artist.set_animated(True)  # left out of the kept bitmap
        self._moving.append(artist)
        return artist

    def redraw_still(self) -> None:
        """Draw the still artists again on the next frame (after a change of the axes' limits)."""
        self._background = None

    def frame(self) -> NDArray[np.uint8]:
        """The ``(height, width, 3)`` uint8 image of the figure as its artists stand now."""
        if self._background is None:
            self.canvas.draw()  # the still artists only: animated ones are skipped
            self._background = self.canvas.copy_from_bbox(self.figure.bbox)
        else:
            self.canvas.restore_region(self._background)
        renderer = self.canvas.get_renderer()
        for artist in self._moving:
            if artist.get_visible():
                artist.draw(renderer)
        return np.asarray(self.canvas.buffer_rgba())[..., :3].copy()


def sigma_ellipse(cov: NDArray[np.floating], k: float = 2.0, points: int = 65) -> NDArray:
    """Offsets ``(2, points)`` of the ``k``σ ellipse of a 2×2 covariance, a closed ring:
    ``P = V diag(λ) Vᵀ`` gives the ring ``k V √λ (cos u, sin u)``. A negative eigenvalue
    (round-off of a singular ``P``) counts as zero; a non-finite ``P`` gives NaN (nothing drawn)."""
    c = np.asarray(cov, dtype=float)
    if not np.all(np.isfinite(c)):
        return np.full((2, points), np.nan)
    lam, V = np.linalg.eigh(0.5 * (c + c.T))
    u = np.linspace(0.0, 2.0 * np.pi, points)
    return (V * (k * np.sqrt(np.clip(lam, 0.0, None)))) @ np.stack([np.cos(u), np.sin(u)])


def status_line(t: float, rewards: Sequence[float]) -> str:
    """``"step N   t T s   reward r   return R"`` of an episode so far (``rewards``: one per
    step; a NaN reward, not known to the renderer, is left out)."""
    steps = len(rewards)
    text = f"step {steps}   t {t:.1f} s"
    if steps and np.isfinite(rewards[-1]):
        text += f"   reward {rewards[-1]:+.2f}   return {float(np.nansum(rewards)):+.2f}"
    return text
