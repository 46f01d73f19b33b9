"""The layout of one robot's observation block, by name: the public seam between the environments
and every policy that reads them.

A block is a run of named parts, in this order (body frame = the robot's own x forward, y left):

=================== ======================================================= ======= ==========
part                meaning                                                 entries unit
=================== ======================================================= ======= ==========
``position``        x, y position                                           2       m
``heading``         cos(theta), sin(theta)                                  2       none
``target``          target position in the body frame                       2       m
``target_distance`` distance to the target                                  1       m
``target_heading``  cos, sin of (target heading - heading)                  2       none
``team``            each other robot j (index order): body-frame dx, dy,    3 each  m
                    surface clearance
``obstacles``       the ``n_obstacle_obs`` nearest obstacles, nearest       3 each  m
                    first: body-frame dx, dy to the centre, surface
                    clearance; missing ones read (0, 0, ``FAR``)
``beams``           with ``sensing="lidar"``, instead of ``obstacles``:     1 each  m
                    the beam readings
``formation_error`` formation task only: e_i = (p_i - p_0) - offset_i       2       m
                    (world frame)
``messages``        with a ``comm`` setting: each other robot j (index      2 each  periods, -
                    order): age of its last message and 1 if one has
                    arrived, else 0
``movers``          with ``movers`` and ``sensing="state"``: the            5 each  m, m/s
                    ``movers.observed`` nearest movers, nearest first:
                    body-frame dx, dy, vx, vy, surface clearance
=================== ======================================================= ======= ==========

``layout["team"]`` is that part's slice of a block and ``layout.entry("heading", 1)`` one entry's
index, so a policy never counts positions by hand; every env front carries its layout
(``env.unwrapped.scenario.observation_layout``), and a policy trained on one layout checks that
it reads the same one. Which parts a setting adds is decided here once: the movers are listed
only when the robots sense the state (with lidar the beams hit them instead).
"""

from __future__ import annotations

from dataclasses import dataclass

from koopman_envs.movers import MOVER_FEATURES

__all__ = ["ObservationLayout", "PART_WIDTH"]

#: entries per item of the parts that list several items (a team-mate, an obstacle, ...)
PART_WIDTH = {"team": 3, "obstacles": 3, "beams": 1, "messages": 2, "movers": MOVER_FEATURES}


@dataclass(frozen=True)
class ObservationLayout:
    """The named parts of one robot's observation block (module docstring).

    Parameters
    ----------
    n_robots : int
        Team size N (N - 1 team-mates listed).
    n_obstacle_obs : int
        Obstacles listed (ignored with ``beams``).
    formation : bool
        Whether the block ends its task part with the formation error.
    beams : int
        Lidar readings replacing the obstacle list (0: the list).
    comm : bool
        Whether the message ages and arrival flags follow.
    movers : int
        Movers listed at the end (``movers.observed``; 0 with lidar or without movers).
    """

    n_robots: int
    n_obstacle_obs: int = 0
    formation: bool = False
    beams: int = 0
    comm: bool = False
    movers: int = 0

    @classmethod
    def for_settings(
        cls,
        n_robots: int,
        n_obstacle_obs: int,
        formation: bool,
        beams: int,
        comm: bool,
        movers_observed: int,
    ) -> ObservationLayout:
        """The layout an env of these settings builds: the movers are listed only when the
        robots sense the state (``beams == 0``); with lidar the beams hit them instead."""
        return cls(n_robots, n_obstacle_obs, formation, beams, comm, 0 if beams else movers_observed)

    @property
    def parts(self) -> tuple[tuple[str, int], ...]:
        """Each part's name and entry count, in block order (absent parts left out)."""
        n = self.n_robots
        out = [
            ("position", 2),
            ("heading", 2),
            ("target", 2),
            ("target_distance", 1),
            ("target_heading", 2),
            ("team", 3 * (n - 1)),
        ]
        out.append(("beams", self.beams) if self.beams else ("obstacles", 3 * self.n_obstacle_obs))
        if self.formation:
            out.append(("formation_error", 2))
        if self.comm:
            out.append(("messages", 2 * (n - 1)))
        if self.movers:
            out.append(("movers", MOVER_FEATURES * self.movers))
        return tuple(out)

    @property
    def size(self) -> int:
        """Entries of one block."""
        return sum(width for _, width in self.parts)

    def __getitem__(self, name: str) -> slice:
        """The slice of part ``name`` in a block (``KeyError`` naming the parts this layout has)."""
        start = 0
        for part, width in self.parts:
            if part == name:
                return slice(start, start + width)
            start += width
        raise KeyError(f"no part {name!r} in this observation layout; it has {[p for p, _ in self.parts]}")

    def entry(self, name: str, index: int = 0) -> int:
        """The position in a block of entry ``index`` of part ``name``."""
        part = self[name]
        start, stop = int(part.start), int(part.stop)
        if not 0 <= index < stop - start:
            raise IndexError(f"part {name!r} has {stop - start} entries; index {index} is outside")
        return start + index

    def has(self, name: str) -> bool:
        """Whether this layout has part ``name``."""
        return any(part == name for part, _ in self.parts)

    def without_movers(self) -> ObservationLayout:
        """The layout of a block with its movers taken off (what a set policy's features read)."""
        return ObservationLayout(self.n_robots, self.n_obstacle_obs, self.formation, self.beams, self.comm, 0)
