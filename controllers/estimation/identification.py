"""What a controller learns online about the robots it drives: the actuation delay and the
localization noise, from how the measured poses follow the commands it sent.

A lab identifies both from a log of commands and poses; :class:`MotionIdentifier` does it
during the episode, from sums only (constant memory and time per period). Per robot and per
channel (the travel along the measured heading, and the turn) the motion measured over a
period is fitted to the command that acted in it, for every candidate delay d in 0..``max_delay``
(the command sent d periods before), with one gain per robot and channel: slip scales a command,
it does not delay it.

- **The delay** is the candidate with the smallest least-squares residual, once the commands
  have moved the team enough to tell.
- **The noise.** White localization noise e_t enters each period's measured motion as
  e_t - e_(t-1), so the residuals of neighbouring periods are correlated by -sigma^2, while slip
  draws, independent from period to period, leave them uncorrelated: sigma^2 is minus the
  residuals' lag-one autocovariance at the identified delay (the simplest case of the
  autocovariance least-squares method of Odelson, Rajamani and Rawlings, 2006). Measured with
  a consensus team under high slip: 0.000-0.003 m without noise, 0.026-0.036 m at 3 cm
  (``realistic``), 0.085-0.127 m at 10 cm (``harsh``). Below :data:`POSITION_FLOOR` /
  :data:`HEADING_FLOOR` the noise is taken as none, so that a team without localization error
  is driven exactly as without the identifier.
"""

from __future__ import annotations

from collections import deque

import numpy as np
from numpy.typing import NDArray

from koopman_envs import wrap_angle

__all__ = ["HEADING_FLOOR", "POSITION_FLOOR", "MotionIdentifier"]

#: identified position noise [m] below which a team is taken to localize exactly (measured without
#: noise under high slip: at most 0.003 m)
POSITION_FLOOR = 0.01
#: identified heading noise [rad] below which a team is taken to localize exactly
HEADING_FLOOR = 0.005


