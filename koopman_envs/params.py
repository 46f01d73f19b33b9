"""The paper's defaults, defined once.

Every number the paper fixes (SPEC sections 1, 3 and 5) lives here and nowhere else: the
simulator, the tasks, the env registrations, the controllers and the docstring tables all read
this module. Values the paper leaves open are marked ``(ours)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "DRIFT_MEAN_INTERVAL",
    "PARAMS",
    "PaperParams",
    "RANDOM_SLIP_MAX",
    "SLIP_SETTINGS",
    "SLIP_MAX_LAMBDA",
    "slip_lambdas",
]


@dataclass(frozen=True)
class PaperParams:
    """Physical, task and controller defaults of the paper (SPEC sections 1, 3, 5).

    Attributes
    ----------
    dt : float
        Control / integration period T_s [s].
    v_max : float
        Forward speed limit ``|v| <= v_max`` [m/s].
    omega_max : float
        Turn-rate limit ``|omega| <= omega_max`` [rad/s].
    workspace : tuple of float
        (x_min, x_max, y_min, y_max) [m]; a robot centre outside it has left the workspace.
    robot_radius : float
        Disc radius of every robot [m] (ours).
    n_robots : int
        Team size used by the paper.
    goal_tolerance : float
        Position tolerance of a settled robot [m] (ours, from the issue: 0.1 m).
    settle_time : float
        How long every robot must stay within tolerance for success [s] (ours: 2 s).
    max_episode_steps : int
        Time limit of an episode in control periods (ours: 60 s of simulated time).
    formation_spacing : float
        Distance between neighbouring robots of a named formation shape [m] (ours: the ``formation``
        env keyword and the random maps' layouts, :mod:`koopman_envs.sim.formations`).
    horizon : int
        NMPC prediction horizon in steps (the paper's "T = 20", read as steps).
    q_leader, q_follower, r_input : tuple of float
        Diagonals of the per-robot stage-cost weights Q_i (4 entries) and R_i (2 entries).
    obstacle_offset : float
        Extra safety distance kept from obstacles by the NMPC [m].
    koopman_trajectories, koopman_steps : int
        Size of the Koopman training set (trajectories x sampling periods).
    koopman_input_bound, koopman_state_bound : float
        Training inputs are uniform on [-b, b]^2 per robot, initial states uniform on [-b, b]^3.
    """

    dt: float = 0.1
    v_max: float = 0.6
    omega_max: float = math.pi / 4
    workspace: tuple[float, float, float, float] = (-10.0, 10.0, -10.0, 10.0)
    robot_radius: float = 0.2  # (ours)
    n_robots: int = 3
    goal_tolerance: float = 0.1  # (ours, issue 3)
    settle_time: float = 2.0  # (ours, issue 3)
    max_episode_steps: int = 600  # (ours) 60 s: paths are a few metres at <= 0.6 m/s
    formation_spacing: float = 0.9  # (ours) two robot diameters plus 0.5 m
    horizon: int = 20
    q_leader: tuple[float, float, float, float] = (4.0, 4.0, 0.1, 0.1)
    q_follower: tuple[float, float, float, float] = (1.0, 1.0, 0.1, 0.1)
    r_input: tuple[float, float] = (0.1, 0.1)
    obstacle_offset: float = 0.015
    koopman_trajectories: int = 1000
    koopman_steps: int = 1000
    koopman_input_bound: float = 1.0
    koopman_state_bound: float = 10.0

    @property
    def settle_steps(self) -> int:
        """Number of consecutive control periods that make ``settle_time``."""
        return int(round(self.settle_time / self.dt))

    @property
    def calibration_budget(self) -> int:
        """Team-transitions a controller may simulate to calibrate: the paper's data set size."""
        return self.koopman_trajectories * self.koopman_steps


PARAMS = PaperParams()

#: Named slip settings: lambda of the most-slipping robot. Robot 1 is always slip-free and the
#: others are spaced linearly up to this value, which for 3 robots gives exactly SPEC's table:
#: nominal (0, 0, 0), low (0, 0.05, 0.1), high (0, 0.1, 0.2). The spacing rule is (ours).
SLIP_MAX_LAMBDA: dict[str, float] = {"nominal": 0.0, "low": 0.1, "high": 0.2}
SLIP_SETTINGS = tuple(SLIP_MAX_LAMBDA)
#: ``slip="random"``: each episode draws its own constant levels (see RANDOM_SLIP_MAX)
RANDOM_SLIP = "random"
#: ``slip="drift"``: every robot's level is redrawn at random times (see DRIFT_MEAN_INTERVAL)
DRIFT_SLIP = "drift"

#: Largest slip mean of the settings that draw their levels (ours: covers and exceeds "high").
#: ``slip="random"`` draws the most-slipping robot's lambda uniformly on [0, RANDOM_SLIP_MAX] once
#: per episode (the others spaced linearly from robot 1's 0); ``slip="drift"`` draws every level
#: of every robot uniformly on [0, RANDOM_SLIP_MAX].
RANDOM_SLIP_MAX = 0.25

#: ``slip="drift"`` (ours): every robot's slip mean is piecewise constant in time and changes at
#: the events of its own Poisson process, i.e. after holding times ~ Exponential with this mean
#: [s], independent across robots. At each event (and at reset) the new level is uniform on
#: [0, RANDOM_SLIP_MAX], independent of the old one. A change at time t applies from the first
#: control period that starts at or after t, so the level of a period is the one drawn last up to
#: the period's start. Exact draw order: koopman_envs.sim.slip_schedule.SlipClock.
DRIFT_MEAN_INTERVAL = 5.0

#: Every named slip setting and what it means: the one table the env docs, the CLI help and the
#: errors read (per-robot lambdas and (time, lambdas) schedules are the unnamed forms).
SLIP_NAMES: dict[str, str] = {
    **{
        name: f"constant levels, robot 1 slip-free, the others spaced linearly up to lambda = {top:g}"
        for name, top in SLIP_MAX_LAMBDA.items()
    },
    RANDOM_SLIP: f"constant levels drawn per episode (largest lambda uniform on [0, {RANDOM_SLIP_MAX:g}])",
    DRIFT_SLIP: f"every robot's level redrawn on [0, {RANDOM_SLIP_MAX:g}] at random times "
    f"(mean interval {DRIFT_MEAN_INTERVAL:g} s)",
}


def slip_lambdas(slip: str | object, n_robots: int) -> NDArray[np.float64]:
    """Resolve a slip setting to per-robot Exponential means lambda_i.

    Parameters
    ----------
    slip : str or sequence of float
        ``"nominal"``, ``"low"``, ``"high"``, or one lambda >= 0 per robot.
    n_robots : int
        Team size.

    Returns
    -------
    ndarray, shape (n_robots,)
        lambda_i >= 0 (dimensionless mean of the slip coefficients alpha, beta, gamma).

    Raises
    ------
    ValueError
        Unknown name, wrong length, negative or non-finite lambda.
    """
    if isinstance(slip, str):
        if slip not in SLIP_MAX_LAMBDA:
            raise ValueError(
                f"slip={slip!r} is not one of {list(SLIP_SETTINGS)} "
                "(or 'random' for a new level per episode, 'drift' for levels that change within an "
                "episode, a sequence of per-robot lambda >= 0, or a list of (time [s], lambdas) pairs)"
            )
        if n_robots == 1:
            return np.zeros(1)
        return np.linspace(0.0, SLIP_MAX_LAMBDA[slip], n_robots)
    if isinstance(slip, (bool, np.bool_)) or (
        isinstance(slip, (list, tuple)) and any(isinstance(v, (bool, np.bool_)) for v in slip)
    ):
        raise ValueError(
            f"slip={slip!r} is a boolean; allowed: a name in {list(SLIP_SETTINGS)}, 'random', 'drift', "
            "one lambda >= 0 per robot, or a list of (time [s], lambdas) pairs (slip-free: 'nominal')"
        )
    try:
        lam = np.asarray(slip, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(
            f"slip={slip!r} is neither a name in {list(SLIP_SETTINGS)} nor a sequence of numbers"
        ) from exc
    if lam.ndim == 0:
        lam = np.full(n_robots, float(lam))
    if lam.shape != (n_robots,):
        raise ValueError(f"slip={slip!r} has {lam.size} values; expected one lambda per robot ({n_robots})")
    if not np.all(np.isfinite(lam)):
        raise ValueError(f"slip={slip!r} contains a non-finite lambda; allowed: finite lambda >= 0")
    if np.any(lam < 0):
        raise ValueError(f"slip={slip!r} contains a negative lambda; allowed: lambda >= 0")
    return lam
