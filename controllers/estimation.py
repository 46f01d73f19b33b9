"""State estimation in front of any controller: an EKF on every robot's pose (``ekf:`` prefix).

``controllers.make("ekf:nominal-nmpc")`` is the nominal NMPC reading, instead of each robot's raw
localization (``info["observed_poses"]``), the estimate of an extended Kalman filter per robot
that fuses the commands (unicycle prediction over one period) with the noisy pose. It smooths the
white part of the localization noise; a drifting bias it cannot see (nothing measures it).
The estimate replaces the robot's own pose in ``observed_poses`` and on the diagonal of
``known_poses``; team-mates' messages are passed on as they are. Learned policies read the
observation, which the filter does not change, so ``ekf:`` is for the model-based controllers.

We use filterpy's ``ExtendedKalmanFilter`` (maintained again since 2.0, 2026) rather than our own:
its predict/update equations, Joseph-form covariance update and residual hook are tested by its
users; we supply the unicycle model, its Jacobian and an angle-wrapping residual.

Options (prefix ``ekf_`` in the evaluator's syntax, e.g. ``ekf:nominal-nmpc:ekf_position_std=0.1``)
are the fields of :class:`EstimatorOptions`.
"""

from __future__ import annotations

import dataclasses
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from controllers.base import BaseController, Controller, ControllerStats
from koopman_envs.checks import check_int, check_number
from koopman_envs.scenario import Scenario
from koopman_envs.sim.dynamics import wrap_angle
from koopman_envs.suggest import did_you_mean

__all__ = ["ESTIMATOR_OPTION_PREFIX", "EstimatorOptions", "PoseEstimator", "wrap"]

#: prefix of the estimator's options in a wrapped configuration's option list
ESTIMATOR_OPTION_PREFIX = "ekf_"


@dataclass(frozen=True)
class EstimatorOptions:
    """Noise levels the filter assumes (the controller is not told the env's).

    Attributes
    ----------
    position_std : float
        Localization noise of x and y [m] (default: the ``realistic`` preset's 0.03).
    heading_std : float
        Localization noise of the heading [rad].
    process_position_std : float
        Unmodelled motion per period (slip, delay) of x and y [m].
    process_heading_std : float
        Unmodelled turn per period [rad].
    delay : int
        Periods between a command and its action that the prediction assumes (the env's
        ``actuation_delay``, if known).
    """

    position_std: float = 0.03
    heading_std: float = 0.02
    process_position_std: float = 0.01
    process_heading_std: float = 0.02
    delay: int = 0

    @classmethod
    def from_options(cls, prefix: str = "", **options: Any) -> EstimatorOptions:
        """Build from keyword options, each checked; errors name the option as given (with ``prefix``)."""
        allowed = [f.name for f in dataclasses.fields(cls)]
        for key, value in options.items():
            if key not in allowed:
                raise ValueError(
                    f"unknown estimator option {prefix + key!r}{did_you_mean(prefix + key, [prefix + a for a in allowed])}; "
                    f"allowed: {[prefix + a for a in allowed]}"
                )
            if key == "delay":
                check_int(prefix + key, value, 0, note="control periods")
            else:
                check_number(prefix + key, value, above=0)
        return cls(**options)


def _unicycle_ekf(pose: NDArray[np.float64], options: EstimatorOptions, dt: float) -> Any:
    from filterpy.kalman import ExtendedKalmanFilter

    class UnicycleEKF(ExtendedKalmanFilter):  # type: ignore[misc]
        """filterpy's EKF with the unicycle's one-period prediction (explicit Euler, as its Jacobian)."""

        def predict_x(self, u: NDArray[np.float64] | None = None) -> None:
            x, y, theta = np.asarray(self.x, dtype=np.float64)  # type: ignore[has-type]
            v, omega = (0.0, 0.0) if u is None else u
            self.F = np.array(
                [[1.0, 0.0, -v * dt * np.sin(theta)], [0.0, 1.0, v * dt * np.cos(theta)], [0.0, 0.0, 1.0]]
            )
            self.x = np.array(
                [
                    x + v * dt * np.cos(theta),
                    y + v * dt * np.sin(theta),
                    float(wrap_angle(theta + omega * dt)),
                ]
            )

    ekf = UnicycleEKF(dim_x=3, dim_z=3, dim_u=2)
    ekf.x = np.array(pose, dtype=np.float64)
    measurement = np.array([options.position_std, options.position_std, options.heading_std]) ** 2
    ekf.R = np.diag(measurement)
    ekf.P = np.diag(measurement)
    ekf.Q = np.diag(np.array([options.process_position_std] * 2 + [options.process_heading_std]) ** 2)
    return ekf


