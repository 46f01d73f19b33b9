"""What a controller may read: the one definition of the observed part of an ``info``.

An env's ``info`` holds the true state (``poses``, ``distances``, collision flags, ...) for
evaluation and for users, beside what the robots believe (:meth:`NavigationEngine.observed_info
<koopman_envs.builder.engine.NavigationEngine.observed_info>`). A controller that is to face the runtime
uncertainty honestly reads only :data:`OBSERVED_KEYS`; every built-in controller receives
``observed_view(info)`` from :meth:`controllers.base.BaseController.act`, so none can read the truth
by accident, and tests/test_observed_view.py hands them poisoned true fields to prove it.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["DERIVED_KEYS", "OBSERVED_KEYS", "SENSED_KEYS", "observed_view"]

#: The info keys an env writes for its controllers: every robot's own pose estimate, what each
#: robot has heard of its team-mates and how old it is, the lidar readings, the targets (a
#: robot's goal is given, not sensed) and, with movers and ``sensing="state"``, the tracked
#: movers (x, y, vx, vy) and which of them have a track (``mover_tracked``).
SENSED_KEYS = (
    "observed_poses",
    "known_poses",
    "message_age",
    "lidar_ranges",
    "targets",
    "observed_movers",
    "mover_tracked",
)
#: The keys a controller's own front-ends write and hand on to the controller they stand in front
#: of, never an env: an estimator's ``pose_covariance`` (N, 3, 3) (``ekf:``), and the lidar
#: perception's ``mover_covariance``, ``mover_radii``, ``perceived_obstacles`` and
#: ``obstacle_covariance`` (``controllers.perception.front``; under lidar it also writes
#: ``observed_movers``, its tracks).
DERIVED_KEYS = (
    "pose_covariance",
    "mover_covariance",
    "mover_radii",
    "perceived_obstacles",
    "obstacle_covariance",
)
#: The info keys a controller may read.
OBSERVED_KEYS = SENSED_KEYS + DERIVED_KEYS


def observed_view(info: dict[str, Any]) -> dict[str, Any]:
    """The observed keys of ``info`` (those present), without the true state, plus what a
    controller of the earlier API reads: ``poses`` (an alias of ``observed_poses``) and
    ``distances`` (from those estimates to the targets).

    An info without ``observed_poses`` (written by hand, as in ``ctrl.act(obs, {"poses":
    poses})``) is one of perfect information: its ``poses`` are then every robot's estimate and
    every team-mate's message, of age 0. Every KoopNav env's info has ``observed_poses``, so
    this never reads the truth of an env.
    """
    view = {key: info[key] for key in OBSERVED_KEYS if key in info}
    if "observed_poses" not in view and "poses" in info:
        poses = np.asarray(info["poses"], dtype=np.float64)
        n = poses.shape[0]
        view["observed_poses"] = poses
        view.setdefault("known_poses", np.broadcast_to(poses[None], (n, n, 3)))
        view.setdefault("message_age", np.zeros((n, n), dtype=np.int64))
    if "observed_poses" in view:
        # a controller written before the observed keys existed reads info["poses"] and
        # info["distances"]: in the view they are the robots' beliefs, so it faces the uncertainty
        # too (and without uncertainty they equal the truth bit for bit: the env's formula)
        poses = np.asarray(view["observed_poses"], dtype=np.float64)
        view["poses"] = poses
        if "targets" in view:
            targets = np.asarray(view["targets"], dtype=np.float64)
            dx, dy = targets[..., 0] - poses[..., 0], targets[..., 1] - poses[..., 1]
            view["distances"] = np.sqrt(dx * dx + dy * dy)
    return view
