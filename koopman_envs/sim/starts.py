"""Start poses of a reset under ``start_noise``: the map's starts, perturbed and redrawn until valid."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from koopman_envs.params import PARAMS
from koopman_envs.sim.dynamics import wrap_angle
from koopman_envs.sim.maps.map_spec import MapSpec

__all__ = ["START_NOISE_ATTEMPTS", "NoValidStarts", "perturbed_starts"]

#: ``start_noise``: draws of a whole team's start perturbation before a reset gives up (ours).
START_NOISE_ATTEMPTS = 100


class NoValidStarts(ValueError, RuntimeError):
    """No valid start poses in :data:`START_NOISE_ATTEMPTS` draws: a ``ValueError`` (the
    ``start_noise`` a user set is too large for the map, and the message names it, as every bad
    keyword's), and the ``RuntimeError`` it was before, for the code that catches that."""


def perturbed_starts(
    spec: MapSpec, rng: np.random.Generator, n_robots: int, noise: float, radius: float
) -> NDArray[np.float64]:
    """The map's starts, each displaced uniformly in a disc of radius ``noise`` [m] and turned
    uniformly within +-``noise`` [rad], redrawn for the whole team until the placement passes
    :meth:`MapSpec.pose_problem` (the check every map passes).

    Raises
    ------
    NoValidStarts
        No valid draw in :data:`START_NOISE_ATTEMPTS` attempts (a ``ValueError`` and a
        ``RuntimeError``).
    """
    n = n_robots
    base = spec.starts[:n]
    for _ in range(START_NOISE_ATTEMPTS):
        # sqrt of a uniform radius fraction makes the displacement uniform over the disc's area
        distance = noise * np.sqrt(rng.uniform(size=n))
        bearing = rng.uniform(-np.pi, np.pi, size=n)
        turn = rng.uniform(-noise, noise, size=n)
        starts = np.column_stack(
            [
                base[:, 0] + distance * np.cos(bearing),
                base[:, 1] + distance * np.sin(bearing),
                wrap_angle(base[:, 2] + turn),
            ]
        )
        problem = spec.pose_problem(starts, radius, PARAMS.workspace, "start")
        if problem is None:
            return starts
    raise NoValidStarts(
        f"start_noise={noise!r}: no valid start poses on map {spec.name!r} in "
        f"{START_NOISE_ATTEMPTS} draws of the whole team (last: {problem}); use a smaller start_noise"
    )
