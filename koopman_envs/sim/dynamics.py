"""Differential-drive kinematics with wheel slip (SPEC section 1), compiled with numba.

One RK4 step is defined once, in :func:`rk4_pose` (scalars). Everything else calls it:
:func:`rk4_step` on ``(..., N, 3)`` pose arrays (the convenient form for users and models),
:func:`rk4_channels` on separate x / y / theta arrays (open-loop data collection) and
:func:`advance_teams`, the engine's fused saturate-integrate-wrap pass. A single environment's
step is a few dozen tiny array operations, where numpy's per-call overhead, not arithmetic,
dominates; compiled loops remove it, and keep the arithmetic in numpy's order, so results are
bit-identical to the earlier pure-numpy engine.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from koopman_envs.params import PARAMS

__all__ = [
    "Limits",
    "advance_teams",
    "rk4_channels",
    "rk4_pose",
    "rk4_step",
    "saturated_command",
    "slip_velocity",
    "wrap_angle",
    "wrap_scalar",
]

#: the actuation as the compiled physics takes it: ``command_low``, ``command_high`` and
#: ``effort_scale``, (2,) each over the channels v, omega (a plain tuple: numba types one at a
#: call almost as fast as loose arrays, a named tuple field by field in Python)
Limits = tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]


def slip_velocity(
    pose: NDArray[np.float64], command: NDArray[np.float64], slip: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Time derivative of the poses under slip (paper eq. 15).

    Parameters
    ----------
    pose : ndarray, shape (..., N, 3)
        x [m], y [m], theta [rad] per robot.
    command : ndarray, shape (..., N, 2)
        v [m/s], omega [rad/s] per robot.
    slip : ndarray, shape (..., N, 3)
        alpha (side slip), beta (traction slip), gamma (turn slip) per robot, dimensionless.

    Returns
    -------
    ndarray, shape (..., N, 3)
        (xdot [m/s], ydot [m/s], thetadot [rad/s]).
    """
    v = command[..., 0]
    theta = pose[..., 2]
    forward = v * (1.0 + slip[..., 1])
    side = v * slip[..., 0]
    c, s = np.cos(theta), np.sin(theta)
    return np.stack(
        [forward * c + side * s, forward * s - side * c, command[..., 1] * (1.0 + slip[..., 2])],
        axis=-1,
    )


@njit(cache=True)
def rk4_pose(
    x: float,
    y: float,
    theta: float,
    v: float,
    omega: float,
    alpha: float,
    beta: float,
    gamma: float,
    dt: float,
) -> tuple[float, float, float]:
    """One RK4 period of one robot (scalars; compiled, callable from Python and from kernels).

    The command and the slip are held through the period (zero-order hold). Because the heading
    rate does not depend on the state, RK4's second and third stages are evaluated at the same
    heading and coincide, so the update needs three heading evaluations
    (theta, theta + dt w / 2, theta + dt w) with weights 1, 2 + 2, 1 over 6. This is RK4
    exactly, written with a third fewer trigonometric calls. Returns x, y, theta one period
    later (theta not wrapped).
    """
    forward = (beta + 1.0) * v
    side = alpha * v
    turn_rate = (gamma + 1.0) * omega
    mid = turn_rate * (0.5 * dt) + theta
    end = turn_rate * dt + theta
    w_end = dt / 6.0
    w_mid = 4.0 * w_end
    cw = math.cos(theta) * w_end + math.cos(mid) * w_mid + math.cos(end) * w_end
    sw = math.sin(theta) * w_end + math.sin(mid) * w_mid + math.sin(end) * w_end
    return forward * cw + side * sw + x, forward * sw - side * cw + y, end


@njit(cache=True)
def wrap_scalar(angle: float) -> float:
    """Wrap one angle to [-pi, pi) [rad]; the same arithmetic as :func:`wrap_angle`."""
    shifted = angle + math.pi
    if 0.0 <= shifted < 2.0 * math.pi:
        # the remainder would return ``shifted`` itself; skipping it saves an fmod per robot
        return shifted - math.pi
    return shifted % (2.0 * math.pi) - math.pi


