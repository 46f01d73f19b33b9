"""Matplotlib drawing of a scenario and its trajectories, and GIF/MP4 export.

Only matplotlib (and Pillow, which matplotlib already requires) is used; ``rgb_array`` renders
off-screen through the Agg canvas, ``human`` opens a pyplot window.

A frame is cheap because the figure is built once per episode: slip zones, obstacles, targets,
start markers, axes and grid form a static background that is drawn once and kept as a bitmap, and
each frame only restores that bitmap and draws the moving artists (trails, robot bodies,
headings, the clock in the title, and the layers of :mod:`koopman_envs.rendering.layers`: lidar
beams and collision marks) on top of it (blitting). The view holds the map and the area the movers
roam; a robot or mover that leaves it widens it in 1 m steps, and a frame in which the axis limits
change redraws the background.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, cast

import numpy as np
from numpy.typing import NDArray

from koopman_envs.rendering.animation import save_episode
from koopman_envs.rendering.layers import (
    MOVER_TRAIL,
    Overlay,
    engine_frame,
    frame_title,
)
from koopman_envs.rendering.scene import Scene, draw_scenario, static_key
from koopman_envs.scenario import Scenario
from koopman_envs.sim.slip.zones import SlipZone

if TYPE_CHECKING:  # pragma: no cover - typing only (matplotlib is imported when first used)
    from matplotlib.axes import Axes
    from matplotlib.backend_bases import RendererBase
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.text import Text

__all__ = [
    "MOVER_TRAIL",
    "Renderer",
    "draw_engine_env",
    "draw_scenario",
    "frame_title",
    "save_episode",
    "title_parts",
]

#: most ``tight_layout`` passes per layout (two settle it in practice)
_LAYOUT_PASSES = 4


def title_parts(title: str, elapsed: float | None) -> tuple[str, str, str]:
    """The displayed title as (head, clock, tail), e.g. ``"<title> | t = "``, ``"1.2"``, ``" s"``.

    Only the clock changes from frame to frame; the whole title is ``head + clock + tail`` (just
    ``title`` when ``elapsed`` is None).
    """
    if elapsed is None:
        return title, "", ""
    return (f"{title} | t = " if title else "t = "), f"{elapsed:.1f}", " s"


def _rgb(canvas: Any) -> NDArray[np.uint8]:
    """The canvas as a new contiguous (H, W, 3) uint8 array."""
    rgba = np.asarray(canvas.buffer_rgba())
    out = np.empty(rgba.shape[:2] + (3,), dtype=np.uint8)
    # channel by channel: ~10x faster than copying the strided rgba[..., :3] view at once
    for channel in range(3):
        out[..., channel] = rgba[..., channel]
    return out


class Renderer:
    """Reusable figure for an environment's ``render()``.

    The figure is created on the first :meth:`draw`, and again after the renderer has been
    copied or unpickled (a figure does not survive pickling with its canvas, so it is dropped).

    Parameters
    ----------
    human : bool
        Open a pyplot window (``render_mode="human"``) instead of drawing off-screen.
    size : tuple of float
        Figure size in inches (at 100 dpi).
    blit : bool
        Off-screen only: keep the static background as a bitmap and draw only the moving
        artists per frame (the default, a few ms a frame). ``False`` redraws the whole figure
        every frame (~10x slower); it exists as the reference the fast path is tested against.
    show_beams : bool, optional
        Draw the lidar beams of a ``sensing="lidar"`` env (:func:`draw_engine_env`); None: the
        class default :attr:`show_beams`.
    """

    #: the default of every renderer: ``Renderer.show_beams = False`` hides the lidar beams in
    #: every env's frames drawn from then on
    show_beams: bool = True

    # the figure and what is drawn on it: None until the first draw (see _no_figure and _open)
    figure: Figure | None
    ax: Axes | None
    _scene: Scene | None
    _scene_key: tuple[Any, ...] | None
    _background: Any  # the Agg canvas's bitmap (matplotlib leaves its type unannotated)
    _title_layout: tuple[str, int, str] | None
    _head: Text | None
    _clock: Text | None
    _tail: Text | None
    _initial_subplotpars: dict[str, float] | None

    def __init__(
        self,
        human: bool = False,
        size: tuple[float, float] = (5.0, 5.0),
        blit: bool = True,
        show_beams: bool | None = None,
    ) -> None:
        if show_beams is not None:
            self.show_beams = show_beams
        self.human = human
        self.size = size
        self.blit = blit and not human
        self._reset_figure()

    @staticmethod
    def _no_figure() -> dict[str, Any]:
        """The attributes that hold the figure and what is drawn on it, all unset."""
        return {
            "figure": None,
            "ax": None,
            "_scene": None,  # the artists of the episode drawn last
            "_scene_key": None,  # the geometry they show
            "_background": None,  # bitmap of the static artists
            "_title_layout": None,  # the title head and clock length the background was laid out for
            "_head": None,
            "_clock": None,
            "_tail": None,
            "_initial_subplotpars": None,  # the new figure's subplot parameters, where every layout starts
        }

    def _reset_figure(self) -> None:
        self.__dict__.update(self._no_figure())

    def __getstate__(self) -> dict[str, Any]:
        # a pickled figure comes back with a bare canvas that cannot draw off-screen (no
        # buffer_rgba), and a copy must not share the original's window: copies (pickle and
        # copy.deepcopy alike) drop the figure, and their first draw builds a new one
        return {**self.__dict__, **self._no_figure()}

    def _open(self) -> None:
        if self.human:
            import matplotlib.pyplot as plt

            plt.ion()
            self.figure = plt.figure(figsize=self.size, dpi=100)
        else:
            from matplotlib.backends.backend_agg import FigureCanvasAgg
            from matplotlib.figure import Figure

            self.figure = Figure(figsize=self.size, dpi=100)
            FigureCanvasAgg(self.figure)
        self.ax = self.figure.add_subplot(1, 1, 1)
        params = self.figure.subplotpars
        self._initial_subplotpars = {
            k: getattr(params, k) for k in ("left", "right", "bottom", "top", "wspace", "hspace")
        }
        if self.blit:
            from matplotlib.transforms import IdentityTransform

            # the title in three parts at pixel positions: the fixed head and tail go into the
            # background, so that a frame lays out and rasterizes only the few glyphs of the clock
            # (text is by far the most expensive artist: ~10 ms for a whole title)
            self._head, self._clock, self._tail = (
                self.figure.text(0, 0, "", va="baseline", transform=IdentityTransform(), animated=True)
                for _ in range(3)
            )  # animated: head and tail are drawn into the background once they are placed

    def draw(
        self,
        scenario: Scenario,
        trail: NDArray[np.float64],
        title: str = "",
        elapsed: float | None = None,
        slip_zones: Sequence[SlipZone] = (),
        movers: NDArray[np.float64] | None = None,
        overlay: Overlay | None = None,
    ) -> NDArray[np.uint8] | None:
        """Draw one frame.

        Parameters
        ----------
        scenario : Scenario
            Geometry of the episode.
        trail : ndarray, shape (T, N, 3)
            Poses so far; the last row is drawn as the robots.
        title : str
            Fixed part of the title.
        elapsed : float, optional
            Episode time [s], shown after the title as ``t = 1.2 s``.
        slip_zones : sequence of SlipZone
            The map's slip zones, shaded in the static background (see :func:`draw_scenario`).
        movers : ndarray, shape (T, C, 2), optional
            The movers' recent positions (``scenario.n_movers`` of them): the last
            :data:`MOVER_TRAIL` as dotted trails, the last row as hatched discs.
        overlay : Overlay, optional
            Lidar beams and collision flags of this step (:func:`draw_engine_env` reads them).

        Returns
        -------
        ndarray or None
            An (H, W, 3) uint8 image off-screen, None in a window.
        """
        if self.figure is None:
            self._open()
        assert self.figure is not None and self.ax is not None  # made by _open()
        key = static_key(scenario, slip_zones)
        stale = False
        if self._scene is None or key != self._scene_key:
            self._scene = Scene(self.ax, scenario, animated=self.blit, slip_zones=slip_zones)
            self._scene_key = key
            stale = True
        head, clock, tail = title_parts(title, elapsed)
        stale = self._scene.update(trail, head + clock + tail, movers, overlay, elapsed) or stale
        canvas = self.figure.canvas
        if self.human:
            if stale:
                self._lay_out()
            canvas.draw_idle()
            import matplotlib.pyplot as plt

            plt.pause(1e-3)
            return None
        if not self.blit:
            self._lay_out()
            canvas.draw()
            return _rgb(canvas)
        # blit is off-screen only: _open() made an Agg canvas and the three title parts
        agg = cast("FigureCanvasAgg", canvas)
        assert self._head is not None and self._clock is not None and self._tail is not None
        # the parts' positions depend on the whole title's width, which changes only with the
        # clock's length (the default font's digits all have the same width)
        layout = (head, len(clock), tail)
        if stale or layout != self._title_layout or self._background is None:
            self._lay_out()
            canvas.draw()  # everything but the animated artists; places the axes and their title
            self._place_title(head, clock, tail)
            self.figure.draw_artist(self._head)
            self.figure.draw_artist(self._tail)
            self._title_layout = layout
            # matplotlib's backend_agg is unannotated: its methods are untyped to the type checker
            self._background = agg.copy_from_bbox(self.figure.bbox)  # type: ignore[no-untyped-call]
        else:
            agg.restore_region(self._background)  # type: ignore[no-untyped-call]
        for artist in self._scene.dynamic:
            self.ax.draw_artist(artist)
        if clock:
            self._clock.set_text(clock)
            self.figure.draw_artist(self._clock)
        return _rgb(canvas)

    def _lay_out(self) -> None:
        """``tight_layout`` until the axes stop moving: with the equal aspect, one pass from
        another layout can leave them up to ~15 px off where the next pass puts them."""
        # always from the figure's initial layout: tight_layout's result depends on where the
        # axes are, so a figure laid out before would differ by a few pixels from a copy's new
        # one, and a frame would depend on the drawing history instead of the state alone
        # (only draw() calls this, after _open() has set these)
        assert self.figure is not None and self.ax is not None and self._initial_subplotpars is not None
        self.figure.subplots_adjust(**self._initial_subplotpars)
        for _ in range(_LAYOUT_PASSES):
            before = self.ax.get_position(original=True).bounds
            self.figure.tight_layout()
            if np.allclose(self.ax.get_position(original=True).bounds, before, rtol=0.0, atol=1e-9):
                break

    def _place_title(self, head: str, clock: str, tail: str) -> None:
        """Put the parts where the axes title, which holds all of them, draws their glyphs (the
        pixels come out the same: text widths are sums of glyph advances)."""
        # only draw() calls this, with blit set: _open() has made the figure, its Agg canvas and the parts
        assert self.figure is not None and self.ax is not None
        assert self._head is not None and self._clock is not None and self._tail is not None
        title = self.ax.title
        canvas = cast("FigureCanvasAgg", self.figure.canvas)
        # matplotlib's backend_agg is unannotated: get_renderer() is untyped to the type checker
        renderer: RendererBase = canvas.get_renderer()  # type: ignore[no-untyped-call]
        prop = title.get_fontproperties()

        def width(text: str) -> float:
            return renderer.get_text_width_height_descent(text, prop, ismath=False)[0]

        x = title.get_window_extent(renderer).x0
        baseline = title.get_transform().transform(title.get_position())[1]
        for part, text, offset in (
            (self._head, head, 0.0),
            (self._clock, clock, width(head) if clock else 0.0),
            (self._tail, tail, width(head + clock) if tail else 0.0),
        ):
            part.set_fontproperties(prop)
            part.set_color(title.get_color())
            part.set_text(text)
            part.set_position((x + offset, baseline))

    def close(self) -> None:
        """Release the figure."""
        if self.human and self.figure is not None:
            import matplotlib.pyplot as plt

            plt.close(self.figure)
        self._reset_figure()


def draw_engine_env(
    renderer: Renderer, engine: Any, index: int, trail: Sequence[NDArray[np.float64]]
) -> NDArray[np.uint8] | None:
    """One frame of environment ``index`` of a :class:`~koopman_envs.engine.engine.NavigationEngine`
    (what the single env's and the vector env's ``render()`` draw): with its movers, its lidar
    beams (unless ``renderer.show_beams`` is False) and a mark at a collision.

    Parameters
    ----------
    renderer : Renderer
    engine : NavigationEngine
        After a reset of ``index``.
    index : int
        The environment within the engine's batch.
    trail : sequence of ndarray, shape (N, 3) each
        Its poses since its episode started; the last is drawn as the robots.
    """
    frame = engine_frame(engine, index, renderer.show_beams)
    return renderer.draw(engine.scenario(index), np.asarray(trail), **frame)
