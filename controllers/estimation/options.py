"""The options of the pose front-end (:class:`controllers.estimation.PoseFrontEnd`): the noise
levels and delay it assumes, and the levers it can switch off, each checked on construction."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from koopman_envs.checks import check_int, check_number, checked_options
from koopman_envs.params import LIMITS

__all__ = ["AUTO", "ESTIMATOR_OPTION_PREFIX", "EstimatorOptions"]

#: prefix of the estimator's options in a wrapped configuration's option list (``ekf:``)
ESTIMATOR_OPTION_PREFIX = "ekf_"

#: ``delay="auto"``: identify the actuation delay online
AUTO = "auto"


@dataclass(frozen=True)
class EstimatorOptions:
    """Noise levels the filter assumes (the controller is not told the env's).

    Attributes
    ----------
    position_std : float or "auto"
        Localization noise of x and y [m] (default: the ``realistic`` preset's 0.03), or
        ``"auto"``: identified online (:class:`~controllers.estimation.identification.MotionIdentifier`).
        While the identified noise is below its floor (none) the measured poses are passed on
        as they are, with no covariance: a team that localizes exactly is driven exactly as
        without the estimator.
    heading_std : float or "auto"
        Localization noise of the heading [rad], or ``"auto"`` (identified with the position's).
    process_position_std : float
        Unmodelled motion per period (slip, delay) of x and y [m].
    process_heading_std : float
        Unmodelled turn per period [rad].
    delay : int or "auto"
        Periods between a command and its action that the prediction assumes: the env's
        ``actuation_delay`` if known (the datasheet), or ``"auto"``: identified online from how
        the measured motion follows the commands (:class:`DelayIdentifier`; 0 until it is sure).
    max_delay : int
        With ``delay="auto"``: the largest delay considered [periods] (default 10).
    compensate_delay : bool
        Hand the inner controller the pose predicted through the ``delay`` commands already sent
        (where its new command will act) instead of the filtered pose now (default True; a no-op
        at ``delay=0``).
    filter_poses : bool
        Filter the measured poses (default True). False: the measured poses are used as they
        are, with the measurement noise (the options' or the identified) as their covariance
        (the ``"estimation"`` lever of the ablation).
    """

    position_std: float | str = 0.03
    heading_std: float | str = 0.02
    process_position_std: float = 0.01
    process_heading_std: float = 0.02
    delay: int | str = 0
    max_delay: int = 10
    compensate_delay: bool = True
    filter_poses: bool = True

    @classmethod
    def from_options(cls, prefix: str = "", **options: Any) -> EstimatorOptions:
        """Build from keyword options, each checked; errors name the option as given (with ``prefix``)."""
        return checked_options(cls, "estimator", prefix, options, cls.check)

    @staticmethod
    def check(key: str, value: Any, prefix: str = "") -> None:
        """Raise ``ValueError`` naming option ``prefix + key`` when ``value`` is not allowed."""
        if key == "delay":
            if value != AUTO:
                check_int(
                    prefix + key,
                    value,
                    0,
                    maximum=LIMITS.actuation_delay,
                    note=f"control periods, or {AUTO!r}",
                )
        elif key == "max_delay":
            check_int(prefix + key, value, 1, maximum=LIMITS.actuation_delay, note="control periods")
        elif key in ("position_std", "heading_std") and value == AUTO:
            return
        elif key in ("compensate_delay", "filter_poses"):
            if not isinstance(value, (bool, np.bool_)):
                raise ValueError(f"{prefix + key}={value!r} must be True or False")
        else:
            check_number(prefix + key, value, above=0)
