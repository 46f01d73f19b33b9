"""What a controller may read: the observed part of an ``info``, as one typed value.

An env's ``info`` holds the true state (``poses``, ``distances``, collision flags, ...) for
evaluation and for users, beside what the robots believe (:meth:`NavigationEngine.observed_info
<koopman_envs.engine.engine.NavigationEngine.observed_info>`). A controller that is to face the
runtime uncertainty honestly reads only what :meth:`Observed.from_info` takes of it
(:data:`OBSERVED_KEYS`); every built-in controller receives an :class:`Observed` from
:meth:`controllers.base.BaseController.act`, so none can read the truth by accident, and
tests/test_observed_view.py hands them poisoned true fields to prove it.

The Gymnasium ``info`` stays a dict for its users. The stages a controller puts in front of its
planner (the radio of a central controller, the pose estimator, the lidar perception) each take
an :class:`Observed` and return a new one (:func:`dataclasses.replace`), filling the optional
derived fields; none edits the value it was given.
"""

from __future__ import annotations

import functools
import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, NoReturn

import numpy as np
from numpy.typing import NDArray

# the release that removes the dict view of the earlier API (observed_view, reading an Observed by
# key), deprecated in CHANGELOG.md
from koopman_envs.deprecation import REMOVAL

__all__ = ["DERIVED_KEYS", "OBSERVED_KEYS", "SENSED_KEYS", "Observed", "observed_view"]

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
#: The fields a controller's own front-ends fill and hand on to the controller they stand in
#: front of, never an env: an estimator's ``pose_covariance`` (N, 3, 3) (``ekf:``), the lidar
#: perception's ``mover_covariance``, ``mover_radii``, ``perceived_obstacles`` and
#: ``obstacle_covariance`` (``controllers.perception.front``; under lidar it also writes
#: ``observed_movers``, its tracks), and the radio's ``pose_age`` (N,) (a central controller's,
#: :func:`controllers.base.over_the_radio`). An info written by hand may carry them too.
DERIVED_KEYS = (
    "pose_covariance",
    "mover_covariance",
    "mover_radii",
    "perceived_obstacles",
    "obstacle_covariance",
    "pose_age",
)
#: The info keys a controller may read (what :meth:`Observed.from_info` takes).
OBSERVED_KEYS = SENSED_KEYS + DERIVED_KEYS

#: every array field of :class:`Observed`: its dtype and its shape, each axis a length, ``"N"`` (the
#: team size, the rows of ``observed_poses``) or None (any length). :meth:`Observed.from_info` reads
#: an info's values as these dtypes (every env writes them already, so reading an env's info
#: converts nothing); :meth:`Observed.__post_init__` refuses a value of another dtype or shape,
#: however the value was built
_FIELDS: dict[str, tuple[type, tuple[int | str | None, ...]]] = {
    "observed_poses": (np.float64, ("N", 3)),
    "known_poses": (np.float64, ("N", "N", 3)),
    "message_age": (np.int64, ("N", "N")),
    "targets": (np.float64, ("N", 3)),
    "lidar_ranges": (np.float64, ("N", None)),
    "observed_movers": (np.float64, (None, 4)),
    "mover_tracked": (np.bool_, (None,)),
    "pose_age": (np.int64, ("N",)),
    "pose_covariance": (np.float64, ("N", 3, 3)),
    "mover_covariance": (np.float64, (None, 4, 4)),
    "mover_radii": (np.float64, (None,)),
    "perceived_obstacles": (np.float64, (None, 3)),
    "obstacle_covariance": (np.float64, (None, 2, 2)),
}
#: the ages, counted in whole control periods (read through :func:`_whole_periods`)
_AGES = ("message_age", "pose_age")


#: each field's dtype as NumPy's (compared by identity first), in :data:`_FIELDS`' order
_DTYPES = tuple((name, np.dtype(dtype)) for name, (dtype, _) in _FIELDS.items())
#: the fields every value has
_REQUIRED = frozenset({"observed_poses", "known_poses", "message_age"})


@functools.lru_cache(maxsize=256)
def _shapes(n: int) -> dict[str, tuple[int | None, ...]]:
    """Each field's shape for a team of ``n`` (None: any length), built once per team size."""
    return {name: tuple(n if a == "N" else a for a in shape) for name, (_, shape) in _FIELDS.items()}  # type: ignore[misc]


