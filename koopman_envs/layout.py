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

``layout["team"]`` is that part's slice of a block, ``layout.entry("heading", 1)`` one entry's
index and ``layout.items(blocks, "movers")[..., MoverEntry.CLEARANCE]`` one field of every item of
a listing part (the fields of an item are named by :data:`ITEM_ENTRIES`), so a policy never
counts positions by hand; every env front carries its layout
(``env.unwrapped.scenario.observation_layout``), and a policy trained on one layout checks that
it reads the same one. Which parts a setting adds is decided here once: the movers are listed
only when the robots sense the state (with lidar the beams hit them instead). The compiled
writer (:mod:`koopman_envs.tasks.observation`) takes where each part begins from
:attr:`ObservationLayout.offsets` and its bounds part by part, so the table above is the one
definition of the order.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from koopman_envs.checks import check_choice, check_flag, check_int

__all__ = [
    "FAR",
    "ITEM_ENTRIES",
    "MessageEntry",
    "MoverEntry",
    "ObservationLayout",
    "ObstacleEntry",
    "PART_WIDTH",
    "PartOffsets",
    "TeamEntry",
]


#: What an absent item of a listing part reads as its clearance [m] (a team-mate out of sight, an
#: obstacle or a mover not listed): farther than anything in a 20 m workspace.
FAR = 30.0


class TeamEntry(IntEnum):
    """The entries of one team-mate in ``team``: body-frame offset [m] and surface clearance [m]."""

    DX = 0
    DY = 1
    CLEARANCE = 2


class ObstacleEntry(IntEnum):
    """The entries of one listed obstacle in ``obstacles``: body-frame offset of its centre [m]
    and surface clearance [m] (an absent one reads (0, 0, ``FAR``))."""

    DX = 0
    DY = 1
    CLEARANCE = 2


class MessageEntry(IntEnum):
    """The entries of one team-mate in ``messages``: age of its last message [periods] and 1 if
    one has arrived, else 0."""

    AGE = 0
    HEARD = 1


class MoverEntry(IntEnum):
    """The entries of one listed mover in ``movers``: body-frame offset of its centre [m],
    body-frame velocity [m/s] and surface clearance [m]."""

    DX = 0
    DY = 1
    VX = 2
    VY = 3
    CLEARANCE = 4


#: the named entries of one item of each part that lists several (a beam is one reading)
ITEM_ENTRIES: dict[str, type[IntEnum]] = {
    "team": TeamEntry,
    "obstacles": ObstacleEntry,
    "messages": MessageEntry,
    "movers": MoverEntry,
}
#: entries per item of the parts that list several items (a team-mate, an obstacle, ...)
PART_WIDTH = {**{part: len(entries) for part, entries in ITEM_ENTRIES.items()}, "beams": 1}


class PartOffsets(NamedTuple):
    """Where each part begins in a block, in block order (the one definition of that order),
    and the block's size: what the compiled writer is handed. A part a layout lacks begins
    where the next one does (it has no entries), so every part's width is the gap to the next."""

    position: int
    heading: int
    target: int
    target_distance: int
    target_heading: int
    team: int
    obstacles: int
    beams: int
    formation_error: int
    messages: int
    movers: int
    size: int

    def as_record(self) -> NDArray[np.void]:
        """These offsets as a one-element structured array, one int64 field per name: what the
        compiled writer is handed. Numba reads a record's fields by name as a named tuple's, but
        types a record argument at a call as fast as a plain array, where it types a named tuple
        field by field in Python (several microseconds a call, on every step of a single env)."""
        return np.array([tuple(self)], dtype=[(name, np.int64) for name in self._fields])


#: every part a block may have, in block order (``obstacles`` and ``beams`` exclude each other)
PART_NAMES: tuple[str, ...] = PartOffsets._fields[:-1]


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

    def __post_init__(self) -> None:
        """Refuse a team of no robot, a count that is no integer >= 0 and a flag that is no bool,
        each by name (``ValueError``); numpy integers and bools are taken as Python's."""
        object.__setattr__(self, "n_robots", check_int("n_robots", self.n_robots, 1))
        for name in ("n_obstacle_obs", "beams", "movers"):
            object.__setattr__(self, name, check_int(name, getattr(self, name), 0))
        for name in ("formation", "comm"):
            object.__setattr__(self, name, check_flag(name, getattr(self, name)))

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
        others = self.n_robots - 1
        widths: dict[str, int | None] = {  # None: a part this layout does not have
            "position": 2,
            "heading": 2,
            "target": 2,
            "target_distance": 1,
            "target_heading": 2,
            "team": PART_WIDTH["team"] * others,
            "obstacles": None if self.beams else PART_WIDTH["obstacles"] * self.n_obstacle_obs,
            "beams": self.beams or None,
            "formation_error": 2 if self.formation else None,
            "messages": PART_WIDTH["messages"] * others if self.comm else None,
            "movers": PART_WIDTH["movers"] * self.movers or None,
        }
        return tuple((name, width) for name in PART_NAMES if (width := widths[name]) is not None)

    @property
    def size(self) -> int:
        """Entries of one block."""
        return sum(width for _, width in self.parts)

    @property
    def offsets(self) -> PartOffsets:
        """Where each part begins in a block (:class:`PartOffsets`), for the compiled writer."""
        widths = dict(self.parts)
        starts = [0]
        for name in PART_NAMES:
            starts.append(starts[-1] + widths.get(name, 0))
        return PartOffsets(*starts)

    def count(self, name: str) -> int:
        """How many items part ``name`` lists (0 when this layout has no such part); ``ValueError``
        naming ``name`` and the parts that list items for any other name."""
        check_choice("part", name, sorted(PART_WIDTH), sep=" ", among="the parts that list items")
        return dict(self.parts).get(name, 0) // PART_WIDTH[name]

    def items(self, blocks: NDArray[np.float64], name: str) -> NDArray[np.float64]:
        """Part ``name`` of ``blocks`` (..., F) as its items, (..., count, PART_WIDTH[name]): field
        ``f`` of every item is ``[..., f]`` with ``f`` one of ``ITEM_ENTRIES[name]``."""
        count = self.count(name)
        return blocks[..., self[name]].reshape(blocks.shape[:-1] + (count, PART_WIDTH[name]))

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
