"""A run's outcome as data: its episode records, the run configuration, and what is derived from
them (cells, leaderboard rows, paired comparisons). It knows no output format; the renderers
(:mod:`evaluation.report`, :mod:`evaluation.html`, :mod:`evaluation.figures`) read it, and
:class:`evaluation.results.Results` adds the formats."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from evaluation.aggregate import BREAKDOWNS, Cell, aggregate, breakdown, leaderboard, paired_comparisons
from evaluation.distinct import read_once
from evaluation.records import ran

__all__ = ["RunData"]


@dataclass
class RunData:
    """Everything a run produced: episode records, cells, and the run configuration (data only:
    :class:`evaluation.results.Results` adds its formats).

    ``records`` are read once (:func:`evaluation.distinct.read_once`): an episode given twice
    alike is kept once, one given twice with different outcomes raises
    :class:`~evaluation.distinct.ConflictingRecords` (a ``ValueError``)."""

    records: list[dict[str, Any]]
    config: dict[str, Any]
    cells: list[Cell] = field(default_factory=list)

    def __post_init__(self) -> None:
        # every episode once, whoever assembled the records (a page pooling several runs, a
        # sweep level, an API caller): a repeat counts once, a conflicting one is refused
        self.records = read_once(self.records, "the run's records")
        if not self.cells:
            self.cells = aggregate(self.records)

    @property
    def failed_episodes(self) -> list[dict[str, Any]]:
        """Records of episodes that raised."""
        return [r for r in self.records if not ran(r)]

    def cell(self, env_id: str, controller: str, map_name: str, slip: str) -> Cell:
        """One cell by its coordinates."""
        for c in self.cells:
            if (c.env_id, c.controller, c.map, c.slip) == (env_id, controller, map_name, slip):
                return c
        raise KeyError((env_id, controller, map_name, slip))

    def leaderboard(self) -> list[dict[str, Any]]:
        """One row per (task, controller), ranked; see :func:`evaluation.aggregate.leaderboard`."""
        return leaderboard(self.cells, self.records)

    def suite_breakdown(self) -> list[dict[str, Any]]:
        """A suite run's success per tier, then per family, of every (task, controller)
        (:func:`evaluation.aggregate.breakdown`); empty for a run without a suite."""
        return [row for by in BREAKDOWNS for row in breakdown(self.records, by)]

    def paired(self) -> list[dict[str, Any]]:
        """Paired comparisons of every two controllers of a task on their shared seeds."""
        return paired_comparisons(self.records)

    def table_keys(self) -> list[tuple[str, str]]:
        """(env id, controller) of every per-controller table, in report order."""
        return [
            (env_id, name)
            for env_id in dict.fromkeys(c.env_id for c in self.cells)
            for name in dict.fromkeys(c.controller for c in self.cells if c.env_id == env_id)
        ]
