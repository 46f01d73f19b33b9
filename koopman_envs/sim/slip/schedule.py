"""Slip levels that change within an episode: an explicit schedule, or random drift.

``slip=[(0.0, [0, 0.1, 0.2]), (5.0, [0.3, 0.3, 0.3])]`` holds each listed level from its time
[s] until the next; ``slip="drift"`` redraws every robot's level at random times (the law is
documented at :data:`koopman_envs.params.DRIFT_MEAN_INTERVAL`). Both set the robots' **base**
level; slip zones (:mod:`koopman_envs.sim.slip.zones`) act on top of it.

A change at time t applies to every control period that starts at t or later: the level of the
period starting at ``elapsed * dt`` is the one of the last change at or before that time (with
:data:`TIME_SLACK` for the rounding of ``elapsed * dt``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from koopman_envs.params import DRIFT_MEAN_INTERVAL, DRIFT_SLIP, PARAMS, RANDOM_SLIP_MAX, slip_lambdas

__all__ = ["SlipClock", "SlipSchedule", "TIME_SLACK", "is_schedule"]

#: a change time within this much [s] of a period's start counts as at the start (``0.3 / 0.1``
#: is 2.9999999999999996 periods in floating point)
TIME_SLACK = 1e-9


def is_schedule(slip: Any) -> bool:
    """Whether a ``slip`` argument is a time schedule (``"drift"`` or a list of (time, lambdas)
    pairs) rather than a setting name or one lambda per robot."""
    if isinstance(slip, str):
        return slip == DRIFT_SLIP
    if isinstance(slip, np.ndarray) or not isinstance(slip, Sequence) or len(slip) == 0:
        return False
    return isinstance(slip[0], (list, tuple))


@dataclass(frozen=True, eq=False)
class SlipSchedule:
    """How the robots' base slip levels change within an episode.

    Build it with :meth:`parse`.

    Attributes
    ----------
    drift : bool
        True for ``slip="drift"`` (then ``times`` and ``levels`` are empty).
    times : ndarray, shape (J,)
        Change times [s]: 0 first, strictly increasing.
    levels : ndarray, shape (J, N)
        Slip mean of every robot from ``times[j]`` on.
    """

    drift: bool
    times: NDArray[np.float64]
    levels: NDArray[np.float64]

    @classmethod
    def parse(cls, slip: Any, n_robots: int) -> SlipSchedule:
        """Check a schedule argument (see :func:`is_schedule`).

        Each entry is a pair ``(time [s], lambdas)``, where ``lambdas`` is anything
        :func:`koopman_envs.params.slip_lambdas` takes: a setting name, one number for every robot
        or one per robot.

        Raises
        ------
        ValueError
            An entry that is not a pair, a time that is not a finite number, times that do not
            start at 0 or do not increase strictly, lambdas of the wrong length or negative.
        """
        if isinstance(slip, str):
            if slip != DRIFT_SLIP:
                raise ValueError(
                    f"slip={slip!r} is not a schedule; allowed: {DRIFT_SLIP!r} or (time, lambdas) pairs"
                )
            return cls(True, np.zeros(0), np.zeros((0, n_robots)))
        times: list[float] = []
        levels: list[NDArray[np.float64]] = []
        for j, entry in enumerate(slip):
            if not isinstance(entry, (list, tuple)) or len(entry) != 2:
                raise ValueError(
                    f"slip schedule entry {j} {entry!r} is not a (time [s], lambdas) pair; "
                    "allowed: e.g. slip=[(0.0, [0, 0.1, 0.2]), (5.0, [0.3, 0.3, 0.3])]"
                )
            time, value = entry
            if (
                isinstance(time, bool)
                or not isinstance(time, (int, float, np.integer, np.floating))
                or not math.isfinite(time)
            ):
                raise ValueError(f"slip schedule entry {j}: time={time!r} must be a finite number of seconds")
            previous = times[-1] if times else None
            if previous is None and time != 0:
                raise ValueError(f"slip schedule entry 0: time={time!r}; the schedule must start at time 0")
            if previous is not None and not time > previous:
                raise ValueError(
                    f"slip schedule entry {j}: time={time!r} is not after the previous entry's {previous!r}; "
                    "allowed: strictly increasing times"
                )
            try:
                levels.append(slip_lambdas(value, n_robots))
            except ValueError as exc:
                raise ValueError(f"slip schedule entry {j} at time {time!r}: {exc}") from None
            times.append(float(time))
        if not times:
            raise ValueError("slip=[] is an empty schedule; allowed: at least the entry at time 0")
        times_arr, levels_arr = np.array(times), np.array(levels)
        times_arr.setflags(write=False)
        levels_arr.setflags(write=False)
        return cls(False, times_arr, levels_arr)

    def levels_at(self, time: NDArray[np.float64] | float) -> NDArray[np.float64]:
        """Levels of the listed schedule in effect at ``time`` [s] (any shape S): (*S, N)."""
        if self.drift:
            raise ValueError("a drift schedule has no fixed levels; they are drawn per episode")
        index = np.searchsorted(self.times, np.asarray(time) + TIME_SLACK, side="right") - 1
        return self.levels[index]

    def describe(self) -> dict[str, Any]:
        """Plain-JSON description (what determines the process, e.g. for cache keys)."""
        if self.drift:
            return {"drift": {"mean_interval": DRIFT_MEAN_INTERVAL, "max": RANDOM_SLIP_MAX}}
        return {"times": self.times.tolist(), "levels": self.levels.tolist()}


class SlipClock:
    """The scheduled base levels of K environments during their episodes (the engine's).

    Each environment draws from its own generator, so sub-environment i of a batch follows the
    same levels as a lone environment with the same generator state.

    Drift draws, all from the environment's generator: at :meth:`reset_env` (the last draws of a
    reset) ``uniform(0, RANDOM_SLIP_MAX, N)`` for the first levels then
    ``exponential(DRIFT_MEAN_INTERVAL, N)`` for every robot's first holding time [s]; at the end
    of each step, for every robot (in index order) whose change time is at or before the next
    period's start, one ``uniform(0, RANDOM_SLIP_MAX)`` level then one
    ``exponential(DRIFT_MEAN_INTERVAL)`` holding time, repeated while the robot's next change is
    still due. A listed schedule draws nothing.

    Parameters
    ----------
    schedule : SlipSchedule
        What changes when.
    num_envs, n_robots : int
        Batch size K and team size N.
    """

    def __init__(self, schedule: SlipSchedule, num_envs: int, n_robots: int) -> None:
        self.schedule = schedule
        #: (K, N) time [s] of every robot's next change (inf: none)
        self.next_time = np.full((num_envs, n_robots), np.inf)
        #: (K,) index of the next listed change of every environment
        self.next_index = np.zeros(num_envs, dtype=np.int64)
        # a lower bound of next_time.min(): lets advance() skip its array work on the (usual)
        # steps where no change is due (it runs every step)
        self._earliest = np.inf

    def reset_env(self, index: int, rng: np.random.Generator) -> NDArray[np.float64]:
        """Restart the schedule of environment ``index``; returns the levels of its first period."""
        schedule = self.schedule
        n = self.next_time.shape[1]
        if schedule.drift:
            levels = rng.uniform(0.0, RANDOM_SLIP_MAX, n)
            self.next_time[index] = rng.exponential(DRIFT_MEAN_INTERVAL, n)
        else:
            self.next_index[index] = 1
            self.next_time[index] = schedule.times[1] if len(schedule.times) > 1 else np.inf
            levels = schedule.levels[0].copy()
        self._earliest = min(self._earliest, float(self.next_time[index].min()))
        return levels

    def advance(
        self,
        elapsed: NDArray[np.int64],
        active: NDArray[np.bool_] | None,
        rngs: Sequence[np.random.Generator | None],
        lambdas: NDArray[np.float64],
        dt: float = PARAMS.dt,
    ) -> None:
        """After a step: set ``lambdas`` (K, N) to the levels of every environment's next period.

        Parameters
        ----------
        elapsed : ndarray of int, shape (K,)
            Periods since each reset (the next period starts at ``elapsed * dt``).
        active : ndarray of bool, shape (K,), optional
            Environments that stepped; the others neither change nor draw.
        rngs : sequence of Generator
            Every environment's generator (drift only).
        lambdas : ndarray, shape (K, N)
            Base levels, updated in place.
        dt : float
            Control period [s].
        """
        # elapsed * dt + TIME_SLACK rounds monotonically in elapsed, so when its largest value is
        # below every next change time no entry of ``due`` below could be True
        if float(elapsed.max()) * dt + TIME_SLACK < self._earliest:
            return
        now = elapsed * dt + TIME_SLACK
        due = self.next_time <= now[:, None]
        if active is not None:
            due &= active[:, None]
        if not due.any():
            return
        schedule = self.schedule
        for k in np.flatnonzero(due.any(axis=1)):
            if schedule.drift:
                rng = rngs[int(k)]
                # k is due, so reset_env() set its next_time, and the engine attached its
                # generator to the slip sampler in the same reset
                assert rng is not None
                for i in np.flatnonzero(due[k]):
                    while self.next_time[k, i] <= now[k]:
                        lambdas[k, i] = rng.uniform(0.0, RANDOM_SLIP_MAX)
                        self.next_time[k, i] += rng.exponential(DRIFT_MEAN_INTERVAL)
                continue
            j = int(self.next_index[k])
            times = schedule.times
            while j < len(times) and times[j] <= now[k]:
                j += 1
            lambdas[k] = schedule.levels[j - 1]
            self.next_index[k] = j
            self.next_time[k] = times[j] if j < len(times) else np.inf
        self._earliest = float(self.next_time.min())
