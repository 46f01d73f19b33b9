"""The NMPC's parameter hooks: read and write the named blocks of the parameter vector the next
solve uses (:mod:`controllers.mpc.layout`). The distributed NMPC drives each robot's NMPC through
them (its neighbours' plans, goals, obstacles, margins); the central NMPC fills the same blocks at
reset and before every solve.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:  # pragma: no cover - typing only
    from controllers.mpc.problem import Problem
    from controllers.mpc.slots import PairSlots

__all__ = ["ParameterHooks"]


class ParameterHooks:
    """The ``set_*`` hooks and the parameter reads of :class:`controllers.mpc.controller.NMPCController`
    (a mixin: the controller holds the built problem, the parameter values and the slots)."""

    _problem: Problem | None
    _params: NDArray[np.float64]
    _pair_slots: PairSlots
    _moving_xy: NDArray[np.float64]
    _moving_reach: NDArray[np.float64]
    neighbour_slots: int  # the controller's (moving-disc slots of the built problem)

    def _block(self, name: str) -> slice:
        assert self._problem is not None  # built by _reset
        return self._problem.layout[name]

    def parameter(self, name: str) -> NDArray[np.float64]:
        """A copy of block ``name`` of the parameter values the next solve uses
        (:data:`~controllers.mpc.layout.BLOCKS`; ``x_meas`` is written at every solve)."""
        return self._params[self._block(name)].copy()

    def parameter_vector(self) -> NDArray[np.float64]:
        """A copy of the whole parameter vector the next solve uses (``x_meas`` not yet written)."""
        return self._params.copy()

    @property
    def pairs_in_slots(self) -> list[tuple[int, int] | None]:
        """The robot pair each pair slot holds (None: parked)."""
        return list(self._pair_slots.held)

    def set_margins(self, obstacle: NDArray, pair: NDArray) -> None:
        """Use these safety margins from the next solve on (shapes as :meth:`safety_margins`)."""
        self._params[self._block("obstacle_margin")] = obstacle
        self._params[self._block("pair_margin")] = pair

    def set_neighbours(self, positions: NDArray, reach: NDArray) -> None:
        """Use these moving discs from the next solve on (a problem built with neighbour slots).

        ``positions`` (T, K, 2): each slot's predicted position at stages 1..T; ``reach`` (K,):
        the slot's radius plus the margin to keep. An unused slot is parked
        (:data:`~controllers.mpc.config.PARKED`).
        """
        self._set_moving(0, positions, reach)

    def set_movers(self, positions: NDArray, reach: NDArray) -> None:
        """Use these predicted movers from the next solve on (:func:`controllers.movers.mover_slots`:
        ``positions`` (T, M, 2), ``reach`` (M,), M the problem's mover slots)."""
        self._set_moving(self.neighbour_slots, positions, reach)

    def _set_moving(self, first: int, positions: NDArray, reach: NDArray) -> None:
        # the block is stage-major over every moving slot: team-mates first, then movers
        count = np.shape(reach)[0]
        self._moving_xy[:, first : first + count] = positions
        self._moving_reach[first : first + count] = reach
        self._params[self._block("neighbour_xy")] = self._moving_xy.reshape(-1)
        self._params[self._block("neighbour_reach")] = self._moving_reach

    def set_goal(self, index: int, xy: NDArray) -> None:
        """Track ``xy`` instead of robot ``index``'s target position from the next solve on."""
        start = self._block("goal_xy").start
        self._params[start + 2 * index : start + 2 * index + 2] = xy

    def set_obstacles(self, obstacles: NDArray) -> None:
        """Use these obstacles (M, 3) from the next solve on (M as the problem was built for)."""
        self._params[self._block("obstacles")] = np.ravel(obstacles)

    def set_model_parameters(self, theta: NDArray) -> None:
        """Use these model coefficients (the model's ``nlp_parameters`` layout) from the next solve on."""
        self._params[self._block("model")] = theta
