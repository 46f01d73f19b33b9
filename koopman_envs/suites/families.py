"""The layout families of the benchmark suites: seeded generators of obstacles, starts and targets.

A layout is drawn in a local frame where the team travels along +x, from a start end near
``x = -L/2`` to a target end near ``x = +L/2`` (``L`` uniform in :data:`TRAVEL`), then turned by a
uniform heading and shifted by up to 1 m, so that it lies inside
:data:`~koopman_envs.suites.measures.ARENA`. Every layout holds exactly ``n_obstacles`` circular
obstacles (the engine sizes its arrays once per environment, so one env serves every layout of a
suite): the family's walls, then open clutter up to that count.

=========== =====================================================================================
family      layout
=========== =====================================================================================
clutter     open clutter, as the random maps (:mod:`koopman_envs.sim.maps.generator`): isolated discs
            of radius 0.25-0.5 m with at least 0.6 m between them, across the travel
passages    a wall of touching discs across the travel (tilted up to 20 degrees) with one or two
            openings 0.7-1.2 m wide; for target reaching the targets are in reverse order, so that
            the robots' paths cross through the openings as in Map 2; clutter on both sides
rooms       a closed square room (side 4.4-5.2 m, walls of touching discs) with one or two doors
            0.8-1.3 m wide on random sides, around the targets or around the starts (the team
            enters or leaves it); clutter outside and in
=========== =====================================================================================

Walls are rows of discs 0.2 m apart at most (surface to surface), narrower than a robot, so a
robot passes only through the openings; every wall's openings are wider than the narrowest gap
the planner passes (:data:`~koopman_envs.suites.measures.GAP_PASSABLE`).

Teams: target reaching places the three robots in a line across the travel at each end
(1.2-1.8 m apart, 0.8-1.0 m inside a room), formation a wedge of
:func:`~koopman_envs.sim.formations.formation_shape` (``PARAMS.formation_spacing`` apart) at both
ends, its targets the leader's target plus the wedge's offsets. Starts and targets keep
:data:`CLEARANCE` from every obstacle. Which layouts are kept (every target reachable) is decided
by the suite builder (:mod:`koopman_envs.suites.build`).

Every draw comes from ``numpy.random.default_rng((seed, TASK_CODES[task]))``, in one fixed order:
travel, room end (rooms), team, the family's walls, clutter, turn, shift (before the clutter, the
team and walls are centred along the travel: no draw). Coordinates are rounded to the millimetre
(headings to 1e-4 rad), so that a layout is the same number for number on every machine.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from koopman_envs.checks import check_choice, check_int
from koopman_envs.params import PARAMS
from koopman_envs.sim.formations import formation_shape
from koopman_envs.sim.maps.map_spec import MapSpec
from koopman_envs.tasks.base import TASKS

__all__ = ["CLEARANCE", "FAMILIES", "TASK_CODES", "TRAVEL", "DrawnLayout", "draw_layout", "family_of_seed"]

#: the layout families, in the order seeds cycle through them (:func:`family_of_seed`)
FAMILIES = ("clutter", "passages", "rooms")
#: the task's entry in a layout's seed sequence (the same seed draws unrelated layouts per task)
TASK_CODES = {"target_reaching": 0, "formation": 1}
#: distance between the start and target ends [m] (ours: the paper's maps travel 5.5-6.5 m)
TRAVEL = (6.0, 8.0)
#: free space between any start or target robot disc and any obstacle [m] (the random maps')
CLEARANCE = 0.3
#: free space between two clutter discs, and between clutter and walls [m] (the random maps')
CLUTTER_GAP = 0.6
#: largest surface gap between neighbouring discs of a wall [m]: below a robot's diameter
WALL_GAP = 0.2
#: every disc lies within this distance of the layout's centre [m] (then inside the arena)
_REACH = 6.9
_CLUTTER_ATTEMPTS = 300


@dataclass(frozen=True, eq=False)
class DrawnLayout:
    """One drawn layout (before the builder's reachability check and measures).

    Attributes
    ----------
    family : str
        One of :data:`FAMILIES`.
    seed : int
        The layout seed.
    obstacles : ndarray, shape (M, 3)
        x [m], y [m], radius [m].
    starts, targets : ndarray, shape (N, 3)
        Start and target poses per robot (x [m], y [m], heading [rad]).
    """

    family: str
    seed: int
    obstacles: NDArray[np.float64]
    starts: NDArray[np.float64]
    targets: NDArray[np.float64]


def family_of_seed(seed: int) -> str:
    """The family a layout seed draws: seeds cycle through :data:`FAMILIES` (``seed % 3``), so
    that any run of consecutive seeds is balanced across families."""
    return FAMILIES[seed % len(FAMILIES)]


def _line(rng: np.random.Generator, n: int, x: float, spacing: tuple[float, float]) -> NDArray[np.float64]:
    """n positions across the travel at ``x``: uniform spacing, each jittered up to 0.3 m along x."""
    gap = rng.uniform(*spacing)
    out = np.zeros((n, 2))
    out[:, 0] = x + rng.uniform(-0.3, 0.3, size=n)
    out[:, 1] = (np.arange(n) - (n - 1) / 2.0) * gap
    return out


def _team(
    rng: np.random.Generator, task: str, family: str, n: int, travel: float, room_end: int
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Local start and target poses (N, 3); ``room_end`` 0: a room around the starts, 1: the
    targets, -1: no room."""
    starts, targets = np.zeros((n, 3)), np.zeros((n, 3))
    if TASKS[task].formation:
        local = formation_shape("wedge", n, PARAMS.formation_spacing)
        centre = local.mean(axis=0)
        starts[:, :2] = local - centre + [-travel / 2.0, 0.0]
        targets[:, :2] = local - centre + [travel / 2.0, 0.0]
        starts[:, 2] = rng.uniform(-math.pi / 8, math.pi / 8, size=n)
        return starts, targets
    tight, loose = (0.8, 1.0), (1.2, 1.8)
    starts[:, :2] = _line(rng, n, -travel / 2.0, tight if room_end == 0 else loose)
    targets[:, :2] = _line(rng, n, travel / 2.0, tight if room_end == 1 else loose)
    if family == "passages":
        order = np.arange(n)[::-1]  # the robots' paths cross, as Map 2's outer robots swap sides
    elif family == "clutter" and rng.uniform() < 0.5:
        order = np.arange(n)
    else:
        order = rng.permutation(n)
    targets = targets[order]
    starts[:, 2] = rng.uniform(-math.pi / 4, math.pi / 4, size=n)
    return starts, targets


def _fill(a: float, b: float, radius: float, closed: bool) -> NDArray[np.float64]:
    """Centre positions from a to b (b included when ``closed``) evenly, neighbours at most
    ``2 radius + WALL_GAP`` apart."""
    count = max(1, math.ceil((b - a) / (2.0 * radius + WALL_GAP)))
    t = a + (b - a) * np.arange(count + 1) / count
    return t if closed else t[:-1]


def _wall(
    p: NDArray[np.float64],
    q: NDArray[np.float64],
    radius: float,
    openings: list[tuple[float, float]],
    closed: bool,
) -> list[NDArray[np.float64]]:
    """Discs along p -> q (centres from p to q) leaving the ``openings`` (surface intervals
    along the wall, in metres from p) free; ``closed``: a disc on q too."""
    length = float(np.hypot(*(q - p)))
    unit = (q - p) / length
    stops = [0.0]
    for low, high in openings:
        stops += [low - radius, high + radius]
    stops.append(length)
    discs = []
    for k in range(0, len(stops), 2):
        a, b = stops[k], stops[k + 1]
        last = closed or k + 2 < len(stops)  # the centre at an opening's post always stays
        for t in _fill(a, b, radius, last):
            discs.append(np.array([*(p + t * unit), radius]))
    return discs


def _passage_walls(rng: np.random.Generator) -> list[NDArray[np.float64]]:
    """A tilted wall across the travel with one or two openings."""
    x, radius, half = rng.uniform(-1.0, 1.0), rng.uniform(0.3, 0.45), rng.uniform(3.5, 4.5)
    tilt = rng.uniform(-math.radians(20), math.radians(20))
    n_open = int(rng.integers(1, 3))
    widths = rng.uniform(0.7, 1.2, size=n_open)
    if n_open == 1:
        centres = np.array([rng.uniform(-1.5, 1.5)])
    else:
        centres = np.array([-rng.uniform(0.9, 2.2), rng.uniform(0.9, 2.2)])
    direction = np.array([-math.sin(tilt), math.cos(tilt)])
    p = np.array([x, 0.0]) - half * direction
    openings = [(half + c - w / 2.0, half + c + w / 2.0) for c, w in zip(centres, widths)]
    return _wall(p, p + 2.0 * half * direction, radius, openings, closed=True)


def _room_walls(rng: np.random.Generator, centre: NDArray[np.float64]) -> list[NDArray[np.float64]]:
    """A closed square room around ``centre`` with one or two doors on random sides."""
    side, radius = rng.uniform(4.4, 5.2), rng.uniform(0.45, 0.55)
    centre = centre + rng.uniform(-0.2, 0.2, size=2)
    n_doors = int(rng.integers(1, 3))
    sides = rng.choice(4, size=n_doors, replace=False)
    widths = rng.uniform(0.8, 1.3, size=n_doors)
    room = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]]) * side / 2.0 + centre
    discs = []
    for k in range(4):
        openings = []
        if k in sides:
            width = float(widths[list(sides).index(k)])
            slack = side / 2.0 - width / 2.0 - 2.0 * radius - WALL_GAP
            middle = side / 2.0 + rng.uniform(-slack, slack)
            openings.append((middle - width / 2.0, middle + width / 2.0))
        discs += _wall(room[k], room[(k + 1) % 4], radius, openings, closed=False)
    return discs


