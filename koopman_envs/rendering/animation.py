"""Rendered frames to a file: an animated GIF (Pillow) or an MP4 (ffmpeg through matplotlib)."""

from __future__ import annotations

import os
import shutil
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from koopman_envs.files import write_atomic

__all__ = ["save_episode"]


def save_episode(frames: Sequence[NDArray[np.uint8]], path: str | os.PathLike[str], fps: int = 10) -> str:
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
        # whole or not at all: a run's animation is published beside its report
        write_atomic(
            path,
            lambda tmp: images[0].save(
                tmp, format="GIF", save_all=True, append_images=images[1:], duration=int(1000 / fps), loop=0
            ),
        )
        return path
    if ext == ".mp4":
        if shutil.which("ffmpeg") is None:
            raise RuntimeError("saving .mp4 needs the ffmpeg program on PATH; save a .gif instead")
        from matplotlib import animation
        from matplotlib.figure import Figure

        h, w = np.asarray(frames[0]).shape[:2]
        fig = Figure(figsize=(w / 100, h / 100), dpi=100)
        ax = fig.add_axes((0, 0, 1, 1))
        ax.axis("off")
        image = ax.imshow(frames[0])

        def write(tmp: str) -> None:
            writer = animation.FFMpegWriter(fps=fps)
            with writer.saving(fig, tmp, dpi=100):
                for frame in frames:
                    image.set_data(frame)
                    writer.grab_frame()

        write_atomic(path, write)  # the temporary file keeps the .mp4 suffix ffmpeg picks the format by
        return path
    raise ValueError(f"path={path!r} must end in '.gif' or '.mp4'")
