"""The controller contract: one protocol for every controller, plus per-episode statistics.

Any object with ``reset(scenario, seed=...)``, ``act(observation, info)`` and ``stats()`` is a
controller: the model-based ones read the structured state in ``info`` (its observed part, as a
:class:`koopman_envs.Observed`) and the geometry in the scenario, a learned policy reads the
observation. Solver status and timing go into
:class:`ControllerStats`, never onto stdout.
"""

from __future__ import annotations

import dataclasses
import time
from abc import ABC, abstractmethod
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from koopman_envs import Observed
from koopman_envs.scenario import Scenario, scenario_of

if TYPE_CHECKING:  # pragma: no cover - typing only
    from controllers.perception.front import LidarPerception
    from koopman_envs import CalibrationPlant

__all__ = [
    "BaseController",
    "Calibratable",
    "Controller",
    "ControllerStats",
    "FrontEnd",
    "calibratable",
    "hand_on",
    "over_the_radio",
    "take_over_radio",
]


@dataclass
class ControllerStats:
    """What a controller did during one episode.

    Attributes
    ----------
    solve_times : list of float
        Wall time of each control decision [s].
    iterations : list of int
        Solver iterations per decision (empty for controllers without a solver).
    failures : int
        Decisions where the solver failed and a fallback command was used.
    statuses : Counter
        Solver return statuses by name.
    extra_times : dict of str to list of float
        Wall times [s] of other per-step work by name (an online model update, a filter...),
        summarized as ``<name>_ms_median`` / ``<name>_ms_p95``.
    counts : Counter
        Other per-episode counts by name (reported as they are).
    solver : str or None
        The optimizer behind the decisions (e.g. ``"rti/hpipm"``, ``"ipopt"``), reported as
        ``solver`` in the summary when set.
    """

    solve_times: list[float] = field(default_factory=list)
    iterations: list[int] = field(default_factory=list)
    failures: int = 0
    statuses: Counter[str] = field(default_factory=Counter)
    extra_times: dict[str, list[float]] = field(default_factory=dict)
    counts: Counter[str] = field(default_factory=Counter)
    solver: str | None = None

    @property
    def steps(self) -> int:
        """Number of decisions recorded."""
        return len(self.solve_times)

    def percentile(self, q: float) -> float:
        """q-th percentile of the solve time [s] (NaN when nothing was recorded)."""
        return float(np.percentile(self.solve_times, q)) if self.solve_times else float("nan")

    def summary(self) -> dict[str, Any]:
        """Plain-JSON summary: steps, median/p95/max solve time [ms], iterations, failures."""
        return {
            "steps": self.steps,
            "solve_ms_median": 1e3 * self.percentile(50),
            "solve_ms_p95": 1e3 * self.percentile(95),
            "solve_ms_max": 1e3 * max(self.solve_times) if self.solve_times else float("nan"),
            "iterations_mean": float(np.mean(self.iterations)) if self.iterations else float("nan"),
            "failures": self.failures,
            "statuses": dict(self.statuses),
            **{
                f"{name}_ms_{label}": 1e3 * float(np.percentile(times, q)) if times else float("nan")
                for name, times in self.extra_times.items()
                for label, q in (("median", 50), ("p95", 95))
            },
            **{name: int(value) for name, value in self.counts.items()},
            **({"solver": self.solver} if self.solver is not None else {}),
        }


@runtime_checkable
class Controller(Protocol):
    """Anything that can drive a KoopNav team through an episode."""

    name: str

    def reset(self, scenario: Scenario | Any, *, seed: int | None = None) -> None:
        """Prepare for a new episode on ``scenario`` (geometry, targets, limits, dt), given as
        the :class:`Scenario` or as the env it comes from (any front, after ``env.reset``)."""

    def act(self, observation: NDArray[np.float64], info: dict[str, Any]) -> NDArray[np.float64]:
        """Joint command, shape (2N,): (v [m/s], omega [rad/s]) per robot."""

    def stats(self) -> ControllerStats:
        """Statistics of the current episode."""


@runtime_checkable
class Calibratable(Protocol):
    """The optional capability of a controller that learns from the calibration plant before
    its episodes (the evaluator offers every controller the same plant and budget)."""

    def calibrate(self, plant: CalibrationPlant, *, seed: int = 0) -> dict[str, Any]:
        """Learn what it needs from ``plant`` (within its budget); return a plain-JSON summary
        with at least ``transitions`` (team-transitions of data behind the calibration)."""


def calibratable(controller: Any) -> Calibratable | None:
    """The object that calibrates for ``controller``: the controller itself when it is
    :class:`Calibratable`, else the first calibratable one down its wrappers' ``.inner`` chain
    (a wrapper such as ``safe:`` calibrates as the controller it wraps), or None."""
    seen = 0
    while controller is not None and seen < 16:  # a wrapper chain, not a cycle
        if isinstance(controller, Calibratable):
            return controller
        controller = getattr(controller, "inner", None)
        seen += 1
    return None


