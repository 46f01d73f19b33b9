"""Obstacle maps: the shipped data files and user map files (the seeded random-map generator is
:mod:`koopman_envs.sim.maps.generator`).

A map holds circular obstacles, optional slip zones (:mod:`koopman_envs.sim.slip.zones`) and, per
robot, a start pose and a target pose. Formation maps are written as a leader target plus
follower offsets; both forms load into the same :class:`MapSpec`, whose ``formation_offsets``
are the targets relative to robot 0's target.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field, replace
from importlib import resources
from typing import Any

import numpy as np
from numpy.typing import NDArray

from koopman_envs.checks import check_int, choice_message, did_you_mean, parse_json
from koopman_envs.files import read_text, write_atomic
from koopman_envs.params import LIMITS, PARAMS
from koopman_envs.sim.formations import FORMATION_SHAPES, formation_offsets_for
from koopman_envs.sim.geometry import TeamGeometry
from koopman_envs.sim.slip.zones import SlipZone, check_zone_robots

__all__ = [
    "BUILTIN_MAPS",
    "MAP_NAMES",
    "MAP_KEYS",
    "MapSpec",
    "formation_offsets",
    "load_map",
]

#: the shipped maps: map1-map4 are the paper's (SPEC section 5), map5 (target reaching) and map6
#: (formation) add a high-slip zone across the shortest route, map7 (target reaching) and map8
#: (formation) hold six robots (ours)
BUILTIN_MAPS = ("map1", "map2", "map3", "map4", "map5", "map6", "map7", "map8")
MAP_NAMES = (*BUILTIN_MAPS, "random")


def formation_offsets(targets: NDArray[np.float64]) -> NDArray[np.float64]:
    """Target position of each robot relative to the leader's (robot 0), shape (N, 2) [m], from
    the target poses (N, 3)."""
    return targets[:, :2] - targets[0, :2]


def _as_array(value: Any, name: str, columns: int, map_name: str) -> NDArray[np.float64]:
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"map {map_name!r}: {name}={value!r} is not a list of numbers") from exc
    if arr.size == 0:
        arr = arr.reshape(0, columns)
    if arr.ndim != 2 or arr.shape[1] != columns:
        raise ValueError(f"map {map_name!r}: {name} has shape {arr.shape}; expected (k, {columns}) rows")
    if not np.isfinite(arr).all():
        raise ValueError(f"map {map_name!r}: {name} contains NaN or inf")
    return arr


#: the keys of a map's JSON form (:meth:`MapSpec.from_dict`); any other is refused by name
MAP_KEYS = (
    "name",
    "description",
    "obstacles",
    "starts",
    "targets",
    "leader_target",
    "formation_offsets",
    "slip_zones",
    "metadata",
)


@dataclass(frozen=True, eq=False)
class MapSpec:
    """One navigation scenario layout.

    Attributes
    ----------
    name : str
        Identifier shown in reports.
    obstacles : ndarray, shape (M, 3)
        Circular obstacles: centre x, y and radius [m].
    starts : ndarray, shape (S, 3)
        Start pose (x [m], y [m], theta [rad]) of each robot the map supports.
    targets : ndarray, shape (S, 3)
        Target pose of each robot. For formation, row 0 is the leader's target and row i its
        target plus the formation offset of follower i.
    description : str
        Free text.
    metadata : dict
        Free JSON data kept with the map.
    slip_zones : tuple of SlipZone
        Regions with their own slip mean (:mod:`koopman_envs.sim.slip.zones`); a sequence of
        :class:`~koopman_envs.sim.slip.zones.SlipZone` or of their map-file dicts. A per-robot zone
        lambda lists one value per start of the map.
    """

    name: str
    obstacles: NDArray[np.float64]
    starts: NDArray[np.float64]
    targets: NDArray[np.float64]
    description: str = ""
    metadata: dict[str, Any] = field(default_factory=dict)
    slip_zones: tuple[SlipZone, ...] = ()

    def __post_init__(self) -> None:
        obstacles = _as_array(self.obstacles, "obstacles", 3, self.name)
        starts = _as_array(self.starts, "starts", 3, self.name)
        targets = _as_array(self.targets, "targets", 3, self.name)
        if starts.shape[0] < 1:
            raise ValueError(f"map {self.name!r}: needs at least one start pose")
        if targets.shape != starts.shape:
            raise ValueError(
                f"map {self.name!r}: {starts.shape[0]} starts but {targets.shape[0]} targets; "
                "each robot needs one of each"
            )
        if (obstacles[:, 2] <= 0).any():
            raise ValueError(f"map {self.name!r}: obstacle radii must be > 0, got {obstacles[:, 2]}")
        for arr in (obstacles, starts, targets):
            arr.setflags(write=False)
        object.__setattr__(self, "slip_zones", self._zones(self.slip_zones, starts.shape[0]))
        object.__setattr__(self, "obstacles", obstacles)
        object.__setattr__(self, "starts", starts)
        object.__setattr__(self, "targets", targets)

    @classmethod
    def generated(
        cls,
        name: str,
        obstacles: NDArray[np.float64],
        starts: NDArray[np.float64],
        targets: NDArray[np.float64],
        description: str,
        slip_zones: tuple[SlipZone, ...] = (),
    ) -> MapSpec:
        """A map from a generator that builds its arrays to the checked form itself (float64,
        (k, 3) rows, finite, radii > 0, as many starts as targets, zones of the right type), as
        :func:`~koopman_envs.sim.maps.generator.generate_random_map` does at every reset: the arrays
        are taken as they are (made read-only) without :meth:`__post_init__`'s checks, which cost
        a quarter of a random-map reset. Everything else builds a map the checked way."""
        spec = object.__new__(cls)
        for key, value in (("name", name), ("obstacles", obstacles), ("starts", starts), ("targets", targets),
                           ("description", description), ("metadata", {}), ("slip_zones", slip_zones)):  # fmt: skip
            if isinstance(value, np.ndarray):
                value.setflags(write=False)
            object.__setattr__(spec, key, value)
        return spec

    def _zones(self, value: Any, n_robots: int) -> tuple[SlipZone, ...]:
        """``slip_zones`` checked and converted (dicts of the map-file form become zones)."""
        if not isinstance(value, (list, tuple)):
            raise ValueError(f"map {self.name!r}: slip_zones={value!r} must be a list of zones")
        zones = []
        for j, item in enumerate(value):
            try:
                zones.append(item if isinstance(item, SlipZone) else SlipZone.from_dict(item))
            except ValueError as exc:
                raise ValueError(f"map {self.name!r}: slip zone {j}: {exc}") from None
        try:
            check_zone_robots(zones, n_robots)
        except ValueError as exc:
            raise ValueError(f"map {self.name!r}: {exc}") from None
        return tuple(zones)

    @property
    def max_robots(self) -> int:
        """How many robots the map has starts and targets for."""
        return int(self.starts.shape[0])

    @property
    def formation_offsets(self) -> NDArray[np.float64]:
        """Target position of each robot relative to the leader's (robot 0), shape (S, 2) [m]."""
        return formation_offsets(self.targets)

    def validate(
        self,
        n_robots: int,
        robot_radius: float = PARAMS.robot_radius,
        workspace: tuple[float, float, float, float] = PARAMS.workspace,
    ) -> None:
        """Check that the first ``n_robots`` starts and targets form a valid scenario.

        Raises
        ------
        ValueError
            Naming the first problem: too many robots, a pose outside the workspace,
            overlapping starts or targets, a start or target inside an obstacle.
        """
        check_int("n_robots", n_robots, 1)
        if n_robots > self.max_robots:
            raise ValueError(
                f"n_robots={n_robots} is larger than map {self.name!r} supports "
                f"(1..{self.max_robots}): it holds {self.max_robots} robots; allowed: n_robots <= "
                f"{self.max_robots}, or map='random' (any team size) or a map with more starts"
            )
        for label, poses in (("start", self.starts[:n_robots]), ("target", self.targets[:n_robots])):
            problem = self.pose_problem(poses, robot_radius, workspace, label)
            if problem is not None:
                raise ValueError(f"map {self.name!r}: {problem}")

    def with_formation(
        self,
        shape: str,
        n_robots: int,
        spacing: float = PARAMS.formation_spacing,
        robot_radius: float = PARAMS.robot_radius,
        workspace: tuple[float, float, float, float] = PARAMS.workspace,
    ) -> MapSpec:
        """This map with the first ``n_robots`` targets set by a formation shape.

        The leader's (robot 0's) target stays; follower i's target becomes the leader's target
        plus offset i of :func:`~koopman_envs.sim.formations.formation_offsets_for` for the
        leader target's heading, with the leader's heading. Starts, obstacles, zones and the
        targets of robots beyond ``n_robots`` are the map's.

        Parameters
        ----------
        shape : str
            One of :data:`~koopman_envs.sim.formations.FORMATION_SHAPES`.
        n_robots : int
            Team size N (at most :attr:`max_robots`).
        spacing : float
            Distance between neighbouring robots of the shape [m].
        robot_radius : float
            Disc radius of every robot [m], for the placement check.
        workspace : tuple of float
            (x_min, x_max, y_min, y_max) [m].

        Raises
        ------
        ValueError
            The shape is unknown, or its targets leave the workspace, overlap an obstacle or
            each other on this map (the message names the shape, the map and the collision).
        """
        self.validate(n_robots, robot_radius, workspace)
        leader = self.targets[0]
        offsets = formation_offsets_for(shape, int(n_robots), float(spacing), float(leader[2]))
        targets = np.array(self.targets)
        targets[:n_robots, :2] = leader[:2] + offsets
        targets[:n_robots, 2] = leader[2]
        problem = self.pose_problem(targets[:n_robots], robot_radius, workspace, "target")
        if problem is not None:
            raise ValueError(
                f"formation={shape!r} does not fit map {self.name!r} with n_robots={n_robots} "
                f"(spacing {spacing} m): {problem}; allowed: a shape whose targets around the leader's "
                f"{leader.tolist()} lie inside the workspace {workspace}, clear of every obstacle and of "
                f"each other; try another of {list(FORMATION_SHAPES)} or formation=None (the map's own)"
            )
        return replace(self, targets=targets)

    def pose_problem(
        self,
        poses: NDArray[np.float64],
        robot_radius: float = PARAMS.robot_radius,
        workspace: tuple[float, float, float, float] = PARAMS.workspace,
        label: str = "start",
    ) -> str | None:
        """The first reason why a team at ``poses`` cannot stand on this map, or None if it can.

        The one placement check of the package: :meth:`validate` runs it on the map's own starts
        and targets, and the engine on the perturbed starts of ``start_noise``.

        Parameters
        ----------
        poses : ndarray, shape (N, 2) or (N, 3)
            Robot centres x, y [m] (a heading column is ignored).
        robot_radius : float
            Disc radius of every robot [m].
        workspace : tuple of float
            (x_min, x_max, y_min, y_max) [m]; every disc must lie inside it.
        label : str
            What the poses are (``"start"``, ``"target"``), used in the message.

        Returns
        -------
        str or None
            The problem (a disc outside the workspace, two robots overlapping, a robot
            overlapping an obstacle), or None.
        """
        poses = np.asarray(poses, dtype=np.float64)
        n_robots = poses.shape[0]
        radii = np.full(n_robots, float(robot_radius))
        geometry = TeamGeometry(1, radii, self.obstacles.shape[0])
        geometry.set_obstacles(0, self.obstacles)
        x0, x1, y0, y1 = workspace
        inside = (
            (poses[:, 0] - robot_radius >= x0)
            & (poses[:, 0] + robot_radius <= x1)
            & (poses[:, 1] - robot_radius >= y0)
            & (poses[:, 1] + robot_radius <= y1)
        )
        if not inside.all():
            robot = int(np.argmin(inside))
            return (
                f"{label} of robot {robot} at {poses[robot, :2].tolist()} is not "
                f"inside the workspace {workspace} with radius {robot_radius}"
            )
        clearance = geometry.clearances(poses[None, :, 0], poses[None, :, 1])[0]
        robots, obstacles = clearance[:, :n_robots], clearance[:, n_robots:]
        if robots.min() < 0:
            i, j = np.unravel_index(np.argmin(robots), robots.shape)
            return (
                f"overlapping {label}s of robots {i} and {j} "
                f"({poses[i, :2].tolist()} and {poses[j, :2].tolist()}); centres must be at "
                f"least {2 * robot_radius} m apart"
            )
        if obstacles.size and obstacles.min() < 0:
            i, k = np.unravel_index(np.argmin(obstacles), obstacles.shape)
            return (
                f"{label} of robot {i} at {poses[i, :2].tolist()} "
                f"overlaps obstacle {k} {self.obstacles[k].tolist()}"
            )
        return None

    def to_dict(self) -> dict[str, Any]:
        """Plain-JSON form, readable by :func:`load_map`."""
        return {
            "name": self.name,
            "description": self.description,
            "obstacles": self.obstacles.tolist(),
            "starts": self.starts.tolist(),
            "targets": self.targets.tolist(),
            **({"metadata": self.metadata} if self.metadata else {}),
            **({"slip_zones": [zone.to_dict() for zone in self.slip_zones]} if self.slip_zones else {}),
        }

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write the map as a JSON file."""
        write_atomic(path, json.dumps(self.to_dict(), indent=1))

    @classmethod
    def from_file_text(cls, raw: str, path: str | os.PathLike[str]) -> MapSpec:
        """Build a map from the text of the map file ``path``, already read (named by the file's
        stem unless it names itself), as :func:`load_map` builds it from the file.

        The evaluator reads a user map file once, fingerprints those bytes and builds every
        episode's map from the same text, so that the recorded fingerprint is the map that ran.

        Raises
        ------
        ValueError
            The text is not a JSON map; the message names ``path``.
        """
        text = os.fspath(path)
        try:
            data = parse_json(raw, f"map file {text!r}")
        except json.JSONDecodeError as exc:
            raise ValueError(f"map file {text!r} is not valid JSON: {exc}") from exc
        stem = os.path.splitext(os.path.basename(text))[0]
        return cls.from_dict(data, default_name=stem)

    @classmethod
    def from_dict(cls, data: dict[str, Any], default_name: str = "custom") -> MapSpec:
        """Build a map from its JSON form.

        Either ``targets`` (one pose per robot) or ``leader_target`` plus ``formation_offsets``
        (one (dx, dy) per robot, the leader's being (0, 0); every target takes the leader's
        heading) must be given. ``slip_zones`` is optional: a list of
        ``{"circle": [x, y, r], "lambda": l, "mode": "replace"}`` or
        ``{"rect": [xmin, ymin, xmax, ymax], ...}`` objects (:meth:`SlipZone.from_dict`).
        """
        if not isinstance(data, dict):
            raise ValueError(f"map {default_name!r}: must be a JSON object, got {type(data).__name__}")
        name = str(data.get("name", default_name))
        unknown = [key for key in data if key not in MAP_KEYS]
        if unknown:
            hints = "".join(did_you_mean(str(key), MAP_KEYS) for key in unknown)
            raise ValueError(f"map {name!r}: unknown keys {unknown}; allowed: {list(MAP_KEYS)}{hints}")
        missing = [key for key in ("obstacles", "starts") if key not in data]
        if missing:
            raise ValueError(f"map {name!r}: missing keys {missing}")
        if "targets" in data:
            targets = data["targets"]
        elif "leader_target" in data and "formation_offsets" in data:
            leader = _as_array([data["leader_target"]], "leader_target", 3, name)[0]
            offsets = _as_array(data["formation_offsets"], "formation_offsets", 2, name)
            targets = np.column_stack(
                [leader[0] + offsets[:, 0], leader[1] + offsets[:, 1], np.full(len(offsets), leader[2])]
            )
        else:
            raise ValueError(
                f"map {name!r}: give either 'targets' or 'leader_target' and 'formation_offsets'"
            )
        return cls(
            name=name,
            obstacles=data["obstacles"],
            starts=data["starts"],
            targets=targets,
            description=str(data.get("description", "")),
            metadata=dict(data.get("metadata", {})),
            slip_zones=data.get("slip_zones", ()),
        )


def load_map(spec: str | os.PathLike[str] | MapSpec) -> MapSpec:
    """Resolve a map argument to a :class:`MapSpec`.

    Parameters
    ----------
    spec : str, path or MapSpec
        A shipped map name (``"map1"`` .. ``"map8"``), a path to a JSON map file, or a map.
        ``"random"`` is handled by the environment, which draws a new map per reset.

    Raises
    ------
    ValueError
        Unknown name, unreadable or malformed file.
    """
    if isinstance(spec, MapSpec):
        return spec
    if isinstance(spec, (str, os.PathLike)):
        text = os.fspath(spec)
        if text in BUILTIN_MAPS:
            raw = resources.files("koopman_envs.maps").joinpath(f"{text}.json").read_text("utf-8")
            return MapSpec.from_dict(parse_json(raw, f"map {text!r}"), default_name=text)
        if text.endswith(".json") or os.path.sep in text:
            # a regular file of bounded size before it is read whole (map="/dev/zero" read forever)
            raw = read_text(text, LIMITS.map_file_bytes, what="map file", expected="a JSON map file")
            return MapSpec.from_file_text(raw, text)
    raise ValueError(choice_message("map", spec, MAP_NAMES, ", a path to a .json map file, or a MapSpec"))
