"""Formation shapes for teams of any size."""

from __future__ import annotations

import math

import numpy as np
import pytest

from koopman_envs.sim.formations import FORMATION_SHAPES, formation_offsets_for, formation_shape


def test_documented_offsets_for_several_team_sizes():
    s = 0.9
    np.testing.assert_allclose(
        formation_shape("wedge", 5, s), [[0, 0], [-s, s], [-s, -s], [-2 * s, 2 * s], [-2 * s, -2 * s]]
    )
    np.testing.assert_allclose(formation_shape("line", 4, s), [[0, 0], [0, s], [0, -s], [0, 2 * s]])
    np.testing.assert_allclose(formation_shape("column", 3, s), [[0, 0], [-s, 0], [-2 * s, 0]])
    # circle: leader at the centre, the first follower straight behind, then counter-clockwise
    circle = formation_shape("circle", 5, s)
    np.testing.assert_allclose(circle, [[0, 0], [-s, 0], [0, -s], [s, 0], [0, s]], atol=1e-12)
    # grid of 3 x 3 for 9 robots: the leader in the front row's middle
    grid = formation_shape("grid", 9, s)
    assert sorted(map(tuple, np.round(grid / s).astype(int).tolist())) == sorted(
        (-r, c) for r in range(3) for c in (-1, 0, 1)
    )
    assert np.all(grid[0] == 0)
    # the paper's 3-robot offsets are the wedge with spacing 0.8
    np.testing.assert_allclose(formation_shape("wedge", 3, 0.8), [[0, 0], [-0.8, 0.8], [-0.8, -0.8]])


@pytest.mark.parametrize("shape", FORMATION_SHAPES)
@pytest.mark.parametrize("n", [1, 2, 3, 6, 10, 16])
def test_every_shape_keeps_neighbours_at_least_spacing_apart(shape, n):
    offsets = formation_shape(shape, n, 0.9)
    assert offsets.shape == (n, 2) and np.all(offsets[0] == 0)
    if n > 1:
        gaps = np.hypot(*(offsets[:, None] - offsets[None]).transpose(2, 0, 1))
        np.fill_diagonal(gaps, np.inf)
        assert gaps.min() >= 0.9 - 1e-9


def test_world_offsets_turn_with_the_leader_heading():
    local = formation_shape("wedge", 3, 1.0)
    turned = formation_offsets_for("wedge", 3, 1.0, math.pi / 2)  # travelling north: behind = south
    np.testing.assert_allclose(turned, [[0, 0], [-1, -1], [1, -1]], atol=1e-12)
    np.testing.assert_allclose(formation_offsets_for("wedge", 3, 1.0, 0.0), local)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"name": "diamond", "n_robots": 3, "spacing": 1.0}, r"formation='diamond' is not one of \['wedge'"),
        ({"name": "line", "n_robots": 0, "spacing": 1.0}, "n_robots=0 must be an integer >= 1"),
        ({"name": "line", "n_robots": 3, "spacing": 0.0}, "spacing=0.0 must be a finite number > 0"),
        ({"name": "line", "n_robots": 3, "spacing": float("nan")}, "spacing=nan"),
    ],
)
def test_bad_shapes_are_rejected(kwargs, message):
    with pytest.raises(ValueError, match=message):
        formation_shape(**kwargs)
