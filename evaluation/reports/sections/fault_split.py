"""Crowd collisions split by fault (issue 60): per controller and level of a sweep among movers,
success and success excusing the unavoidable collisions, each with its Wilson interval, their
paired difference on the same episodes, and the collisions that ended episodes split into those
at a robot's fault and those that were not (the rule of docs/movers.md, "Who is at fault").

The split reads two fields every episode record holds since the rule was added,
:data:`FAULT_FIELDS`; records written before lack them, and a publication with any such record
is refused by name (:class:`MissingFaultFields`) rather than shown with an "excusing" rate equal
to success as if it had been measured. docs/make_robustness_md.py ``--fault-split`` puts the
section on a page (docs/crowd_results.md).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from evaluation.episodes.distinct import distinct_records
from evaluation.episodes.records import ran
from evaluation.reports.sections.blocks import Note, Section, TableBlock, interval_cell, level_text
from evaluation.stats.run_data import RunData
from evaluation.stats.statistics import paired_comparison, wilson_interval

__all__ = [
    "FAULT_FIELDS",
    "FaultRow",
    "MissingFaultFields",
    "fault_rows",
    "fault_section",
    "pending_section",
]

#: the record fields the split reads (recorded since the fault rule, docs/movers.md)
FAULT_FIELDS = ("collision_at_fault", "success_excusing_unavoidable")

#: the section's anchor and title
ANCHOR = "collisions-by-fault"
TITLE = "Collisions by fault"


class MissingFaultFields(ValueError):
    """A record that ran without the fields of the fault rule (written before it)."""


@dataclass(frozen=True)
class FaultRow:
    """One controller at one level: its distinct episodes that ran and how they ended.

    ``collisions`` counts the episodes ended by a collision; ``at_fault`` those of them that were
    a robot's fault and ``not_at_fault`` the rest (a mover ran into a robot that was stopped or
    moving away): ``collisions == at_fault + not_at_fault``. ``excused`` counts the successes
    excusing the unavoidable collisions (a success, or an episode ended by a collision that was
    no robot's fault with the team arrived). ``difference``, ``low`` and ``high``: excusing
    minus success, paired on the same episodes, with its 95% Newcombe interval. ``unhit_ci``:
    the Wilson interval of the success rate among the episodes no unavoidable collision ended
    (``successes`` of ``episodes - not_at_fault``; None when a mover ended every one)."""

    controller: str
    level: Any
    episodes: int
    successes: int
    excused: int
    collisions: int
    at_fault: int
    not_at_fault: int
    success_ci: tuple[float, float]
    excused_ci: tuple[float, float]
    difference: float
    low: float
    high: float
    unhit_ci: tuple[float, float] | None = None

    @property
    def unhit(self) -> int:
        """The episodes no unavoidable collision ended: the denominator of success without them."""
        return self.episodes - self.not_at_fault


def _checked(record: Mapping[str, Any], source: str) -> Mapping[str, Any]:
    """``record`` if it holds the fault rule's fields; :class:`MissingFaultFields` naming the
    publication, the episode and the field otherwise."""
    for name in FAULT_FIELDS:
        if name not in record:
            raise MissingFaultFields(
                f"{source}: episode {record.get('key', '?')!r} has no field {name!r}: its records were "
                f"written before the fault rule (docs/movers.md, 'Who is at fault') and cannot be split "
                f"by fault; republish the run so that its records carry {' and '.join(FAULT_FIELDS)}"
            )
    return record


def _row(controller: str, level: Any, records: Sequence[Mapping[str, Any]]) -> FaultRow:
    success = [bool(r["success"]) for r in records]
    excused = [bool(r["success_excusing_unavoidable"]) for r in records]
    collisions = sum(r["collision"] is not None for r in records)
    at_fault = sum(r["collision"] is not None and bool(r["collision_at_fault"]) for r in records)
    test = paired_comparison(excused, success)
    unhit = len(records) - (collisions - at_fault)
    return FaultRow(
        controller,
        level,
        len(records),
        sum(success),
        sum(excused),
        collisions,
        at_fault,
        collisions - at_fault,
        wilson_interval(sum(success), len(records)),
        wilson_interval(sum(excused), len(records)),
        test.difference,
        test.low,
        test.high,
        wilson_interval(sum(success), unhit) if unhit else None,
    )


def fault_rows(levels: Sequence[tuple[Any, RunData]], source: str) -> list[FaultRow]:
    """Every controller's :class:`FaultRow` at every level of ``levels`` (one sweep axis's
    ``[(level, results), ...]``, :func:`evaluation.experiments.sweep.load_sweep`), ordered by
    controller, then level; the distinct episodes that ran only. ``source`` names the
    publication in the error a record without :data:`FAULT_FIELDS` raises
    (:class:`MissingFaultFields`)."""
    rows = []
    for index, (level, results) in enumerate(levels):
        by_controller: dict[str, list[Mapping[str, Any]]] = {}
        for record in distinct_records(results.records):
            if ran(record):
                by_controller.setdefault(record["controller"], []).append(_checked(record, source))
        rows += [(name, index, _row(name, level, records)) for name, records in by_controller.items()]
    return [row for _, _, row in sorted(rows, key=lambda item: item[:2])]


def _percent(count: int, n: int, ci: tuple[float, float]) -> str:
    return interval_cell(count / n, ci[0], ci[1], 100)


#: what the section's table shows (its note)
NOTE = (
    "Every episode ended by a collision, split by whose fault it was (the rule of "
    "[Moving obstacles](movers.md#who-is-at-fault): a mover that runs into a robot that is stopped "
    "or moving away is not the robot's fault; any contact with an obstacle or a team-mate is): "
    "collisions in all = at the robot's fault + not at its fault. Success with 95% Wilson "
    "intervals; success excusing unavoidable: a success, or an episode ended by a collision that was "
    "no robot's fault with every robot within its goal tolerance (the team had arrived and was "
    "settling), so it counts only those of the collisions not at fault that came after arriving. "
    "Excusing - success: the two rates paired on the same episodes, with a 95% Newcombe interval. "
    "Success without the unavoidable: success among the episodes that no collision not at the "
    "robot's fault ended (those episodes left out of the denominator; n/a when a mover ended every "
    "one), with its 95% Wilson interval: the rate had the crowd never run into the team, on the "
    "episodes it did not. "
    "Distinct episodes that ran only."
)


def fault_section(rows: Sequence[FaultRow], key: str, command: str, missing: Sequence[str] = ()) -> Section:
    """The section of ``rows`` (levels of the sweep axis ``key``), naming the run's ``command``
    and its levels not finished yet (``missing``)."""
    header = [
        "Controller",
        key,
        "Episodes",
        "Success [%]",
        "Success excusing unavoidable [%]",
        "Excusing - success [pp]",
        "Collisions",
        "At the robot's fault",
        "Not at its fault",
        "Success without the unavoidable [%]",
    ]
    table = [
        [
            row.controller,
            level_text(row.level),
            str(row.episodes),
            _percent(row.successes, row.episodes, row.success_ci),
            _percent(row.excused, row.episodes, row.excused_ci),
            interval_cell(row.difference, row.low, row.high, 100),
            str(row.collisions),
            str(row.at_fault),
            str(row.not_at_fault),
            "n/a" if row.unhit_ci is None else _percent(row.successes, row.unhit, row.unhit_ci),
        ]
        for row in rows
    ]
    blocks: list[Any] = [Note(f"Command: `{command}`")]
    if missing:
        blocks.append(Note(f"Levels not finished yet, left out: {', '.join(missing)}."))
    blocks += [Note(NOTE), TableBlock((header, table))]
    return Section(ANCHOR, TITLE, tuple(blocks))


def pending_section(publication: str, run: str) -> Section:
    """The section while ``publication`` (made by ``bash data/publish.sh RUN``) is absent: it
    says so and names the commands that make it and rebuild the page."""
    text = (
        f"Pending: the publication `{publication}` is not made yet, so this page does not split the "
        "crowd's collisions by fault (the earlier runs' records predate the fields the split reads, "
        f"{' and '.join(f'`{name}`' for name in FAULT_FIELDS)}). Make it with "
        f"`bash data/publish.sh {run}` (resumable), `bash data/publish.sh pack`, then rebuild the page "
        "(`python docs/make_pages.py`, data/pages.json)."
    )
    return Section(ANCHOR, TITLE, (Note(text),))
