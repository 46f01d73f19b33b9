"""What the controllers assume of the moving obstacles: which ones matter and where they will be.

Every built-in controller reads the movers from what it observes (``observed_movers`` of
:class:`koopman_envs.Observed`: x, y, vx, vy per mover, tracked with ``sensing="state"``; with
lidar, the tracks of the team's perception of the beams, :mod:`controllers.perception.front`,
with their radii). The prediction is one of
:data:`MOVER_PREDICTIONS`:

``"constant_velocity"``
    Each mover keeps its observed velocity over the horizon: stage ``s`` at ``p + s dt v``. It
    is exact for ``"constant"`` movers between reflections and the usual first guess for people
    (the constant-velocity baseline of pedestrian prediction).
``"static"``
    Each mover stays where it is now: prediction off, the ablation the comparison pairs against.

The NMPCs take the predicted discs as time-varying obstacle slots
(:func:`controllers.mpc.slots.mover_slots`), the safety filter the
observed velocity in its moving barrier, and consensus the current positions in its repulsion.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from koopman_envs import Observed
from koopman_envs.checks import check_choice

__all__ = [
    "MOVER_PREDICTIONS",
    "check_mover_prediction",
    "observed_mover_radii",
    "observed_movers",
    "predict_movers",
]

#: how a controller predicts a mover over its horizon (module docstring)
MOVER_PREDICTIONS = ("constant_velocity", "static")


def check_mover_prediction(value: Any) -> str:
    """``value`` if it is one of :data:`MOVER_PREDICTIONS`, else ``ValueError`` naming it."""
    return str(check_choice("mover_prediction", value, MOVER_PREDICTIONS))


def observed_movers(observed: Observed) -> NDArray[np.float64]:
    """The tracked movers of ``observed``, (C, 4): x, y, vx, vy (shape (0, 4) without any).
    A mover the env's tracker reports no track of (``mover_tracked`` False) is left out."""
    if observed.observed_movers is None:
        return np.zeros((0, 4))
    movers = observed.observed_movers.reshape(-1, 4)
    if observed.mover_tracked is None:
        return movers
    tracked = observed.mover_tracked.reshape(-1)
    return movers if tracked.all() else movers[tracked]


def observed_mover_radii(observed: Observed, default: float) -> NDArray[np.float64]:
    """Each observed mover's radius [m], (C,): the perception's estimates (``mover_radii``, under
    lidar: a track may be a larger object than a person) or ``default`` (the scenario's
    ``mover_radius``) for every mover."""
    count = observed_movers(observed).shape[0]
    if observed.mover_radii is None:
        return np.full(count, float(default))
    radii = observed.mover_radii.reshape(-1)
    if radii.shape[0] != count:
        raise ValueError(f"mover_radii has {radii.shape[0]} entries for {count} observed movers")
    return radii


def predict_movers(
    movers: NDArray[np.float64], horizon: int, dt: float, prediction: str
) -> NDArray[np.float64]:
    """Predicted mover centres at stages 1..T, shape (T, C, 2) (module docstring)."""
    stages = np.arange(1, horizon + 1, dtype=np.float64)[:, None, None]
    position = movers[None, :, :2]
    if prediction == "static":
        return np.broadcast_to(position, (horizon, *movers[:, :2].shape)).copy()
    return position + stages * dt * movers[None, :, 2:4]
