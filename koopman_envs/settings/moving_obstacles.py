"""Moving obstacles and people: the setting of the env keyword ``movers``.

Movers are discs that move on their own and do not cooperate with the team. Three behaviours:

``"constant"``
    Straight lines at ``speed``, reflecting off the workspace boundary and the static obstacles
    (the classic "dynamic obstacle" of MPC benchmarks).
``"waypoints"``
    Each mover walks to a random waypoint (drawn so that the straight way there is clear of the
    static obstacles) at a random speed between half and all of ``speed``, pauses there for up to
    ``pause`` seconds, and draws the next one.
``"crowd"``
    Pedestrians with the waypoints' goals whose velocities come from ORCA (optimal reciprocal
    collision avoidance, the RVO2 library through ``pyrvo``, the crowd model of IR-SIM and
    CrowdNav): they avoid each other and the static obstacles and, with ``aware=True``, the
    robots. ``pip install -e '.[crowd]'``; docs/movers.md says why this library.

:mod:`koopman_envs.sim.movers` simulates them. A setting with ``count=0`` draws nothing from any
generator, so it replays an env without the keyword bit for bit.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from numbers import Integral
from typing import Any

import numpy as np

from koopman_envs.checks import check_choice, check_flag, check_int, check_number, did_you_mean
from koopman_envs.layout import MoverEntry
from koopman_envs.params import LIMITS

__all__ = ["MOVER_BEHAVIOURS", "MOVER_FEATURES", "MoverConfig", "parse_movers"]

#: entries per listed mover in a robot's observation block: body-frame dx, dy, vx, vy, surface
#: clearance (koopman_envs.layout.MoverEntry; written by koopman_envs.sim.movers.field.mover_features)
MOVER_FEATURES = len(MoverEntry)

#: the mover behaviours (module docstring)
MOVER_BEHAVIOURS = ("constant", "waypoints", "crowd")


@dataclass(frozen=True)
class MoverConfig:
    """The moving obstacles of every episode (``movers`` keyword).

    Attributes
    ----------
    count : int
        Movers per environment, 0 (none) to ``LIMITS.movers`` (512;
        :class:`~koopman_envs.params.SizeLimits` says why).
    radius : float
        Disc radius of every mover [m] (ours: 0.2, a person's shoulder half-width with margin).
    speed : float
        Speed [m/s]: every constant mover's, the largest of a waypoint leg or a pedestrian
        (ours: 0.3, below the robots' 0.6 m/s limit, so that a robot can get out of the way); at
        most ``LIMITS.mover_speed`` (2 m/s, a brisk walk). Movers are placed ``speed`` x 1 s
        (at least 0.5 m) away from every start and target, so fast movers need room.
    behaviour : str
        One of :data:`MOVER_BEHAVIOURS`.
    aware : bool
        ``"crowd"`` only: the pedestrians see the robots and avoid them too (True) or walk as if
        the robots were not there (False: the robots must do all the avoiding).
    observed : int
        Nearest movers listed in each robot's observation block with ``sensing="state"``
        (relative position and velocity, clearance; absent ones masked), at most
        ``LIMITS.movers``. With lidar the beams hit the movers instead.
    pause : float
        ``"waypoints"`` and ``"crowd"``: longest pause at a waypoint [s] (drawn uniformly), at
        most ``LIMITS.mover_pause`` (an hour).
    tracking : bool
        ``sensing="state"``: the controllers and the observation get the movers as a people
        tracker reports them (True: detected within ``detection_range`` with
        ``detection_noise``, filtered; :mod:`koopman_envs.sim.movers.tracking`), or their exact
        states (False, the behaviour before 0.2). ``info["movers"]`` is the truth either way.
    detection_range : float
        Largest robot-mover distance at which a mover is detected [m] (5: a 2D lidar's useful
        range for legs, as the default lidar's).
    detection_noise : float
        Standard deviation of a detection's position error per axis [m] (0.05: a leg or person
        detector on a 2D lidar at a few metres), at most ``LIMITS.pose_noise``.
    """

    count: int = 0
    radius: float = 0.2
    speed: float = 0.3
    behaviour: str = "constant"
    aware: bool = False
    observed: int = 4
    pause: float = 2.0
    tracking: bool = True
    detection_range: float = 5.0
    detection_noise: float = 0.05

    def __post_init__(self) -> None:
        check_choice("movers.behaviour", self.behaviour, MOVER_BEHAVIOURS)
        if not isinstance(self.aware, (bool, np.bool_)):
            raise ValueError(f"movers.aware={self.aware!r} must be True or False")
        object.__setattr__(self, "aware", bool(self.aware))  # NumPy's booleans too, stored as bool
        checked = {
            "count": check_int("movers.count", self.count, 0, maximum=LIMITS.movers),
            "radius": check_number("movers.radius", self.radius, above=0, note="metres"),
            "speed": check_number(
                "movers.speed", self.speed, at_least=0, at_most=LIMITS.mover_speed, note="m/s"
            ),
            "observed": check_int("movers.observed", self.observed, 0, maximum=LIMITS.movers),
            "pause": check_number(
                "movers.pause", self.pause, at_least=0, at_most=LIMITS.mover_pause, note="seconds"
            ),
            "tracking": check_flag("movers.tracking", self.tracking),
            "detection_range": check_number(
                "movers.detection_range",
                self.detection_range,
                above=0,
                at_most=LIMITS.lidar_range,
                note="metres",
            ),
            # an error the size of the workspace's side is no detection at all (as pose_noise)
            "detection_noise": check_number(
                "movers.detection_noise",
                self.detection_noise,
                at_least=0,
                at_most=LIMITS.pose_noise,
                note="metres",
            ),
        }
        for name, value in checked.items():  # stored in normal form (0 and 0.0 are one setting)
            object.__setattr__(self, name, value)
        if self.aware and self.behaviour != "crowd":
            raise ValueError(
                f"movers.aware=True applies to behaviour='crowd' (a {self.behaviour!r} mover never reacts)"
            )

    @property
    def active(self) -> bool:
        """True when there are movers."""
        return self.count > 0


def parse_movers(name: str, value: Any) -> MoverConfig:
    """The ``movers`` keyword as a :class:`MoverConfig`: an instance, a dict of its fields, a
    number (that many ``"constant"`` movers) or None (no movers).

    Raises
    ------
    ValueError
        An unknown field (with did-you-mean), a bad value, or another type.
    """
    if value is None:
        return MoverConfig()
    if isinstance(value, MoverConfig):
        return value
    # an integer of any kind, NumPy's included (movers=np.int64(3))
    if isinstance(value, Integral) and not isinstance(value, bool):
        return MoverConfig(count=check_int(name, value, 0, maximum=LIMITS.movers))
    fields = [f.name for f in dataclasses.fields(MoverConfig)]
    if isinstance(value, dict):
        unknown = [key for key in value if key not in fields]
        if unknown:
            raise ValueError(
                f"{name} has unknown field {unknown[0]!r}{did_you_mean(unknown[0], fields)}; allowed: {fields}"
            )
        return MoverConfig(**value)
    raise ValueError(
        f"{name}={value!r} must be a dict of {fields}, a MoverConfig, a count of constant movers, or None"
    )
