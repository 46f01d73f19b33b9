"""Whether a run reproduced a baseline's episodes field for field (``bash .ci/leaderboard.sh --exact``).

The gate of :mod:`evaluation.reports.baseline` asks whether a controller got significantly worse,
and passes a run whose every episode ended a millimetre elsewhere. Issue 61 asks for more of a
change meant to keep outcomes (a refactoring, a faster kernel): every gate episode equal to the
committed baseline's, field for field. :func:`exact_differences` pairs every episode of the run
with the baseline's episode of the same identity
(:func:`evaluation.episodes.distinct.episode_identity`: task, controller label, map, slip, suite
layout, seed) and names

- every baseline episode the run lacks and every run episode the baseline lacks (a run of other
  seeds or cells pairs nothing, and must not pass as "no differences");
- every field in which two paired episodes differ, with both values, comparing every field but
  those that are no outcome (:data:`evaluation.episodes.distinct.NOT_OUTCOME`: the times measured
  on the machine, ``wall_seconds`` and ``solve_ms_*`` and, inside a record's summaries,
  ``calibration.seconds`` and ``controller_extra``'s ``*_ms_*``, which differ between any two runs
  of one episode; the episode's place in its run, ``key`` and ``trial``, which the seed already
  names; where a calibration came from, ``calibration.source``, one model either way; and an
  error's traceback, whose text names the machine's files, while its message is compared). The
  rule is the one by which :func:`~evaluation.episodes.distinct.read_once` tells a record read
  twice from two outcomes of one episode, so that "the same episode" means one thing everywhere.

A run of part of the gate (``KOOPNAV_GATE_ARGS``: some controllers, fewer episodes) is compared
with the part of the baseline it covers (:func:`within_run`).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any, NamedTuple

from evaluation.episodes.distinct import episode_identity, outcome_fields, read_once
from evaluation.episodes.records import shown_value
from evaluation.run.plan import RANDOM_MAP

__all__ = ["ExactComparison", "FieldDifference", "episode_name", "exact_differences", "within_run"]


class FieldDifference(NamedTuple):
    """One field in which a run's episode differs from the baseline's."""

    #: the episode (:func:`episode_name`)
    episode: str
    #: the record field
    field: str
    #: its value in the baseline's record and in the run's (cut to 60 characters; ``absent``)
    baseline: str
    run: str


@dataclass(frozen=True)
class ExactComparison:
    """A run's episodes against a baseline's, field for field (:func:`exact_differences`).

    Attributes
    ----------
    compared : int
        Episodes present on both sides.
    missing : tuple of str
        The baseline's episodes the run lacks, named (:func:`episode_name`), in the baseline's order.
    extra : tuple of str
        The run's episodes the baseline lacks, in the run's order.
    differing : tuple of FieldDifference
        Every field of a paired episode that differs, in the baseline's order.
    """

    compared: int
    missing: tuple[str, ...]
    extra: tuple[str, ...]
    differing: tuple[FieldDifference, ...]

    @property
    def equal(self) -> bool:
        """Whether the run reproduced the baseline: every episode on both sides, none differing."""
        return not (self.missing or self.extra or self.differing)

    def problems(self) -> list[str]:
        """One line per missing, extra or differing episode (empty when :attr:`equal`)."""
        lines = [f"missing from the run: {name}" for name in self.missing]
        lines += [f"not in the baseline: {name}" for name in self.extra]
        fields: dict[str, list[FieldDifference]] = {}
        for difference in self.differing:
            fields.setdefault(difference.episode, []).append(difference)
        lines += [
            f"{episode} differs in {', '.join(d.field for d in found)} ("
            + "; ".join(f"{d.field}: baseline {d.baseline}, run {d.run}" for d in found)
            + ")"
            for episode, found in fields.items()
        ]
        return lines


def episode_name(record: Mapping[str, Any]) -> str:
    """An episode as the messages name it: its key in its run and its seed (a run of other seeds
    has the same keys)."""
    return f"{record.get('key')!r} (seed {record.get('seed')!r})"


def _shown(fields: Mapping[str, str], record: Mapping[str, Any], name: str) -> str:
    return shown_value(record[name]) if name in fields else "absent"


def exact_differences(
    records: Iterable[Mapping[str, Any]], baseline_records: Iterable[Mapping[str, Any]]
) -> ExactComparison:
    """Pair a run's episode records with a baseline's by episode and compare them field for field.

    Parameters
    ----------
    records : iterable of mapping
        The run's episode records (``results.json``'s ``episodes``), errors included.
    baseline_records : iterable of mapping
        The baseline's, or the part of it the run covers (:func:`within_run`).

    Returns
    -------
    ExactComparison
        The episodes each side lacks and every differing field; the timing fields and the others
        that are no outcome are not compared (:data:`evaluation.episodes.distinct.NOT_OUTCOME`).

    Raises
    ------
    ConflictingRecords
        One side records an episode twice with different outcomes
        (:func:`evaluation.episodes.distinct.read_once`).
    """
    mine = {episode_identity(r): r for r in read_once(records, "the run")}
    theirs = {episode_identity(r): r for r in read_once(baseline_records, "the baseline")}
    differing = []
    for identity, base in theirs.items():
        if identity not in mine:
            continue
        run = mine[identity]
        ours, others = outcome_fields(run), outcome_fields(base)
        differing += [
            FieldDifference(episode_name(base), name, _shown(others, base, name), _shown(ours, run, name))
            for name in sorted(set(ours) | set(others))
            if ours.get(name) != others.get(name)
        ]
    return ExactComparison(
        compared=len(set(mine) & set(theirs)),
        missing=tuple(episode_name(r) for i, r in theirs.items() if i not in mine),
        extra=tuple(episode_name(r) for i, r in mine.items() if i not in theirs),
        differing=tuple(differing),
    )


def within_run(baseline_records: Iterable[Mapping[str, Any]], config: Mapping[str, Any]) -> list[Any]:
    """The baseline's records of the episodes a run of part of the gate planned: its controller
    labels, tasks, maps per task and slips, and the first ``episodes`` trials of each cell, as its
    ``config`` (a ``results.json``'s) names them. What the run planned but lacks, or ran on other
    seeds, stays missing: only what it never meant to run is left out."""
    labels = {c["label"] for c in config["controller_configs"]}
    maps = config["maps"]

    def trials(map_name: str) -> int:  # as RunSpec plans them: a random map's own count
        return (
            config["random_maps"] if map_name == RANDOM_MAP and config["random_maps"] else config["episodes"]
        )

    return [
        r
        for r in baseline_records
        if r["controller"] in labels
        and r["map"] in maps.get(r["env_id"], ())
        and r["slip"] in config["slips"]
        and r["trial"] < trials(r["map"])
    ]
