"""The pose front-end: the EKF per robot, delay compensation, the estimate's covariance, and
``ekf:<name>`` (:func:`wrap`); the package docstring says what each does."""

from __future__ import annotations

import dataclasses
import math
import time
from collections import deque
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from controllers.base import BaseController, Controller, ControllerStats, hand_on, take_over_radio
from controllers.estimation.identification import MotionIdentifier
from controllers.estimation.options import AUTO, ESTIMATOR_OPTION_PREFIX, EstimatorOptions
from koopman_envs import Observed, rk4_pose, wrap_angle, wrap_scalar
from koopman_envs.checks import check_choice
from koopman_envs.scenario import Scenario
from koopman_envs.settings import UNCERTAINTY_PRESETS

__all__ = [
    "ABLATIONS",
    "ESTIMATORS",
    "LEVERS",
    "PoseEstimator",
    "PoseFrontEnd",
    "auto_front_end",
    "check_estimator",
    "estimator_choices",
    "front_end_for",
    "front_end_option",
    "wrap",
]

#: the model-based controllers' ``estimator`` option (:func:`front_end_for`): what stands between
#: the robots' localization and the planner. ``"auto"``: everything identified online;
#: ``"realistic"``: the team's datasheet held at the ``realistic`` preset's values (one period of
#: delay, 3 cm and 0.02 rad of noise) whatever the team really has, the mis-specified case;
#: ``"none"``: nothing, as in the paper
ESTIMATORS = (AUTO, "realistic", "none")
#: the parts of a deployed MPC that the ``ablate`` option switches off one at a time: the filter
#: (``"estimation"``: the measured poses are used as they are, with the measurement noise as
#: their covariance), the prediction through the commands already sent (``"delay_compensation"``),
#: the chance-constrained margins (``"tightening"``) and holding still near the goal
#: (``"settling"``); the last two belong to the NMPCs
LEVERS = ("estimation", "delay_compensation", "tightening", "settling")
#: the values of ``ablate``: no lever off, or one
ABLATIONS = ("none", *LEVERS)
#: the levers that live in the front-end alone, all that a controller without margins or a plan
#: to settle (consensus, the classic baselines) can switch off
FRONT_END_LEVERS = ("estimation", "delay_compensation")
#: the oldest pose heard over the radio [periods] that the front-end carries forward through the
#: commands sent since (:meth:`PoseFrontEnd.view`, ``pose_age``); an older one is carried forward
#: this far only
MAX_MESSAGE_AGE = 30


def _predict_pose(pose: NDArray[np.float64], command: NDArray[np.float64], dt: float) -> NDArray[np.float64]:
    """One period of the unicycle under ``command`` (RK4, no slip: the env's integrator), heading wrapped."""
    x, y, theta = rk4_pose(
        float(pose[0]),
        float(pose[1]),
        float(pose[2]),
        float(command[0]),
        float(command[1]),
        0.0,
        0.0,
        0.0,
        dt,
    )
    return np.array([x, y, wrap_scalar(theta)])


def _jacobian(pose: NDArray[np.float64], command: NDArray[np.float64], dt: float) -> NDArray[np.float64]:
    """d(next pose)/d(pose) of one period (explicit Euler's: the covariance needs no more)."""
    v, theta = float(command[0]), float(pose[2])
    return np.array(
        [[1.0, 0.0, -v * dt * math.sin(theta)], [0.0, 1.0, v * dt * math.cos(theta)], [0.0, 0.0, 1.0]]
    )


def _measurement_noise(position_std: float, heading_std: float) -> NDArray[np.float64]:
    # a floor keeps R invertible when one part is identified as exact
    return np.diag(np.maximum([position_std, position_std, heading_std], 1e-4) ** 2)


def _unicycle_ekf(
    pose: NDArray[np.float64], options: EstimatorOptions, noise: tuple[float, float], dt: float
) -> Any:
    from filterpy.kalman import ExtendedKalmanFilter

    class UnicycleEKF(ExtendedKalmanFilter):  # type: ignore[misc]
        """filterpy's EKF with the unicycle's one-period prediction (RK4 mean, Euler Jacobian)."""

        def predict_x(self, u: NDArray[np.float64] | None = None) -> None:
            command = np.zeros(2) if u is None else np.asarray(u, dtype=np.float64)
            pose = np.asarray(self.x, dtype=np.float64)  # type: ignore[has-type]
            self.F = _jacobian(pose, command, dt)
            self.x = _predict_pose(pose, command, dt)

    ekf = UnicycleEKF(dim_x=3, dim_z=3, dim_u=2)
    ekf.x = np.array(pose, dtype=np.float64)
    ekf.R = _measurement_noise(*noise)
    ekf.P = ekf.R.copy()
    ekf.Q = _process_noise(options)
    return ekf


