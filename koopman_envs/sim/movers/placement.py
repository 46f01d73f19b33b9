"""Where the movers may go and where they start: the arena and the placement at reset.

The arena is the bounding box of a map's starts, targets and obstacles grown by
:data:`ARENA_MARGIN` and clipped to the workspace (a mover anywhere in the 20 m workspace would
seldom meet a team working in a 6 m patch of it). At reset every mover is drawn uniformly in it,
clear of the static obstacles, of the other movers and of every start and target
(:func:`place_movers`). Both run at every reset of every environment, so both are compiled.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

__all__ = [
    "ARENA_MARGIN",
    "PLACEMENT_ATTEMPTS",
    "arena_into",
    "mover_arena",
    "PlacementError",
    "place_movers",
    "place_movers_batch",
]

#: how far the movers' arena reaches beyond the map's starts, targets and obstacles [m] (ours)
ARENA_MARGIN = 1.5
#: placement attempts per mover at reset
PLACEMENT_ATTEMPTS = 2000
#: gap kept between a mover and a static obstacle or another mover at placement [m]
_PLACEMENT_GAP = 0.1


class PlacementError(ValueError):
    """No free place for a mover: a ``ValueError`` whose :attr:`row` is the environment's
    position in the batch of :func:`place_movers_batch`."""

    def __init__(self, row: int, message: str) -> None:
        super().__init__(message)
        self.row = row


def mover_arena(
    starts: NDArray[np.float64],
    targets: NDArray[np.float64],
    obstacles: NDArray[np.float64],
    workspace: tuple[float, float, float, float],
) -> NDArray[np.float64]:
    """(x_min, x_max, y_min, y_max) [m] of the region the movers keep to (module docstring)."""
    arena = np.empty(4)
    arena_into(
        np.array(starts, dtype=np.float64),
        np.array(targets, dtype=np.float64),
        np.asarray(obstacles, dtype=np.float64).reshape(-1, 3),
        np.asarray(workspace, dtype=np.float64),
        arena,
    )
    return arena


@njit(cache=True)
def arena_into(
    starts: NDArray[np.float64],
    targets: NDArray[np.float64],
    obstacles: NDArray[np.float64],
    workspace: NDArray[np.float64],
    out: NDArray[np.float64],
) -> None:  # pragma: no cover - compiled (called at every reset: numpy's small calls cost more)
    x_min, y_min, x_max, y_max = np.inf, np.inf, -np.inf, -np.inf
    for points in (starts, targets):
        for j in range(points.shape[0]):
            x_min, x_max = min(x_min, points[j, 0]), max(x_max, points[j, 0])
            y_min, y_max = min(y_min, points[j, 1]), max(y_max, points[j, 1])
    for j in range(obstacles.shape[0]):
        r = obstacles[j, 2]
        x_min, x_max = min(x_min, obstacles[j, 0] - r), max(x_max, obstacles[j, 0] + r)
        y_min, y_max = min(y_min, obstacles[j, 1] - r), max(y_max, obstacles[j, 1] + r)
    out[0] = max(x_min - ARENA_MARGIN, workspace[0])
    out[1] = min(x_max + ARENA_MARGIN, workspace[1])
    out[2] = max(y_min - ARENA_MARGIN, workspace[2])
    out[3] = min(y_max + ARENA_MARGIN, workspace[3])


def place_movers(
    rng: np.random.Generator,
    count: int,
    radius: float,
    arena: NDArray[np.float64],
    obstacles: NDArray[np.float64],
    keep_clear: tuple[NDArray[np.float64], NDArray[np.float64]],
    clearance: float,
) -> NDArray[np.float64]:
    """``count`` mover centres (C, 2) drawn uniformly in ``arena``, clear of the obstacles, of each
    other and by ``clearance`` + ``radius`` of every point of the two ``keep_clear`` arrays
    (rows x, y, ...: the starts and the targets): :func:`place_movers_batch` for one
    environment.

    Raises
    ------
    ValueError
        A mover is wider than the arena, or finds no free place in :data:`PLACEMENT_ATTEMPTS`
        draws.
    """
    starts, targets = (np.array(points, dtype=np.float64)[None] for points in keep_clear)
    obstacles = np.asarray(obstacles, dtype=np.float64).reshape(1, -1, 3)
    arenas = np.asarray(arena, dtype=np.float64).reshape(1, 4)
    placed: NDArray[np.float64] = place_movers_batch(
        [rng], count, radius, arenas, obstacles, starts, targets, clearance
    )[0]
    return placed


def place_movers_batch(
    rngs: list[np.random.Generator],
    count: int,
    radius: float,
    arenas: NDArray[np.float64],
    obstacles: NDArray[np.float64],
    starts: NDArray[np.float64],
    targets: NDArray[np.float64],
    clearance: float,
) -> NDArray[np.float64]:
    """The movers of B environments (B, C, 2), environment b's from ``rngs[b]`` in its
    ``arenas[b]`` (B, 4), clear of its ``obstacles[b]`` (B, M, 3), of each other and by
    ``clearance`` + ``radius`` of its ``starts[b]`` and ``targets[b]`` (B, N, 3).

    Candidates come in blocks of uniforms from each generator and a compiled loop takes the
    first free ones in order: the first block of every environment in one call, the rare
    further blocks one environment at a time. Each environment draws and places exactly as it
    would alone (a vector env resets the environments that end in the same step together).

    Raises
    ------
    ValueError
        A mover is wider than an arena; :class:`PlacementError` (a ``ValueError``) when one finds
        no free place in :data:`PLACEMENT_ATTEMPTS` draws (naming the arena).
    """
    for arena in arenas:
        if not (arena[1] - arena[0] > 2.0 * radius and arena[3] - arena[2] > 2.0 * radius):
            # the candidates would lie outside the arena (or be NaN for a huge radius: every test
            # against a NaN passes, so they were "free")
            raise ValueError(
                f"movers: a mover of radius {radius!r} m (movers.radius) does not fit the arena "
                f"{np.round(arena, 2).tolist()}; use smaller movers"
            )
    batch = len(rngs)
    placed = np.zeros((batch, count, 2))
    done = np.zeros((batch, 2), dtype=np.int64)  # movers placed, failed attempts at the current one
    block = 4 * count + 16
    first = np.stack([rng.random((block, 2)) for rng in rngs]) if batch else np.zeros((0, block, 2))
    _place_batch(first, arenas, radius, obstacles, starts, targets, clearance, placed, done)
    for b, rng in enumerate(rngs):
        while True:
            if done[b, 1] >= PLACEMENT_ATTEMPTS:
                raise PlacementError(
                    b,
                    f"movers: no free place for mover {done[b, 0] + 1} of {count} (radius {radius} m) in "
                    f"the arena {np.round(arenas[b], 2).tolist()} clear of the obstacles, the other movers "
                    "and the starts and targets; use fewer or smaller movers",
                )
            if done[b, 0] >= count:
                break
            one = slice(b, b + 1)  # the kernel on a batch of one: this environment's rows
            _place_batch(
                rng.random((1, block, 2)), arenas[one], radius, obstacles[one], starts[one], targets[one],
                clearance, placed[one], done[one],
            )  # fmt: skip
    return placed


@njit(cache=True)
def _place_batch(
    candidates: NDArray[np.float64],
    arenas: NDArray[np.float64],
    radius: float,
    obstacles: NDArray[np.float64],
    starts: NDArray[np.float64],
    targets: NDArray[np.float64],
    clearance: float,
    placed: NDArray[np.float64],
    done: NDArray[np.int64],
) -> None:  # pragma: no cover - compiled
    """For every environment k of the batch, try its ``candidates[k]`` (T, 2) of uniforms in
    order for its movers from ``done[k, 0]`` on (see :func:`place_movers_batch`), each in its
    own rows of the other arrays; an environment stops at :data:`PLACEMENT_ATTEMPTS` failures
    of one mover. A further block of one environment is a batch of one."""
    for k in range(candidates.shape[0]):
        arena, mine, done_k = arenas[k], placed[k], done[k]
        lo_x, span_x = arena[0] + radius, arena[1] - arena[0] - 2.0 * radius
        lo_y, span_y = arena[2] + radius, arena[3] - arena[2] - 2.0 * radius
        for b in range(candidates.shape[1]):
            c = done_k[0]
            if c >= mine.shape[0] or done_k[1] >= PLACEMENT_ATTEMPTS:
                break
            x, y = lo_x + span_x * candidates[k, b, 0], lo_y + span_y * candidates[k, b, 1]
            free = True
            for m in range(obstacles.shape[1]):
                reach = obstacles[k, m, 2] + radius + _PLACEMENT_GAP
                if (obstacles[k, m, 0] - x) ** 2 + (obstacles[k, m, 1] - y) ** 2 < reach * reach:
                    free = False
                    break
            reach = clearance + radius
            for points in (starts[k], targets[k]):
                for m in range(points.shape[0]):
                    if free and (points[m, 0] - x) ** 2 + (points[m, 1] - y) ** 2 < reach * reach:
                        free = False
            if free:
                reach = 2.0 * radius + _PLACEMENT_GAP
                for m in range(c):
                    if (mine[m, 0] - x) ** 2 + (mine[m, 1] - y) ** 2 < reach * reach:
                        free = False
                        break
            if free:
                mine[c, 0], mine[c, 1] = x, y
                done_k[0], done_k[1] = c + 1, 0
            else:
                done_k[1] += 1
