"""The random-map generator's settings, and which team shapes fit its layouts.

:class:`RandomMapConfig` holds the settings of :func:`~koopman_envs.sim.maps.generator.generate_random_map`
(each checked when it is built, naming the field and what is allowed) and decides which formation
shape a team of a given size takes (:meth:`RandomMapConfig.shape_for`: the wedge while it fits the
workspace, the grid beyond, by the exact share of placements that fit, :func:`placement_share`).
Nothing here draws: a layout is the generator's (:mod:`koopman_envs.sim.maps.generator`, which
re-exports these names).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass
from numbers import Real

import numpy as np
from numpy.typing import NDArray

from koopman_envs.checks import check_choice, check_int, check_number
from koopman_envs.params import LIMITS, PARAMS
from koopman_envs.sim.formations import FORMATION_SHAPES, formation_shape
from koopman_envs.sim.slip.zones import SLIP_ZONE_MODES

__all__ = [
    "AUTO_FORMATION",
    "MIN_PLACEMENT_SHARE",
    "MIN_TRAVEL",
    "RandomMapConfig",
    "placement_share",
]


#: shortest travel of a random layout [m] (ours): the corridor's direction is the travel over
#: its length, which a denormal travel turns into NaN obstacles
MIN_TRAVEL = 0.01
#: ``RandomMapConfig.formation`` default: the wedge while it fits the workspace, the grid beyond
AUTO_FORMATION = "auto"
#: the share of the generator's draws (heading, travel, lead position) that must place a team's
#: starts and targets inside the workspace for its shape to count as fitting (ours): the generator
#: tries ``max_attempts`` = 10,000 draws, so a reset then fails with probability below
#: (1 - 2e-3)^10000 ~ 2e-9. The wedge fits up to 20 robots at the default spacing (21: 1.3e-3).
MIN_PLACEMENT_SHARE = 2e-3


def placement_share(
    local: NDArray[np.float64], travel: tuple[float, float], width: float, height: float
) -> float:
    """Share of the random generator's draws that put a team's starts and targets inside a box.

    The generator draws a heading uniformly, a travel distance uniformly in ``travel`` and the
    leader's start uniformly in the box; the layout is kept when every start and target lies
    inside. For a heading and a travel the layout spans ``ptp(x) + travel |cos|`` by
    ``ptp(y) + travel |sin|``, so the kept share of lead positions is the product of
    ``max(0, 1 - span / side)`` over both axes; this averages it over 720 headings and 64 travels.

    Parameters
    ----------
    local : ndarray, shape (N, 2)
        The shape's offsets in the leader's travel frame.
    travel : (float, float)
        Range of the travel distance [m].
    width, height : float
        Sides of the box that leader starts are drawn in [m].

    Returns
    -------
    float
        The share in [0, 1] (0 when the box has no room).
    """
    if not (width > 0 and height > 0):  # no room at all (the formula below would read |width|)
        return 0.0
    heading = np.linspace(-math.pi, math.pi, 720, endpoint=False)
    cos_h, sin_h = np.cos(heading), np.sin(heading)
    x = np.outer(cos_h, local[:, 0]) - np.outer(sin_h, local[:, 1])  # (headings, N)
    y = np.outer(sin_h, local[:, 0]) + np.outer(cos_h, local[:, 1])
    distance = np.linspace(travel[0], travel[1], 64)
    span_x = np.ptp(x, axis=1)[:, None] + np.outer(np.abs(cos_h), distance)
    span_y = np.ptp(y, axis=1)[:, None] + np.outer(np.abs(sin_h), distance)
    share = np.clip(1.0 - span_x / width, 0.0, None) * np.clip(1.0 - span_y / height, 0.0, None)
    return float(share.mean())


@functools.lru_cache(maxsize=256)
def _shape_share(
    shape: str, n_robots: int, spacing: float, travel: tuple[float, float], width: float, height: float
) -> float:
    return placement_share(formation_shape(shape, n_robots, spacing), travel, width, height)


@dataclass(frozen=True)
class RandomMapConfig:
    """Parameters of the random-map generator (all ours).

    The layout mirrors the paper's maps: a team in formation (``formation``, a shape of
    :mod:`koopman_envs.sim.formations` with neighbours ``spacing`` apart; the wedge by default)
    travels ``travel`` metres in a random direction, and isolated circular obstacles sit in the corridor between starts and
    targets. With ``n_slip_zones`` > 0, circular slip zones (one lambda for every robot) are
    placed in the same corridor after the rest of the layout is drawn, so the obstacles, starts
    and targets of a seed do not depend on them.
    """

    n_obstacles: int = 4
    travel: tuple[float, float] = (3.0, 6.5)
    obstacle_radius: tuple[float, float] = (0.3, 0.6)
    #: where along the corridor (0: the starts' centroid, 1: the targets') obstacle centres are
    #: drawn; the default keeps the last quarter of the route free, (0.15, 0.95) also puts
    #: obstacles beside the targets (as Map 4 does), still ``clearance`` away from each one
    obstacle_along: tuple[float, float] = (0.25, 0.75)
    spacing: float = PARAMS.formation_spacing  # distance between neighbouring robots in the formation [m]
    #: the team's shape at its starts and targets, one of FORMATION_SHAPES (koopman_envs.sim.formations),
    #: or "auto": the wedge while it fits the workspace (up to 20 robots at the default spacing),
    #: the grid beyond (see :meth:`shape_for`)
    formation: str = AUTO_FORMATION
    clearance: float = 0.3  # free space around every start and target [m]
    gap: float = 0.6  # free space between two obstacles, > one robot diameter [m]
    border: float = 1.0  # free space between any start/target and the workspace edge [m]
    max_attempts: int = 10_000
    #: probability that the targets go to the robots in a random order, so that paths cross as
    #: in Map 2 (target reaching; for formation it reshapes the formation itself)
    swap_targets: float = 0.0
    #: circular slip zones per map, centred in the corridor like the obstacles
    n_slip_zones: int = 0
    slip_zone_radius: tuple[float, float] = (0.6, 1.5)  # zone radius range [m]
    slip_zone_lambda: tuple[float, float] = (0.2, 0.5)  # range of the zone's slip mean
    slip_zone_mode: str = "replace"  # see koopman_envs.sim.slip.zones

    def __post_init__(self) -> None:
        # NumPy scalars (np.int8(3), np.float32(0.5)) as the Python numbers they hold: the sizes
        # feed array arithmetic that a small integer type would overflow; Python values are kept
        # as given (a cache key reads them)
        for field in dataclasses.fields(self):
            value = getattr(self, field.name)
            if isinstance(value, np.generic):
                object.__setattr__(self, field.name, value.item())
            elif isinstance(value, (list, tuple)) and any(isinstance(v, np.generic) for v in value):
                object.__setattr__(
                    self, field.name, tuple(v.item() if isinstance(v, np.generic) else v for v in value)
                )
        # bounded (koopman_envs.params.LIMITS): obstacle arrays grow with the first, a reset's
        # time with the last
        check_int("n_obstacles", self.n_obstacles, 0, maximum=LIMITS.random_obstacles)
        check_int("max_attempts", self.max_attempts, 1, maximum=LIMITS.map_attempts)
        for name in ("clearance", "gap", "border"):  # any real number, NumPy scalars included
            check_number(name, getattr(self, name), at_least=0, note="metres")
        for name in ("travel", "obstacle_radius"):
            pair = getattr(self, name)
            try:
                low, high = (float(v) for v in pair)
            except (TypeError, ValueError):
                raise ValueError(f"{name}={pair!r} must be a (low, high) pair of numbers [m]") from None
            if not (math.isfinite(low) and math.isfinite(high) and 0 < low <= high):
                raise ValueError(
                    f"{name}={pair!r} must be a finite (low, high) pair with 0 < low <= high [m]"
                )
            if name == "travel" and low < MIN_TRAVEL:  # the corridor's direction divides by it
                raise ValueError(
                    f"travel={pair!r} must have low >= {MIN_TRAVEL:g} [m] (a shorter trip is none)"
                )
        # the name among the shapes and "auto", then the shape's own check of the spacing
        check_choice("formation", self.formation, [AUTO_FORMATION, *FORMATION_SHAPES])
        formation_shape("grid" if self.formation == AUTO_FORMATION else self.formation, 1, self.spacing)
        swap = self.swap_targets
        if isinstance(swap, bool) or not isinstance(swap, Real) or not 0.0 <= swap <= 1.0:
            raise ValueError(f"swap_targets={swap!r} must be a probability in [0, 1]")
        n = self.n_slip_zones
        check_int("n_slip_zones", n, 0, maximum=LIMITS.slip_zones)
        try:
            low, high = (float(v) for v in self.obstacle_along)
        except (TypeError, ValueError):
            low, high = math.nan, math.nan  # refused below, with the one message
        if not (0.0 <= low <= high <= 1.0):
            raise ValueError(
                f"obstacle_along={self.obstacle_along!r} must be a (low, high) pair with 0 <= low <= high <= 1"
            )
        for name, low_allowed in (("slip_zone_radius", "> 0"), ("slip_zone_lambda", ">= 0")):
            pair = getattr(self, name)
            try:
                low, high = (float(v) for v in pair)
            except (TypeError, ValueError):
                raise ValueError(f"{name}={pair!r} must be a (low, high) pair of numbers") from None
            positive = low > 0 if name == "slip_zone_radius" else low >= 0
            # a zone's slip mean has the bound of every slip mean (finite draws, finite states)
            top = LIMITS.slip_lambda if name == "slip_zone_lambda" else math.inf
            if not (math.isfinite(low) and math.isfinite(high) and positive and low <= high <= top):
                bound = f" <= {top:g}" if name == "slip_zone_lambda" else ""
                raise ValueError(
                    f"{name}={pair!r} must be a finite (low, high) pair with low {low_allowed} and "
                    f"low <= high{bound}"
                )
        check_choice("slip_zone_mode", self.slip_zone_mode, SLIP_ZONE_MODES)

    def placement_share(
        self,
        shape: str,
        n_robots: int,
        robot_radius: float = PARAMS.robot_radius,
        workspace: tuple[float, float, float, float] = PARAMS.workspace,
    ) -> float:
        """Share of this generator's draws that place a team of ``shape`` inside the workspace
        (:func:`placement_share` on the box that leader starts are drawn in)."""
        x0, x1, y0, y1 = workspace
        margin = self.border + robot_radius
        travel = (float(self.travel[0]), float(self.travel[1]))
        return _shape_share(
            shape, int(n_robots), float(self.spacing), travel, x1 - x0 - 2 * margin, y1 - y0 - 2 * margin
        )

    def shape_for(
        self,
        n_robots: int,
        robot_radius: float = PARAMS.robot_radius,
        workspace: tuple[float, float, float, float] = PARAMS.workspace,
    ) -> str:
        """The formation shape a team of ``n_robots`` starts and ends in on these random maps.

        A shape fits when at least :data:`MIN_PLACEMENT_SHARE` of the generator's draws place the
        team inside the workspace (:func:`placement_share`). ``"auto"`` is the wedge while it
        fits and the grid beyond; a named shape is used as it is.

        Raises
        ------
        ValueError
            The shape (the grid, for ``"auto"``) does not fit: naming the team size, the shape
            and what to change.
        """

        def share(shape: str) -> float:
            return self.placement_share(shape, n_robots, robot_radius, workspace)

        x0, x1, y0, y1 = workspace
        margin = self.border + robot_radius
        if not (x1 - x0 > 2 * margin and y1 - y0 > 2 * margin):
            raise ValueError(
                f"random_map border={self.border:g} m and robot_radius={robot_radius:g} m leave no room in the "
                f"workspace {list(workspace)}: every start and target keeps border + robot_radius from its "
                "edges; use a smaller border or robot_radius"
            )

        shape = self.formation
        if shape == AUTO_FORMATION:
            shape = "wedge" if share("wedge") >= MIN_PLACEMENT_SHARE else "grid"
        fits = share(shape)
        if fits < MIN_PLACEMENT_SHARE:
            # the roomiest shapes first
            roomy = sorted(
                (name for name in FORMATION_SHAPES if share(name) >= MIN_PLACEMENT_SHARE),
                key=lambda name: -share(name),
            )
            raise ValueError(
                f"a {shape} of n_robots={n_robots} with spacing {self.spacing:g} m does not fit a random "
                f"map's workspace {list(workspace)} (it is placed in {fits:.1e} of the draws; at least "
                f"{MIN_PLACEMENT_SHARE:g} is needed); "
                + (
                    f"use formation={roomy[0]!r}" + (f" (or one of {roomy[1:]})" if roomy[1:] else "")
                    if roomy
                    else "use fewer robots"
                )
                + ", a smaller random_map spacing or shorter travel"
            )
        return shape
