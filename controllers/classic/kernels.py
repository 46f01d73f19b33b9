"""Compiled loops of ``dwa`` (numba): the two places where numpy's temporaries cost more than the
arithmetic (``bench/policy_speed.py``: 5 ms per three-robot decision, 3 of them here).

Both compute exactly what the numpy expressions they replace computed, operation for operation
(no fast-math, so no reassociation or fused multiply-add), and so return the same bits:

- :func:`closest_approach`: each trajectory's closest approach to every disc,
  ``sqrt(min_k (dx^2 + dy^2))``, without the (N, S, K, O) arrays;
- :func:`unicycle_arcs`: every velocity sample's arc at the simulated times (the exact unicycle,
  ``np.sinc``'s chord factor computed as numpy computes it), without the (N, S, K) temporaries;
- :func:`relax_wavefront`: the relaxation sweeps of :func:`controllers.classic.plan.wavefront`
  (each move reads the field as it was before that move, as ``np.minimum`` on overlapping views
  does), in place, without a copy per move.

The wavefront is still the relaxation, not a Dijkstra search: its sweeps let a value pass through
one lethal cell between the resets at the end of a sweep, and a search over free cells alone
would give other plans (and other episodes) than the published ones.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

__all__ = ["closest_approach", "polyline_distances", "relax_wavefront", "unicycle_arcs"]


@njit(cache=True)
def unicycle_arcs(
    pose: NDArray[np.float64], samples: NDArray[np.float64], times: NDArray[np.float64]
) -> NDArray[np.float64]:
    """(N, S, K, 3) poses along each sample's arc: ``pose`` (N, 3) the start, ``samples``
    (N, S, 2) the (v, omega) pairs, ``times`` (K,) the simulated times. With ``half = 0.5 omega
    t`` the chord is ``v t sinc(half)`` (``sin(half) / half``, through ``np.sinc``'s ``pi (half /
    pi)``, 1e-20 in place of 0), x and y advance by the chord along ``theta0 + half`` and theta
    is ``theta0 + omega t``."""
    n, s = samples.shape[0], samples.shape[1]
    k = times.shape[0]
    out = np.empty((n, s, k, 3))
    for i in range(n):
        x0, y0, theta0 = pose[i, 0], pose[i, 1], pose[i, 2]
        for j in range(s):
            v, w = samples[i, j, 0], samples[i, j, 1]
            for q in range(k):
                t = times[q]
                half = 0.5 * w * t
                ratio = half / np.pi
                y = np.pi * (ratio if ratio != 0.0 else 1.0e-20)
                chord = v * t * (math.sin(y) / y)
                out[i, j, q, 0] = x0 + chord * math.cos(theta0 + half)
                out[i, j, q, 1] = y0 + chord * math.sin(theta0 + half)
                out[i, j, q, 2] = theta0 + w * t
    return out


@njit(cache=True)
def closest_approach(path: NDArray[np.float64], centres: NDArray[np.float64]) -> NDArray[np.float64]:
    """(N, S, O) ``sqrt(min over k of |path[n, s, k, :2] - centres[n, k, o]|^2)``: ``path``
    (N, S, K, >=2), ``centres`` (N, K, O, 2) the discs' centres at the same times."""
    n, s, k, _ = path.shape
    o = centres.shape[2]
    out = np.empty((n, s, o))
    for i in range(n):
        for j in range(s):
            for m in range(o):
                best = np.inf
                for t in range(k):
                    dx = path[i, j, t, 0] - centres[i, t, m, 0]
                    dy = path[i, j, t, 1] - centres[i, t, m, 1]
                    d = dx * dx + dy * dy
                    if d < best or math.isnan(d):  # np.min propagates a NaN
                        best = d
                        if math.isnan(d):
                            break
                out[i, j, m] = math.sqrt(best)
    return out


@njit(cache=True)
def relax_wavefront(
    field: NDArray[np.float64],
    free: NDArray[np.bool_],
    start: NDArray[np.bool_],
    seed: NDArray[np.float64],
    cost: NDArray[np.float64],
    moves: NDArray[np.int64],
) -> None:
    """The relaxation sweeps of :func:`controllers.classic.plan.wavefront` on ``field`` (in
    place) until nothing changes: per sweep, for each move (dx, dy) of ``moves`` in order, every
    cell ``c`` takes ``min(field[c], before[c - (dx, dy)] + |(dx, dy)| cost[c])`` with ``before``
    the field before that move; then lethal cells are infinite and seed cells keep their seed."""
    rows, cols = field.shape
    sweep_start = np.empty_like(field)
    while True:
        sweep_start[:, :] = field
        for move in range(moves.shape[0]):
            dx, dy = moves[move, 0], moves[move, 1]
            step = math.hypot(dx, dy)
            # in place, visiting the cells against the move's direction: the cell read,
            # (i + dx, j + dy), is then always one this move has not written yet, so every read
            # sees the field as it was before the move, with no copy
            i_lo, i_hi = max(-dx, 0), rows + min(-dx, 0)
            j_lo, j_hi = max(-dy, 0), cols + min(-dy, 0)
            for a in range(i_hi - i_lo):
                i = i_lo + a if dx > 0 else i_hi - 1 - a
                for b in range(j_hi - j_lo):
                    j = j_lo + b if dy > 0 else j_hi - 1 - b
                    candidate = field[i + dx, j + dy] + step * cost[i, j]
                    if candidate < field[i, j] or math.isnan(candidate):  # np.minimum propagates NaN
                        field[i, j] = candidate
        changed = False
        for i in range(rows):
            for j in range(cols):
                if not free[i, j]:
                    field[i, j] = np.inf
                if start[i, j] and seed[i, j] < field[i, j]:
                    field[i, j] = seed[i, j]
                if field[i, j] != sweep_start[i, j]:
                    changed = True
        if not changed:
            return


@njit(cache=True)
def polyline_distances(points: NDArray[np.float64], line: NDArray[np.float64]) -> NDArray[np.float64]:
    """(P,) distance of each of ``points`` (P, 2) to the polyline ``line`` (L, 2), L >= 2: the
    numpy expression of :func:`controllers.classic.plan.polyline_distance`, operation for
    operation (projection clipped to each segment, then the nearest)."""
    p_count, segments = points.shape[0], line.shape[0] - 1
    out = np.empty(p_count)
    for i in range(p_count):
        best = np.inf
        for k in range(segments):
            ax = line[k + 1, 0] - line[k, 0]
            ay = line[k + 1, 1] - line[k, 1]
            t = ((points[i, 0] - line[k, 0]) * ax + (points[i, 1] - line[k, 1]) * ay) / max(
                ax * ax + ay * ay, 1e-12
            )
            t = min(max(t, 0.0), 1.0)
            dx = points[i, 0] - (line[k, 0] + t * ax)
            dy = points[i, 1] - (line[k, 1] + t * ay)
            d = math.sqrt(dx * dx + dy * dy)
            if d < best or math.isnan(d):
                best = d
                if math.isnan(d):
                    break
        out[i] = best
    return out
