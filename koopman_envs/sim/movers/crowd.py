"""The ``"crowd"`` movers' velocities: ORCA (optimal reciprocal collision avoidance) from the
RVO2 library through ``pyrvo``, one simulator per environment (docs/movers.md says why this
library).

The waypoint kernel (:mod:`koopman_envs.sim.movers.motion`) gives each pedestrian its preferred
velocity; ORCA turns it into a collision-free one among the other pedestrians, the static
obstacles (circumscribed polygons) and, when the crowd is aware of them, the robots (agents moved
to where the robots are every period).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from koopman_envs.checks import import_optional
from koopman_envs.settings.moving_obstacles import MoverConfig

__all__ = ["ORCA_KEEP_RIGHT", "ORCA_ROBOT_MARGIN", "orca_restore", "orca_simulator", "orca_step"]

#: ORCA's settings (RVO2's example values scaled to a person): neighbour distance [m], the
#: largest neighbour count, and the time horizons for agents and for obstacles [s]
ORCA_NEIGHBOUR_DIST, ORCA_MAX_NEIGHBOURS, ORCA_HORIZON, ORCA_HORIZON_OBSTACLE = 3.0, 10, 2.0, 1.0
#: a pedestrian's preferred direction turned this far to its right [rad] (ours): ORCA alone
#: deadlocks two walkers who meet exactly head-on (RVO2's examples perturb at random for this);
#: a small turn breaks the symmetry without a draw, as the keep-right habit of people does
ORCA_KEEP_RIGHT = 0.05
#: how much larger the aware crowd sees each robot than it is [m] (ours): ORCA shares every
#: avoidance half and half, but a robot follows its controller, not ORCA, so a pedestrian doing
#: only its half would brush a robot that stands still (2 of 8 episodes of 12 pedestrians around
#: a standing team; with this margin none of 20)
ORCA_ROBOT_MARGIN = 0.1
#: sides of the polygon that stands in for a round obstacle in ORCA (circumscribed: never smaller)
ORCA_POLYGON_SIDES = 16


#: the refusal when pyrvo is missing: a ValueError, as every other bad env keyword gets
INSTALL_HINT = (
    "movers with behaviour='crowd' need pyrvo (ORCA): pip install -e '.[crowd]' (or pip install pyrvo)"
)


def _import_pyrvo() -> Any:
    return import_optional("pyrvo", INSTALL_HINT, ValueError)


def orca_simulator(
    obstacles: NDArray[np.float64],
    movers: NDArray[np.float64],
    config: MoverConfig,
    n_robots: int,
    robot_radius: float,
    dt: float,
) -> object:
    """An ORCA simulator of one environment: the movers first, then (aware) one agent per robot."""
    pyrvo = _import_pyrvo()
    sim = pyrvo.RVOSimulator()
    sim.set_time_step(dt)
    sim.set_agent_defaults(
        ORCA_NEIGHBOUR_DIST,
        ORCA_MAX_NEIGHBOURS,
        ORCA_HORIZON,
        ORCA_HORIZON_OBSTACLE,
        config.radius,
        config.speed,
    )
    for x, y in movers:
        sim.add_agent((float(x), float(y)))
    if config.aware:
        for _ in range(n_robots):
            agent = sim.add_agent((1e6, 1e6))
            sim.set_agent_radius(agent, robot_radius + ORCA_ROBOT_MARGIN)
    # a circumscribed polygon per obstacle, counter-clockwise (RVO2's convention for obstacles)
    sides = ORCA_POLYGON_SIDES
    scale = 1.0 / math.cos(math.pi / sides)
    for ox, oy, r in obstacles:
        angles = 2 * math.pi * np.arange(sides) / sides
        sim.add_obstacle(
            [(float(ox + r * scale * math.cos(a)), float(oy + r * scale * math.sin(a))) for a in angles]
        )
    if len(obstacles):
        sim.process_obstacles()
    return sim


def orca_restore(
    obstacles: NDArray[np.float64],
    position: NDArray[np.float64],
    velocity: NDArray[np.float64],
    config: MoverConfig,
    n_robots: int,
    robot_radius: float,
    dt: float,
) -> object:
    """The ORCA simulator of an environment between two periods, rebuilt from what the env stores
    (a copied or unpickled env: the C++ simulator does not pickle).

    Between periods ORCA's whole state is each pedestrian's position and velocity: every period
    sets the preferred velocities and (aware) the robots' agents before it steps, and rebuilds
    the neighbours, the ORCA lines and the agent tree from the positions. ``position`` and
    ``velocity`` (C, 2) hold ORCA's own single-precision values (:func:`orca_step` copies them
    out exactly), so the rebuilt simulator steps bit for bit as the original.
    """
    sim = orca_simulator(obstacles, position, config, n_robots, robot_radius, dt)
    for c in range(position.shape[0]):
        sim.set_agent_velocity(c, (float(velocity[c, 0]), float(velocity[c, 1])))  # type: ignore[attr-defined]
    return sim


def orca_step(
    sims: list[Any],
    rows: NDArray[np.int64],
    position: NDArray[np.float64],
    velocity: NDArray[np.float64],
    robots_before: NDArray[np.float64],
    robots_after: NDArray[np.float64],
    aware: bool,
    dt: float,
) -> None:
    """One ORCA period of the environments ``rows``: the waypoint kernel's velocities are the
    preferred ones; each environment's ``position`` and ``velocity`` rows (K, C, 2) become ORCA's.

    What every environment needs is computed for all of them in numpy first (the preferred
    velocities turned right, the robots' agents) and handed to each simulator as Python lists.
    RVO2 has no batch interface, so the calls remain: for 8 pedestrians about 8 us of RVO2's
    own step against 6 us of setting the preferred velocities and 29 us of reading positions
    and velocities back (each read builds a ``Vector2``). The arithmetic is numpy's element
    by element, as Python's floats did it before, so the crowd moves bit for bit as it did.
    """
    turn_c, turn_s = math.cos(ORCA_KEEP_RIGHT), math.sin(ORCA_KEEP_RIGHT)
    vx, vy = velocity[rows, :, 0], velocity[rows, :, 1]
    preferred = np.stack(
        [turn_c * vx + turn_s * vy, turn_c * vy - turn_s * vx], axis=-1
    ).tolist()  # turned clockwise
    if aware:
        before, after = robots_before[rows, :2], robots_after[rows, :2]
        robot_at = before.transpose(0, 2, 1).tolist()
        robot_velocity = ((after - before) / dt).transpose(0, 2, 1).tolist()
    count = position.shape[1]
    for q, k in enumerate(rows.tolist()):
        sim = sims[k]
        if sim is None:
            raise RuntimeError(
                "the crowd has no ORCA simulator before its first reset: reset the env before stepping"
            )
        for c, pref in enumerate(preferred[q]):
            sim.set_agent_pref_velocity(c, pref)
        if aware:
            for i, (at, v) in enumerate(zip(robot_at[q], robot_velocity[q])):
                sim.set_agent_position(count + i, at)
                sim.set_agent_velocity(count + i, v)
                sim.set_agent_pref_velocity(count + i, v)
        sim.do_step()
        position[k] = [sim.get_agent_position(c).to_tuple() for c in range(count)]
        velocity[k] = [sim.get_agent_velocity(c).to_tuple() for c in range(count)]
