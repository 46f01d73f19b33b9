"""Prediction models of the NMPC: what a model must offer (:class:`PredictionModel`), how the NLP
state codes poses, and the nominal (slip-free) unicycle of the team. The Koopman model lives in
:mod:`controllers.koopman`; it satisfies the same protocol."""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any, Protocol

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from koopman_envs import rk4_step
from koopman_envs.checks import choice_message
from koopman_envs.params import PARAMS

__all__ = [
    "CODING_SIZE",
    "PredictionModel",
    "UnicycleModel",
    "coding_memory",
    "coding_size",
    "coding_velocity",
    "decode_state",
    "encode_state",
    "model_step",
]


class PredictionModel(Protocol):
    """What the NMPC needs of a model: team size, period, and a CasADi step function.

    ``coding`` names the per-robot NLP state: ``"pose"`` = (x, y, theta), ``"cs"`` =
    (x, y, cos theta, sin theta), or ``"cs+uL"`` = the ``"cs"`` state followed by the robot's
    last L commands, most recent first (a model with memory, which the controller fills with the
    commands it sent), each with ``"+v"`` followed by the robot's (x, y, cos, sin) one period
    before (the velocity memory, which the controller fills with the poses it measured); ``casadi_nlp_step()`` maps (state, u) to the next state in it.
    """

    # read-only members: a frozen dataclass (UnicycleModel) satisfies them, the NMPC only reads them
    @property
    def n_robots(self) -> int: ...

    @property
    def dt(self) -> float: ...

    @property
    def coding(self) -> str: ...

    def casadi_nlp_step(self) -> ca.Function: ...


def model_step(model: PredictionModel) -> tuple[ca.Function, NDArray[np.float64], Any]:
    """(step function (s, u, theta) -> s_next, theta's values, structure key) of a model.

    A model may offer its coefficients as NLP parameters (``casadi_nlp_step_parametric``,
    ``nlp_parameters``, ``nlp_structure``): the NMPC's problem then depends on its structure
    only, and models of the same structure share one built (and compiled) problem. Otherwise
    the coefficients are constants and the model itself is the key.
    """
    if (
        hasattr(model, "casadi_nlp_step_parametric")
        and hasattr(model, "nlp_parameters")
        and hasattr(model, "nlp_structure")
    ):
        return (
            model.casadi_nlp_step_parametric(),
            np.asarray(model.nlp_parameters(), dtype=float),
            model.nlp_structure(),
        )
    fixed = model.casadi_nlp_step()
    s = ca.SX.sym("s", fixed.size1_in(0))
    u = ca.SX.sym("u", fixed.size1_in(1))
    theta = ca.SX.sym("theta", 0)
    step = ca.Function("step", [s, u, theta], [fixed(s, u)], ["s", "u", "theta"], ["s_next"])
    # the model itself, not id(model): Python reuses the id of a collected object, and a new
    # model at an old address would silently inherit the old model's NLP
    return step, np.zeros(0), model


CODING_SIZE = {"pose": 3, "cs": 4}
_LIFT_CODING = re.compile(r"cs(?:\+u([1-9][0-9]*))?(\+v)?")


def _lift_coding(coding: str) -> tuple[int, bool]:
    """(commands remembered, velocity) of a coding; an unknown coding is a ``ValueError``
    naming the allowed ones."""
    if coding in CODING_SIZE:
        return 0, False
    match = _LIFT_CODING.fullmatch(coding) if isinstance(coding, str) else None
    if match is None:
        raise ValueError(
            choice_message(
                "model coding", coding, sorted(CODING_SIZE), ", 'cs+uL' (L >= 1), 'cs+v' or 'cs+uL+v'"
            )
        )
    return int(match.group(1) or 0), match.group(2) is not None


def coding_memory(coding: str) -> int:
    """Commands a coding remembers per robot (``"cs+uL"``, ``"cs+uL+v"``: L; the others 0); an
    unknown coding is a ``ValueError`` naming the allowed ones."""
    return _lift_coding(coding)[0]


