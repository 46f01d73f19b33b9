"""Team-mates' plans as a robot hears them over the env's radio (``comm``), for the distributed NMPC.

A robot's message carries its pose estimate and the plan it made the period before; the env
delivers it ``latency`` periods late, or loses it (:mod:`koopman_envs.sim.perception`). The
receiver knows the message's age (``Observed.message_age``), so it uses the plan the sender made
``age + 1`` periods ago, shifted by as many steps (its end held). A plan as old as the horizon,
or one made before the episode, is replaced by the prediction that the sender holds its last
known position. With instant messages (age 0) this is the previous period's plan shifted by
one, or the plan made in this period under sequential coordination: the behaviour before
``comm`` existed, bit for bit.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["PlanLog"]


class PlanLog:
    """Every robot's plans by the period they were made in (the last ``horizon`` periods).

    Parameters
    ----------
    horizon : int
        Stages of a plan.
    """

    def __init__(self, horizon: int) -> None:
        self.horizon = int(horizon)
        self.period = 0
        self._made: dict[int, NDArray[np.float64]] = {}

    def record(self, plans: NDArray[np.float64]) -> None:
        """Log this period's plans (H, N, 2) of the whole team and move to the next period."""
        self._made[self.period] = plans
        self._made.pop(self.period - self.horizon, None)
        self.period += 1

    def heard(
        self,
        latest: NDArray[np.float64],
        j: int,
        age: int,
        fresh: bool,
        last_known: NDArray[np.float64],
    ) -> tuple[NDArray[np.float64], str]:
        """Robot j's plan as a team-mate has it: positions (H, 2) at this period's stages 1..H.

        Parameters
        ----------
        latest : ndarray, shape (H, N, 2)
            The team's latest plans (this period's for the robots that solved already).
        j : int
            The sender.
        age : int
            Age of the receiver's last message from j [periods] (>= 0).
        fresh : bool
            ``latest[:, j]`` was made in this period (sequential coordination).
        last_known : ndarray, shape (>= 2,)
            The receiver's last known position of j.

        Returns
        -------
        plan : ndarray, shape (H, 2)
        kind : str
            ``""`` (a message of this period), ``"plans_aged"`` or ``"plans_replaced"``: the
            counts :meth:`DistributedNMPC.stats` reports.
        """
        if age == 0:
            plan = latest[:, j]
            return (plan if fresh else np.concatenate([plan[1:], plan[-1:]])), ""
        made = self._made.get(self.period - age - 1)
        if made is None or age + 1 >= self.horizon:
            return np.repeat(np.asarray(last_known)[None, :2], self.horizon, axis=0), "plans_replaced"
        plan = made[:, j]
        return np.concatenate([plan[age + 1 :], np.repeat(plan[-1:], age + 1, axis=0)]), "plans_aged"