def _process_noise(options: EstimatorOptions) -> NDArray[np.float64]:
    return np.diag(np.array([options.process_position_std] * 2 + [options.process_heading_std]) ** 2)


def _residual(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    out = np.asarray(a, dtype=np.float64) - b
    out[2] = wrap_angle(out[2])
    return out


_IDENTITY = np.eye(3)


class PoseFrontEnd:
    """What a deployed MPC has between the localization and the planner: the filter, delay
    compensation and the covariance (see the module docstring), for any controller.

    :meth:`view` turns the observed part of an ``info`` into what the controller should plan
    from; :meth:`sent` records the command it sent. :class:`PoseEstimator` (``ekf:``) puts one in
    front of any controller; the model-based controllers carry their own
    (:attr:`controllers.base.BaseController.front_end`, their ``estimator`` option).

    Parameters
    ----------
    **options
        Fields of :class:`EstimatorOptions`.
    """

    def __init__(self, **options: Any) -> None:
        self.options = EstimatorOptions.from_options(**options)
        self.scenario: Scenario | None = None
        self._filters: list[Any] = []
        self._sent: deque[NDArray[np.float64]] = deque()
        #: the pose estimate of the last view, before the delay compensation (N, 3)
        self.filtered: NDArray[np.float64] = np.zeros((0, 3))
        self._identifier: MotionIdentifier | None = None
        #: the front-end's own time per period [s]
        self.times: list[float] = []

    def reset(self, scenario: Scenario) -> None:
        """Start an episode on ``scenario``."""
        self.scenario = scenario
        self._filters = []
        self.times = []
        options = self.options
        longest = options.max_delay if options.delay == AUTO else int(options.delay)
        # the commands sent, newest last; the env's queue starts with zero commands too (long
        # enough to carry a pose heard over the radio forward, MAX_MESSAGE_AGE)
        size = longest + MAX_MESSAGE_AGE + 1
        self._sent = deque([np.zeros((scenario.n_robots, 2))] * size, maxlen=size)
        identify = AUTO in (options.delay, options.position_std, options.heading_std)
        self._identifier = (
            MotionIdentifier(scenario.n_robots, options.max_delay, scenario.dt) if identify else None
        )
        self._limits = np.array([scenario.v_max, scenario.omega_max])

    @property
    def delay(self) -> int:
        """The delay the prediction assumes now [periods]: the option, or the identified one
        (0 while :class:`~controllers.estimation.identification.MotionIdentifier` cannot tell yet)."""
        if self.options.delay != AUTO:
            return int(self.options.delay)
        assert self._identifier is not None  # made by reset for "auto"
        return self._identifier.delay or 0

    @property
    def noise(self) -> tuple[float, float]:
        """The localization noise the filter assumes now (position [m], heading [rad]): the
        options, or the identified levels (0 while unknown or below the floor)."""
        options = self.options
        identified = self._identifier.noise_levels() if self._identifier is not None else None
        levels = identified or (0.0, 0.0)
        position = levels[0] if options.position_std == AUTO else float(options.position_std)
        heading = levels[1] if options.heading_std == AUTO else float(options.heading_std)
        return position, heading

    def _estimate(
        self, observed: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
        """One predict (with the command acting in the period that just ended) and update per
        robot: the filtered poses (N, 3) and their covariances (N, 3, 3). While there is no noise
        to filter (identified as none), the measured poses as they are and no covariance."""
        scenario = self.scenario
        assert scenario is not None  # act() checked it
        noise = self.noise
        if noise == (0.0, 0.0) and not self._filters:  # exact localization (so far): nothing to filter
            return observed.copy(), None
        if not self.options.filter_poses:  # the ablation's "estimation" lever: no filter
            return observed.copy(), np.repeat(_measurement_noise(*noise)[None], observed.shape[0], axis=0)
        if not self._filters:
            # the first period with noise: the measurement is the best there is
            self._filters = [_unicycle_ekf(pose, self.options, noise, scenario.dt) for pose in observed]
            return observed.copy(), np.stack([np.array(ekf.P, dtype=np.float64) for ekf in self._filters])
        acting = self._sent[-1 - self.delay]  # sent `delay` periods before the period that just ended
        measurement = _measurement_noise(*noise)
        estimate = np.empty_like(observed)
        for i, ekf in enumerate(self._filters):
            ekf.R = measurement  # an identified level is refined every period
            ekf.predict(u=acting[i])
            ekf.update(observed[i], lambda _x: _IDENTITY, lambda x: x, residual=_residual)
            ekf.x[2] = wrap_angle(ekf.x[2])
            estimate[i] = ekf.x
        return estimate, np.stack([np.array(ekf.P, dtype=np.float64) for ekf in self._filters])

    def _compensate(
        self, poses: NDArray[np.float64], covariances: NDArray[np.float64] | None
    ) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
        """The poses (and covariances) at which a command sent now will act: propagated through
        the ``delay`` commands already sent (the unicycle, no slip; the covariance grows by the
        process noise each period). The identity at ``delay=0`` or ``compensate_delay=False``."""
        delay = self.delay
        if delay == 0 or not self.options.compensate_delay:
            return poses, covariances
        scenario = self.scenario
        assert scenario is not None  # act() checked it
        # exact localization: the prediction's own uncertainty only, grown from zero
        covariances = np.zeros((poses.shape[0], 3, 3)) if covariances is None else covariances.copy()
        poses = poses.copy()
        q = _process_noise(self.options)
        for queued in list(self._sent)[len(self._sent) - delay :]:  # oldest first: as they will act
            for i in range(poses.shape[0]):
                f = _jacobian(poses[i], queued[i], scenario.dt)
                poses[i] = _predict_pose(poses[i], queued[i], scenario.dt)
                covariances[i] = f @ covariances[i] @ f.T + q
        return poses, covariances

    def _carried_forward(self, poses: NDArray[np.float64], ages: NDArray[np.int64]) -> NDArray[np.float64]:
        """``poses`` with each row measured ``ages[i] > 0`` periods ago predicted to now through
        the commands that acted since (the unicycle, no slip): a late message's pose is where the
        robot was, not where it is."""
        scenario = self.scenario
        assert scenario is not None  # view() checked it
        out = poses.copy()
        sent = list(self._sent)
        for i in np.flatnonzero(ages > 0):
            for k in range(min(int(ages[i]), MAX_MESSAGE_AGE) - 1, -1, -1):  # oldest first
                out[i] = _predict_pose(out[i], sent[-1 - self.delay - k][i], scenario.dt)
        return out

    def view(self, observed: Observed) -> Observed:
        """``observed`` as the controller should plan from it, a new value: the estimate at which
        the next command acts in ``observed_poses`` and on the diagonal of ``known_poses``, and
        its covariance in ``pose_covariance`` (left as it was while there is none)."""
        if self.scenario is None:
            raise RuntimeError("PoseFrontEnd: call reset(scenario) before view()")
        start = time.perf_counter()
        measured = observed.observed_poses
        ages = observed.pose_age  # a central controller's team heard over the radio
        fresh = None if ages is None else ages == 0
        if ages is not None and fresh is not None and not fresh.all():
            measured = self._carried_forward(measured, ages)
        if self._identifier is not None:
            self._identifier.observe(measured, fresh)
        filtered, filtered_covariance = self._estimate(measured)
        #: the pose estimate of now, before the delay compensation carries it forward (N, 3)
        self.filtered = filtered
        estimate, covariance = self._compensate(filtered, filtered_covariance)
        known = np.array(observed.known_poses, dtype=np.float64)
        n = known.shape[0]
        known[np.arange(n), np.arange(n)] = estimate
        view = dataclasses.replace(
            observed,
            observed_poses=estimate,
            known_poses=known,
            pose_covariance=observed.pose_covariance if covariance is None else covariance,
        )
        self.times.append(time.perf_counter() - start)
        return view

    def acting(self) -> NDArray[np.float64]:
        """The command (N, 2) that acted in the period that just ended: the one sent ``delay``
        periods before it (what moved the robots from the last estimate to this one)."""
        return self._sent[-1 - self.delay]

    def sent(self, command: NDArray[np.float64]) -> None:
        """Record the joint command sent this period ((2N,) or (N, 2); clipped as the robots clip it)."""
        sent = np.clip(np.asarray(command, dtype=np.float64).reshape(-1, 2), -self._limits, self._limits)
        self._sent.append(sent)
        if self._identifier is not None:
            self._identifier.sent(sent)

    def counts(self) -> dict[str, int]:
        """What it identified so far: ``identified_delay`` (-1 while the data cannot tell),
        ``identified_position_std_mm`` and ``identified_heading_std_mrad`` (once the delay is
        known); empty when it identifies nothing."""
        if self._identifier is None:
            return {}
        identified = self._identifier.delay
        out = {"identified_delay": -1 if identified is None else identified}
        noise = self._identifier.noise_levels()
        if noise is not None:  # in millimetres and milliradians: the counts are integers
            out["identified_position_std_mm"] = round(1e3 * noise[0])
            out["identified_heading_std_mrad"] = round(1e3 * noise[1])
        return out


def auto_front_end() -> PoseFrontEnd:
    """The front-end of the model-based controllers' ``estimator="auto"``: delay and noise
    identified online, a no-op on a team without either."""
    return PoseFrontEnd(delay=AUTO, position_std=AUTO, heading_std=AUTO)


def check_estimator(estimator: Any, ablate: Any = "none", levers: tuple[str, ...] = LEVERS) -> None:
    """Raise ``ValueError`` naming a bad ``estimator`` (one of :data:`ESTIMATORS`) or ``ablate``
    (``"none"`` or one of ``levers``, the controller's; a lever needs an estimator)."""
    check_choice("estimator", estimator, ESTIMATORS)
    check_choice("ablate", ablate, ("none", *levers))
    if ablate != "none" and estimator == "none":
        raise ValueError(
            f"ablate={ablate!r} switches off a lever of an estimator, and estimator='none' has none"
        )


def front_end_for(estimator: str, ablate: str = "none") -> PoseFrontEnd | None:
    """The front-end of a model-based controller's ``estimator`` option (:data:`ESTIMATORS`),
    with the ``ablate`` lever of the front-end switched off (:data:`LEVERS`: ``"estimation"``,
    ``"delay_compensation"``; the others act in the controller). None for ``"none"``."""
    check_estimator(estimator, ablate)
    if estimator == "none":
        return None
    if estimator == AUTO:
        options: dict[str, Any] = dict(delay=AUTO, position_std=AUTO, heading_std=AUTO)
    else:  # a datasheet: a preset's values, held whatever the team really has
        preset = UNCERTAINTY_PRESETS[estimator]
        options = dict(
            delay=preset.actuation_delay,
            position_std=preset.pose_noise.xy,
            heading_std=preset.pose_noise.heading,
        )
    options["filter_poses"] = ablate != "estimation"
    options["compensate_delay"] = ablate != "delay_compensation"
    return PoseFrontEnd(**options)


def estimator_choices(levers: tuple[str, ...] = FRONT_END_LEVERS) -> dict[str, tuple[str, ...]]:
    """The allowed values of the ``estimator`` and ``ablate`` options of a controller whose
    levers are ``levers`` (for its ``OPTION_CHOICES``, :mod:`controllers.option_spec`)."""
    return {"estimator": ESTIMATORS, "ablate": ("none", *levers)}


def front_end_option(
    estimator: str, ablate: str = "none", levers: tuple[str, ...] = FRONT_END_LEVERS
) -> PoseFrontEnd | None:
    """The front-end of a controller's ``estimator`` and ``ablate`` options, checked against the
    controller's ``levers`` first (``ValueError`` naming a bad value): the one routine behind the
    option in consensus and the classic baselines."""
    check_estimator(estimator, ablate, levers=levers)
    return front_end_for(estimator, ablate)


class PoseEstimator(BaseController):
    """Any controller behind a :class:`PoseFrontEnd` (``ekf:``; see the module docstring). The
    controller's own front-end, if it has one, is switched off: this one replaces it.

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
        if getattr(inner, "front_end", None) is not None:
            inner.front_end = None  # type: ignore[attr-defined]  # a BaseController's own
        take_over_radio(self, inner)
        self.estimator = PoseFrontEnd(**options)
        self.options = self.estimator.options
        self.name = f"ekf:{getattr(inner, 'name', type(inner).__name__)}"

    def _reset(self, scenario: Scenario, seed: int | None) -> None:
        self.inner.reset(scenario, seed=seed)
        self.estimator.reset(scenario)

    @property
    def delay(self) -> int:
        """The delay its prediction assumes now (:attr:`PoseFrontEnd.delay`)."""
        return self.estimator.delay

    @property
    def noise(self) -> tuple[float, float]:
        """The noise its filter assumes now (:attr:`PoseFrontEnd.noise`)."""
        return self.estimator.noise

    @property
    def _identifier(self) -> MotionIdentifier | None:
        return self.estimator._identifier

    def _act(self, observation: NDArray, observed: Observed) -> NDArray[np.float64]:
        # (act() applied the inner controller's radio, which this wrapper took over)
        command = np.asarray(
            hand_on(self.inner, observation, self.estimator.view(observed)), dtype=np.float64
        )
        self.estimator.sent(command)
        return command

    def stats(self) -> ControllerStats:
        """The inner controller's statistics, with the front-end's time per period
        (``estimator``) and what it identified (:meth:`PoseFrontEnd.counts`)."""
        inner = self.inner.stats()
        counts = inner.counts.copy()
        for key, value in self.estimator.counts().items():  # values, not increments
            counts[key] = value
        return dataclasses.replace(
            inner, extra_times={**inner.extra_times, "estimator": list(self.estimator.times)}, counts=counts
        )


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