class FrontEnd(Protocol):
    """What may stand between the observed ``info`` and a controller's ``_act``: an estimator
    (:class:`controllers.estimation.PoseFrontEnd`)."""

    times: list[float]

    def reset(self, scenario: Scenario) -> None:
        """Start an episode."""

    def view(self, observed: Observed) -> Observed:
        """``observed`` as the controller should plan from it: a new value (``observed`` is
        left as it is)."""

    def sent(self, command: NDArray[np.float64]) -> None:
        """Record the command sent."""

    def counts(self) -> dict[str, int]:
        """What it identified so far (reported as counts)."""


def take_over_radio(wrapper: Any, inner: Any) -> None:
    """A wrapper (``ekf:``, ``safe:``) in front of a central controller hears the team over its
    radio instead (its estimator or filter then acts on what the radio delivers)."""
    station = getattr(inner, "radio_station", None)
    if station is not None:
        wrapper.radio_station = station
        inner.radio_station = None


def over_the_radio(observed: Observed, station: int, planned: NDArray[np.float64]) -> Observed:
    """``observed`` as a central controller on robot ``station``'s computer has it: each robot's
    pose as the last message from it says (``known_poses[station]``; the station's own estimate
    on the diagonal), with its age in periods as ``pose_age`` (N,); a robot never heard from
    stands at its ``planned`` start. Without a ``comm`` setting every message arrives at once and
    the poses are unchanged, bit for bit. A new value: ``observed`` is left as it is."""
    known = np.array(observed.known_poses[station], dtype=np.float64)
    age = np.array(observed.message_age[station], dtype=np.int64)
    unheard = age < 0
    known[unheard] = planned[unheard]
    # pose_age -1: never heard (the planned start stands in)
    return dataclasses.replace(observed, observed_poses=known, pose_age=age)


def hand_on(inner: Controller, observation: NDArray[np.float64], observed: Observed) -> NDArray[np.float64]:
    """``inner``'s command on what a wrapper in front (``ekf:``, ``safe:``) planned from: a
    :class:`BaseController` takes the :class:`~koopman_envs.Observed` as it is, any other
    controller the dict of its observed keys (:meth:`~koopman_envs.Observed.to_info`)."""
    if isinstance(inner, BaseController):
        return inner.act(observation, observed)
    return inner.act(observation, observed.to_info())