def coding_velocity(coding: str) -> bool:
    """Whether a coding holds each robot's pose one period before (``"+v"``: a model with the
    velocity memory)."""
    return _lift_coding(coding)[1]


def coding_size(coding: str) -> int:
    """NLP state entries per robot of a coding."""
    memory, velocity = _lift_coding(coding)
    if not (memory or velocity):
        return CODING_SIZE[coding]
    return CODING_SIZE["cs"] + 2 * memory + (CODING_SIZE["cs"] if velocity else 0)


def _cos_sin(poses: NDArray) -> list[NDArray]:
    """Columns x, y, cos theta, sin theta of poses (N, 3)."""
    return [poses[:, :2], np.cos(poses[:, 2:3]), np.sin(poses[:, 2:3])]


def encode_state(
    poses: NDArray, coding: str, previous: NDArray | None = None, before: NDArray | None = None
) -> NDArray[np.float64]:
    """Stacked NLP state of poses (N, 3) in a model's coding.

    ``previous`` (L, N, 2): with a ``"cs+uL"`` coding, the commands the robots were sent in the
    last L periods, most recent first (None: a team at rest); unused by the other codings.
    ``before`` (N, 3): with a ``"+v"`` coding, the poses one period earlier (None: the robots
    stand, their poses now).
    """
    poses = np.asarray(poses, dtype=np.float64)
    if coding == "pose":
        return poses.reshape(-1)
    blocks = _cos_sin(poses)
    memory, velocity = _lift_coding(coding)
    if memory:
        sent = (
            np.zeros((memory, poses.shape[0], 2)) if previous is None else np.asarray(previous, dtype=float)
        )
        blocks.append(sent[:memory].transpose(1, 0, 2).reshape(poses.shape[0], 2 * memory))
    if velocity:
        blocks += _cos_sin(poses if before is None else np.asarray(before, dtype=np.float64))
    return np.concatenate(blocks, axis=1).reshape(-1)


def decode_state(states: NDArray, coding: str) -> NDArray[np.float64]:
    """Poses (..., N, 3) from NLP states (..., N * size) in a coding."""
    size = coding_size(coding)
    s = np.asarray(states).reshape(states.shape[:-1] + (-1, size))
    if coding == "pose":
        return s.copy()
    return np.concatenate([s[..., :2], np.arctan2(s[..., 3], s[..., 2])[..., None]], axis=-1)


@dataclass(frozen=True)
class UnicycleModel:
    """x+ = RK4 of the slip-free kinematics (SPEC eq. 15 with alpha = beta = gamma = 0)."""

    n_robots: int
    dt: float = PARAMS.dt

    def step(self, poses: NDArray, commands: NDArray) -> NDArray[np.float64]:
        """Predicted poses (..., N, 3) one period later."""
        poses = np.asarray(poses, dtype=np.float64)
        return rk4_step(poses, commands, np.zeros(poses.shape), self.dt)

    coding = "pose"  # the NMPC state of this model: (x, y, theta) per robot

    def casadi_nlp_step(self) -> ca.Function:
        """The step in the NMPC's coding (poses): :meth:`casadi_step`."""
        return self.casadi_step()

    def casadi_step(self, name: str = "unicycle_step") -> ca.Function:
        """The same RK4 map as a CasADi SX function ``x_next = f(x, u)`` on stacked vectors."""
        n = self.n_robots
        x = ca.SX.sym("x", 3 * n)
        u = ca.SX.sym("u", 2 * n)

        def rate(state: ca.SX) -> ca.SX:
            parts = []
            for i in range(n):
                th = state[3 * i + 2]
                parts += [u[2 * i] * ca.cos(th), u[2 * i] * ca.sin(th), u[2 * i + 1]]
            return ca.vertcat(*parts)

        h = self.dt
        k1 = rate(x)
        k2 = rate(x + h / 2 * k1)
        k3 = rate(x + h / 2 * k2)
        k4 = rate(x + h * k3)
        return ca.Function(name, [x, u], [x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)], ["x", "u"], ["x_next"])