def _clear_of(disc: NDArray[np.float64], points: NDArray[np.float64], space: float) -> bool:
    """True when ``disc`` keeps ``space`` from robot discs at ``points`` (K, 2)."""
    distance = np.hypot(points[:, 0] - disc[0], points[:, 1] - disc[1])
    return bool(np.all(distance - disc[2] - PARAMS.robot_radius >= space))


def _x_middle(points: NDArray[np.float64], discs: list[NDArray[np.float64]]) -> float:
    """The middle of the x extent of the robot discs at ``points`` and of ``discs``."""
    low = float(points[:, 0].min()) - PARAMS.robot_radius
    high = float(points[:, 0].max()) + PARAMS.robot_radius
    for disc in discs:
        low, high = min(low, disc[0] - disc[2]), max(high, disc[0] + disc[2])
    return (low + high) / 2.0


def _clutter(
    rng: np.random.Generator, count: int, placed: list[NDArray[np.float64]], keep: NDArray[np.float64]
) -> list[NDArray[np.float64]] | None:
    """``count`` isolated discs across the travel (from 1.5 m before the team's first robot to
    1.5 m past its last), or None when one does not fit."""
    placed = list(placed)
    low, high = float(keep[:, 0].min()) - 1.5, float(keep[:, 0].max()) + 1.5
    for _ in range(count):
        for _attempt in range(_CLUTTER_ATTEMPTS):
            x = rng.uniform(low, high)
            disc = np.array([x, rng.uniform(-4.5, 4.5), rng.uniform(0.25, 0.5)])
            if math.hypot(disc[0], disc[1]) + disc[2] > _REACH or not _clear_of(disc, keep, CLEARANCE):
                continue
            if all(math.hypot(*(disc[:2] - o[:2])) - disc[2] - o[2] >= CLUTTER_GAP for o in placed):
                placed.append(disc)
                break
        else:
            return None
    return placed


