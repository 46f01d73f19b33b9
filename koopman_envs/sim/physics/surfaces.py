"""Wheel-ground surfaces of the physics plant: the names, the friction checks and the draws.

Plain numpy (no MuJoCo): the env keywords and the map files are checked with it whether or not
the ``[physics]`` extra is installed. The numbers live in :mod:`koopman_envs.params`
(:data:`~koopman_envs.params.SURFACES`, :data:`~koopman_envs.params.SLIP_SURFACES`).

A surface *setting* is a surface name (its friction drawn per episode from the stated range) or
a friction coefficient in (0, :data:`~koopman_envs.params.FRICTION_MAX`] (fixed).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from koopman_envs.checks import did_you_mean
from koopman_envs.params import FRICTION_MAX, SLIP_SURFACES, SURFACE_LAMBDA_BOUNDS, SURFACES

__all__ = [
    "SurfaceSetting",
    "check_friction",
    "check_surface",
    "draw_friction",
    "floor_surface",
    "surface_for_lambda",
]

#: a surface name of :data:`~koopman_envs.params.SURFACES` or a fixed friction coefficient
SurfaceSetting = str | float


def check_friction(name: str, value: Any) -> float:
    """``value`` as a friction coefficient in (0, FRICTION_MAX], else ValueError naming ``name``."""
    numeric = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(
        value, (bool, np.bool_)
    )
    if not numeric or not math.isfinite(float(value)) or not 0.0 < float(value) <= FRICTION_MAX:
        raise ValueError(
            f"{name}={value!r} is not a friction coefficient; allowed: a number in (0, {FRICTION_MAX:g}] "
            f"or a surface name in {list(SURFACES)}"
        )
    return float(value)


def check_surface(name: str, value: Any) -> SurfaceSetting:
    """A surface setting: a name of :data:`~koopman_envs.params.SURFACES` (with did-you-mean) or
    a friction coefficient (:func:`check_friction`)."""
    if isinstance(value, str):
        if value not in SURFACES:
            raise ValueError(
                f"{name}={value!r} is not a surface; allowed: one of {list(SURFACES)}"
                f"{did_you_mean(value, SURFACES)} or a friction coefficient in (0, {FRICTION_MAX:g}]"
            )
        return value
    return check_friction(name, value)


def floor_surface(slip: Any) -> SurfaceSetting:
    """The floor of the physics plant for the ``slip`` keyword: a named slip setting's surface
    (:data:`~koopman_envs.params.SLIP_SURFACES`), a surface name, or a friction coefficient.

    Raises
    ------
    ValueError
        Anything else (the kinematic plant's per-robot lambdas, ``"random"``, ``"drift"`` and
        schedules have no physical counterpart here), naming the value and what is allowed.
    """
    if isinstance(slip, str) and slip in SLIP_SURFACES:
        return SLIP_SURFACES[slip]
    if isinstance(slip, str) and slip not in SURFACES:
        allowed = [*SLIP_SURFACES, *SURFACES]
        raise ValueError(
            f"slip={slip!r} has no surface on plant='mujoco'; allowed: one of {allowed}"
            f"{did_you_mean(slip, allowed)} or a friction coefficient in (0, {FRICTION_MAX:g}]"
        )
    if not isinstance(slip, str) and not isinstance(slip, (int, float, np.integer, np.floating)):
        raise ValueError(
            f"slip={slip!r} has no surface on plant='mujoco' (per-robot lambdas and schedules are the "
            f"kinematic plant's); allowed: one of {[*SLIP_SURFACES, *SURFACES]} or a friction "
            f"coefficient in (0, {FRICTION_MAX:g}]"
        )
    return check_surface("slip", slip)


def surface_for_lambda(lam: float) -> str:
    """The surface of a slip zone that names none, from its slip mean (the rule of
    :data:`~koopman_envs.params.SURFACE_LAMBDA_BOUNDS`)."""
    low, high = SURFACE_LAMBDA_BOUNDS
    return "carpet" if lam <= low else ("gravel" if lam <= high else "ice")


def draw_friction(rng: np.random.Generator, setting: SurfaceSetting, size: int) -> NDArray[np.float64]:
    """``size`` friction coefficients of ``setting``: uniform on a surface's range (``size``
    uniform draws from ``rng``), or the fixed coefficient (no draw)."""
    if isinstance(setting, str):
        low, high = SURFACES[setting]
        return rng.uniform(low, high, size)
    return np.full(size, float(setting))
