"""Slip zones: regions of a map where the robots' slip mean differs from their base level.

A zone is a circle or an axis-aligned rectangle with a slip mean lambda per robot and a mode:

``"replace"``
    inside, the robot's slip mean is the zone's lambda instead of its base level;
``"add"``
    inside, the zone's lambda is added to the robot's level.

Overlapping zones (in the order the map lists them): the **last** listed ``replace`` zone that
contains the robot sets its level (the base level if none does), and every ``add`` zone that
contains it adds its lambda on top of that level, wherever ``add`` zones appear in the list.
A robot is inside a zone when its centre is (boundary included).

The level of a control period is taken where the robot is at the **start** of the period, and
only the scale changes: the unit-mean Exponential draws of
:class:`~koopman_envs.sim.slip.sampling.SlipSampler` are the same stream with or without zones, so an
environment with zones consumes its generator exactly as one without, and a robot outside every
zone slips exactly (bit for bit) as it would on the map without zones.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, cast

import numpy as np
from numba import njit
from numpy.typing import NDArray

from koopman_envs.checks import check_choice
from koopman_envs.params import LIMITS
from koopman_envs.sim.physics.surfaces import SurfaceSetting, check_surface

__all__ = [
    "SLIP_ZONE_MODES",
    "SLIP_ZONE_SHAPES",
    "SlipZone",
    "ZoneTable",
    "check_zone_robots",
    "zone_slip_means",
]

#: zone shapes and the numbers their key holds in a map file
SLIP_ZONE_SHAPES = {"circle": "[x, y, radius]", "rect": "[xmin, ymin, xmax, ymax]"}
#: how a zone's lambda combines with the robot's level (see the module docstring)
SLIP_ZONE_MODES = ("replace", "add")
_ZONE_KEYS = (*SLIP_ZONE_SHAPES, "lambda", "mode", "surface")
_CIRCLE, _RECT = 0, 1


def _is_number(value: Any) -> bool:
    numeric = isinstance(value, (int, float, np.integer, np.floating))
    return numeric and not isinstance(value, (bool, np.bool_))


def _floats(value: Any) -> float | tuple[float, ...] | None:
    """A number as a float, a flat list/tuple/array of numbers as a tuple of floats, anything
    else None (bools are not numbers). Plain Python: a random map builds its zones every reset."""
    if isinstance(value, np.ndarray):
        if value.dtype.kind not in "iuf" or value.ndim > 1:
            return None
        value = value.tolist()
    if isinstance(value, (list, tuple)):
        return tuple(float(v) for v in value) if all(_is_number(v) for v in value) else None
    return float(value) if _is_number(value) else None


@dataclass(frozen=True, eq=False)
class SlipZone:
    """One slip zone of a map (see the module docstring for the combination rules).

    Attributes
    ----------
    shape : str
        ``"circle"`` or ``"rect"``.
    bounds : tuple of float
        Circle: centre x, y and radius [m] (radius > 0). Rectangle: xmin, ymin, xmax, ymax [m]
        (xmin < xmax, ymin < ymax).
    lam : float or tuple of float
        Slip mean inside the zone (dimensionless, finite, 0 to ``LIMITS.slip_lambda``): one value
        for every robot, or one per robot of the map.
    mode : str
        ``"replace"`` (default) or ``"add"``.
    surface : str or float, optional
        The zone's floor on the physics plant (``plant="mujoco"``): a surface name of
        :data:`~koopman_envs.params.SURFACES` or a friction coefficient in (0, 2]; None: the
        surface its lambda names (:func:`~koopman_envs.sim.physics.surfaces.surface_for_lambda`).
        The kinematic plant ignores it.

    Raises
    ------
    ValueError
        Naming the bad value and what is allowed.
    """

    shape: str
    bounds: tuple[float, ...]
    lam: float | tuple[float, ...]
    mode: str = "replace"
    surface: SurfaceSetting | None = None

    def __post_init__(self) -> None:
        check_choice("shape", self.shape, SLIP_ZONE_SHAPES)
        form = SLIP_ZONE_SHAPES[self.shape]
        bounds = _floats(self.bounds)
        size = 3 if self.shape == "circle" else 4
        if not isinstance(bounds, tuple) or len(bounds) != size or not all(map(math.isfinite, bounds)):
            raise ValueError(f"{self.shape}={self.bounds!r} must be {size} finite numbers {form}")
        if self.shape == "circle" and bounds[2] <= 0:
            raise ValueError(f"circle={list(bounds)} has radius {bounds[2]:g}; allowed: radius > 0 in {form}")
        if self.shape == "rect" and not (bounds[0] < bounds[2] and bounds[1] < bounds[3]):
            raise ValueError(
                f"rect={list(bounds)} is empty; allowed: {form} with xmin < xmax and ymin < ymax"
            )
        lam = _floats(self.lam)
        # a None ``lam`` is rejected below before ``values`` is read, so its entries are floats
        values = cast("tuple[float, ...]", lam if isinstance(lam, tuple) else (lam,))
        # bounded as every slip mean (LIMITS.slip_lambda): the draws scaled by it stay finite
        top = LIMITS.slip_lambda
        if lam is None or not values or not all(math.isfinite(v) and 0 <= v <= top for v in values):
            raise ValueError(
                f"lambda={self.lam!r} must be a finite number >= 0 <= {top:g} or a list of them (one per robot)"
            )
        check_choice("mode", self.mode, SLIP_ZONE_MODES)
        if self.surface is not None:
            object.__setattr__(self, "surface", check_surface("surface", self.surface))
        object.__setattr__(self, "bounds", bounds)
        object.__setattr__(self, "lam", lam)

    @property
    def per_robot(self) -> bool:
        """True when the zone lists one lambda per robot."""
        return isinstance(self.lam, tuple)

    def lambdas_for(self, n_robots: int) -> NDArray[np.float64]:
        """The zone's lambda of robots 0 .. n_robots - 1, shape (n_robots,)."""
        # isinstance rather than self.per_robot (the same test) narrows lam for the type checker
        if isinstance(self.lam, tuple):
            return np.asarray(self.lam[:n_robots], dtype=np.float64)
        return np.full(n_robots, self.lam)

    def extent(self) -> tuple[float, float, float, float]:
        """Bounding box (xmin, ymin, xmax, ymax) [m]."""
        if self.shape == "circle":
            x, y, r = self.bounds
            return (x - r, y - r, x + r, y + r)
        return self.bounds  # type: ignore[return-value]

    def contains(self, x: float, y: float) -> bool:
        """Whether the point (x, y) [m] is inside (the rule of :func:`zone_slip_means`)."""
        if self.shape == "circle":
            cx, cy, r = self.bounds
            return (x - cx) * (x - cx) + (y - cy) * (y - cy) <= r * r
        x0, y0, x1, y1 = self.bounds
        return x0 <= x <= x1 and y0 <= y <= y1

    def to_dict(self) -> dict[str, Any]:
        """Map-file form, readable by :meth:`from_dict`."""
        form = {
            self.shape: list(self.bounds),
            # isinstance rather than self.per_robot (the same test) narrows lam for the type checker
            "lambda": list(self.lam) if isinstance(self.lam, tuple) else self.lam,
            "mode": self.mode,
        }
        return form if self.surface is None else {**form, "surface": self.surface}

    @classmethod
    def from_dict(cls, data: Any) -> SlipZone:
        """A zone from its map-file form, e.g. ``{"circle": [0, 0, 1.5], "lambda": 0.4}`` or
        ``{"rect": [-1, -2, 1, 2], "lambda": [0, 0.1, 0.2], "mode": "add"}`` (``mode`` defaults to
        ``"replace"``).

        Raises
        ------
        ValueError
            Not an object, unknown keys, not exactly one shape key, no ``lambda``, or a bad value.
        """
        if not isinstance(data, dict):
            raise ValueError(f"{data!r} must be an object with keys from {list(_ZONE_KEYS)}")
        unknown = sorted(set(data) - set(_ZONE_KEYS))
        if unknown:
            raise ValueError(f"unknown keys {unknown}; allowed: {list(_ZONE_KEYS)}")
        shapes = [key for key in SLIP_ZONE_SHAPES if key in data]
        if len(shapes) != 1:
            allowed = " or ".join(f"{k!r}: {v}" for k, v in SLIP_ZONE_SHAPES.items())
            raise ValueError(f"{data!r} must have exactly one shape key, {allowed}")
        if "lambda" not in data:
            raise ValueError(f"{data!r} has no 'lambda' (a number >= 0 or one per robot)")
        return cls(
            shapes[0], data[shapes[0]], data["lambda"], data.get("mode", "replace"), data.get("surface")
        )