def _fits(got: tuple[int, ...], want: tuple[int | None, ...]) -> bool:
    """Whether shape ``got`` is ``want``, a None in it any length."""
    return len(got) == len(want) and all(w is None or g == w for g, w in zip(got, want, strict=True))


def _refuse(name: str, value: Any, n: int) -> NoReturn:
    """Raise the error that names what is wrong with field ``name`` (:meth:`Observed.__post_init__`)."""
    dtype, shape = _FIELDS[name]
    if not isinstance(value, np.ndarray):
        raise TypeError(
            f"Observed.{name} is a {type(value).__name__}; expected an ndarray of {np.dtype(dtype)} "
            "(Observed.from_info reads an info's lists and numbers)"
        )
    if value.dtype != dtype:
        raise TypeError(
            f"Observed.{name} has dtype {value.dtype}; expected {np.dtype(dtype)} "
            "(Observed.from_info converts an info's values)"
        )
    if name == "observed_poses":
        raise ValueError(f"Observed.{name} has shape {value.shape}; expected (N, 3): x, y, theta per robot")
    raise ValueError(
        f"Observed.{name} has shape {value.shape}; expected {_shape_text(shape, n)} for {n} robots"
    )


def _shape_text(shape: tuple[int | str | None, ...], n: int) -> str:
    """An expected shape for a message: ``(3, 3)``, ``(3, *)`` (``*``: any length)."""
    return (
        "("
        + ", ".join(str(n) if a == "N" else "*" if a is None else str(a) for a in shape)
        + (",)" if len(shape) == 1 else ")")
    )


def _whole_periods(key: str, given: Any) -> NDArray[np.int64]:
    """``given`` as int64 ages in control periods (an integer array as it is, not copied), or a
    ``ValueError`` naming ``key`` and the first entry that is no whole number of periods.

    A NaN or fractional age is refused rather than cast: the cast gives an arbitrary integer
    (NaN becomes -2**63, "nothing heard" to readers that test ``age < 0``, or a huge age), and
    every reader acts on the number: leaves an unheard team-mate out (consensus, ORCA, DWA, the
    perception front), puts the planned start in its place (:func:`controllers.base.over_the_radio`)
    or picks the step of its plan by it (:mod:`controllers.mpc.plan_exchange`). An env writes int64.
    """
    ages = np.asarray(given)
    if ages.dtype.kind in "iu":
        return np.asarray(ages, dtype=np.int64)
    if ages.dtype.kind == "f":
        # whole and within int64 (2**63 itself is not): exactly representable, so the cast is exact
        whole = np.isfinite(ages) & (ages == np.round(ages)) & (np.abs(ages) < 2.0**63)
        if whole.all():
            return ages.astype(np.int64)
        at = tuple(int(i) for i in np.argwhere(~whole)[0])
        raise ValueError(
            f"{key}{list(at) if at else ''}={float(ages[at])!r} is not a whole number of periods "
            f"({int((~whole).sum())} such entries); an age counts control periods: 0 at a robot itself, "
            "-1 before a message arrives"
        )
    raise TypeError(f"{key} has dtype {ages.dtype}; expected whole control periods (int64)")