def _turned(poses: NDArray[np.float64], heading: float, shift: NDArray[np.float64]) -> NDArray[np.float64]:
    """Poses (or discs: the third column kept) turned by ``heading`` about the origin, then shifted."""
    c, s = math.cos(heading), math.sin(heading)
    out = np.array(poses, dtype=np.float64)
    out[:, 0] = c * poses[:, 0] - s * poses[:, 1] + shift[0]
    out[:, 1] = s * poses[:, 0] + c * poses[:, 1] + shift[1]
    return out


def draw_layout(
    task: str, seed: int, n_obstacles: int = 24, n_robots: int = PARAMS.n_robots
) -> DrawnLayout | None:
    """Draw the layout of ``seed`` for ``task`` (its family is :func:`family_of_seed`).

    Parameters
    ----------
    task : str
        ``"target_reaching"`` or ``"formation"``.
    seed : int
        The layout seed, >= 0.
    n_obstacles : int
        Obstacles of every layout (walls plus clutter).
    n_robots : int
        Team size.

    Returns
    -------
    DrawnLayout or None
        None when this seed's draw does not fit (walls over ``n_obstacles``, clutter that finds
        no room, a start or target too close to a wall); the suites skip to the next seed.
    """
    check_choice("task", task, list(TASK_CODES))
    check_int("seed", seed, 0)
    family = family_of_seed(seed)
    rng = np.random.default_rng((seed, TASK_CODES[task]))
    travel = rng.uniform(*TRAVEL)
    room_end = int(rng.integers(0, 2)) if family == "rooms" else -1
    starts, targets = _team(rng, task, family, n_robots, travel, room_end)
    keep = np.vstack([starts[:, :2], targets[:, :2]])
    walls: list[NDArray[np.float64]] = []
    if family == "passages":
        walls = _passage_walls(rng)
    elif family == "rooms":
        walls = _room_walls(rng, (starts if room_end == 0 else targets)[:, :2].mean(axis=0))
    if len(walls) > n_obstacles or not all(_clear_of(w, keep, CLEARANCE) for w in walls):
        return None
    # centred along the travel (a room sticks out at one end), then every disc within reach
    middle = _x_middle(keep, walls)
    for array in (starts, targets, keep, *walls):
        array[0 if array.ndim == 1 else (slice(None), 0)] -= middle
    if any(math.hypot(w[0], w[1]) + w[2] > _REACH for w in walls):
        return None
    discs = _clutter(rng, n_obstacles - len(walls), walls, keep)
    if discs is None:
        return None
    heading, shift = rng.uniform(-math.pi, math.pi), rng.uniform(-1.0, 1.0, size=2)
    obstacles = np.round(_turned(np.array(discs), heading, shift), 3)
    poses = []
    for local in (starts, targets):
        pose = _turned(local, heading, shift)
        pose[:, :2] = np.round(pose[:, :2], 3)
        pose[:, 2] = np.round((local[:, 2] + heading + math.pi) % (2.0 * math.pi) - math.pi, 4)
        poses.append(pose)
    spec = MapSpec(f"seed {seed}", obstacles, poses[0], poses[1])
    try:
        spec.validate(n_robots)
    except ValueError:  # rounding never moves a pose 1 mm into trouble, but a kept layout is checked
        return None
    return DrawnLayout(family, seed, spec.obstacles, spec.starts, spec.targets)
