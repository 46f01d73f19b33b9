"""Compiled motion of the ``"constant"`` and ``"waypoints"`` movers (and the crowd's goals).

Numba loops over the environments of a batch, as the robots' physics: straight lines mirrored
at the arena's edges and the static obstacles, and waypoint walkers that draw their goals from a
per-environment pool of uniforms (a fixed number per draw, so that the pool's use does not
depend on the outcome and a sub-environment of a batch draws as a lone one).
:class:`koopman_envs.sim.movers.field.MoverField` calls them.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

__all__ = [
    "DRAW_SIZE",
    "WALKER_MODEL",
    "WAYPOINT_ATTEMPTS",
    "first_goals",
    "follow_waypoints",
    "move_constant",
    "walker_model",
]

#: attempts at a waypoint whose straight way is clear, per draw (then the mover waits a period)
WAYPOINT_ATTEMPTS = 16
#: uniforms one waypoint draw takes at most: two per attempt, then the leg's speed and pause
DRAW_SIZE = 2 * WAYPOINT_ATTEMPTS + 2
#: the fixed terms of a batch's mover motion, one record made with the
#: :class:`~koopman_envs.sim.movers.field.MoverField` (numba reads a record's fields by name and
#: types a record argument as fast as a plain array; five scalars were five arguments)
WALKER_MODEL = np.dtype(
    [
        ("radius", np.float64),  # every mover's radius [m]
        ("speed", np.float64),  # the setting's speed [m/s]: a leg's is half of it to all of it
        ("pause_periods", np.int64),  # the longest pause at a waypoint [periods]
        ("dt", np.float64),  # the control period [s]
        ("move", np.bool_),  # step the positions ("waypoints"); off for the crowd (ORCA moves it)
    ]
)
#: the waypoint walkers as :func:`follow_waypoints` takes them: ``position``, ``velocity``,
#: ``goal`` (K, C, 2), ``leg_speed`` (K, C) and ``waiting`` (K, C) int64 (a plain tuple: numba
#: types one at a call almost as fast as loose arrays, a named tuple field by field in Python)
Walkers = tuple[
    NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]
]


def walker_model(radius: float, speed: float, pause_periods: int, dt: float, move: bool) -> NDArray[np.void]:
    """The :data:`WALKER_MODEL` record (shape (1,)) of movers of ``radius`` [m] and ``speed``
    [m/s] pausing up to ``pause_periods`` at a waypoint, stepped every ``dt`` [s]; ``move``:
    the walkers move themselves (not a crowd, whose positions ORCA steps)."""
    return np.array([(radius, speed, pause_periods, dt, move)], dtype=WALKER_MODEL)


@njit(cache=True)
def _reflect_off_obstacles(
    x: float,
    y: float,
    vx: float,
    vy: float,
    radius: float,
    obstacles: NDArray[np.float64],
    k: int,
) -> tuple[float, float, float, float]:  # pragma: no cover - compiled
    """A disc that has entered a static obstacle of environment ``k`` (row k of the (K, 3, M)
    obstacle sets, rows x, y, radius; a row slice per call would cost more than the motion):
    put back on its surface, the velocity mirrored about the surface normal (only when moving
    inwards)."""
    for m in range(obstacles.shape[2]):
        dx, dy = x - obstacles[k, 0, m], y - obstacles[k, 1, m]
        reach = radius + obstacles[k, 2, m]
        d2 = dx * dx + dy * dy
        if d2 < reach * reach and d2 > 0.0:
            d = math.sqrt(d2)
            nx, ny = dx / d, dy / d
            inward = vx * nx + vy * ny
            if inward < 0.0:
                vx -= 2.0 * inward * nx
                vy -= 2.0 * inward * ny
            x, y = obstacles[k, 0, m] + nx * reach, obstacles[k, 1, m] + ny * reach
    return x, y, vx, vy


@njit(cache=True)
def move_constant(
    position: NDArray[np.float64],
    velocity: NDArray[np.float64],
    rows: NDArray[np.int64],
    model: NDArray[np.void],
    arena: NDArray[np.float64],
    obstacles: NDArray[np.float64],
) -> None:  # pragma: no cover - compiled
    """Straight lines at constant velocity: the movers' ``position`` and ``velocity`` (K, C, 2)
    of the environments ``rows`` one period on, mirrored at the ``arena``'s edges (K, 4) and the
    ``obstacles`` (K, 3, M: rows x, y, radius); ``model`` (:data:`WALKER_MODEL`) gives the
    radius and the period."""
    spec = model[0]
    radius, dt = spec.radius, spec.dt
    for k in rows:
        lo_x, hi_x = arena[k, 0] + radius, arena[k, 1] - radius
        lo_y, hi_y = arena[k, 2] + radius, arena[k, 3] - radius
        for c in range(position.shape[1]):
            vx, vy = velocity[k, c, 0], velocity[k, c, 1]
            x = position[k, c, 0] + vx * dt
            y = position[k, c, 1] + vy * dt
            if x < lo_x:
                x, vx = 2.0 * lo_x - x, abs(vx)
            elif x > hi_x:
                x, vx = 2.0 * hi_x - x, -abs(vx)
            if y < lo_y:
                y, vy = 2.0 * lo_y - y, abs(vy)
            elif y > hi_y:
                y, vy = 2.0 * hi_y - y, -abs(vy)
            x, y, vx, vy = _reflect_off_obstacles(x, y, vx, vy, radius, obstacles, k)
            position[k, c, 0], position[k, c, 1] = x, y
            velocity[k, c, 0], velocity[k, c, 1] = vx, vy


@njit(cache=True)
def _way_is_clear(
    x0: float,
    y0: float,
    x1: float,
    y1: float,
    radius: float,
    obstacles: NDArray[np.float64],
) -> bool:  # pragma: no cover - compiled
    """True when a disc of ``radius`` moving straight from (x0, y0) to (x1, y1) meets no
    obstacle of ``obstacles`` (3, M: rows x, y, radius)."""
    sx, sy = x1 - x0, y1 - y0
    length2 = sx * sx + sy * sy
    for m in range(obstacles.shape[1]):
        px, py = obstacles[0, m] - x0, obstacles[1, m] - y0
        t = 0.0 if length2 == 0.0 else min(max((px * sx + py * sy) / length2, 0.0), 1.0)
        dx, dy = px - t * sx, py - t * sy
        reach = radius + obstacles[2, m] + 0.05
        if dx * dx + dy * dy < reach * reach:
            return False
    return True


@njit(cache=True)
def _draw_goal(
    x: float,
    y: float,
    pool: NDArray[np.float64],
    cursor: NDArray[np.int64],
    arena: NDArray[np.float64],
    obstacles: NDArray[np.float64],
    radius: float,
    speed: float,
) -> tuple[float, float, float, bool]:  # pragma: no cover - compiled
    """A waypoint in the arena with a clear straight way from (x, y), and the leg's speed; always
    takes :data:`DRAW_SIZE` uniforms (so the pool's use does not depend on the outcome).
    Returns (goal x, goal y, speed, found)."""
    at = cursor[0]
    cursor[0] = at + DRAW_SIZE
    lo_x, span_x = arena[0] + radius, arena[1] - arena[0] - 2.0 * radius
    lo_y, span_y = arena[2] + radius, arena[3] - arena[2] - 2.0 * radius
    leg_speed = speed * (0.5 + 0.5 * pool[at + DRAW_SIZE - 2])
    for attempt in range(WAYPOINT_ATTEMPTS):
        gx = lo_x + span_x * pool[at + 2 * attempt]
        gy = lo_y + span_y * pool[at + 2 * attempt + 1]
        if _way_is_clear(x, y, gx, gy, radius, obstacles):
            return gx, gy, leg_speed, True
    return x, y, leg_speed, False


@njit(cache=True)
def first_goals(
    position: NDArray[np.float64],
    goal: NDArray[np.float64],
    leg_speed: NDArray[np.float64],
    pool: NDArray[np.float64],
    cursor: NDArray[np.int64],
    arena: NDArray[np.float64],
    obstacles: NDArray[np.float64],
    model: NDArray[np.void],
) -> None:  # pragma: no cover - compiled
    """The first waypoint (``goal`` (C, 2), ``leg_speed`` (C,)) of every mover of one
    environment from its ``position`` (C, 2), drawn from its ``pool`` at its
    ``cursor`` (1,) in its ``arena`` (4,) among its ``obstacles`` (3, M: rows x, y, radius), for
    the movers of ``model`` (:data:`WALKER_MODEL`)."""
    spec = model[0]
    radius, speed = spec.radius, spec.speed
    for c in range(position.shape[0]):
        gx, gy, s, _ = _draw_goal(
            position[c, 0],
            position[c, 1],
            pool,
            cursor,
            arena,
            obstacles,
            radius,
            speed,
        )
        goal[c, 0], goal[c, 1], leg_speed[c] = gx, gy, s


@njit(cache=True)
def follow_waypoints(
    walkers: Walkers,
    draws: tuple[NDArray[np.float64], NDArray[np.int64]],
    rows: NDArray[np.int64],
    model: NDArray[np.void],
    arena: NDArray[np.float64],
    obstacles: NDArray[np.float64],
) -> None:  # pragma: no cover - compiled
    """One period of the waypoint walkers of the environments ``rows``: pause, arrive, draw the
    next waypoint, or walk on.

    ``walkers`` (:data:`Walkers`) is the walkers' ``position``, ``velocity``, ``goal`` (K, C, 2),
    ``leg_speed`` and ``waiting`` (K, C); ``draws`` their uniforms, ``pool`` (K, P) and
    ``cursor`` (K,); ``arena`` (K, 4) and ``obstacles`` (K, 3, M) where they walk. ``model``
    (:data:`WALKER_MODEL`) gives
    the radius, speed, pause and period, and ``move``: step the positions ("waypoints");
    otherwise only set the velocities, which the crowd uses as the preferred velocities of ORCA
    (arrival then within one radius).
    """
    position, velocity, goal, leg_speed, waiting = walkers
    pool, cursor = draws
    spec = model[0]
    radius, speed, pause_periods, dt, move = spec.radius, spec.speed, spec.pause_periods, spec.dt, spec.move
    for k in rows:
        own_cursor = cursor[k : k + 1]
        for c in range(position.shape[1]):
            x, y = position[k, c, 0], position[k, c, 1]
            if waiting[k, c] > 0:
                waiting[k, c] -= 1
                velocity[k, c, 0], velocity[k, c, 1] = 0.0, 0.0
                if waiting[k, c] == 0:
                    gx, gy, s, found = _draw_goal(
                        x, y, pool[k], own_cursor, arena[k], obstacles[k], radius, speed,
                    )  # fmt: skip
                    goal[k, c, 0], goal[k, c, 1], leg_speed[k, c] = gx, gy, s
                    if not found:
                        waiting[k, c] = 1  # no clear way from here now: try again next period
                continue
            dx, dy = goal[k, c, 0] - x, goal[k, c, 1] - y
            distance = math.sqrt(dx * dx + dy * dy)
            stride = leg_speed[k, c] * dt
            if distance <= (stride if move else max(stride, radius)):
                if move:
                    position[k, c, 0], position[k, c, 1] = goal[k, c, 0], goal[k, c, 1]
                velocity[k, c, 0], velocity[k, c, 1] = 0.0, 0.0
                at = own_cursor[0]
                own_cursor[0] = at + 1
                waiting[k, c] = 1 + int(pool[k, at] * pause_periods)
                continue
            vx, vy = leg_speed[k, c] * dx / distance, leg_speed[k, c] * dy / distance
            velocity[k, c, 0], velocity[k, c, 1] = vx, vy
            if move:
                position[k, c, 0], position[k, c, 1] = x + vx * dt, y + vy * dt
