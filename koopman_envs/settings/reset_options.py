"""``reset(options=...)`` of every front: the allowed keys and their one check (docs/reset_options.md)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from numbers import Integral
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["RESET_OPTIONS", "ResetOptions", "parse_reset_options"]


#: the keys of ``reset(options=...)``, on every front (docs/reset_options.md)
RESET_OPTIONS = ("start_poses", "targets", "layout")
#: the keys whose value is an array of poses
_POSE_OPTIONS = ("start_poses", "targets")


@dataclass(frozen=True)
class ResetOptions:
    """Per-episode replacements of one environment's map data (None: the map's).

    Attributes
    ----------
    start_poses : ndarray, shape (N, 3), optional
        Start pose (x [m], y [m], heading [rad]) of every robot, used as given (no
        ``start_noise``).
    targets : ndarray, shape (N, 3), optional
        Target pose of every robot; for formation, the formation offsets are these targets
        relative to robot 0's.
    layout : int, optional
        With ``map="suite:<name>/<split>"``: the index of the split's layout this episode runs on
        (None: the one drawn from the seed).
    """

    start_poses: NDArray[np.float64] | None = None
    targets: NDArray[np.float64] | None = None
    layout: int | None = None


def _layouts(value: Any, count: int, vector: bool) -> list[int | None]:
    """``options["layout"]`` per environment: one integer >= 0 (every environment), or, for the
    vector env, one per sub-environment. Its upper bound is the suite's, checked at the reset."""
    values = list(value) if vector and isinstance(value, (list, tuple, np.ndarray)) else [value] * count
    allowed = "an integer >= 0 (a layout index of the env's suite)" + (
        f", or a sequence of {count} of them (one per sub-env)" if vector else ""
    )
    if len(values) != count or not all(
        isinstance(v, Integral) and not isinstance(v, (bool, np.bool_)) and int(v) >= 0 for v in values
    ):
        raise ValueError(f"options['layout']={value!r} is not allowed; allowed: {allowed}")
    return [int(v) for v in values]


def parse_reset_options(
    options: dict[str, Any] | None,
    n_robots: int,
    num_envs: int | None = None,
    ignored: Sequence[str] = (),
) -> list[ResetOptions]:
    """Check the ``options`` of a ``reset`` and split them per environment.

    The one check of every front's reset options. Keys (see docs/reset_options.md):

    ``start_poses``
        (N, 3) array of x [m], y [m], heading [rad] per robot that replaces the map's starts
        for this episode (``start_noise`` is not applied to it).
    ``targets``
        (N, 3) array of target poses that replaces the map's targets for this episode.
    ``layout``
        With ``map="suite:<name>/<split>"``, the index of the layout to run (per sub-env for
        the vector env); the engine checks it against the suite.

    A value of None means the map's. Here only the keys, shapes and finiteness are checked; the
    engine checks the placement (inside the workspace, clear of obstacles and of each other)
    against the episode's map, which with ``map="random"`` is drawn by the reset itself.

    Parameters
    ----------
    options : dict or None
        What the user passed to ``reset``.
    n_robots : int
        Team size N.
    num_envs : int, optional
        None for a single environment; K for the vector env, where an (N, 3) array applies to
        every sub-environment and a (K, N, 3) array gives sub-environment i its row i.
    ignored : sequence of str
        Keys to accept without effect (the PettingZoo fronts: the probe of ``pettingzoo.test``).

    Returns
    -------
    list of ResetOptions
        One per environment (one for a single environment).

    Raises
    ------
    ValueError
        ``options`` is not a dict, has an unknown key (the message lists the allowed ones), or a
        value of the wrong shape or with NaN/inf entries.
    """
    count = 1 if num_envs is None else int(num_envs)
    if options is None:
        return [ResetOptions()] * count
    if not isinstance(options, dict):
        raise ValueError(f"options={options!r} must be a dict or None; allowed keys: {list(RESET_OPTIONS)}")
    unknown = [key for key in options if key not in RESET_OPTIONS and key not in ignored]
    if unknown:
        raise ValueError(
            f"reset options {unknown} are not supported; allowed keys: {list(RESET_OPTIONS)} "
            "(see docs/reset_options.md)"
        )
    shapes = [(n_robots, 3)] if num_envs is None else [(n_robots, 3), (count, n_robots, 3)]
    per_env: dict[str, list[Any]] = {}
    layout = options.get("layout")
    per_env["layout"] = [None] * count if layout is None else _layouts(layout, count, num_envs is not None)
    for key in _POSE_OPTIONS:
        value = options.get(key)
        if value is None:
            per_env[key] = [None] * count
            continue
        try:
            arr = np.array(value, dtype=np.float64)  # a copy: later changes by the caller do not leak in
        except (TypeError, ValueError) as exc:
            raise ValueError(f"options[{key!r}]={value!r} is not an array of numbers") from exc
        if arr.shape not in shapes:
            allowed = " or ".join(str(shape) for shape in shapes)
            raise ValueError(
                f"options[{key!r}] has shape {arr.shape}; allowed: {allowed}, rows of (x [m], y [m], heading [rad])"
            )
        if not np.isfinite(arr).all():
            bad = np.argwhere(~np.isfinite(arr))[0].tolist()
            raise ValueError(
                f"options[{key!r}] has a non-finite entry at index {bad} ({arr[tuple(bad)]}); allowed: finite numbers"
            )
        arr.setflags(write=False)
        per_env[key] = [arr if arr.ndim == 2 else arr[i] for i in range(count)]
    return [ResetOptions(**{key: per_env[key][i] for key in RESET_OPTIONS}) for i in range(count)]
