"""Matplotlib drawing of a scenario and its trajectories, and GIF/MP4 export.

Only matplotlib (and Pillow, which matplotlib already requires) is used; ``rgb_array`` renders
off-screen through the Agg canvas, ``human`` opens a pyplot window.

A frame is cheap because the figure is built once per episode: slip zones, obstacles, targets,
start markers, axes and grid form a static background that is drawn once and kept as a bitmap, and
each frame only restores that bitmap and draws the moving artists (trails, robot bodies,
headings, the clock in the title, and the layers of :mod:`koopman_envs.fronts.rendering_layers`: lidar
beams and collision marks) on top of it (blitting). The view holds the map and the area the movers
roam; a robot or mover that leaves it widens it in 1 m steps, and a frame in which the axis limits
change redraws the background.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, cast

import numpy as np
from numpy.typing import NDArray

from koopman_envs.fronts.animation import save_episode
from koopman_envs.fronts.rendering_layers import (
    MOVER_TRAIL,
    FrameLayers,
    Overlay,
    engine_frame,
    frame_title,
    view_limits,
)
from koopman_envs.scenario import Scenario
from koopman_envs.sim.zones import SlipZone

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

_COLORS = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown", "tab:pink")
#: most ``tight_layout`` passes per layout (two settle it in practice)
_LAYOUT_PASSES = 4
#: movers: body colour and the opacity of their trails (dark and hatched: not a robot, not a map obstacle)
_MOVER_COLOR = "0.15"
#: where a mover disc waits before its first position is known (outside every view)
PARKED_VIEW = 1e3
#: length of a robot's heading stroke, in robot radii
_HEADING_LENGTH = 1.6
#: slip zones: fill colour, and the opacity of a zone whose largest lambda is 0 and of one whose
#: largest lambda is _ZONE_FULL_LAMBDA or more (linear in between), so that slipperier looks darker
_ZONE_COLOR = "tab:cyan"
_ZONE_ALPHA = (0.08, 0.45)
_ZONE_FULL_LAMBDA = 0.5


class _Scene:
    """The artists of one scenario on one axes: static ones, built here once, and the dynamic
    ones (:attr:`dynamic`) that :meth:`update` moves.

    Every dynamic artist has a higher zorder than every static one (beams 2.7, trails 3, bodies 4,
    headings 5, collision marks 6, above the spines' 2.5), so drawing them over a bitmap of the
    static artists gives the same picture as drawing everything at once. The axes title holds the whole title
    (it places the layout); with ``animated`` it is left out of the drawing, because the
    :class:`Renderer` draws it in parts.
    """

    def __init__(
        self, ax: Any, scenario: Scenario, animated: bool, slip_zones: Sequence[SlipZone] = ()
    ) -> None:
        from matplotlib.patches import Circle, Rectangle

        ax.clear()
        self.ax = ax
        self.scenario = scenario
        self.slip_zones = tuple(slip_zones)
        low, high = _ZONE_ALPHA
        style: dict[str, Any] = {"color": _ZONE_COLOR, "lw": 0, "zorder": 0.8}
        for zone in self.slip_zones:
            # beneath the obstacles (zorder 1); static, so drawn into the background bitmap once
            largest = float(zone.lambdas_for(scenario.n_robots).max())
            alpha = low + (high - low) * min(largest / _ZONE_FULL_LAMBDA, 1.0)
            if zone.shape == "circle":
                x, y, r = zone.bounds
                patch: Circle | Rectangle = Circle((x, y), r, alpha=alpha, **style)
            else:
                x0, y0, x1, y1 = zone.bounds
                patch = Rectangle((x0, y0), x1 - x0, y1 - y0, alpha=alpha, **style)
            ax.add_patch(patch)
        for x, y, r in scenario.obstacles:
            ax.add_patch(Circle((x, y), r, color="0.45", zorder=1))
        radius = scenario.robot_radius
        self.trails, self.bodies = [], []
        # per robot in this order, so that artists of equal zorder stack as they always have
        for i in range(scenario.n_robots):
            color = _COLORS[i % len(_COLORS)]
            tx, ty, _ = scenario.targets[i]
            ax.add_patch(Circle((tx, ty), radius[i], fill=False, ls="--", color=color, zorder=2))
            ax.plot(*scenario.starts[i, :2], marker="s", ms=4, color=color, alpha=0.6, zorder=2)
            self.trails.append(ax.plot([], [], color=color, lw=1.5, zorder=3)[0])
            self.bodies.append(ax.add_patch(Circle((0.0, 0.0), radius[i], color=color, alpha=0.85, zorder=4)))
        # one black stroke per robot, all in one line broken by NaN rows: one artist to draw
        # (the same pixels unless two strokes come within a pixel of each other)
        self.headings = ax.plot([], [], color="k", lw=1.5, zorder=5)[0]
        # movers: a dotted trail and a hatched dark disc each, above the robots' trails
        self.mover_trails = [
            ax.plot([], [], color=_MOVER_COLOR, lw=1.0, ls=":", zorder=3.5)[0]
            for _ in range(scenario.n_movers)
        ]
        self.movers = [
            ax.add_patch(
                Circle((PARKED_VIEW, PARKED_VIEW), scenario.mover_radius, facecolor="0.75", edgecolor=_MOVER_COLOR,
                       hatch="////", lw=1.0, zorder=4)
            )
            for _ in range(scenario.n_movers)
        ]  # fmt: skip
        self._stroke = np.full((3 * scenario.n_robots, 2), np.nan)
        ax.set_aspect("equal")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.grid(alpha=0.3)
        self.title = ax.set_title("", fontsize=9)
        self.layers = FrameLayers(ax, _COLORS, scenario.n_robots, animated)
        # the scene's own dynamic artists, in drawing (zorder) order
        self._own = [*self.trails, *self.mover_trails, *self.bodies, *self.movers, self.headings]
        for artist in (*self._own, self.title):
            artist.set_animated(animated)
        self.limits: tuple[float, float, float, float] | None = None

    @property
    def dynamic(self) -> list[Any]:
        """The artists that change from frame to frame, in drawing (zorder) order."""
        beams, hits, marks, *labels = self.layers.artists
        return [beams, hits, *self._own, marks, *labels]

    def update(
        self,
        trail: NDArray[np.float64] | None,
        title: str,
        movers: NDArray[np.float64] | None = None,
        overlay: Overlay | None = None,
        elapsed: float | None = None,
    ) -> bool:
        """Move the dynamic artists to ``trail`` (T, N, 3) and the movers to ``movers`` (T', C,
        2: their recent positions, the last drawn as the discs), and draw ``overlay`` (beams,
        collision marks at time ``elapsed``); True when the axis limits changed (then the static
        background is stale)."""
        scenario = self.scenario
        now = None
        if movers is not None and len(movers):
            recent = np.asarray(movers)[-MOVER_TRAIL:]
            now = recent[-1]
            for c, (line, disc) in enumerate(zip(self.mover_trails, self.movers, strict=True)):
                line.set_data(recent[:, c, 0], recent[:, c, 1])
                disc.set_center(recent[-1, c])
        poses = scenario.starts[None] if trail is None or len(trail) == 0 else np.asarray(trail)
        for i in range(scenario.n_robots):
            self.trails[i].set_data(poses[:, i, 0], poses[:, i, 1])
            self.bodies[i].set_center(poses[-1, i, :2])
        x, y, th = poses[-1].T
        reach = _HEADING_LENGTH * scenario.robot_radius
        self._stroke[0::3, 0], self._stroke[0::3, 1] = x, y
        self._stroke[1::3, 0], self._stroke[1::3, 1] = x + reach * np.cos(th), y + reach * np.sin(th)
        self.headings.set_data(self._stroke[:, 0].copy(), self._stroke[:, 1].copy())
        self.title.set_text(title)
        limits = view_limits(scenario, poses[-1], self.slip_zones, now)
        self.layers.update(scenario, poses[-1], overlay, now, elapsed, limits)
        if limits == self.limits:
            return False
        self.ax.set_xlim(limits[0], limits[1])
        self.ax.set_ylim(limits[2], limits[3])
        self.limits = limits
        return True


def _static_key(scenario: Scenario, slip_zones: Sequence[SlipZone] = ()) -> tuple[Any, ...]:
    """What the static background depends on: a new episode with other geometry rebuilds it."""
    return tuple(
        np.ascontiguousarray(a).tobytes()
        for a in (scenario.obstacles, scenario.starts, scenario.targets, scenario.robot_radius)
    ) + (scenario.workspace, tuple((z.shape, z.bounds, z.lam, z.mode) for z in slip_zones))


def draw_scenario(
    ax: Any,
    scenario: Scenario,
    trail: NDArray[np.float64] | None = None,
    title: str = "",
    slip_zones: Sequence[SlipZone] = (),
) -> None:
    """Draw slip zones, obstacles, targets, trails and robots (with heading) on a matplotlib axes.

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
    slip_zones : sequence of SlipZone
        The map's slip zones (``MapSpec.slip_zones``), shaded beneath the obstacles, darker the
        larger their lambda. Passed apart from the scenario, which carries no slip parameters.
    """
    _Scene(ax, scenario, animated=False, slip_zones=slip_zones).update(trail, title)


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
    _scene: _Scene | None
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
        key = _static_key(scenario, slip_zones)
        stale = False
        if self._scene is None or key != self._scene_key:
            self._scene = _Scene(self.ax, scenario, animated=self.blit, slip_zones=slip_zones)
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
    """One frame of environment ``index`` of a :class:`~koopman_envs.builder.engine.NavigationEngine`
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
