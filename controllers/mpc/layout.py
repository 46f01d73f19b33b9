"""The NMPC's parameter vector as named blocks.

Every number an NMPC problem takes at solve time (the measured state, goals, obstacles, margins,
the distributed NMPC's neighbour plans, pair slots, the model's coefficients) is a block of one
parameter vector ``p``. :class:`ParameterLayout` names the blocks once, in order; the problem
builds its symbols from it and the controller writes values through it, so the two cannot drift
apart (as do-mpc's and acados' named parameters).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import casadi as ca
import numpy as np
from numpy.typing import NDArray

__all__ = ["BLOCKS", "ParameterLayout", "nmpc_layout"]

#: the blocks of the NMPC's parameter vector, in order, with what each holds
BLOCKS = {
    "x_meas": "the measured state of the team in the model's coding",
    "goal_xy": "each robot's goal position (x, y)",
    "goal_cs": "each robot's goal heading as (cos, sin)",
    "obstacles": "every obstacle (x, y, r), or with obstacle slots each robot's K nearest, robot-major",
    "obstacle_margin": "each robot's margin toward obstacles [m]",
    "pair_margin": "each pair's margin (i < j, row-major upper triangle) [m]",
    "neighbour_xy": "the distributed NMPC's moving discs: (x, y) per slot and stage 1..T, stage-major",
    "neighbour_reach": "per neighbour slot, its radius plus the margin to keep [m]",
    "pair_select": "per pair slot, +1 at robot i and -1 at robot j (zeros when parked)",
    "pair_offset": "per pair slot, an offset added to p_i - p_j (far away when parked)",
    "pair_reach": "per pair slot, both radii plus the pair's margin [m]",
    "model": "the prediction model's coefficients (empty for a model with constant ones)",
}


@dataclass(frozen=True)
class ParameterLayout:
    """Named, ordered blocks of a parameter vector.

    Attributes
    ----------
    sizes : tuple of (str, int)
        Each block's name and length, in order.
    """

    sizes: tuple[tuple[str, int], ...]
    _slices: dict[str, slice] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        slices, start = {}, 0
        for name, size in self.sizes:
            if name in slices:
                raise ValueError(f"parameter block {name!r} appears twice")
            slices[name] = slice(start, start + int(size))
            start += int(size)
        object.__setattr__(self, "_slices", slices)

    @property
    def size(self) -> int:
        """Length of the whole vector."""
        return sum(size for _, size in self.sizes)

    def __getitem__(self, name: str) -> slice:
        """The slice of block ``name`` in the vector."""
        try:
            return self._slices[name]
        except KeyError:
            raise KeyError(f"no parameter block {name!r}; the blocks are {list(self._slices)}") from None

    def symbols(self, given: dict[str, ca.SX] | None = None) -> dict[str, ca.SX]:
        """One CasADi symbol per block, named as the block (``given`` ones used as they are)."""
        given = given or {}
        return {name: given[name] if name in given else ca.SX.sym(name, size) for name, size in self.sizes}

    def vector(self, symbols: dict[str, ca.SX]) -> ca.SX:
        """The parameter vector: the blocks' symbols stacked in order."""
        return ca.vertcat(*(symbols[name] for name, _ in self.sizes))

    def zeros(self) -> NDArray[np.float64]:
        """A value vector of the right length."""
        return np.zeros(self.size)


def nmpc_layout(
    nx: int,
    n_robots: int,
    obstacle_values: int,
    horizon: int,
    neighbour_slots: int,
    pair_slots: int,
    model_parameters: int,
) -> ParameterLayout:
    """The layout of an NMPC problem (:data:`BLOCKS`, with the sizes of this problem)."""
    n = n_robots
    pairs = n * (n - 1) // 2
    return ParameterLayout(
        (
            ("x_meas", nx),
            ("goal_xy", 2 * n),
            ("goal_cs", 2 * n),
            ("obstacles", obstacle_values),
            ("obstacle_margin", n),
            ("pair_margin", pairs),
            ("neighbour_xy", 2 * neighbour_slots * horizon),
            ("neighbour_reach", neighbour_slots),
            ("pair_select", n * pair_slots),
            ("pair_offset", 2 * pair_slots),
            ("pair_reach", pair_slots),
            ("model", model_parameters),
        )
    )
