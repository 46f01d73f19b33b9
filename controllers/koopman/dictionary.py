"""Dictionaries of observables phi(x) for a team of N robots, in numpy and in CasADi.

Every dictionary starts with the constant 1 and contains, for each robot, x, y, cos(theta) and
sin(theta), so that the state can be read back from the lifted vector (see
:meth:`Dictionary.state_rows`).

A lift with memory (:func:`lift_memory`, ``memory`` > 0) appends observables of the robots'
previous commands to a dictionary's: the robots of the physics plant move with a lag (inertia,
the motors' ramp), so a period's move depends on the commands before it (docs/physics.md).
A lift with the velocity memory (:func:`lift_velocity`, ``velocity=True``) appends the robots'
measured velocity instead (or as well): the last period's move in the body frame, which carries
the lag without a window of commands.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import TypeVar

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from koopman_envs.checks import check_choice, check_int

__all__ = [
    "DICTIONARIES",
    "MAX_MEMORY",
    "MEMORY_TERMS",
    "VELOCITY_TERMS",
    "Dictionary",
    "ExtendedDictionary",
    "MinimalDictionary",
    "check_memory",
    "check_velocity",
    "get_dictionary",
    "lifted_size",
    "lift_memory",
    "lift_memory_casadi",
    "lift_state",
    "lift_velocity",
    "lift_velocity_casadi",
    "memory_size",
    "shift_memory",
    "velocity_size",
]

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


# ----------------------------------------------------------------------------- memory
#: the largest number of previous commands a lift may hold (1 s at the paper's 0.1 s period)
MAX_MEMORY = 10
#: lifted terms per robot and remembered command: v, omega, v cos, v sin, omega cos, omega sin
MEMORY_TERMS = 6


def check_memory(memory: object) -> int:
    """``memory`` (previous commands in the lift) as an int in [0, :data:`MAX_MEMORY`], else
    ``ValueError`` naming it."""
    return check_int(
        "memory", memory, 0, maximum=MAX_MEMORY, note="previous commands in the lift; 0: the pose-only lift"
    )


def memory_size(n_robots: int, memory: int) -> int:
    """Observables the memory adds to the lift of ``n_robots`` robots."""
    return MEMORY_TERMS * n_robots * memory


def lift_memory(poses: NDArray, previous: NDArray, memory: int) -> NDArray[np.float64]:
    """The memory observables of poses (..., N, 3) and previous commands (..., L, N, 2).

    ``previous[..., l, i]`` is robot i's command l + 1 periods ago (L >= ``memory``; the first
    ``memory`` are used). Per remembered command and robot (lag-major, then robot): v, omega and
    their products with cos theta and sin theta. The products are what make a delayed unicycle
    bilinear: a period's move v_k-1 (cos theta, sin theta) dt is linear in them, and their own
    next values v_k (cos, sin)(theta_k+1) are bilinear in the command and the pose's terms.

    Returns
    -------
    ndarray, shape (..., MEMORY_TERMS * N * memory)
    """
    poses = np.asarray(poses, dtype=np.float64)
    lead = poses.shape[:-2]
    if memory == 0:
        return np.zeros(lead + (0,))
    previous = np.asarray(previous, dtype=np.float64)
    if previous.shape[-3] < memory or previous.shape[-2:] != poses.shape[-2:-1] + (2,):
        raise ValueError(
            f"previous commands of shape {previous.shape} do not fit poses {poses.shape} and "
            f"memory={memory}: need (..., L >= {memory}, N, 2)"
        )
    u = np.broadcast_to(previous[..., :memory, :, :], lead + (memory,) + previous.shape[-2:])
    c = np.cos(poses[..., 2])[..., None, :]  # (..., 1, N)
    s = np.sin(poses[..., 2])[..., None, :]
    v, w = u[..., 0], u[..., 1]  # (..., L, N)
    terms = np.stack([v, w, v * c, v * s, w * c, w * s], axis=-1)  # (..., L, N, 6)
    return terms.reshape(lead + (-1,))


def lift_memory_casadi(cos_sin: list, previous: list) -> list:
    """:func:`lift_memory` in CasADi: ``cos_sin`` [(c_i, s_i)] per robot, ``previous`` [[(v, omega)
    per robot] per lag], as a list of scalars in the same order."""
    terms: list = []
    for lag in previous:
        for (c, s), (v, w) in zip(cos_sin, lag):
            terms += [v, w, v * c, v * s, w * c, w * s]
    return terms


def shift_memory(previous: NDArray, command: NDArray) -> NDArray[np.float64]:
    """The previous commands one period later: ``command`` (..., N, 2) first, the oldest dropped.

    ``previous`` (..., L, N, 2) -> (..., L, N, 2).
    """
    previous = np.asarray(previous, dtype=np.float64)
    if previous.shape[-3] == 0:
        return previous.copy()
    command = np.broadcast_to(
        np.asarray(command, dtype=np.float64), previous.shape[:-3] + previous.shape[-2:]
    )
    return np.concatenate([command[..., None, :, :], previous[..., :-1, :, :]], axis=-3)


# ----------------------------------------------------------------------------- velocity
#: lifted terms per robot of the velocity memory: the last period's move in the body frame
#: (forward, lateral, turn) and their products with cos theta and sin theta
VELOCITY_TERMS = 9


def check_velocity(velocity: object) -> bool:
    """``velocity`` (the last period's move in the lift) as a bool, else ``ValueError`` naming it."""
    if not isinstance(velocity, (bool, np.bool_)):
        raise ValueError(
            f"velocity={velocity!r} must be True or False (the last period's move in the lift; "
            "False: without it)"
        )
    return bool(velocity)


def velocity_size(n_robots: int, velocity: bool) -> int:
    """Observables the velocity memory adds to the lift of ``n_robots`` robots."""
    return VELOCITY_TERMS * n_robots if velocity else 0


def _move_terms(dx, dy, c, s, c_before, s_before, atan2) -> list:
    """The velocity observables of one robot (or arrays of them): the move (dx, dy) since the
    pose before, turned into the body frame of the current heading (c, s), the heading's change
    (from the two headings' cos and sin), and the three times cos and sin. One formula for numpy
    and CasADi, so that the NMPC's lift is the fit's."""
    forward = dx * c + dy * s
    lateral = dy * c - dx * s
    turn = atan2(s * c_before - c * s_before, c * c_before + s * s_before)
    return [forward, lateral, turn, forward * c, forward * s, lateral * c, lateral * s, turn * c, turn * s]


def lift_velocity(poses: NDArray, before: NDArray) -> NDArray[np.float64]:
    """The velocity observables of poses (..., N, 3) and the poses one period before (..., N, 3).

    The measured velocity times the period: the move since the pose before in the current body
    frame (forward, lateral) and the heading's change (wrapped to (-pi, pi]), then their products
    with cos theta and sin theta, robot by robot. A robot with inertia or motor lag keeps part
    of its last move, so its next move is linear in these (a world-frame move is forward cos -
    lateral sin) plus the command's push (bilinear: the model's N (u kron z) holds the commands'
    products with every observable).

    Returns
    -------
    ndarray, shape (..., VELOCITY_TERMS * N)
    """
    poses = np.asarray(poses, dtype=np.float64)
    before = np.asarray(before, dtype=np.float64)
    if before.shape[-2:] != poses.shape[-2:]:
        raise ValueError(
            f"poses before of shape {before.shape} do not fit poses {poses.shape}: need (..., N, 3)"
        )
    before = np.broadcast_to(before, poses.shape)
    th, th_before = poses[..., 2], before[..., 2]
    terms = _move_terms(
        poses[..., 0] - before[..., 0],
        poses[..., 1] - before[..., 1],
        np.cos(th),
        np.sin(th),
        np.cos(th_before),
        np.sin(th_before),
        np.arctan2,
    )
    return np.stack(terms, axis=-1).reshape(poses.shape[:-2] + (-1,))


def lift_velocity_casadi(now: list, before: list) -> list:
    """:func:`lift_velocity` in CasADi: ``now`` and ``before`` [(x, y, cos, sin)] per robot (the
    cos and sin normalized), as a list of scalars in the same order."""
    terms: list = []
    for (x, y, c, s), (xb, yb, cb, sb) in zip(now, before):
        terms += _move_terms(x - xb, y - yb, c, s, cb, sb, ca.atan2)
    return terms


# ----------------------------------------------------------------------------- the whole lift
def lifted_size(dictionary: Dictionary, n_robots: int, memory: int = 0, velocity: bool = False) -> int:
    """Dimension D of the lifted state of ``n_robots`` robots (:func:`lift_state`)."""
    return dictionary.size(n_robots) + memory_size(n_robots, memory) + velocity_size(n_robots, velocity)


def lift_state(
    dictionary: Dictionary,
    poses: NDArray,
    memory: int = 0,
    previous: NDArray | None = None,
    velocity: bool = False,
    before: NDArray | None = None,
) -> NDArray[np.float64]:
    """The lifted state of poses (..., N, 3): the dictionary's observables, then the memory's
    (:func:`lift_memory` of ``previous`` (..., L, N, 2), with ``memory`` > 0), then the
    velocity's (:func:`lift_velocity` of ``before`` (..., N, 3), with ``velocity``). The one
    order of the lift, which the fit and the model share.

    Returns
    -------
    ndarray, shape (..., D)
        D = :func:`lifted_size`.
    """
    parts = [dictionary.lift(poses)]
    if memory:
        if previous is None:
            raise ValueError(f"memory={memory} needs the previous commands (..., L, N, 2), not None")
        parts.append(lift_memory(poses, previous, memory))
    if velocity:
        if before is None:
            raise ValueError("velocity=True needs the poses one period before (..., N, 3), not None")
        parts.append(lift_velocity(poses, before))
    return parts[0] if len(parts) == 1 else np.concatenate(parts, axis=-1)
