"""Any controller behind the safety filter: ``safe:<name>`` (:func:`wrap`), its statistics."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from controllers.base import BaseController, Controller, ControllerStats, hand_on, take_over_radio
from controllers.movers import observed_mover_radii, observed_movers
from controllers.mpc.margins import chance_tightening
from controllers.safety.barriers import BarrierFilter
from controllers.safety.options import FILTER_OPTION_PREFIX, SafetyOptions
from koopman_envs import Observed
from koopman_envs.scenario import Scenario

__all__ = ["SafetyFilter", "SafetyStats", "wrap"]


@dataclass
class SafetyStats(ControllerStats):
    """Statistics of a filtered controller: the inner controller's, plus the filter's.

    ``solve_times`` is the wall time of each whole decision (inner controller plus filter), so the
    evaluator's solve-time columns rank the filtered controller as it runs; ``iterations``,
    ``failures`` and ``statuses`` are the inner controller's.

    Attributes
    ----------
    filter_times : list of float
        Wall time of the filter alone per decision [s].
    changed : int
        Decisions where the filter changed at least one robot's command.
    changed_robots : int
        Robot-decisions changed (at most N per decision).
    infeasible : int
        Decisions where at least one robot's QP was infeasible (least-violating fallback used).
    barrier_min : float
        Smallest barrier value seen in the episode [m] (negative: a robot was inside a margin).
    inner : ControllerStats or None
        The inner controller's own statistics (its solve times exclude the filter).
    """

    filter_times: list[float] = field(default_factory=list)
    changed: int = 0
    changed_robots: int = 0
    infeasible: int = 0
    barrier_min: float = float("inf")
    inner: ControllerStats | None = None

    def summary(self) -> dict[str, Any]:
        """The base summary plus ``filter_ms_median/p95/max``, ``filter_changed``,
        ``filter_changed_robots``, ``filter_infeasible``, ``filter_barrier_min`` and
        ``inner_ms_median``."""
        times = np.asarray(self.filter_times)
        inner = self.inner.summary() if self.inner is not None else {}
        return {
            **super().summary(),
            "filter_ms_median": 1e3 * float(np.median(times)) if times.size else float("nan"),
            "filter_ms_p95": 1e3 * float(np.percentile(times, 95)) if times.size else float("nan"),
            "filter_ms_max": 1e3 * float(times.max()) if times.size else float("nan"),
            "filter_changed": self.changed,
            "filter_changed_robots": self.changed_robots,
            "filter_infeasible": self.infeasible,
            "filter_barrier_min": self.barrier_min,
            "inner_ms_median": inner.get("solve_ms_median", float("nan")),
            **({"solver": inner["solver"]} if "solver" in inner else {}),
        }


class SafetyFilter(BaseController):
    """Any controller behind a CBF safety filter (see the module docstring).

    Parameters
    ----------
    inner : Controller
        The controller whose commands are filtered (``.inner``). The evaluator calibrates it
        as it would alone (:func:`controllers.base.calibratable` looks down ``.inner``).
    **options
        Fields of :class:`SafetyOptions`: ``gamma``, ``margin``, ``lookahead``, ``omega_weight``,
        ``mover_velocity``.

    Raises
    ------
    ValueError
        An unknown option or a value out of its range (the message names both).
    TypeError
        ``inner`` has no ``act`` / ``reset``.

    Examples
    --------
    >>> ctrl = SafetyFilter(controllers.make("consensus-free"), gamma=2.0, margin=0.05)
    >>> ctrl = controllers.make("safe:consensus-free", safety_margin=0.1)   # the same by name
    """

    _stats: SafetyStats  # set in __init__, and by _reset over the plain one reset() starts with

    def __init__(self, inner: Controller, **options: Any) -> None:
        super().__init__()
        for method in ("reset", "act"):
            if not callable(getattr(inner, method, None)):
                raise TypeError(
                    f"SafetyFilter needs a controller with {method}(); got {type(inner).__name__}"
                )
        self.inner = inner
        # the inner controller's estimator moves in front of the filter: both then act on the
        # same estimate (delay compensated, filtered), and the filter widens its barriers by its
        # covariance
        self.front_end, inner_front_end = getattr(inner, "front_end", None), None
        if self.front_end is not None:
            inner.front_end = inner_front_end  # type: ignore[attr-defined]  # a BaseController's own
        take_over_radio(self, inner)
        self.options = SafetyOptions.from_options(**options)
        self.name = f"safe:{getattr(inner, 'name', type(inner).__name__)}"
        self._filter: BarrierFilter | None = None
        self._stats = SafetyStats()

    def _reset(self, scenario: Scenario, seed: int | None) -> None:
        self.inner.reset(scenario, seed=seed)
        self._filter = BarrierFilter(scenario, self.options)
        self._stats = SafetyStats()

    def obstacles_seen(self, obstacles: NDArray[np.float64]) -> bool:
        """Perceived obstacles (map unknown): the barriers are rebuilt on them."""
        changed = super().obstacles_seen(obstacles)
        if changed:
            assert self.scenario is not None  # set by the base
            self._filter = BarrierFilter(self.scenario, self.options)
        return changed

    @property
    def sensing_radius(self) -> tuple[float, float]:
        """Clearances beyond which obstacles / walls and other robots cannot constrain a robot [m]
        (after ``reset``)."""
        if self._filter is None:
            raise RuntimeError(f"{self.name}: call reset(scenario) first")
        return self._filter.sensing_radius

    def _act(self, observation: NDArray, observed: Observed) -> NDArray[np.float64]:
        start = time.perf_counter()
        command = hand_on(self.inner, observation, observed)
        middle = time.perf_counter()
        assert self._filter is not None  # built by _reset, which act() requires
        covariance = observed.pose_covariance
        widen = (
            None
            if covariance is None
            else chance_tightening(covariance, self.options.chance_risk, observed.n_robots)[0]
        )
        assert self.scenario is not None  # act() checked it
        radii = observed_mover_radii(observed, self.scenario.mover_radius)
        step = self._filter.filter(
            observed.observed_poses,
            command,
            observed_movers(observed),
            widen,
            float(radii.max(initial=self.scenario.mover_radius)),
        )
        end = time.perf_counter()
        stats = self._stats
        stats.solve_times.append(end - start)
        stats.filter_times.append(end - middle)
        stats.changed += bool(step.changed.any())
        stats.changed_robots += int(step.changed.sum())
        stats.infeasible += bool(step.infeasible.any())
        stats.barrier_min = min(stats.barrier_min, step.barrier_min)
        return step.command.reshape(-1)

    def stats(self) -> SafetyStats:
        """This episode's statistics, with the inner controller's iterations, failures and statuses."""
        inner_stats = self.inner.stats()
        self._stats.inner = inner_stats
        self._stats.iterations = list(inner_stats.iterations)
        self._stats.failures = inner_stats.failures
        self._stats.statuses = inner_stats.statuses.copy()
        return self._stats


def wrap(inner_factory: Callable[..., Controller], **options: Any) -> SafetyFilter:
    """Registry wrapper of the ``safe:`` prefix: options named ``safety_<field>`` go to the filter
    (prefix removed), the others to ``inner_factory``.

    >>> wrap(factory("nominal-nmpc"), horizon=10, safety_gamma=1.0)   # = make("safe:nominal-nmpc", ...)
    """
    mine = {
        k[len(FILTER_OPTION_PREFIX) :]: v for k, v in options.items() if k.startswith(FILTER_OPTION_PREFIX)
    }
    theirs = {k: v for k, v in options.items() if not k.startswith(FILTER_OPTION_PREFIX)}
    SafetyOptions.from_options(FILTER_OPTION_PREFIX, **mine)  # errors name the prefixed option the user wrote
    return SafetyFilter(inner_factory(**theirs), **mine)