class BaseController(ABC):
    """Convenience base: keeps the scenario and the statistics; subclasses implement ``_act``.

    A subclass may set :attr:`front_end` (the model-based controllers do, by their ``estimator``
    option): ``_act`` then plans from its view of the observed ``info`` (filtered, delay
    compensated, with a covariance), and its time and what it identified go into the statistics
    (``estimator`` in ``extra_times``; ``identified_*`` counts).
    """

    name = "base"
    #: the estimator in front of ``_act`` (None: ``_act`` reads the observed info as it is)
    front_end: FrontEnd | None = None
    #: a central controller's computer: the robot whose radio it hears the team over (the
    #: leader's, 0, for the central NMPCs), so that it meets the same late and lost messages as
    #: the robots do (:func:`over_the_radio`); None: each robot's own estimate (a controller
    #: whose robots decide for themselves reads its team-mates' messages itself)
    radio_station: int | None = None
    #: whether the controller sees through the lidar's perception under ``sensing="lidar"``
    #: (:mod:`controllers.perception.front`: tracked movers and, with the map unknown, the
    #: perceived obstacles); a learned policy that reads the beams itself sets False
    perceives = True
    #: whether :meth:`act_many` decides for many teams at once (an evaluation then runs this
    #: controller's episodes together in the vector env rather than one by one)
    acts_in_batch = False
    #: how long an episode of this controller takes beside the others, for scheduling only: the
    #: evaluator hands the costliest controllers' episodes to its workers first, so that no
    #: worker idles at the end of a run (0: the cheap ones; the Koopman-NMPC 2, the nominal NMPC
    #: 1). Read from the class, never from a built controller; no record depends on it.
    episode_cost = 0

    def __init__(self) -> None:
        self.scenario: Scenario | None = None
        self._stats = ControllerStats()
        #: the perception front of the current episode (None without lidar, or not :attr:`perceives`)
        self.perception: LidarPerception | None = None

    def reset(self, scenario: Scenario | Any, *, seed: int | None = None) -> None:
        """Prepare for an episode: ``scenario`` is the env (any front, wrapped or not, after its
        ``reset``) or its :class:`~koopman_envs.scenario.Scenario`."""
        try:
            scenario = scenario_of(scenario)
        except TypeError as exc:
            raise TypeError(f"{self.name}: reset() {exc}") from None
        scenario = scenario.planner_view()  # without the map's obstacles when it is not known
        self.scenario = scenario
        self._stats = ControllerStats()
        if self.front_end is not None:
            self.front_end.reset(scenario)
        self.perception = None
        if self.perceives and scenario.lidar_beams:
            # imported here: scipy and filterpy cost half a second, which no run without lidar pays
            from controllers.perception.front import LidarPerception

            self.perception = LidarPerception()
            self.perception.reset(scenario)
        self._reset(scenario, seed)

    def act(self, observation: NDArray[np.float64], info: dict[str, Any] | Observed) -> NDArray[np.float64]:
        """The joint command; its wall time is recorded in :meth:`stats` unless ``_act`` records
        its own (an optimizer timing only its solve).

        ``_act`` receives only the observed part of ``info``
        (:meth:`koopman_envs.Observed.from_info`: pose estimates, messages and their ages, lidar
        readings, targets), never the true state. A wrapper in front (``ekf:``, ``safe:``) hands
        on the :class:`~koopman_envs.Observed` it planned from instead of an info."""
        recorded = len(self._stats.solve_times)
        view = self._view(info)
        start = time.perf_counter()
        command = self._act(observation, view)
        self._acted(command, None if len(self._stats.solve_times) > recorded else time.perf_counter() - start)
        return command

    @classmethod
    def act_many(
        cls,
        controllers: Sequence[BaseController],
        observations: Sequence[NDArray[np.float64]],
        infos: Sequence[dict[str, Any]],
    ) -> list[NDArray[np.float64]]:
        """The commands of many teams, ``controllers[i]`` acting on ``observations[i]`` and
        ``infos[i]``, each equal to ``controllers[i].act(observations[i], infos[i])``.

        A controller that can decide for many teams at once (one forward pass of a learned
        policy for all of them) overrides this and sets :attr:`acts_in_batch`, which tells an
        evaluation to run its episodes together
        (:func:`koopman_envs.episodes.batch.run_episodes_in_batch`).
        """
        return [c.act(o, i) for c, o, i in zip(controllers, observations, infos, strict=True)]

    def _view(self, info: dict[str, Any] | Observed) -> Observed:
        """What ``_act`` reads of ``info``: its observed part, over the radio, through the front
        end and the perception."""
        if self.scenario is None:
            raise RuntimeError(f"{self.name}: call reset(scenario) before act()")
        observed = info if isinstance(info, Observed) else Observed.from_info(info)
        if observed.pose_age is not None:
            # a wrapper in front (ekf:, safe:) hands on what it planned from (an Observed, or its
            # dict for a controller of the earlier API); its radio's ages were for its own front
            # end and stay with it, as the dict view of the earlier API (no key for them) left them
            observed = dataclasses.replace(observed, pose_age=None)
        if self.radio_station is not None:
            observed = over_the_radio(observed, self.radio_station, self.scenario.starts)
        front_end = self.front_end
        if front_end is not None:
            observed = front_end.view(observed)
        # a wrapper in front (ekf:, safe:) that perceived hands its perception on: perceive once
        if self.perception is not None and observed.lidar_ranges is not None and not observed.perceived:
            observed = self.perception.view(observed)
            self._stats.extra_times["perception"] = self.perception.times
        if observed.perceived_obstacles is not None:
            self.obstacles_seen(observed.perceived_obstacles)
        return observed

    def _acted(self, command: NDArray[np.float64], seconds: float | None) -> None:
        """Record a decision: its time (None: ``_act`` recorded its own) and the front end's counts."""
        if seconds is not None:
            self._stats.solve_times.append(seconds)
        front_end = self.front_end
        if front_end is not None:
            front_end.sent(command)
            for key, value in front_end.counts().items():  # values, not increments
                self._stats.counts[key] = value
            self._stats.extra_times["estimator"] = front_end.times

    def stats(self) -> ControllerStats:
        return self._stats

    def obstacles_seen(self, obstacles: NDArray[np.float64]) -> bool:
        """The obstacles the lidar has shown so far (the map unknown, ``lidar.map_known=False``),
        (M, 3): x, y, r. They become the scenario's obstacles, which the controller reads each
        period; a controller that prepares its obstacles once at reset extends this hook.

        Returns
        -------
        bool
            Whether they differ from the scenario's until now.
        """
        assert self.scenario is not None  # act() checked it
        obstacles = np.asarray(obstacles, dtype=np.float64).reshape(-1, 3)
        if np.array_equal(obstacles, self.scenario.obstacles):
            return False
        self.scenario = dataclasses.replace(self.scenario, obstacles=obstacles)
        return True

    def _reset(self, scenario: Scenario, seed: int | None) -> None:  # noqa: B027 - optional hook
        """Subclass hook called by :meth:`reset`."""

    @abstractmethod
    def _act(self, observation: NDArray[np.float64], observed: Observed) -> NDArray[np.float64]:
        """Compute the joint command from the observation and what the robots believe."""
