"""One scenario on one matplotlib axes: the static background (slip zones, obstacles, targets,
starts), built once per episode, and the dynamic artists (trails, robot bodies, headings, movers
and the layers of :mod:`koopman_envs.rendering.layers`) that every frame moves. The
renderer (:mod:`koopman_envs.rendering.renderer`) blits them; :func:`draw_scenario` draws a whole
episode on an axes of the caller's."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from koopman_envs.rendering.layers import MOVER_TRAIL, FrameLayers, Overlay, view_limits
from koopman_envs.scenario import Scenario
from koopman_envs.sim.slip.zones import SlipZone

if TYPE_CHECKING:  # pragma: no cover - typing only (matplotlib is imported when first used)
    pass

__all__ = ["PARKED_VIEW", "Scene", "draw_scenario", "static_key"]

_COLORS = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown", "tab:pink")
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


class Scene:
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


def static_key(scenario: Scenario, slip_zones: Sequence[SlipZone] = ()) -> tuple[Any, ...]:
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
    Scene(ax, scenario, animated=False, slip_zones=slip_zones).update(trail, title)
