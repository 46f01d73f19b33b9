"""The nominal (slip-free) unicycle model of the team, for the nominal NMPC."""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from koopman_envs.params import PARAMS
from koopman_envs.sim.dynamics import rk4_step

__all__ = ["UnicycleModel"]


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