def _residual(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    out = np.asarray(a, dtype=np.float64) - b
    out[2] = wrap_angle(out[2])
    return out


_IDENTITY = np.eye(3)


class PoseEstimator(BaseController):
    """Any controller behind a per-robot pose EKF (see the module docstring).

    Parameters
    ----------
    inner : Controller
        The controller that receives the estimates.
    **options
        Fields of :class:`EstimatorOptions`.
    """

    def __init__(self, inner: Controller, **options: Any) -> None:
        super().__init__()
        self.inner = inner
        self.options = EstimatorOptions.from_options(**options)
        self.name = f"ekf:{getattr(inner, 'name', type(inner).__name__)}"
        self._filters: list[Any] = []
        self._commands: deque[NDArray[np.float64]] = deque()

    def _reset(self, scenario: Scenario, seed: int | None) -> None:
        self.inner.reset(scenario, seed=seed)
        self._filters = []
        self._commands = deque([np.zeros((scenario.n_robots, 2))] * (self.options.delay + 1))
        self._limits = np.array([scenario.v_max, scenario.omega_max])

    def _estimate(self, observed: NDArray[np.float64]) -> NDArray[np.float64]:
        """One predict (with the command acting in the period that just ended) and update per robot."""
        scenario = self.scenario
        assert scenario is not None  # act() checked it
        if not self._filters:  # the first period: the measurement is the best there is
            self._filters = [_unicycle_ekf(pose, self.options, scenario.dt) for pose in observed]
            return observed.copy()
        acting = self._commands[0]
        estimate = np.empty_like(observed)
        for i, ekf in enumerate(self._filters):
            ekf.predict(u=acting[i])
            ekf.update(observed[i], lambda _x: _IDENTITY, lambda x: x, residual=_residual)
            ekf.x[2] = wrap_angle(ekf.x[2])
            estimate[i] = ekf.x
        return estimate

    def _act(self, observation: NDArray, info: dict[str, Any]) -> NDArray[np.float64]:
        start = time.perf_counter()
        estimate = self._estimate(np.asarray(info["observed_poses"], dtype=np.float64))
        view = dict(info, observed_poses=estimate)
        if "known_poses" in info:
            known = np.array(info["known_poses"], dtype=np.float64)
            n = known.shape[0]
            known[np.arange(n), np.arange(n)] = estimate
            view["known_poses"] = known
        middle = time.perf_counter()
        command = np.asarray(self.inner.act(observation, view), dtype=np.float64)
        self._commands.append(np.clip(command.reshape(-1, 2), -self._limits, self._limits))
        self._commands.popleft()
        self._stats.extra_times.setdefault("estimator", []).append(middle - start)
        return command

    def stats(self) -> ControllerStats:
        """The inner controller's statistics, with the filter's time per period (``estimator``)."""
        inner = self.inner.stats()
        times = self._stats.extra_times.get("estimator", [])
        return dataclasses.replace(inner, extra_times={**inner.extra_times, "estimator": list(times)})


def wrap(inner_factory: Callable[..., Controller], **options: Any) -> PoseEstimator:
    """Registry wrapper of the ``ekf:`` prefix: options named ``ekf_<field>`` go to the filter
    (prefix removed), the others to ``inner_factory``."""
    mine = {
        k[len(ESTIMATOR_OPTION_PREFIX) :]: v
        for k, v in options.items()
        if k.startswith(ESTIMATOR_OPTION_PREFIX)
    }
    theirs = {k: v for k, v in options.items() if not k.startswith(ESTIMATOR_OPTION_PREFIX)}
    EstimatorOptions.from_options(ESTIMATOR_OPTION_PREFIX, **mine)  # errors name the prefixed option
    return PoseEstimator(inner_factory(**theirs), **mine)