@dataclass(frozen=True, eq=False)
class Observed:
    """What a model-based controller receives each period: what the robots believe, never the truth.

    The first three fields are always there (an info written by hand with ``poses`` only is one
    of perfect information: see :meth:`from_info`); the others are None where nothing supplies
    them. The sensed ones come from the env's ``info``; the derived ones from the stages in
    front of the controller, each of which returns a new value. The arrays are the info's own
    (not copies): a stage that changes one copies it first.

    Attributes
    ----------
    observed_poses : ndarray, shape (N, 3)
        Every robot's estimate of its own pose: x [m], y [m], theta [rad].
    known_poses : ndarray, shape (N, N, 3)
        Row i: robot i's own estimate at i, its last message of each team-mate elsewhere
        (zeros before one arrives).
    message_age : ndarray of int64, shape (N, N)
        Periods since that message was sent (0 at i itself, -1 before one arrives).
    targets : ndarray, shape (N, 3), optional
        The goals (given, not sensed); None only in an info written by hand without them.
    lidar_ranges : ndarray, shape (N, B), optional
        The beam readings [m], with ``sensing="lidar"``.
    observed_movers : ndarray, shape (C, 4), optional
        The movers as observed: x [m], y [m], vx, vy [m/s] (with ``sensing="state"`` the env's
        tracker; under lidar the perception's moving tracks).
    mover_tracked : ndarray of bool, shape (C,), optional
        Which of ``observed_movers`` have a track (the env's tracker).
    pose_age : ndarray of int64, shape (N,), optional
        Derived by the radio of a central controller (:func:`controllers.base.over_the_radio`):
        how old each row of ``observed_poses`` is [periods], -1 for a robot never heard from; the
        pose estimator in the same controller carries a late pose forward by it.
    pose_covariance : ndarray, shape (N, 3, 3), optional
        Derived by a pose estimator: the covariance of ``observed_poses``.
    mover_covariance : ndarray, shape (C, 4, 4), optional
        Derived by the lidar perception: the covariance of each moving track.
    mover_radii : ndarray, shape (C,), optional
        Derived by the lidar perception: each moving track's radius [m].
    perceived_obstacles : ndarray, shape (M, 3), optional
        Derived by the lidar perception with the map unknown: the local map, x, y, r [m].
    obstacle_covariance : ndarray, shape (M, 2, 2), optional
        Derived with ``perceived_obstacles``: the covariance of each disc's centre.
    perceived : bool
        Whether the lidar perception has run on this value (a wrapper in front that perceived
        hands it on, and the controller behind it does not perceive again).
    """

    observed_poses: NDArray[np.float64]
    known_poses: NDArray[np.float64]
    message_age: NDArray[np.int64]
    targets: NDArray[np.float64] | None = None
    lidar_ranges: NDArray[np.float64] | None = None
    observed_movers: NDArray[np.float64] | None = None
    mover_tracked: NDArray[np.bool_] | None = None
    pose_age: NDArray[np.int64] | None = None
    pose_covariance: NDArray[np.float64] | None = None
    mover_covariance: NDArray[np.float64] | None = None
    mover_radii: NDArray[np.float64] | None = None
    perceived_obstacles: NDArray[np.float64] | None = None
    obstacle_covariance: NDArray[np.float64] | None = None
    perceived: bool = False

    def __post_init__(self) -> None:
        """Refuse a field of another type, dtype or shape than :data:`_FIELDS` gives, whether the
        value came from :meth:`from_info` or was built directly (a stage's
        :func:`dataclasses.replace` included): ``TypeError`` for a type or dtype, ``ValueError``
        for a shape, each naming the field."""
        poses = self.observed_poses
        n = poses.shape[0] if isinstance(poses, np.ndarray) and poses.ndim else -1  # checked first
        shapes = _shapes(n)
        for name, dtype in _DTYPES:
            value = getattr(self, name)
            if value is None and name not in _REQUIRED:
                continue
            # every value is checked on every stage's replace: the common case in a few compares
            if (
                not isinstance(value, np.ndarray)
                or (value.dtype is not dtype and value.dtype != dtype)
                or (value.shape != shapes[name] and not _fits(value.shape, shapes[name]))
            ):
                _refuse(name, value, n)
        if not isinstance(self.perceived, bool):
            raise TypeError(f"Observed.perceived={self.perceived!r}; expected True or False")

    @classmethod
    def from_info(cls, info: Mapping[str, Any]) -> Observed:
        """The observed part of ``info`` (the keys of :data:`OBSERVED_KEYS` it has), without the
        true state.

        An info without ``observed_poses`` (written by hand, as in ``ctrl.act(obs, {"poses":
        poses})``) is one of perfect information: its ``poses`` are then every robot's estimate;
        an info without ``known_poses`` / ``message_age`` has every robot hear every team-mate at
        once (each row of ``known_poses`` the team, of age 0). Every KoopNav env's info has all
        three, so this never reads the truth of an env. An info that carries the perception's
        ``mover_radii`` counts as perceived.

        Raises
        ------
        ValueError
            ``info`` has neither ``observed_poses`` nor ``poses``, the poses, messages or ages
            are not of shapes (N, 3), (N, N, 3) and (N, N), or an age is not a whole number of
            periods (NaN, a fraction).
        TypeError
            ``message_age`` is not numeric.
        """
        given = info.get("observed_poses")
        if given is None:
            given = info.get("poses")
        if given is None:
            raise ValueError(
                "an info for a controller needs 'observed_poses' (every KoopNav env writes it) or, "
                f"written by hand, 'poses'; this one has {sorted(info)}"
            )
        poses = np.asarray(given, dtype=np.float64)
        values: dict[str, Any] = {"observed_poses": poses}
        for key, (dtype, _) in _FIELDS.items():
            if key == "observed_poses" or info.get(key) is None:
                continue
            values[key] = (
                _whole_periods(key, info[key]) if key in _AGES else np.asarray(info[key], dtype=dtype)
            )
        # a team that hears every team-mate at once: each row of known_poses the team, of age 0
        # (poses of another shape are refused by the constructor, which checks them first)
        n = poses.shape[0] if poses.ndim else 0
        if "known_poses" not in values:
            values["known_poses"] = (
                np.broadcast_to(poses[None], (n, n, 3)) if poses.shape == (n, 3) else np.zeros((n, n, 3))
            )
        if "message_age" not in values:
            values["message_age"] = np.zeros((n, n), dtype=np.int64)
        return cls(**values, perceived=info.get("mover_radii") is not None)

    @property
    def n_robots(self) -> int:
        """Team size N."""
        return int(self.observed_poses.shape[0])

    @property
    def poses(self) -> NDArray[np.float64]:
        """The robots' pose estimates, (N, 3): ``observed_poses`` (what a controller of the
        earlier API read as ``info["poses"]``; without uncertainty settings, the truth)."""
        return self.observed_poses

    @property
    def distances(self) -> NDArray[np.float64] | None:
        """Each robot's distance to its target as it believes it [m], (N,): from its estimate
        (the env's formula, so without uncertainty settings equal to ``info["distances"]`` bit
        for bit); None without ``targets``."""
        if self.targets is None:
            return None
        poses = self.observed_poses
        dx, dy = self.targets[..., 0] - poses[..., 0], self.targets[..., 1] - poses[..., 1]
        return np.sqrt(dx * dx + dy * dy)

    def to_info(self) -> dict[str, Any]:
        """The fields that are set, as the dict of observed keys a controller of the earlier API
        reads (:data:`OBSERVED_KEYS` in order, then ``poses`` and ``distances``): what a wrapper
        hands a controller that takes no :class:`Observed`, read back whole by :meth:`from_info`
        (``perceived`` from ``mover_radii``)."""
        out = {key: value for key in OBSERVED_KEYS if (value := getattr(self, key)) is not None}
        out["poses"] = self.poses
        distances = self.distances
        if distances is not None:
            out["distances"] = distances
        return out

    # ------------------------------------------------------------------ the earlier API
    def _legacy(self, key: str) -> Any:
        warnings.warn(
            f"reading the observed view by key ({key!r}) is deprecated and will be removed in KoopNav "
            f"{REMOVAL}; read the attribute of koopman_envs.Observed instead (observed.{key})",
            DeprecationWarning,
            stacklevel=3,
        )
        return self.to_info().get(key)

    def __getitem__(self, key: str) -> Any:
        """Deprecated: ``observed[key]`` as the dict view was read (``KeyError`` for a field not set)."""
        value = self._legacy(key)
        if value is None:
            raise KeyError(key)
        return value

    def get(self, key: str, default: Any = None) -> Any:
        """Deprecated: ``observed.get(key, default)`` as the dict view was read."""
        value = self._legacy(key)
        return default if value is None else value

    def __contains__(self, key: object) -> bool:
        """Deprecated: ``key in observed`` as the dict view was read."""
        return isinstance(key, str) and self._legacy(key) is not None


def observed_view(info: Mapping[str, Any]) -> dict[str, Any]:
    """Deprecated: the observed part of ``info`` as a dict, ``Observed.from_info(info).to_info()``.

    Use :meth:`Observed.from_info`; this function is removed in the release named by
    :data:`REMOVAL`.
    """
    warnings.warn(
        f"koopman_envs.observed.observed_view is deprecated and will be removed in KoopNav {REMOVAL}; "
        "use koopman_envs.Observed.from_info(info)",
        DeprecationWarning,
        stacklevel=2,
    )
    return Observed.from_info(info).to_info()
