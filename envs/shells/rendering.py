"""Frames for the Gymnasium and PettingZoo shells: an env's renderer draws scenario 0 of the
states of the episode so far; ``"human"`` shows each frame in a matplotlib window.

An env names its renderer as a module path (``renderer = "sensorgym.envs.<env>.render"``, a
module with ``draw(params, history) -> (H, W, 3) uint8``), imported on the first frame so that
importing an env never imports matplotlib.
"""

from __future__ import annotations

import importlib
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
        self._window: tuple[Any, Any] | None = None

    def start(self, state: Any) -> None:
        """A new episode from ``state``."""
        if self.mode is not None:
            self.history = [state]

    def add(self, state: Any) -> None:
        """The state after a step."""
        if self.mode is not None:
            self.history.append(state)

    def draw(self, params: Any) -> NDArray[np.uint8]:
        """The RGB frame of the episode so far."""
        if not self.history:
            raise RuntimeError("render: call reset() first")
        module = importlib.import_module(str(self.renderer))
        return module.draw(params, self.history)

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
        """Close the window, if one was opened."""
        if self._window is not None:
            import matplotlib.pyplot as plt

            plt.close(self._window[0])
            self._window = None
