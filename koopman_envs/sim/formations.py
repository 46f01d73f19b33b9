"""Formation shapes for teams of any size: where each follower stands relative to the leader.

A shape gives the offsets of robots 0..N-1 in the *travel frame* of the leader (x forward, y to
the left), robot 0 (the leader) at the origin, neighbouring robots ``spacing`` metres apart.
:func:`formation_offsets_for` turns them into world-frame offsets for a leader heading.

==========  ===================================================================================
shape       layout (travel frame)
==========  ===================================================================================
wedge       leader at the tip, followers alternating left and right on the two arms behind it,
            ``spacing`` back and ``spacing`` out per rank (the random maps' formation)
line        line abreast: followers alternating left and right of the leader, ``spacing`` apart
column      single file behind the leader, ``spacing`` apart
circle      leader at the centre, followers evenly on a circle (the first straight behind the
            leader, then counter-clockwise) whose radius keeps neighbours ``spacing`` apart (at
            least ``spacing``)
grid        rows of ceil(sqrt(N)) robots, ``spacing`` apart, the leader in the front row's
            middle and the rows behind it
==========  ===================================================================================

The paper's Map 3 / Map 4 offsets ((-0.8, +-0.8) for 3 robots) are a wedge with spacing 0.8;
the shipped maps keep their own offsets unless a shape is asked for.
"""

from __future__ import annotations

import math
from numbers import Real

import numpy as np
from numpy.typing import NDArray

from koopman_envs.checks import check_choice, check_int
from koopman_envs.params import LIMITS

__all__ = ["FORMATION_SHAPES", "formation_offsets_for", "formation_shape"]

FORMATION_SHAPES = ("wedge", "line", "column", "circle", "grid")


def _alternating(n_robots: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Rank 1, 1, 2, 2, ... and side +1, -1, +1, ... of followers 1..N-1 (leader: rank 0)."""
    k = np.arange(n_robots)
    rank = (k + 1) // 2
    side = np.where(k % 2 == 1, 1.0, -1.0)
    side[0] = 0.0
    return rank.astype(np.float64), side


def formation_shape(name: str, n_robots: int, spacing: float) -> NDArray[np.float64]:
    """Offsets (N, 2) of a named shape in the leader's travel frame; row 0 (the leader) is zero.

    Parameters
    ----------
    name : str
        One of :data:`FORMATION_SHAPES`.
    n_robots : int
        Team size N >= 1.
    spacing : float
        Distance between neighbouring robots [m], > 0.
    """
    check_choice("formation", name, FORMATION_SHAPES)
    check_int("n_robots", n_robots, 1, maximum=LIMITS.robots)  # (N, 2) offsets: bounded before allocating
    # any real number, NumPy scalars included
    if (
        isinstance(spacing, bool)
        or not isinstance(spacing, Real)
        or not (math.isfinite(spacing) and spacing > 0)
    ):
        raise ValueError(f"spacing={spacing!r} must be a finite number > 0 [m]")
    spacing = float(spacing)
    n = int(n_robots)
    offsets = np.zeros((n, 2))
    if n == 1:
        return offsets
    rank, side = _alternating(n)
    if name == "wedge":
        offsets[:, 0] = -spacing * rank
        offsets[:, 1] = side * spacing * rank
    elif name == "line":
        offsets[:, 1] = side * spacing * rank
    elif name == "column":
        offsets[:, 0] = -spacing * np.arange(n)
    elif name == "circle":
        followers = n - 1
        # chord between neighbours = spacing; never closer to the leader than spacing
        radius = spacing if followers < 6 else spacing / (2.0 * math.sin(math.pi / followers))
        angle = math.pi + 2.0 * math.pi * np.arange(followers) / followers
        offsets[1:, 0] = radius * np.cos(angle)
        offsets[1:, 1] = radius * np.sin(angle)
    else:  # grid
        width = math.ceil(math.sqrt(n))
        row, column = np.divmod(np.arange(n), width)
        # the leader takes the front row's middle slot; robots fill the row around it
        order = np.argsort(np.abs(np.arange(width) - (width - 1) / 2.0), kind="stable")
        column = order[column]
        offsets[:, 0] = -spacing * row
        offsets[:, 1] = spacing * (column - column[0])
    offsets[0] = 0.0
    return offsets


def formation_offsets_for(name: str, n_robots: int, spacing: float, heading: float) -> NDArray[np.float64]:
    """World-frame offsets (N, 2) of a shape for a leader travelling with ``heading`` [rad]."""
    local = formation_shape(name, n_robots, spacing)
    c, s = math.cos(heading), math.sin(heading)
    return local @ np.array([[c, s], [-s, c]], dtype=np.float64)  # local @ rot.T