@njit(cache=True)
def _rk4_flat(
    pose: tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]],
    command: tuple[NDArray[np.float64], NDArray[np.float64]],
    slip: tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]],
    dt: float,
    out: NDArray[np.float64],
) -> None:  # pragma: no cover
    """:func:`rk4_pose` over flat arrays: ``pose`` (x, y, theta), ``command`` (v, omega) and
    ``slip`` (alpha, beta, gamma), each a tuple of (P,) arrays, into rows x, y, theta of ``out``
    (3, P)."""
    x, y, theta = pose
    v, omega = command
    alpha, beta, gamma = slip
    for i in range(x.shape[0]):
        out[0, i], out[1, i], out[2, i] = rk4_pose(
            x[i], y[i], theta[i], v[i], omega[i], alpha[i], beta[i], gamma[i], dt
        )


def rk4_channels(
    x: NDArray[np.float64],
    y: NDArray[np.float64],
    theta: NDArray[np.float64],
    v: NDArray[np.float64],
    omega: NDArray[np.float64],
    alpha: NDArray[np.float64],
    beta: NDArray[np.float64],
    gamma: NDArray[np.float64],
    dt: float = PARAMS.dt,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """One RK4 period (:func:`rk4_pose`) of the slip kinematics on separate arrays.

    Parameters
    ----------
    x, y, theta : ndarray
        Poses [m, m, rad], any common shape (the others broadcast against it).
    v, omega : ndarray
        Commands [m/s, rad/s], already within the actuation limits.
    alpha, beta, gamma : ndarray
        Slip coefficients of this period (dimensionless).
    dt : float
        Period [s].

    Returns
    -------
    tuple of ndarray
        x, y, theta one period later (theta not wrapped).
    """
    arrays = np.broadcast_arrays(x, y, theta, v, omega, alpha, beta, gamma)
    shape = arrays[0].shape
    flat = [np.ascontiguousarray(a, dtype=np.float64).reshape(-1) for a in arrays]
    out = np.empty((3,) + shape)
    flat_out = out.reshape(3, -1)
    # named rather than splatted: a type checker cannot count a list's entries before ``dt``
    fx, fy, ftheta, fv, fomega, falpha, fbeta, fgamma = flat
    _rk4_flat((fx, fy, ftheta), (fv, fomega), (falpha, fbeta, fgamma), float(dt), flat_out)
    return out[0], out[1], out[2]


def rk4_step(
    pose: NDArray[np.float64], command: NDArray[np.float64], slip: NDArray[np.float64], dt: float = PARAMS.dt
) -> NDArray[np.float64]:
    """Advance every robot by one control period with classical RK4 (see :func:`rk4_channels`).

    Parameters
    ----------
    pose : ndarray, shape (..., N, 3)
        x [m], y [m], theta [rad] per robot.
    command : ndarray, shape (..., N, 2)
        v [m/s], omega [rad/s], already within the actuation limits.
    slip : ndarray, shape (..., N, 3)
        alpha, beta, gamma drawn for this period (dimensionless).
    dt : float
        Period [s].

    Returns
    -------
    ndarray, shape (..., N, 3)
        Poses one period later (theta not wrapped).
    """
    pose = np.asarray(pose, dtype=np.float64)
    command = np.asarray(command, dtype=np.float64)
    slip = np.asarray(slip, dtype=np.float64)
    x, y, th = rk4_channels(
        pose[..., 0],
        pose[..., 1],
        pose[..., 2],
        command[..., 0],
        command[..., 1],
        slip[..., 0],
        slip[..., 1],
        slip[..., 2],
        dt,
    )
    return np.stack([x, y, th], axis=-1)


def wrap_angle(angle: NDArray[np.float64]) -> NDArray[np.float64]:
    """Wrap angles to [-pi, pi) [rad]."""
    return (angle + np.pi) % (2.0 * np.pi) - np.pi


@njit(cache=True)
def advance_teams(
    state: NDArray[np.float64],
    commands: NDArray[np.float64],
    slip_unit: NDArray[np.float64],
    slip_cursor: NDArray[np.int64],
    lambdas: NDArray[np.float64],
    active: NDArray[np.bool_],
    limits: Limits,
    dt: float,
    new_state: NDArray[np.float64],
    effort: NDArray[np.float64],
) -> None:  # pragma: no cover - compiled
    """Saturate the commands and advance K teams by one period (the engine's physics, compiled).

    Parameters
    ----------
    state : ndarray, shape (K, 3, N)
        Rows x [m], y [m], theta [rad].
    commands : ndarray, shape (K, N, 2)
        Requested (v [m/s], omega [rad/s]); saturated here to ``command_low``/``command_high``.
    slip_unit : ndarray, shape (K, B, 3, N)
        Unit-mean Exponential draws (:class:`~koopman_envs.sim.slip.sampling.SlipSampler`); environment k
        uses row ``slip_cursor[k]`` (rows alpha, beta, gamma) scaled by ``lambdas[k]``.
    slip_cursor : ndarray of int, shape (K,)
        Next unread row per environment; advanced here for active environments.
    lambdas : ndarray, shape (K, N)
        Slip means per robot for this period (the base levels, or where slip zones apply, the
        output of :func:`koopman_envs.sim.slip.zones.zone_slip_means`).
    active : ndarray of bool, shape (K,)
        Inactive environments keep their state, consume no slip and report zero effort.
    limits : tuple of ndarray, shape (2,) each
        :data:`Limits`: ``command_low``, ``command_high`` (the actuation limits) and
        ``effort_scale`` (the effort weight of each channel).
    dt : float
        Period [s].
    new_state : ndarray, shape (K, 3, N)
        Output poses, theta wrapped to [-pi, pi).
    effort : ndarray, shape (K, N)
        Output ``scale_v v^2 + scale_omega omega^2`` of the saturated commands.
    """
    command_low, command_high, effort_scale = limits
    n_envs, _, n_robots = state.shape
    for k in range(n_envs):
        if not active[k]:
            # element by element: a slice assignment makes numba compile its shape-mismatch
            # error message (string formatting), 3.5 s of a cold start for nothing
            for i in range(n_robots):
                for r in range(3):
                    new_state[k, r, i] = state[k, r, i]
                effort[k, i] = 0.0
            continue
        slip = slip_unit[k, slip_cursor[k]]
        slip_cursor[k] += 1
        for i in range(n_robots):
            v, omega, effort[k, i] = saturated_command(
                commands[k, i, 0], commands[k, i, 1], command_low, command_high, effort_scale
            )
            x, y, theta = rk4_pose(
                state[k, 0, i],
                state[k, 1, i],
                state[k, 2, i],
                v,
                omega,
                slip[0, i] * lambdas[k, i],
                slip[1, i] * lambdas[k, i],
                slip[2, i] * lambdas[k, i],
                dt,
            )
            new_state[k, 0, i] = x
            new_state[k, 1, i] = y
            new_state[k, 2, i] = wrap_scalar(theta)


@njit(cache=True)
def saturated_command(
    v: float,
    omega: float,
    command_low: NDArray[np.float64],
    command_high: NDArray[np.float64],
    effort_scale: NDArray[np.float64],
) -> tuple[float, float, float]:
    """One robot's command saturated to the actuation limits, and its effort
    ``scale_v v^2 + scale_omega omega^2`` (the one rule of every plant; compiled)."""
    v = min(max(v, command_low[0]), command_high[0])
    omega = min(max(omega, command_low[1]), command_high[1])
    return v, omega, (v * v) * effort_scale[0] + (omega * omega) * effort_scale[1]