def check_zone_robots(zones: Sequence[SlipZone], n_robots: int) -> None:
    """Raise ValueError when a per-robot zone lambda list does not have ``n_robots`` entries."""
    for j, zone in enumerate(zones):
        # isinstance rather than zone.per_robot (the same test) narrows lam for the type checker
        if isinstance(zone.lam, tuple) and len(zone.lam) != n_robots:
            raise ValueError(
                f"slip zone {j}: lambda={list(zone.lam)} has {len(zone.lam)} values; allowed: one number "
                f"for every robot or one per robot of the map ({n_robots})"
            )


class ZoneTable:
    """The slip zones of K environments as arrays for :func:`zone_slip_means`.

    Parameters
    ----------
    num_envs : int
        Batch size K.
    n_zones : int
        Zones per environment Z (the same for every environment of a config).
    n_robots : int
        Robots per environment N.
    """

    def __init__(self, num_envs: int, n_zones: int, n_robots: int) -> None:
        self.n_robots = int(n_robots)
        self.kind = np.zeros((num_envs, n_zones), dtype=np.int64)
        self.geometry = np.zeros((num_envs, n_zones, 4))
        self.add = np.zeros((num_envs, n_zones), dtype=np.bool_)
        self.lambdas = np.zeros((num_envs, n_zones, n_robots))

    def set_env(self, index: int, zones: Sequence[SlipZone], values: Sequence[float] | None = None) -> None:
        """Load the zones of environment ``index`` (exactly Z of them).

        ``values`` (one per zone) replace the zones' lambdas, every zone then in ``"replace"``
        mode: the physics plant's zone frictions, looked up by the same kernel.
        """
        if len(zones) != self.kind.shape[1]:
            raise ValueError(
                f"{len(zones)} slip zones for environment {index}; the table holds {self.kind.shape[1]}"
            )
        for j, zone in enumerate(zones):
            self.kind[index, j] = _CIRCLE if zone.shape == "circle" else _RECT
            self.geometry[index, j] = 0.0
            self.geometry[index, j, : len(zone.bounds)] = zone.bounds
            self.add[index, j] = zone.mode == "add" and values is None
            self.lambdas[index, j] = zone.lambdas_for(self.n_robots) if values is None else values[j]

    def slip_means(
        self, state: NDArray[np.float64], base: NDArray[np.float64], out: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        """Slip mean of every robot at ``state`` (K, 3, N) given the base levels (K, N), into ``out``."""
        zone_slip_means(state, base, self.kind, self.geometry, self.add, self.lambdas, out)
        return out


@njit(cache=True)
def zone_slip_means(
    state: NDArray[np.float64],
    base: NDArray[np.float64],
    kind: NDArray[np.int64],
    geometry: NDArray[np.float64],
    add: NDArray[np.bool_],
    zone_lambdas: NDArray[np.float64],
    out: NDArray[np.float64],
) -> None:  # pragma: no cover - compiled
    """Slip mean of every robot where it stands (compiled; the rules of the module docstring).

    Parameters
    ----------
    state : ndarray, shape (K, 3, N)
        Rows x [m], y [m], theta [rad].
    base : ndarray, shape (K, N)
        Base slip level of every robot (setting or schedule).
    kind : ndarray of int, shape (K, Z)
        0 circle, 1 rectangle.
    geometry : ndarray, shape (K, Z, 4)
        Circle: x, y, radius, unused; rectangle: xmin, ymin, xmax, ymax [m].
    add : ndarray of bool, shape (K, Z)
        True for ``"add"`` zones, False for ``"replace"``.
    zone_lambdas : ndarray, shape (K, Z, N)
        Each zone's lambda per robot.
    out : ndarray, shape (K, N)
        Output slip means.
    """
    n_envs, _, n_robots = state.shape
    n_zones = kind.shape[1]
    for k in range(n_envs):
        for i in range(n_robots):
            x = state[k, 0, i]
            y = state[k, 1, i]
            level = base[k, i]
            extra = 0.0
            for z in range(n_zones):
                # scalar reads: a per-zone array view (geometry[k, z]) costs more than the test
                a0, a1, a2 = geometry[k, z, 0], geometry[k, z, 1], geometry[k, z, 2]
                if kind[k, z] == 0:
                    dx = x - a0
                    dy = y - a1
                    inside = dx * dx + dy * dy <= a2 * a2
                else:
                    inside = a0 <= x <= a2 and a1 <= y <= geometry[k, z, 3]
                if inside:
                    if add[k, z]:
                        extra += zone_lambdas[k, z, i]
                    else:
                        level = zone_lambdas[k, z, i]
            # level + 0.0 is level itself: outside every zone the base level passes unchanged
            out[k, i] = level + extra
