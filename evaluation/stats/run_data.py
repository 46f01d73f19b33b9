"""A run's outcome as data: its episode records, the run configuration, and what is derived from
them (cells, leaderboard rows, paired comparisons). It knows no output format; the renderers
(:mod:`evaluation.reports.sections`, :mod:`evaluation.reports.html`, :mod:`evaluation.reports.figures`) read it, and
:class:`evaluation.reports.results.Results` adds the formats."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

from evaluation.episodes.distinct import read_once
from evaluation.episodes.records import ran
from evaluation.stats.aggregate import Cell, aggregate, leaderboard, paired_comparisons
from evaluation.stats.suite_statistics import (
    BREAKDOWNS,
    breakdown,
    is_suite_run,
    layout_summary,
    suite_tables,
)

__all__ = ["RunData"]


@dataclass
class RunData:
    """Everything a run produced: episode records, cells, and the run configuration (data only:
    :class:`evaluation.reports.results.Results` adds its formats).

    ``records`` are read once (:func:`evaluation.episodes.distinct.read_once`): an episode given twice
    alike is kept once, one given twice with different outcomes raises
    :class:`~evaluation.episodes.distinct.ConflictingRecords` (a ``ValueError``)."""

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
        """One row per (task, controller), ranked; see :func:`evaluation.stats.aggregate.leaderboard`.
        Computed once (every format reads it; a suite run's intervals are bootstraps)."""
        return self._leaderboard

    @cached_property
    def _leaderboard(self) -> list[dict[str, Any]]:
        return leaderboard(self.cells, self.records)

    def suite_breakdown(self) -> list[dict[str, Any]]:
        """A suite run's success per tier, then per family, of every (task, controller)
        (:func:`evaluation.stats.suite_statistics.breakdown`); empty for a run without a suite."""
        return self._suite_breakdown

    @cached_property
    def _suite_breakdown(self) -> list[dict[str, Any]]:
        return [row for by in BREAKDOWNS for row in breakdown(self.records, by)]

    def paired(self) -> list[dict[str, Any]]:
        """Paired comparisons of every two controllers of a task on their shared seeds
        (:func:`evaluation.stats.aggregate.paired_comparisons`; a suite run's: its success table's rows)."""
        if is_suite_run(self.records):  # no tables: one controller, nothing to pair
            return list(self.suite_tables[0]["rows"]) if self.suite_tables else []
        return paired_comparisons(self.records)

    @cached_property
    def suite_tables(self) -> list[dict[str, Any]]:
        """A suite run's tested tables, success first (:func:`evaluation.stats.suite_statistics.suite_tables`:
        each a declared family, Holm within it, its power statement); empty for other runs.
        Computed once (the bootstraps and sign-flip tests take a while on a full split)."""
        return suite_tables(self.records)

    @cached_property
    def layout_summary(self) -> list[dict[str, Any]]:
        """A suite run's rates and metrics per (task, controller) with their intervals over layouts
        (:func:`evaluation.stats.suite_statistics.layout_summary`); empty for other runs."""
        return layout_summary(self.records)

    def table_keys(self) -> list[tuple[str, str]]:
        """(env id, controller) of every per-controller table, in report order."""
        return [
            (env_id, name)
            for env_id in dict.fromkeys(c.env_id for c in self.cells)
            for name in dict.fromkeys(c.controller for c in self.cells if c.env_id == env_id)
        ]
