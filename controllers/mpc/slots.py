"""Slots of the NMPCs: the rows that are filled before every solve instead of written once.

Obstacle slots give each robot its K nearest obstacles (one problem then serves maps with any
obstacle count). Pair slots constrain only the robot pairs that can meet within the horizon,
nearest first; a pair keeps its slot while it stays within reach, unused slots are parked far
away (:data:`~controllers.mpc.config.PARKED`), and pairs beyond the slots are counted as dropped.
Mover slots hold the movers nearest to the team (or to one robot), predicted over the horizon.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from controllers.movers import predict_movers
from controllers.mpc.config import PARKED
from koopman_envs import nearest_by_clearance

__all__ = ["PairSlots", "closing_distance", "mover_slots", "nearest_obstacle_slots"]


def closing_distance(v_max: float, horizon: int, dt: float) -> float:
    """How far two robots can close in on each other over a horizon [m]: both at ``v_max`` for
    ``horizon`` periods of ``dt`` (the pair slots' and the distributed NMPC's neighbour reach)."""
    return 2 * v_max * horizon * dt


def nearest_obstacle_slots(positions: NDArray, obstacles: NDArray, k: int) -> NDArray[np.float64]:
    """Obstacle slot values: each robot's ``k`` nearest obstacles by surface clearance, robot-major,
    flat (slots beyond the obstacle count parked).

    Parameters
    ----------
    positions : ndarray, shape (N, 2)
    obstacles : ndarray, shape (M, 3)
        (x, y, r) per obstacle.
    k : int
        Slots per robot.
    """
    n = positions.shape[0]
    slots = np.tile([PARKED, PARKED, 0.0], (n, k, 1))
    if obstacles.size:
        nearest = nearest_by_clearance(positions, obstacles, k)
        count = nearest.shape[1]
        slots[:, :count] = obstacles[nearest]
    return slots.reshape(-1)


class PairSlots:
    """Which robot pair holds each of ``count`` pair slots, and their parameter values.

    Parameters
    ----------
    count : int
        Pair slots P.
    n_robots : int
        Team size N.
    radius : ndarray, shape (N,)
        Robot radii [m].
    reach : float
        Centre distance [m] within which a pair can meet over the horizon (before radii and margins).
    """

    def __init__(self, count: int, n_robots: int, radius: NDArray, reach: float) -> None:
        self.count, self.n_robots = count, n_robots
        self.radius = np.asarray(radius, dtype=float)
        self.reach = reach
        self.held: list[tuple[int, int] | None] = [None] * count

    def parked(self) -> NDArray[np.float64]:
        """The parameter values of ``count`` parked slots (select, offset, reach)."""
        n, p = self.n_robots, self.count
        return np.concatenate([np.zeros(n * p), np.full(2 * p, PARKED), np.zeros(p)])

    def assign(self, positions: NDArray, pair_margin: NDArray) -> tuple[NDArray[np.float64], int]:
        """Refill the slots from the robots' current positions.

        Returns
        -------
        values : ndarray
            The pair-slot blocks (``pair_select``, ``pair_offset``, ``pair_reach``) stacked.
        dropped : int
            Pairs within reach that found no slot.
        """
        p_slots, n = self.count, positions.shape[0]
        i_index, j_index = np.triu_indices(n, 1)  # the order of pair_margin
        distance = np.hypot(*(positions[i_index] - positions[j_index]).T)
        keep = self.radius[i_index] + self.radius[j_index] + pair_margin
        within = distance < self.reach + keep
        candidates = [
            (int(i_index[q]), int(j_index[q])) for q in np.flatnonzero(within)[np.argsort(distance[within])]
        ]
        active = set(candidates)
        # a pair keeps its slot while it stays within reach (its multipliers stay meaningful)
        slots = [pair if pair in active else None for pair in self.held]
        placed = {pair for pair in slots if pair is not None}
        free = [s for s, pair in enumerate(slots) if pair is None]
        waiting = [pair for pair in candidates if pair not in placed]
        for slot, waiting_pair in zip(free, waiting, strict=False):
            slots[slot] = waiting_pair
        dropped = len(waiting) - min(len(waiting), len(free))
        select = np.zeros((p_slots, n))
        offset = np.full((p_slots, 2), PARKED)
        reach = np.zeros(p_slots)
        for slot, held in enumerate(slots):
            if held is None:
                continue
            i, j = held
            select[slot, i], select[slot, j] = 1.0, -1.0
            offset[slot] = 0.0
            # position of pair (i, j), i < j, in the row-major upper triangle (pair_margin's order)
            reach[slot] = keep[i * n - i * (i + 1) // 2 + (j - i - 1)]
        self.held = slots
        return np.concatenate([select.ravel(), offset.ravel(), reach]), dropped


def mover_slots(
    points: NDArray[np.float64],
    movers: NDArray[np.float64],
    slots: int,
    horizon: int,
    dt: float,
    prediction: str,
    reach: float | NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The ``slots`` movers nearest to any of ``points`` (P, 2), predicted over the horizon;
    ``reach`` is the distance to keep from a mover's centre (its radius plus the margin), one for
    all or one per mover (C,).

    Returns
    -------
    positions : ndarray, shape (T, slots, 2)
        Each slot's predicted centre at stages 1..T, nearest mover first; unused slots parked
        (:data:`~controllers.mpc.config.PARKED`).
    reaches : ndarray, shape (slots,)
        ``reach`` (the mover's radius plus the margin to keep) per used slot, 0 when parked.
    """
    positions = np.full((horizon, slots, 2), PARKED)
    reaches = np.zeros(slots)
    if slots == 0 or movers.shape[0] == 0:
        return positions, reaches
    distance = np.hypot(*(points[:, None, :] - movers[None, :, :2]).transpose(2, 0, 1)).min(axis=0)
    nearest = np.argsort(distance, kind="stable")[:slots]
    positions[:, : nearest.size] = predict_movers(movers[nearest], horizon, dt, prediction)
    reaches[: nearest.size] = np.broadcast_to(np.asarray(reach, dtype=np.float64), (movers.shape[0],))[
        nearest
    ]
    return positions, reaches
