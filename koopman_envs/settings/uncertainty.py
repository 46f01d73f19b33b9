"""Runtime uncertainty beyond wheel slip: what robots sense, what they hear, when commands act.

The settings of the env keywords ``pose_noise``, ``sensing``/``lidar``, ``comm``,
``actuation_delay`` and the named presets of ``uncertainty`` are defined here, each as a frozen
dataclass that checks itself; :mod:`koopman_envs.sim.perception` simulates them and
:mod:`koopman_envs.sim.lidar` casts the beams.

Every field's zero (or infinite range) is the perfect case, and a setting at its perfect value
draws nothing from any generator, so ``pose_noise=0`` replays an env without the keyword bit for
bit. The preset numbers and their sources are in :data:`UNCERTAINTY_PRESETS`.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from numbers import Real
from typing import Any

from koopman_envs.checks import check_flag, check_int, check_number, did_you_mean
from koopman_envs.params import LIMITS

__all__ = [
    "CommConfig",
    "LidarConfig",
    "PoseNoise",
    "SENSING_MODES",
    "UNCERTAINTY_PRESETS",
    "UncertaintyPreset",
    "parse_setting",
]

#: how the robots observe obstacles, from the known map ("state") or through range beams only ("lidar")
SENSING_MODES = ("state", "lidar")
#: narrowest lidar field of view [rad] (ours: a milliradian; the beam caster divides by the
#: beams' spacing, which a denormal field of view rounds to 0)
MIN_LIDAR_FOV = 1e-3


@dataclass(frozen=True)
class PoseNoise:
    """Localization error of every robot's estimate of its own pose.

    observed = truth + bias + white noise, per robot and period; the bias starts at 0 each
    episode and follows a random walk (a localizer drifting between corrections).

    Attributes
    ----------
    xy : float
        Standard deviation of the white noise on x and on y [m].
    heading : float
        Standard deviation of the white noise on the heading [rad].
    drift_xy : float
        Random-walk rate of the x and y bias [m / sqrt(s)]: after t seconds its std is
        ``drift_xy * sqrt(t)``.
    drift_heading : float
        Random-walk rate of the heading bias [rad / sqrt(s)].
    """

    xy: float = 0.0
    heading: float = 0.0
    drift_xy: float = 0.0
    drift_heading: float = 0.0

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):  # checked, and stored as float (0 and 0.0 are one setting)
            value = check_number(
                f"pose_noise.{f.name}", getattr(self, f.name), at_least=0, at_most=LIMITS.pose_noise
            )
            object.__setattr__(self, f.name, value)

    @property
    def active(self) -> bool:
        """True when any field is non-zero (then the env draws noise)."""
        return any(getattr(self, f.name) > 0 for f in dataclasses.fields(self))


@dataclass(frozen=True)
class LidarConfig:
    """A planar range sensor on every robot (``sensing="lidar"``).

    Beams start at the robot's centre and read the distance to the first surface they meet:
    an obstacle, another robot or the workspace boundary, up to ``range``.

    Attributes
    ----------
    beams : int
        Beams per scan, 1 to ``LIMITS.lidar_beams`` (4096; :class:`~koopman_envs.params.SizeLimits`).
    fov : float
        Field of view [rad], in [:data:`MIN_LIDAR_FOV`, 2 pi]: the beams span it evenly, centred on the heading
        (a full circle spaces them 2 pi / beams apart, starting straight ahead).
    range : float
        Largest reading [m], at most ``LIMITS.lidar_range`` (100 m); a beam that meets nothing reads it.
    noise : float
        Standard deviation of the Gaussian error added to each reading [m] (clipped to [0, range]).
    dropout : float
        Probability that a beam returns nothing this period (it reads ``range``).
    map_known : bool
        Whether the planners have the map's obstacles (``True``: the building's map, as the
        paper's controllers); ``False``: they know only what the beams show
        (``env.unwrapped.scenario.planner_view()`` holds no obstacle; docs/perception.md).
        The robots' physics and scoring use the true map either way.
    """

    beams: int = 32
    fov: float = 2 * math.pi
    range: float = 5.0
    noise: float = 0.0
    dropout: float = 0.0
    map_known: bool = True

    def __post_init__(self) -> None:
        checked = {
            "beams": check_int("lidar.beams", self.beams, 1, maximum=LIMITS.lidar_beams),
            "fov": check_number("lidar.fov", self.fov, above=0, at_most=2 * math.pi, note="(0, 2 pi] rad"),
            "range": check_number(
                "lidar.range", self.range, above=0, at_most=LIMITS.lidar_range, note="metres"
            ),
            "noise": check_number("lidar.noise", self.noise, at_least=0),
            "dropout": check_number("lidar.dropout", self.dropout, at_least=0, at_most=1),
            "map_known": check_flag("lidar.map_known", self.map_known),
        }
        if checked["fov"] < MIN_LIDAR_FOV:  # the beams' spacing would round to 0 (a division by it)
            raise ValueError(
                f"lidar.fov={self.fov!r} is narrower than {MIN_LIDAR_FOV:g} rad; allowed: "
                f"[{MIN_LIDAR_FOV:g}, 2 pi] rad"
            )
        for name, value in checked.items():  # stored in normal form (0 and 0.0 are one setting)
            object.__setattr__(self, name, value)

    @property
    def random(self) -> bool:
        """True when readings draw noise or dropouts."""
        return self.noise > 0 or self.dropout > 0


@dataclass(frozen=True)
class CommConfig:
    """The team's radio: what a robot knows of its team-mates is the last message it received.

    Every period each robot broadcasts its own pose estimate. The message sent at period t
    reaches team-mate i at period t + ``latency`` unless it is lost (probability ``drop``, per
    message and receiver, independently) or the two robots were more than ``range`` apart when
    it was sent.

    Attributes
    ----------
    latency : int
        Delivery delay in control periods, 0 to ``LIMITS.latency`` (100;
        :class:`~koopman_envs.params.SizeLimits`).
    drop : float
        Loss probability of each message, in [0, 1].
    range : float
        Largest sender-receiver distance [m] at which a message arrives (``inf``: everywhere).
    """

    latency: int = 0
    drop: float = 0.0
    range: float = math.inf

    def __post_init__(self) -> None:
        object.__setattr__(
            self,
            "latency",
            check_int("comm.latency", self.latency, 0, maximum=LIMITS.latency, note="control periods"),
        )
        object.__setattr__(self, "drop", check_number("comm.drop", self.drop, at_least=0, at_most=1))
        # any real number, NumPy's too: np.float32(np.inf) is the unlimited range as well
        unlimited = (
            isinstance(self.range, Real) and not isinstance(self.range, bool) and self.range == math.inf
        )
        if not unlimited:
            object.__setattr__(
                self, "range", check_number("comm.range", self.range, above=0, note="metres, or inf")
            )
        else:
            object.__setattr__(self, "range", math.inf)

    @property
    def perfect(self) -> bool:
        """True for instant, lossless, unlimited messages (the team shares its estimates at once)."""
        return self.latency == 0 and self.drop == 0 and self.range == math.inf


@dataclass(frozen=True)
class UncertaintyPreset:
    """One named combination of the uncertainty keywords (see :data:`UNCERTAINTY_PRESETS`)."""

    slip: str
    pose_noise: PoseNoise
    comm: CommConfig
    actuation_delay: int
    lidar: LidarConfig
    source: str


#: The ``uncertainty`` presets. Sources of the numbers (ours, rounded to the control period of 0.1 s):
#: localization of an indoor robot with a 2D lidar and AMCL is typically within 2-5 cm and 1-3 deg
#: (ROS navigation tuning reports; "realistic" 3 cm / 1.1 deg, "harsh" 10 cm / 2.9 deg with a drifting
#: bias as between scan-match corrections); indoor Wi-Fi one-way latency of ROS messages is 5-50 ms
#: with spikes past 100 ms and UDP loss of 1-10% (rounded up to 1 period and 5%; "harsh" 3 periods,
#: 30%, 5 m range as through walls); the command pipeline of a ROS base (driver, motor controller)
#: adds 50-150 ms (1 period; "harsh" 2); low-cost lidars (RPLIDAR A1, Hokuyo URG-04LX) read within
#: 1-3 cm and miss a few percent of returns on dark or glancing surfaces.
UNCERTAINTY_PRESETS: dict[str, UncertaintyPreset] = {
    "nominal": UncertaintyPreset(
        "nominal",
        PoseNoise(),
        CommConfig(),
        0,
        LidarConfig(),
        "the paper's setting: only slip (none by default)",
    ),
    "realistic": UncertaintyPreset(
        "low",
        PoseNoise(xy=0.03, heading=0.02, drift_xy=0.005, drift_heading=0.002),
        CommConfig(latency=1, drop=0.05, range=15.0),
        1,
        LidarConfig(noise=0.02, dropout=0.02),
        "a typical indoor robot: AMCL-grade localization, Wi-Fi messages, one period of command latency",
    ),
    "harsh": UncertaintyPreset(
        "high",
        PoseNoise(xy=0.10, heading=0.05, drift_xy=0.02, drift_heading=0.005),
        CommConfig(latency=3, drop=0.3, range=5.0),
        2,
        LidarConfig(noise=0.05, dropout=0.1),
        "a poor day: degraded localization, congested Wi-Fi through walls, a slow command pipeline",
    ),
}


def parse_setting(name: str, value: Any, kind: type, base: Any = None) -> Any:
    """``value`` of keyword ``name`` as an instance of ``kind`` (a dataclass above).

    Accepts an instance, a dict of its fields (merged over ``base``, the preset's setting, when
    given), or None (``base``, or the perfect default). :class:`PoseNoise` also takes one number:
    the std of x and y [m].

    Raises
    ------
    ValueError
        An unknown field (with did-you-mean), a bad value, or another type.
    """
    default = base if base is not None else kind()
    if value is None:
        return default
    if isinstance(value, kind):
        return value
    # one number of any kind, NumPy scalars included (as every numpy user passes them)
    if kind is PoseNoise and isinstance(value, Real) and not isinstance(value, bool):
        return PoseNoise(xy=check_number(name, value, at_least=0, at_most=LIMITS.pose_noise))
    fields = [f.name for f in dataclasses.fields(kind)]
    if isinstance(value, dict):
        unknown = [key for key in value if key not in fields]
        if unknown:
            raise ValueError(
                f"{name} has unknown field {unknown[0]!r}{did_you_mean(unknown[0], fields)}; allowed: {fields}"
            )
        return dataclasses.replace(default, **value)
    extra = " or one number (the x and y std [m])" if kind is PoseNoise else ""
    raise ValueError(f"{name}={value!r} must be a dict of {fields}, a {kind.__name__}{extra}, or None")
