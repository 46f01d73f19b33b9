"""Open-loop rollouts of many robot teams on the simulator core (no maps, no collisions).

This is the simulator without the task around it: the same RK4 slip kinematics and the same
Exponential slip model as the environments, for data collection and model validation.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from koopman_envs.params import PARAMS
from koopman_envs.sim.dynamics import rk4_channels, wrap_angle

__all__ = ["rollout"]


def rollout(
    start: NDArray[np.float64],
    commands: NDArray[np.float64],
    lambdas: NDArray[np.float64],
    rng: np.random.Generator,
    dt: float = PARAMS.dt,
) -> NDArray[np.float64]:
    """Simulate B independent teams under given command sequences.

    Parameters
    ----------
    start : ndarray, shape (B, N, 3)
        Initial poses (x [m], y [m], theta [rad]).
    commands : ndarray, shape (T, B, N, 2)
        Commands (v [m/s], omega [rad/s]) per period, applied as given (no saturation: data
        collection may excite the model beyond the actuation limits, as the paper does).
    lambdas : ndarray, shape (N,) or (B, N)
        Slip means lambda_i >= 0, shared by every team or one row per team.
    rng : numpy.random.Generator
        Source of the slip draws (alpha, beta, gamma per robot per period, in that order).
    dt : float
        Period [s].

    Returns
    -------
    ndarray, shape (T + 1, B, N, 3)
        Poses at every period, theta wrapped to [-pi, pi).
    """
    start = np.asarray(start, dtype=np.float64)
    commands = np.asarray(commands, dtype=np.float64)
    lambdas = np.asarray(lambdas, dtype=np.float64)
    steps, batch, n = commands.shape[:3]
    if start.shape != (batch, n, 3):
        raise ValueError(f"start has shape {start.shape}; expected ({batch}, {n}, 3) to match commands")
    if lambdas.shape not in ((n,), (batch, n)):
        raise ValueError(f"lambdas has shape {lambdas.shape}; expected ({n},) or ({batch}, {n})")
    out = np.empty((steps + 1, batch, n, 3))
    out[0] = start
    x, y, th = start[..., 0].copy(), start[..., 1].copy(), start[..., 2].copy()
    v_all = np.ascontiguousarray(commands[..., 0])
    w_all = np.ascontiguousarray(commands[..., 1])
    slipping = bool(np.any(lambdas > 0))
    zero = np.zeros((batch, n))
    for t in range(steps):
        if slipping:
            slip = rng.standard_exponential((3, batch, n))
            slip *= lambdas
            alpha, beta, gamma = slip
        else:
            alpha = beta = gamma = zero
        x, y, th = rk4_channels(x, y, th, v_all[t], w_all[t], alpha, beta, gamma, dt)
        th = wrap_angle(th)
        out[t + 1, ..., 0] = x
        out[t + 1, ..., 1] = y
        out[t + 1, ..., 2] = th
    return out
