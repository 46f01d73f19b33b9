"""The global plan under ``dwa``: a wavefront over a grid of the map, as ROS's ``navfn`` plans and
as ``dwa_local_planner`` measures its path and goal distances (over its costmap's cells).

:class:`GlobalPlanner` grids the map at ``resolution`` metres; a cell is lethal within the robot's
radius plus the safety margin of an obstacle's surface (the configuration space of a disc robot),
and its costmap value is ROS's inflation (``252 exp(-cost_scaling_factor * c)`` at clearance
``c`` up to the inflation radius). For a goal, :func:`wavefront` (relaxation sweeps over the 8
grid moves) gives two fields, computed once per goal cell and kept:

- the **plan**: navfn's potential, each cell entered at its length times
  ``(COST_NEUTRAL + COST_FACTOR * cost) / COST_NEUTRAL`` (navfn's 50 and 0.8), so that the plan
  keeps to the middle of a gap and prefers the wide way round; the path descends it from the
  robot;
- the **goal distance** the critics read: the plain grid distance through free cells.

:meth:`GlobalPlanner.plan` returns None when the goal is in line of sight (the straight segment
clears every obstacle by the margin): the wavefront distance is then the straight-line one and
nothing needs computing. A team-mate or mover standing on that straight plan bends it round its
right side (:meth:`GlobalPlanner.detour`), where ROS's global costmap would hold the other robot.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from controllers.classic.kernels import polyline_distances, relax_wavefront
from koopman_envs.scenario import Scenario

__all__ = ["Detour", "GlobalPlanner", "Plan", "polyline_distance", "wavefront"]

#: the 8 grid moves and their lengths in cells
_MOVES = ((1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (1, -1), (-1, 1), (-1, -1))
_MOVE_ARRAY = np.array(_MOVES, dtype=np.int64)
#: goal wavefronts kept per episode (the formation's slots move, the targets do not)
_KEPT = 64
#: metres of grid around the map's obstacles, starts and targets
_BORDER = 2.0
#: navfn's cost of a free cell and its factor on the costmap value (navfn.h)
COST_NEUTRAL, COST_FACTOR = 50.0, 0.8


def wavefront(
    free: NDArray[np.bool_], seed: NDArray[np.float64], weight: NDArray[np.float64] | None = None
) -> NDArray[np.float64]:
    """Grid distance [cells] of every cell to the ``seed`` cells (their finite values are their
    distances) through ``free`` cells, 8-connected, each cell entered at its move's length times
    its ``weight`` (1 without), infinite where unreachable: relaxation sweeps over the 8 moves
    until nothing changes."""
    field = np.array(seed, dtype=np.float64)
    start = np.isfinite(seed)
    cost = np.ones(free.shape) if weight is None else np.ascontiguousarray(weight, dtype=np.float64)
    # compiled (controllers.classic.kernels), the same sweeps bit for bit
    relax_wavefront(
        field,
        np.ascontiguousarray(free),
        start,
        np.ascontiguousarray(seed, dtype=np.float64),
        cost,
        _MOVE_ARRAY,
    )
    return field


@dataclass(frozen=True)
class Plan:
    """A goal's wavefront and the path down it.

    Attributes
    ----------
    field : ndarray
        Distance to the goal [m] per cell (infinite in lethal and unreachable cells).
    origin : ndarray, shape (2,)
        Centre of cell (0, 0) [m].
    resolution : float
        Cell size [m].
    path : ndarray, shape (L, 2)
        The plan from the robot to the goal [m].
    """

    field: NDArray[np.float64]
    origin: NDArray[np.float64]
    resolution: float
    path: NDArray[np.float64]

    def goal_distance(
        self, points: NDArray[np.float64], fallback: float | NDArray[np.float64] | None = None
    ) -> NDArray[np.float64]:
        """Wavefront distance [m] of ``points`` (..., 2) to the goal, bilinear in the grid; where a
        corner of the point's cell is lethal or unreachable, ``fallback`` (broadcast with the
        points; None: the largest finite distance plus a cell and a half)."""
        rows, cols = self.field.shape
        at = (points - self.origin) / self.resolution
        i = np.clip(np.floor(at[..., 0]).astype(int), 0, rows - 2)
        j = np.clip(np.floor(at[..., 1]).astype(int), 0, cols - 2)
        fx = np.clip(at[..., 0] - i, 0.0, 1.0)
        fy = np.clip(at[..., 1] - j, 0.0, 1.0)
        f = self.field
        corners = (f[i, j], f[i + 1, j], f[i, j + 1], f[i + 1, j + 1])
        blocked = ~np.isfinite(corners[0] + corners[1] + corners[2] + corners[3])
        with np.errstate(invalid="ignore"):
            low = corners[0] * (1 - fx) + corners[1] * fx
            high = corners[2] * (1 - fx) + corners[3] * fx
            value = low * (1 - fy) + high * fy
        if fallback is None:
            finite = np.isfinite(f)
            fallback = (f[finite].max() if finite.any() else 0.0) + 1.5 * self.resolution
        return np.asarray(np.where(blocked, fallback, value))

    def path_distance(self, points: NDArray[np.float64]) -> NDArray[np.float64]:
        """Distance [m] of ``points`` (..., 2) to the path (a polyline)."""
        return polyline_distance(points, self.path)


def polyline_distance(points: NDArray[np.float64], line: NDArray[np.float64]) -> NDArray[np.float64]:
    """Distance [m] of ``points`` (..., 2) to the polyline ``line`` (L, 2)."""
    if len(line) < 2:
        return np.asarray(np.linalg.norm(points - line[0], axis=-1))
    # compiled (controllers.classic.kernels): the same arithmetic without the (..., L, 2) arrays
    flat = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 2)
    line = np.ascontiguousarray(line, dtype=np.float64)
    return polyline_distances(flat, line).reshape(points.shape[:-1])


@dataclass(frozen=True)
class Detour:
    """The straight plan bent round a team-mate or mover that stands on it, through a waypoint
    beside it on the right of the way to the goal (ours: ROS's global costmap would hold the other
    robot and navfn would plan round it; on the right, so that two robots meeting head-on both
    bend the same way).

    Attributes
    ----------
    path : ndarray, shape (3, 2)
        The robot, the waypoint, the goal [m].
    """

    path: NDArray[np.float64]

    def goal_distance(
        self, points: NDArray[np.float64], fallback: float | NDArray[np.float64] | None = None
    ) -> NDArray[np.float64]:
        """Distance [m] of ``points`` (..., 2) to the goal along the plan: through the waypoint
        until they are past it (``fallback`` is not needed: there is no lethal cell)."""
        start, waypoint, goal = self.path
        leg = waypoint - start
        past = ((points - start) @ leg) / max(float(leg @ leg), 1e-12) >= 1.0
        via = np.linalg.norm(points - waypoint, axis=-1) + float(np.linalg.norm(goal - waypoint))
        return np.asarray(np.where(past, np.linalg.norm(points - goal, axis=-1), via))

    def path_distance(self, points: NDArray[np.float64]) -> NDArray[np.float64]:
        """Distance [m] of ``points`` (..., 2) to the plan."""
        return polyline_distance(points, self.path)


class GlobalPlanner:
    """Wavefront plans over a grid of one episode's map (module docstring).

    Parameters
    ----------
    resolution : float
        Cell size [m].
    margin : float
        Clearance [m] beyond the robot's radius that a free cell keeps from every obstacle.
    inflation_radius, cost_scaling_factor : float
        The costmap's inflation (distance from the robot's centre [m], decay [1/m]).
    """

    def __init__(
        self, resolution: float, margin: float, inflation_radius: float, cost_scaling_factor: float
    ) -> None:
        self.resolution, self.margin = resolution, margin
        self.inflation_radius, self.cost_scaling_factor = inflation_radius, cost_scaling_factor
        self._obstacles = np.zeros((0, 3))
        self._reach = 0.0
        self._origin = np.zeros(2)
        self._free = np.ones((1, 1), dtype=bool)
        self._weight = np.ones((1, 1))
        self._fields: OrderedDict[tuple[int, int], tuple[NDArray[np.float64], NDArray[np.float64]]] = (
            OrderedDict()
        )

    def reset(self, scenario: Scenario) -> None:
        """Grid ``scenario``'s map."""
        self._obstacles = np.array(scenario.obstacles, dtype=np.float64).reshape(-1, 3)
        radius = float(np.max(scenario.robot_radius))
        self._reach = radius + self.margin
        points = np.vstack([self._obstacles[:, :2], scenario.starts[:, :2], scenario.targets[:, :2]])
        x0, x1, y0, y1 = scenario.workspace
        low = np.maximum(points.min(axis=0) - _BORDER, [x0, y0])
        high = np.minimum(points.max(axis=0) + _BORDER, [x1, y1])
        shape = np.maximum(np.ceil((high - low) / self.resolution).astype(int) + 1, 2)
        self._origin = low
        xs = low[0] + self.resolution * np.arange(shape[0])
        ys = low[1] + self.resolution * np.arange(shape[1])
        gx, gy = np.meshgrid(xs, ys, indexing="ij")
        surface = np.full(gx.shape, np.inf)  # distance from the cell's centre to the nearest surface
        for ox, oy, r in self._obstacles:
            surface = np.minimum(surface, np.hypot(gx - ox, gy - oy) - r)
        self._free = surface > self._reach
        inflated = surface <= self.inflation_radius
        value = np.where(
            inflated, 252.0 * np.exp(-self.cost_scaling_factor * np.maximum(surface - radius, 0.0)), 0.0
        )
        self._weight = (COST_NEUTRAL + COST_FACTOR * value) / COST_NEUTRAL
        self._fields = OrderedDict()

    def outdated(self, obstacles: NDArray[np.float64]) -> bool:
        """Whether ``obstacles`` (M, 3) differ from the gridded ones by more than half a cell
        (another count, or a centre or radius moved further): perceived obstacles drift by
        millimetres every period, and the grid is rebuilt only when that shows on it."""
        obstacles = np.asarray(obstacles, dtype=np.float64).reshape(-1, 3)
        if obstacles.shape != self._obstacles.shape:
            return True
        return bool(np.any(np.abs(obstacles - self._obstacles) > 0.5 * self.resolution))

    def in_sight(self, start: NDArray[np.float64], goal: NDArray[np.float64]) -> bool:
        """Whether the segment ``start``-``goal`` clears every obstacle by the radius and margin."""
        if not len(self._obstacles):
            return True
        along = goal - start
        centres = self._obstacles[:, :2]
        t = ((centres - start) @ along) / max(float(along @ along), 1e-12)
        nearest = start + np.clip(t, 0.0, 1.0)[:, None] * along
        gap = np.linalg.norm(centres - nearest, axis=1) - self._obstacles[:, 2]
        return bool((gap > self._reach).all())

    def plan(self, start: NDArray[np.float64], goal: NDArray[np.float64]) -> Plan | None:
        """The plan from ``start`` to ``goal`` (2,), or None in line of sight, off the grid, or
        where no free cell near ``start`` reaches the goal (straight-line distances then)."""
        if self.in_sight(start, goal):
            return None
        target, here = self._cell(goal), self._cell(start)
        if target is None or here is None:
            return None
        potential, distance = self._fields_of(target)
        path = self._descend(potential, here)
        if path is None:
            return None
        points = self._origin + self.resolution * np.asarray(path, dtype=np.float64)
        points = np.vstack([start, points[1:-1], goal]) if len(points) > 2 else np.vstack([start, goal])
        return Plan(self.resolution * distance, self._origin, self.resolution, points)

    def detour(
        self,
        start: NDArray[np.float64],
        goal: NDArray[np.float64],
        centres: NDArray[np.float64],
        reach: NDArray[np.float64],
    ) -> Detour | None:
        """The straight plan bent round the nearest of the discs at ``centres`` (B, 2) that it
        passes closer than their ``reach`` (B,) [m] to (:class:`Detour`); None when none stands
        on it, or when the bend would cross an obstacle."""
        along = goal - start
        length = float(np.hypot(*along))
        if length < 1e-9 or not len(centres):
            return None
        unit = along / length
        ahead = (centres - start) @ unit
        aside = (centres - start) @ np.array([-unit[1], unit[0]])  # > 0: on the left
        on_it = (ahead > 0.0) & (ahead < length) & (np.abs(aside) < reach)
        if not on_it.any():
            return None
        k = int(np.flatnonzero(on_it)[np.argmin(ahead[on_it])])
        right = np.array([unit[1], -unit[0]])
        waypoint = centres[k] + right * (reach[k] + self.resolution)
        if not (self.in_sight(start, waypoint) and self.in_sight(waypoint, goal)):
            return None
        return Detour(np.vstack([start, waypoint, goal]))

    def _cell(self, point: NDArray[np.float64]) -> tuple[int, int] | None:
        at = np.round((point - self._origin) / self.resolution).astype(int)
        rows, cols = self._free.shape
        if not (0 <= at[0] < rows and 0 <= at[1] < cols):
            return None
        return int(at[0]), int(at[1])

    def _fields_of(self, goal: tuple[int, int]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The goal's navfn potential and its grid distance (module docstring), kept."""
        if goal in self._fields:
            self._fields.move_to_end(goal)
            return self._fields[goal]
        free = self._free.copy()
        free[goal] = True  # a goal within the margin of an obstacle is still the goal
        seed = np.full(free.shape, np.inf)
        seed[goal] = 0.0
        potential = wavefront(free, seed, self._weight)
        distance = wavefront(free, seed)
        self._fields[goal] = (potential, distance)
        if len(self._fields) > _KEPT:
            self._fields.popitem(last=False)
        return potential, distance

    def _descend(self, field: NDArray[np.float64], here: tuple[int, int]) -> list[tuple[int, int]] | None:
        """Cells from ``here`` (or the best free cell within 5 cells of it) down to the goal."""
        rows, cols = field.shape
        if not np.isfinite(field[here]):
            i0, j0 = max(here[0] - 5, 0), max(here[1] - 5, 0)
            window = field[i0 : here[0] + 6, j0 : here[1] + 6]
            if not np.isfinite(window).any():
                return None
            di, dj = np.unravel_index(int(np.argmin(window)), window.shape)
            here = (i0 + int(di), j0 + int(dj))
        path = [here]
        while field[here] > 0 and len(path) <= field.size:
            best = here
            for dx, dy in _MOVES:
                i, j = here[0] + dx, here[1] + dy
                if 0 <= i < rows and 0 <= j < cols and field[i, j] < field[best]:
                    best = (i, j)
            if best == here:
                break
            here = best
            path.append(here)
        return path
