"""Matplotlib drawing of a scenario and its trajectories, and GIF/MP4 export.

Only matplotlib (and Pillow, which matplotlib already requires) is used; ``rgb_array`` renders
off-screen through the Agg canvas, ``human`` opens a pyplot window.
"""

from __future__ import annotations

import os
import shutil
from typing import Sequence

import numpy as np
from numpy.typing import NDArray

from koopman_envs.scenario import Scenario

__all__ = ["Renderer", "draw_scenario", "save_episode"]

_COLORS = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown", "tab:pink")


def draw_scenario(ax, scenario: Scenario, trail: NDArray | None = None, title: str = "") -> None:
    """Draw obstacles, targets, trails and robots (with heading) on a matplotlib axes.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        Target axes (cleared first).
    scenario : Scenario
        Geometry of the episode.
    trail : ndarray, shape (T, N, 3), optional
        Poses so far; the last row is drawn as the robots.
    title : str
        Axes title.
    """
    from matplotlib.patches import Circle

    ax.clear()
    for x, y, r in scenario.obstacles:
        ax.add_patch(Circle((x, y), r, color="0.45", zorder=1))
    poses = scenario.starts[None] if trail is None or len(trail) == 0 else np.asarray(trail)
    radius = scenario.robot_radius
    for i in range(scenario.n_robots):
        color = _COLORS[i % len(_COLORS)]
        tx, ty, tth = scenario.targets[i]
        ax.add_patch(Circle((tx, ty), radius[i], fill=False, ls="--", color=color, zorder=2))
        ax.plot(*scenario.starts[i, :2], marker="s", ms=4, color=color, alpha=0.6, zorder=2)
        ax.plot(poses[:, i, 0], poses[:, i, 1], color=color, lw=1.5, zorder=3)
        x, y, th = poses[-1, i]
        ax.add_patch(Circle((x, y), radius[i], color=color, alpha=0.85, zorder=4))
        ax.plot([x, x + 1.6 * radius[i] * np.cos(th)], [y, y + 1.6 * radius[i] * np.sin(th)],
                color="k", lw=1.5, zorder=5)  # fmt: skip
    every = np.vstack([scenario.starts[:, :2], scenario.targets[:, :2], poses[-1, :, :2]])
    if len(scenario.obstacles):
        obs = scenario.obstacles
        every = np.vstack([every, obs[:, :2] - obs[:, 2:], obs[:, :2] + obs[:, 2:]])
    lo, hi = every.min(axis=0) - 1.0, every.max(axis=0) + 1.0
    x0, x1, y0, y1 = scenario.workspace
    ax.set_xlim(max(lo[0], x0), min(hi[0], x1))
    ax.set_ylim(max(lo[1], y0), min(hi[1], y1))
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.grid(alpha=0.3)
    if title:
        ax.set_title(title, fontsize=9)


class Renderer:
    """Reusable figure for an environment's ``render()``.

    Parameters
    ----------
    human : bool
        Open a pyplot window (``render_mode="human"``) instead of drawing off-screen.
    size : tuple of float
        Figure size in inches (at 100 dpi).
    """

    def __init__(self, human: bool = False, size: tuple[float, float] = (5.0, 5.0)) -> None:
        self.human = human
        if human:
            import matplotlib.pyplot as plt

            plt.ion()
            self.figure = plt.figure(figsize=size, dpi=100)
        else:
            from matplotlib.backends.backend_agg import FigureCanvasAgg
            from matplotlib.figure import Figure

            self.figure = Figure(figsize=size, dpi=100)
            FigureCanvasAgg(self.figure)
        self.ax = self.figure.add_subplot(1, 1, 1)

    def draw(self, scenario: Scenario, trail: NDArray, title: str = "") -> NDArray[np.uint8] | None:
        """Draw one frame; returns an (H, W, 3) uint8 image off-screen, None in a window."""
        draw_scenario(self.ax, scenario, trail, title)
        self.figure.tight_layout()
        if self.human:
            import matplotlib.pyplot as plt

            self.figure.canvas.draw_idle()
            plt.pause(1e-3)
            return None
        self.figure.canvas.draw()
        return np.asarray(self.figure.canvas.buffer_rgba())[..., :3].copy()

    def close(self) -> None:
        """Release the figure."""
        if self.human:
            import matplotlib.pyplot as plt

            plt.close(self.figure)
        self.figure = None


def save_episode(frames: Sequence[NDArray[np.uint8]], path: str | os.PathLike, fps: int = 10) -> str:
    """Save rendered frames as an animated GIF or an MP4 file.

    Parameters
    ----------
    frames : sequence of ndarray, each (H, W, 3) uint8
        Frames from ``env.render()`` with ``render_mode="rgb_array"``.
    path : str or path
        Output file ending in ``.gif`` (Pillow) or ``.mp4`` (needs the ``ffmpeg`` program).
    fps : int
        Frames per second (10 = real time at the 0.1 s control period).

    Returns
    -------
    str
        The path written.
    """
    path = os.fspath(path)
    if len(frames) == 0:
        raise ValueError("frames is empty: render at least one frame with render_mode='rgb_array'")
    ext = os.path.splitext(path)[1].lower()
    if ext == ".gif":
        from PIL import Image

        images = [Image.fromarray(np.asarray(f, dtype=np.uint8)) for f in frames]
        images[0].save(path, save_all=True, append_images=images[1:], duration=int(1000 / fps), loop=0)
        return path
    if ext == ".mp4":
        if shutil.which("ffmpeg") is None:
            raise RuntimeError("saving .mp4 needs the ffmpeg program on PATH; save a .gif instead")
        from matplotlib import animation
        from matplotlib.figure import Figure

        h, w = np.asarray(frames[0]).shape[:2]
        fig = Figure(figsize=(w / 100, h / 100), dpi=100)
        ax = fig.add_axes([0, 0, 1, 1])
        ax.axis("off")
        image = ax.imshow(frames[0])
        writer = animation.FFMpegWriter(fps=fps)
        with writer.saving(fig, path, dpi=100):
            for frame in frames:
                image.set_data(frame)
                writer.grab_frame()
        return path
    raise ValueError(f"path={path!r} must end in '.gif' or '.mp4'")
