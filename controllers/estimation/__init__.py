"""State estimation in front of any controller: an EKF on every robot's pose, delay compensation
and the estimate's covariance (``ekf:`` prefix).

``controllers.make("ekf:nominal-nmpc")`` is the nominal NMPC reading, instead of each robot's raw
localization (``observed_poses`` of :class:`koopman_envs.Observed`), what a deployed MPC reads:

1. **the filtered pose**: an extended Kalman filter per robot fuses the commands it sent (the
   unicycle's RK4 period, the env's integrator without slip) with the noisy pose. It smooths the
   white part of the localization noise; a drifting bias it cannot see (nothing measures it);
2. **delay compensation** (``delay`` periods of actuation delay, known or identified): the
   commands already sent but not yet acting are run through the same prediction, so the inner
   controller plans from the pose at which its new command will act. Without noise or slip this
   prediction is exact (tests/test_estimation.py, k = 1..4);
3. **the covariance** of that pose, ``pose_covariance`` (N, 3, 3), grown by the process
   noise over the compensated periods: controllers with margins tighten them by it (the NMPCs'
   ``chance_risk``).

The estimate replaces the robot's own pose in ``observed_poses`` and on the diagonal of
``known_poses``; team-mates' messages are passed on as they are. Learned policies read the
observation, which the filter does not change, so ``ekf:`` is for the model-based controllers.

We use filterpy's ``ExtendedKalmanFilter`` (maintained again since 2.0, 2026) rather than our own:
its predict/update equations, Joseph-form covariance update and residual hook are tested by its
users; we supply the unicycle model, its Jacobian and an angle-wrapping residual.

Options (prefix ``ekf_`` in the evaluator's syntax, e.g. ``ekf:nominal-nmpc:ekf_position_std=0.1``)
are the fields of :class:`EstimatorOptions`.
"""

from controllers.estimation.front_end import (
    ABLATIONS,
    ESTIMATORS,
    FRONT_END_LEVERS,
    LEVERS,
    MAX_MESSAGE_AGE,
    PoseEstimator,
    PoseFrontEnd,
    auto_front_end,
    check_estimator,
    estimator_choices,
    front_end_for,
    front_end_option,
    wrap,
)
from controllers.estimation.identification import HEADING_FLOOR, POSITION_FLOOR, MotionIdentifier
from controllers.estimation.options import AUTO, ESTIMATOR_OPTION_PREFIX, EstimatorOptions

__all__ = [
    "ABLATIONS",
    "AUTO",
    "ESTIMATORS",
    "ESTIMATOR_OPTION_PREFIX",
    "FRONT_END_LEVERS",
    "HEADING_FLOOR",
    "LEVERS",
    "MAX_MESSAGE_AGE",
    "POSITION_FLOOR",
    "EstimatorOptions",
    "MotionIdentifier",
    "PoseEstimator",
    "PoseFrontEnd",
    "auto_front_end",
    "check_estimator",
    "estimator_choices",
    "front_end_for",
    "front_end_option",
    "wrap",
]
