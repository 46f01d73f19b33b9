"""What a frame shows beyond the map and the robots: the lidar beams, the collision marks, and a
view that keeps every mover in sight (used by :mod:`koopman_envs.rendering.renderer`).

* **Beams.** With ``sensing="lidar"`` every robot's beams of the current step are drawn from its
  centre (where the lidar measures from) to the reading, in the robot's colour and faint; a beam
  that met something ends in a dot, one that read the full range does not.
  :attr:`Renderer.show_beams <koopman_envs.rendering.renderer.Renderer.show_beams>` hides them.
* **Collisions.** A collision ends the episode, so the frame of its step is the one that shows it:
  a red cross where the bodies touch (on the robot's rim toward the obstacle, team-mate or mover;
  at the wall for a workspace exit) and a label with the kind
  (:class:`~koopman_envs.sim.collision.CollisionKind`) and the time.
* **View.** With movers the view covers the area they roam (their arena,
  :func:`~koopman_envs.sim.movers.placement.mover_arena`) besides the map, and widens, as for the
  robots, in whole steps for a mover found outside it.

The artists here are dynamic (drawn every frame over the static background) and stack above the
spines' zorder 2.5, as the renderer's blitting requires: beams 2.7-2.8, marks 6.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray

from koopman_envs.params import PARAMS
from koopman_envs.scenario import Scenario
from koopman_envs.sim.collision import CollisionKind
from koopman_envs.sim.lidar import beam_angles
from koopman_envs.sim.movers.placement import mover_arena
from koopman_envs.sim.slip.zones import SlipZone

__all__ = [
    "MOVER_TRAIL",
    "FrameLayers",
    "Overlay",
    "beam_segments",
    "collision_marks",
    "engine_frame",
    "engine_overlay",
    "frame_title",
    "view_limits",
]

#: periods of a mover's trail that a frame shows (2 s at the paper's dt)
MOVER_TRAIL = 20
#: margin around everything drawn [m] (the view is also clipped to the workspace)
VIEW_MARGIN = 1.0
#: a robot or mover that leaves the map's view widens it in steps of this much [m]: a view that
#: followed it exactly would change, and need a full redraw, on every frame
VIEW_STEP = 1.0
#: room around the movers' arena [m] (a mover keeps its whole disc inside the arena)
_ARENA_PAD = 0.2
#: beams: line width [pt], the opacity of one that met something and of one that read the full
#: range (fainter: with dozens of beams per robot the misses would hide the hits), the dot at a hit
_BEAM_WIDTH, _HIT_ALPHA, _MISS_ALPHA, _HIT_SIZE = 0.6, 0.45, 0.15, 9.0
#: collision marks: colour, cross size [pt]
_MARK_COLOR, _MARK_SIZE = "#d62728", 13.0


@dataclass(frozen=True)
class Overlay:
    """The per-step state a frame draws beside the poses (:func:`engine_overlay` reads it off an
    engine; every field may be left at its default).

    Attributes
    ----------
    ranges : ndarray, shape (N, B), optional
        The lidar readings of the current step [m] (the info's ``lidar_ranges``); None: no beams.
    angles : ndarray, shape (B,)
        Beam directions relative to the heading [rad].
    max_range : float
        The lidar's range [m]: a beam reading it met nothing.
    collision : int
        :class:`~koopman_envs.sim.collision.CollisionKind` flags of the current step (0: none).
    mover_hit : ndarray of bool, shape (N,), optional
        Which robots touch a mover (the kind the scenario's geometry cannot tell).
    """

    ranges: NDArray[np.float64] | None = None
    angles: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    max_range: float = 0.0
    collision: int = 0
    mover_hit: NDArray[np.bool_] | None = None


def _widened(
    lo: NDArray[np.float64], hi: NDArray[np.float64], points: NDArray[np.float64], margin: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(lo, hi) grown in whole :data:`VIEW_STEP` steps to hold ``points`` (P, 2) with ``margin``."""
    if not len(points):
        return lo, hi
    low, high = points.min(axis=0) - margin, points.max(axis=0) + margin
    lo = lo - VIEW_STEP * np.ceil(np.maximum(lo - low, 0.0) / VIEW_STEP)
    hi = hi + VIEW_STEP * np.ceil(np.maximum(high - hi, 0.0) / VIEW_STEP)
    return lo, hi


def view_limits(
    scenario: Scenario,
    current: NDArray[np.float64],
    slip_zones: Sequence[SlipZone] = (),
    movers: NDArray[np.float64] | None = None,
) -> tuple[float, float, float, float]:
    """(x_min, x_max, y_min, y_max) [m] of the view: the starts, targets, obstacles and slip zones
    with a margin (and the movers' arena when the scenario has movers), widened in whole steps to
    show the robots at ``current`` (N, 3) and the movers at ``movers`` (C, 2), and clipped to the
    workspace."""
    fixed = np.vstack([scenario.starts[:, :2], scenario.targets[:, :2]])
    if len(scenario.obstacles):
        obs = scenario.obstacles
        fixed = np.vstack([fixed, obs[:, :2] - obs[:, 2:], obs[:, :2] + obs[:, 2:]])
    if len(slip_zones):
        boxes = np.array([zone.extent() for zone in slip_zones])
        fixed = np.vstack([fixed, boxes[:, :2], boxes[:, 2:]])
    lo, hi = fixed.min(axis=0) - VIEW_MARGIN, fixed.max(axis=0) + VIEW_MARGIN
    if scenario.n_movers:
        x0, x1, y0, y1 = mover_arena(
            scenario.starts, scenario.targets, scenario.obstacles, scenario.workspace
        )
        lo = np.minimum(lo, np.array([x0, y0]) - _ARENA_PAD)
        hi = np.maximum(hi, np.array([x1, y1]) + _ARENA_PAD)
    lo, hi = _widened(lo, hi, current[:, :2], VIEW_MARGIN)
    if movers is not None:
        lo, hi = _widened(lo, hi, np.asarray(movers).reshape(-1, 2), scenario.mover_radius + _ARENA_PAD)
    x0, x1, y0, y1 = scenario.workspace
    return (float(max(lo[0], x0)), float(min(hi[0], x1)), float(max(lo[1], y0)), float(min(hi[1], y1)))


def beam_segments(
    poses: NDArray[np.float64], angles: NDArray[np.float64], ranges: NDArray[np.float64], max_range: float
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
    """The beams of robots at ``poses`` (N, 3) reading ``ranges`` (N, B) along ``angles`` (B,):
    segments (N B, 2, 2) from each centre to its reading, their end points (N B, 2), and which
    ends met something (N B,) (a reading below ``max_range``)."""
    poses, ranges = np.asarray(poses, dtype=float), np.asarray(ranges, dtype=float)
    heading = poses[:, 2:3] + np.asarray(angles)[None, :]
    start = np.broadcast_to(poses[:, None, :2], ranges.shape + (2,))
    end = start + ranges[..., None] * np.stack([np.cos(heading), np.sin(heading)], axis=-1)
    segments = np.stack([start, end], axis=2).reshape(-1, 2, 2)
    return segments, end.reshape(-1, 2), (ranges < max_range).reshape(-1)


def _touching(
    centre: NDArray[np.float64], radius: float, others: NDArray[np.float64], other_radius: NDArray[np.float64]
) -> list[NDArray[np.float64]]:
    """Where a disc at ``centre`` touches each overlapping disc of ``others`` (M, 2): the point on
    its rim toward the other's centre, scaled into the overlap (its centre when the two coincide)."""
    points = []
    for other, r in zip(
        np.asarray(others).reshape(-1, 2), np.broadcast_to(other_radius, len(others)), strict=True
    ):
        delta = other - centre
        distance = float(np.hypot(*delta))
        if distance - (radius + r) < 0.0:
            reach = radius * distance / (radius + r) if radius + r > 0 else 0.0
            points.append(centre + (delta / distance * reach if distance > 0 else 0.0))
    return points


def collision_marks(
    scenario: Scenario,
    poses: NDArray[np.float64],
    code: int,
    movers: NDArray[np.float64] | None = None,
    mover_hit: NDArray[np.bool_] | None = None,
) -> list[tuple[float, float, str]]:
    """Where and of what kind the collisions of robots at ``poses`` (N, 3) are, as (x, y, kind)
    for the :class:`~koopman_envs.sim.collision.CollisionKind` flags ``code``: each robot touching
    an obstacle, each touching pair of robots (once), each robot touching a mover at ``movers``
    (C, 2) (those of ``mover_hit`` when given), and each robot whose centre left the workspace (at
    the wall). A flag whose contact is not found (a mover that has moved on) is marked at the
    team's centre."""
    xy, radius = np.asarray(poses, dtype=float)[:, :2], scenario.robot_radius
    marks: list[tuple[float, float, str]] = []

    def add(points: list[NDArray[np.float64]], kind: str) -> None:
        marks.extend((float(p[0]), float(p[1]), kind) for p in points)

    x0, x1, y0, y1 = scenario.workspace
    for i, centre in enumerate(xy):
        if code & CollisionKind.OBSTACLE and len(scenario.obstacles):
            add(_touching(centre, radius[i], scenario.obstacles[:, :2], scenario.obstacles[:, 2]), "obstacle")
        if code & CollisionKind.ROBOT:
            add(_touching(centre, radius[i], xy[i + 1 :], radius[i + 1 :]), "robot")
        if code & CollisionKind.MOVER and movers is not None and (mover_hit is None or mover_hit[i]):
            add(_touching(centre, radius[i], movers, np.array(scenario.mover_radius)), "mover")
        if code & CollisionKind.WORKSPACE and not (x0 <= centre[0] <= x1 and y0 <= centre[1] <= y1):
            add([np.clip(centre, [x0, y0], [x1, y1])], "workspace")
    found = {kind for *_, kind in marks}
    for bit, kind in CollisionKind.NAMES.items():
        if code & bit and kind not in found:
            add([xy.mean(axis=0)], kind)
    return marks


def engine_overlay(engine: Any, index: int, show_beams: bool = True) -> Overlay:
    """The :class:`Overlay` of environment ``index`` of a
    :class:`~koopman_envs.engine.engine.NavigationEngine` after a reset: its lidar readings (the info's
    ``lidar_ranges``; with ``sensing="lidar"`` and ``show_beams``) and its collision flags."""
    lidar = engine.config.lidar
    ranges, angles, max_range = None, np.zeros(0), 0.0
    if lidar is not None and show_beams:
        ranges = engine.observed_info()["lidar_ranges"][index]
        angles, max_range = beam_angles(lidar.beams, lidar.fov), float(lidar.range)
    code = int(engine.collision[index])
    hit = engine.movers.hit[index].copy() if code and engine.movers is not None else None
    return Overlay(ranges, angles, max_range, code, hit)


def frame_title(config: Any) -> str:
    """The fixed part of a frame's title (the renderer appends the episode time): task, map, the
    formation shape asked for, and the slip setting of an :class:`~koopman_envs.engine.config.EngineConfig`."""
    shape = f" | {config.formation}" if config.formation else ""
    return f"{config.task.name} | {config.map_name}{shape} | slip {config.slip_label}"


def engine_frame(engine: Any, index: int, show_beams: bool = True) -> dict[str, Any]:
    """What a frame of environment ``index`` of a :class:`~koopman_envs.engine.engine.NavigationEngine`
    shows besides its scenario and trail: the keywords ``title``, ``elapsed``, ``slip_zones``,
    ``movers`` and ``overlay`` of :meth:`Renderer.draw <koopman_envs.rendering.renderer.Renderer.draw>`."""
    spec = engine.maps[index]
    assert spec is not None  # the env was reset, so a map is installed
    movers = None
    if engine.movers is not None:
        # the movers' trails are recorded from the first frame on (free until something draws)
        engine.movers.keep_trail(MOVER_TRAIL)
        movers = engine.movers.trail_of(index)
    return {
        "title": frame_title(engine.config),
        "elapsed": engine.elapsed[index] * PARAMS.dt,
        "slip_zones": spec.slip_zones,
        "movers": movers,
        "overlay": engine_overlay(engine, index, show_beams),
    }


class FrameLayers:
    """The beams and collision marks of one scene's axes (the module docstring): created empty,
    moved by :meth:`update`; :attr:`artists` lists the dynamic artists in drawing order (labels
    are added as collisions need them)."""

    def __init__(self, ax: Any, colours: Sequence[Any], n_robots: int, animated: bool) -> None:
        from matplotlib.collections import LineCollection

        self.ax, self.animated = ax, animated
        from matplotlib.colors import to_rgba_array

        self.colours = to_rgba_array([colours[i % len(colours)] for i in range(n_robots)])
        self.beams = LineCollection([], linewidths=_BEAM_WIDTH, zorder=2.7)
        ax.add_collection(self.beams, autolim=False)
        self.hits = ax.scatter([], [], s=_HIT_SIZE, linewidths=0, zorder=2.8)
        self.marks = ax.plot([], [], ls="", marker="X", ms=_MARK_SIZE, color=_MARK_COLOR, mec="white",
                             mew=1.2, zorder=6)[0]  # fmt: skip
        self.labels: list[Any] = []
        self.artists: list[Any] = [self.beams, self.hits, self.marks]
        for artist in self.artists:
            artist.set_animated(animated)

    def update(
        self,
        scenario: Scenario,
        poses: NDArray[np.float64],
        overlay: Overlay | None,
        movers: NDArray[np.float64] | None,
        elapsed: float | None,
        limits: tuple[float, float, float, float],
    ) -> None:
        """Draw ``overlay`` for robots at ``poses`` (N, 3) and movers at ``movers`` (C, 2)."""
        overlay = overlay or Overlay()
        if overlay.ranges is not None and len(overlay.angles):
            segments, ends, hit = beam_segments(poses, overlay.angles, overlay.ranges, overlay.max_range)
            per_robot = np.repeat(np.arange(len(poses)), len(overlay.angles))
            colour = self.colours[per_robot]
            colour[:, 3] = np.where(hit, _HIT_ALPHA, _MISS_ALPHA)
            self.beams.set_segments(list(segments))
            self.beams.set_color(cast("Any", colour))  # an (S, 4) RGBA array, unannotated
            self.hits.set_offsets(ends[hit])
            self.hits.set_facecolors(self.colours[per_robot[hit]])
        else:
            self.beams.set_segments([])
            self.hits.set_offsets(np.zeros((0, 2)))
        marks = collision_marks(scenario, poses, overlay.collision, movers, overlay.mover_hit)
        self.marks.set_data([m[0] for m in marks], [m[1] for m in marks])
        while len(self.labels) < len(marks):
            self._add_label()
        when = "" if elapsed is None else f" at t = {elapsed:.1f} s"
        middle = (limits[0] + limits[1]) / 2
        for label, mark in zip(self.labels, marks + [None] * (len(self.labels) - len(marks)), strict=True):
            label.set_visible(mark is not None)
            if mark is not None:
                x, y, kind = mark
                right = x <= middle  # the label toward the view's middle, so that it stays inside
                label.xy = (x, y)
                label.set_text(f"collision: {kind}{when}")
                label.set_horizontalalignment("left" if right else "right")
                label.set_position((7 if right else -7, 7))

    def _add_label(self) -> None:
        label = self.ax.annotate(
            "", xy=(0.0, 0.0), xytext=(7, 7), textcoords="offset points", fontsize=8.5, color=_MARK_COLOR,
            zorder=6, bbox={"boxstyle": "round,pad=0.25", "fc": "white", "ec": _MARK_COLOR, "alpha": 0.9},
        )  # fmt: skip
        label.set_animated(self.animated)
        self.labels.append(label)
        self.artists.append(label)