class MotionIdentifier:
    """The actuation delay and the localization noise (see the module docstring).

    Parameters
    ----------
    n_robots : int
        N.
    max_delay : int
        Largest delay considered [periods].
    dt : float
        Control period [s].
    min_periods : int
        Periods observed before a delay or a noise level is named.
    min_excitation : float
        Commanded travel [m], summed over robots and periods, before a delay is named.
    lock_excitation : float
        Commanded travel [m] after which the delay is kept for the episode.
    """

    #: the turn's weight in the fits [m/rad]: a robot radius, so that a turn counts as the travel
    #: of its rim
    TURN_SCALE = 0.2

    def __init__(
        self,
        n_robots: int,
        max_delay: int,
        dt: float,
        min_periods: int = 10,
        min_excitation: float = 1.0,
        lock_excitation: float = 10.0,
    ) -> None:
        self.max_delay, self.dt = max_delay, dt
        self.min_periods, self.min_excitation = min_periods, min_excitation
        self.lock_excitation = lock_excitation
        self._locked: int | None = None
        shape = (2, n_robots, max_delay + 1)  # channel (travel, turn), robot, candidate delay
        # sums over periods of the motion m, the commanded motion u of each candidate, and of
        # their products with the previous period's (suffix 1): what the fits and the residuals'
        # lag-one autocovariance need
        self._su, self._suu, self._smu = np.zeros(shape), np.zeros(shape), np.zeros(shape)
        self._smu1, self._sum1, self._suu1 = np.zeros(shape), np.zeros(shape), np.zeros(shape)
        self._sm, self._smm, self._smm1 = np.zeros(shape[:2]), np.zeros(shape[:2]), np.zeros(shape[:2])
        self._sent: deque[NDArray[np.float64]] = deque(
            [np.zeros((n_robots, 2))] * (max_delay + 1), maxlen=max_delay + 1
        )
        self._last_pose: NDArray[np.float64] | None = None
        self._last: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None  # (m, u) of the last period
        #: per robot: periods and neighbouring pairs of periods measured fresh
        self._periods = np.zeros(n_robots)
        self._pairs = np.zeros(n_robots)
        self._fresh = np.ones(n_robots, dtype=bool)  # whether the last pose was fresh
        self._last_fresh = np.zeros(n_robots, dtype=bool)  # whether the last period counted
        self.periods = 0
        self.pairs = 0
        self.excitation = 0.0

    def observe(self, measured: NDArray[np.float64], fresh: NDArray[np.bool_] | None = None) -> None:
        """The poses measured now (N, 3); call once per period, before :meth:`sent`. ``fresh``
        (N,): which rows were measured this period (a pose heard over the radio may be older:
        a stale row and the period after it are left out of the fits)."""
        fresh_now = np.ones(measured.shape[0], dtype=bool) if fresh is None else np.asarray(fresh, dtype=bool)
        if self._last_pose is not None:
            counted = fresh_now & self._fresh  # the period's motion is measured at both ends
            step = measured[:, :2] - self._last_pose[:, :2]
            heading = self._last_pose[:, 2]
            motion = np.stack(
                [
                    step[:, 0] * np.cos(heading) + step[:, 1] * np.sin(heading),
                    self.TURN_SCALE * wrap_angle(measured[:, 2] - self._last_pose[:, 2]),
                ]
            )  # (2, N)
            # candidate d: the command sent d periods before the last one acted in this period
            sent = np.stack(list(self._sent)[::-1], axis=-1)  # (N, 2, D + 1): newest first
            commanded = np.stack([sent[:, 0], self.TURN_SCALE * sent[:, 1]]) * self.dt  # (2, N, D + 1)
            if not counted.all():  # stale rows contribute nothing this period
                motion = motion * counted
                commanded = commanded * counted[:, None]
            m = motion[..., None]
            self._sm += motion
            self._smm += motion * motion
            self._su += commanded
            self._suu += commanded * commanded
            self._smu += m * commanded
            if self._last is not None:
                last_m, last_u = self._last
                self._smm1 += motion * last_m
                self._smu1 += m * last_u
                self._sum1 += commanded * last_m[..., None]
                self._suu1 += commanded * last_u
                self._pairs += counted & self._last_fresh
                self.pairs += 1
            self._last = (motion, commanded)
            self._last_fresh = counted
            self._periods += counted
            self.periods += 1
            self.excitation += float(np.abs(commanded[0, :, 0]).sum())
        self._last_pose = np.array(measured, dtype=np.float64)
        self._fresh = fresh_now

    def sent(self, command: NDArray[np.float64]) -> None:
        """The command sent this period (N, 2), as it will act (clipped to the limits)."""
        self._sent.append(np.array(command, dtype=np.float64))

    def _gains(self) -> NDArray[np.float64]:
        # at least 0: a command moves a robot its way, slip only scales it. A negative fit comes
        # from the feedback loop, not the actuators: a controller's command answers the noise of
        # the pose it was given, which the next measured step takes back (near a goal, where the
        # commands are as small as the noise, that alone would name the wrong delay)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(self._suu > 0, np.maximum(self._smu / self._suu, 0.0), 0.0)

    def residuals(self) -> NDArray[np.float64]:
        """The least-squares residual of each candidate delay (D + 1,), summed over robots and channels."""
        explained = self._gains() * self._smu
        return (self._smm[..., None] - explained).sum(axis=(0, 1))

    @property
    def delay(self) -> int | None:
        """The identified delay [periods], or None while the data cannot tell yet. Once the
        commands have moved the team ``lock_excitation`` metres it is kept for the episode (a
        team's delay does not change within one; a team parked at its goals, commanding little
        more than its noise, would otherwise blur it)."""
        if self._locked is not None:
            return self._locked
        if self.periods < self.min_periods or self.excitation < self.min_excitation:
            return None
        delay = int(np.argmin(self.residuals()))
        if self.excitation >= self.lock_excitation:
            self._locked = delay
        return delay

    def noise_levels(self) -> tuple[float, float] | None:
        """The localization noise (position [m], heading [rad]) at the identified delay, each 0
        below its floor; None while the delay is not known."""
        d = self.delay
        if d is None or self.pairs < self.min_periods:
            return None
        g = self._gains()[..., d]
        measured = self._pairs > 0  # robots with fresh neighbouring periods (all, without a radio)
        n, pairs = self._periods[measured], self._pairs[measured]
        g = g[:, measured]
        mean = (self._sm[:, measured] - g * self._su[:, measured, d]) / n
        lagged = (
            self._smm1[:, measured]
            - g * (self._smu1[:, measured, d] + self._sum1[:, measured, d])
            + g * g * self._suu1[:, measured, d]
        ) / pairs
        variance = np.maximum(-(lagged - mean * mean).mean(axis=1), 0.0)  # per channel, pooled over robots
        position, heading = float(np.sqrt(variance[0])), float(np.sqrt(variance[1])) / self.TURN_SCALE
        return (
            position if position >= POSITION_FLOOR else 0.0,
            heading if heading >= HEADING_FLOOR else 0.0,
        )
