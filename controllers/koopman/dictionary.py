"""Dictionaries of observables phi(x) for a team of N robots, in numpy and in CasADi.

Every dictionary starts with the constant 1 and contains, for each robot, x, y, cos(theta) and
sin(theta), so that the state can be read back from the lifted vector (see
:meth:`Dictionary.state_rows`).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import TypeVar

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from koopman_envs.checks import check_choice

__all__ = ["DICTIONARIES", "Dictionary", "ExtendedDictionary", "MinimalDictionary", "get_dictionary"]

_Symbolic = TypeVar("_Symbolic", ca.SX, ca.MX)  # lift_casadi returns the kind of expression it is given


class Dictionary(ABC):
    """A set of observables of the whole team, ordered robot by robot after the constant."""

    name: str = ""
    per_robot: int = 0  # observables per robot (the constant comes once)

    def size(self, n_robots: int) -> int:
        """Dimension D of the lifted state for ``n_robots`` robots."""
        return 1 + self.per_robot * n_robots

    def state_rows(self, n_robots: int) -> NDArray[np.intp]:
        """Rows of (x, y, cos theta, sin theta) of every robot in the lifted vector, shape (N, 4)."""
        base = 1 + self.per_robot * np.arange(n_robots)
        return base[:, None] + np.arange(4)[None, :]

    def lift(self, poses: NDArray) -> NDArray[np.float64]:
        """Lift poses (..., N, 3) to observables (..., D)."""
        poses = np.asarray(poses, dtype=np.float64)
        x, y, th = poses[..., 0], poses[..., 1], poses[..., 2]
        blocks = self._robot_terms(x, y, np.cos(th), np.sin(th))  # (..., N, per_robot)
        ones = np.ones(poses.shape[:-2] + (1,))
        return np.concatenate([ones, blocks.reshape(poses.shape[:-2] + (-1,))], axis=-1)

    def lift_casadi(self, state: _Symbolic) -> _Symbolic:
        """Lift a symbolic stacked state (x_1, y_1, theta_1, x_2, ...) of length 3N to (D, 1)."""
        n = state.shape[0] // 3
        terms: list[_Symbolic | int] = [1]
        for i in range(n):
            x, y, th = state[3 * i], state[3 * i + 1], state[3 * i + 2]
            terms += self._robot_terms_casadi(x, y, ca.cos(th), ca.sin(th))
        return ca.vertcat(*terms)

    @abstractmethod
    def _robot_terms(self, x: NDArray, y: NDArray, c: NDArray, s: NDArray) -> NDArray:
        """Per-robot observables, stacked on a new last axis: (..., N, per_robot)."""

    @abstractmethod
    def _robot_terms_casadi(self, x, y, c, s) -> list:
        """The same observables as a list of CasADi scalars, in the same order."""


class MinimalDictionary(Dictionary):
    """The paper's dictionary: [1, x_i, y_i, cos theta_i, sin theta_i for each robot] (1 + 4N)."""

    name = "minimal"
    per_robot = 4

    def _robot_terms(self, x, y, c, s):
        return np.stack([x, y, c, s], axis=-1)

    def _robot_terms_casadi(self, x, y, c, s):
        return [x, y, c, s]


class ExtendedDictionary(Dictionary):
    """Minimal terms plus second harmonics and position-heading products (1 + 10N).

    Per robot: x, y, cos th, sin th, cos 2th, sin 2th, x cos th, x sin th, y cos th, y sin th.
    With these the continuous-time slip kinematics are exactly bilinear in the commands (the
    time derivative of every observable is a combination of observables times v or omega),
    a subset of the Hermite/trigonometric dictionaries the paper's footnote points to.
    """

    name = "extended"
    per_robot = 10

    def _robot_terms(self, x, y, c, s):
        return np.stack([x, y, c, s, c * c - s * s, 2 * s * c, x * c, x * s, y * c, y * s], axis=-1)

    def _robot_terms_casadi(self, x, y, c, s):
        return [x, y, c, s, c * c - s * s, 2 * s * c, x * c, x * s, y * c, y * s]


DICTIONARIES: dict[str, Dictionary] = {d.name: d for d in (MinimalDictionary(), ExtendedDictionary())}


def get_dictionary(name: str) -> Dictionary:
    """Dictionary by name; raises ``ValueError`` listing the known names."""
    return DICTIONARIES[check_choice("dictionary", name, sorted(DICTIONARIES))]
