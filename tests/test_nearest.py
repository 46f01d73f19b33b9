"""The one nearest-first order: the compiled kernel and the numpy form agree, ties in index order."""

from __future__ import annotations

import numpy as np

from koopman_envs.sim.nearest import (
    disc_clearance,
    nearest_by_clearance,
    nearest_first,
    nearest_first_by_rank,
    nearest_order,
)


def test_compiled_and_numpy_orders_agree_with_ties() -> None:
    rng = np.random.default_rng(0)
    for trial in range(200):
        m = int(rng.integers(1, 12))
        gap = np.round(rng.uniform(-1, 3, m), 1 if trial % 2 else 6)  # rounding makes ties
        order = np.empty(m, dtype=np.int64)
        nearest_first(gap, order, m)
        np.testing.assert_array_equal(order, nearest_order(gap, m))
        by_rank = np.full(m, -1, dtype=np.int64)
        nearest_first_by_rank(gap, by_rank, m)
        np.testing.assert_array_equal(by_rank, order)
        for q in range(m - 1):  # nearest first; equal gaps in index order
            a, b = order[q], order[q + 1]
            assert gap[a] < gap[b] or (gap[a] == gap[b] and a < b)


def test_nearest_discs_by_surface_clearance() -> None:
    points = np.array([[0.0, 0.0], [5.0, 0.0]])
    discs = np.array([[2.0, 0.0, 1.5], [1.0, 0.0, 0.1], [5.0, 3.0, 0.5], [9.0, 0.0, 4.0]])
    np.testing.assert_allclose(disc_clearance(points, discs)[0], [0.5, 0.9, np.hypot(5, 3) - 0.5, 5.0])
    # the big disc beside point 0 is nearer by clearance than the small one nearer by centre
    assert nearest_by_clearance(points, discs, 2).tolist() == [[0, 1], [3, 0]]
    assert nearest_by_clearance(points, discs, 9).shape == (2, 4)
