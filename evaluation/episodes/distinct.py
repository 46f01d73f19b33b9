"""Distinct episodes: an identical rerun is not a sample.

Where nothing random differs between the trials of a cell (exact starts, no slip, no noise),
every trial is the same episode, bit for bit; counting it ten times narrows every interval and
inflates every test by a factor that is pure bookkeeping. Every statistic of the evaluator
therefore counts **distinct** episodes only: two episodes of one controller in one cell (task,
map, slip) are the same when their outcomes agree bit for bit (status, success, collision,
steps and every final pose to the last bit; deterministic controllers on the same inputs end
exactly alike, and different inputs practically never end on the same floating-point poses),
and a paired unit (one seed, both controllers) is the same as another when both of its
episodes are. The reports show how many episodes ran and how many were distinct.

Before that, every record is read once (:func:`read_once`, called by every reader of records: the
resume log, a baseline or sweep level's results.json, a published log, the page generators, a
run's data): an episode is named by its task, controller label, map, slip and seed
(:func:`episode_identity`, what every pairing reads), and two records of one episode either agree
in every field but those that are no outcome (:data:`NOT_OUTCOME`: wall and decision times, where
a calibration came from, the traceback's text, the trial index) and are one record, or disagree
and are refused by name (:class:`ConflictingRecords`): which of them is true cannot be told, and
keeping either ("the last one wins") would decide a gate by the order of lines in a file.
"""

from __future__ import annotations

import json
from collections.abc import Hashable, Iterable, Mapping, Sequence
from typing import Any

from evaluation.episodes.records import json_safe, ran, shown_value

__all__ = [
    "NOT_OUTCOME",
    "ConflictingRecords",
    "distinct_records",
    "distinct_units",
    "duplicates",
    "episode_identity",
    "outcome_fields",
    "paired_identity",
    "read_once",
    "signature",
]

#: record fields that are not the episode's outcome, left out when two records of one episode are
#: compared: its place in the run (``key``, ``trial``: the seed already names the episode), times
#: measured on the machine (they differ between any two runs of one episode) and the traceback of
#: an error (its text names files and lines of the machine; the ``error`` message is compared)
NOT_OUTCOME = ("key", "trial", "wall_seconds", "solve_ms", "solve_ms_median", "solve_ms_p95", "traceback")
#: the calibration summary's fields that are no outcome: its time, and where the model came from
#: (fitted, a cache, shipped: one model either way; its size and key are compared)
_NOT_OUTCOME_CALIBRATION = ("seconds", "source")


class ConflictingRecords(ValueError):
    """Two records of one episode that disagree in an outcome (named by :func:`read_once`)."""


def episode_identity(record: Mapping[str, Any]) -> tuple:
    """What names an episode across records and runs: (task, controller label, map, slip, suite
    layout, seed), the coordinates every pairing reads (the trial index only numbers it within its
    run; the layout is None in records of runs without a suite)."""
    return tuple(record.get(k) for k in ("env_id", "controller", "map", "slip", "layout", "seed"))


def outcome_fields(record: Mapping[str, Any]) -> dict[str, str]:
    """Field -> its value as exact JSON, for every field of ``record`` that is part of what happened
    (all but :data:`NOT_OUTCOME`; inside a record's summaries, the calibration's time and source
    and a controller's own decision times, named ``<part>_ms_<statistic>``). NaN and null are one
    value (a record read back from JSON holds null where the run held NaN)."""
    out = {}
    for name, value in record.items():
        if name in NOT_OUTCOME:
            continue
        if name == "calibration" and isinstance(value, dict):
            value = {k: v for k, v in value.items() if k not in _NOT_OUTCOME_CALIBRATION}
        elif name == "controller_extra" and isinstance(value, dict):
            value = {k: v for k, v in value.items() if "_ms_" not in k}
        out[name] = json.dumps(json_safe(value), sort_keys=True)
    return out


#: the fields a conflict's message names first (what the tables count), the others after them
_FIRST_SHOWN = ("status", "success", "collision", "final_distance", "steps", "error")


def _value(record: Mapping[str, Any], name: str) -> str:
    """A field of ``record`` for a conflict's message (``absent`` when it has none)."""
    return shown_value(record[name]) if name in record else "absent"


def read_once(
    records: Iterable[Mapping[str, Any]], source: str, places: Sequence[str] | None = None
) -> list[Any]:
    """``records`` with every episode once: a record of an episode read before
    (:func:`episode_identity`) that agrees with it in every outcome field (:func:`outcome_fields`)
    is the same record read twice and is dropped; one that disagrees is refused.

    Parameters
    ----------
    records : iterable of mapping
        Episode records, in the order they were read.
    source : str
        What they were read from, for the message (a file, ``"the baseline"``).
    places : sequence of str, optional
        Where each record stands in ``source`` (``"line 7"``, ``"episodes[3]"``); default
        ``"record N"``, counted from 1.

    Returns
    -------
    list
        The first record of every episode, in order.

    Raises
    ------
    ConflictingRecords
        Two records of one episode disagree: the message names ``source``, the episode, both
        places and every field that differs (with both values, for the first three).
    """
    first: dict[tuple, tuple[int, Mapping[str, Any]]] = {}
    out = []
    for index, record in enumerate(records):
        identity = episode_identity(record)
        if identity not in first:
            first[identity] = (index, record)
            out.append(record)
            continue
        earlier_index, earlier = first[identity]
        if earlier is record:  # the very same object listed twice
            continue
        theirs, ours = outcome_fields(earlier), outcome_fields(record)
        differ = sorted(
            (k for k in set(theirs) | set(ours) if theirs.get(k) != ours.get(k)),
            key=lambda k: (_FIRST_SHOWN.index(k) if k in _FIRST_SHOWN else len(_FIRST_SHOWN), k),
        )
        if not differ:
            continue
        values = "; ".join(f"{k}: {_value(earlier, k)}, then {_value(record, k)}" for k in differ[:3])
        where = [places[i] if places is not None else f"record {i + 1}" for i in (earlier_index, index)]
        raise ConflictingRecords(
            f"{source}: episode {earlier.get('key', '')!r} (seed {identity[-1]!r}) is recorded twice "
            f"with different outcomes, at {where[0]} and {where[1]}, which differ in "
            f"{', '.join(differ)} ({values}{'; ...' if len(differ) > 3 else ''}); which one is true "
            "cannot be told, so neither is read (remove the wrong record, or run the episode again)"
        )
    return out


def signature(record: Mapping[str, Any]) -> str:
    """What makes an episode that ran this episode: its outcome and final poses, exactly
    (floats in their shortest round-trip form)."""
    return json.dumps(
        [
            record.get("status"),
            record.get("success"),
            record.get("collision"),
            record.get("steps"),
            record.get("final_poses") or record.get("final_distance"),
        ]
    )


def _cell(record: Mapping[str, Any]) -> tuple:
    return (record.get("env_id"), record.get("controller"), record.get("map"), record.get("slip"))


def distinct_records(records: Iterable[Mapping[str, Any]]) -> list[Any]:
    """``records`` with every episode that ran kept once per cell (the first of identical ones);
    episodes that raised are kept (they are not samples of an outcome and no rate counts them)."""
    seen: set[tuple] = set()
    out = []
    for record in records:
        if ran(record):
            key = (*_cell(record), signature(record))
            if key in seen:
                continue
            seen.add(key)
        out.append(record)
    return out


def duplicates(records: Sequence[Mapping[str, Any]]) -> int:
    """How many episodes that ran repeat an earlier one of their cell."""
    return len(records) - len(distinct_records(records))


def distinct_units(
    keys: Iterable[tuple],
    a: Mapping[tuple, Mapping[str, Any]],
    b: Mapping[tuple, Mapping[str, Any]],
    cell_of: Any = None,
) -> list[tuple]:
    """The paired units ``keys`` (both episodes ran) with repeats dropped: a unit whose two
    episodes (``a[key]``, ``b[key]``) both equal those of an earlier unit of the same cell
    (``cell_of(key)``, default: the key without its last element, the seed)."""
    cell_of = cell_of or (lambda key: key[:-1])
    seen: set[tuple] = set()
    out = []
    for key in keys:
        identity = (cell_of(key), signature(a[key]), signature(b[key]))
        if identity in seen:
            continue
        seen.add(identity)
        out.append(key)
    return out


def paired_identity(
    context: Hashable,
    keys: Iterable[tuple],
    a: Mapping[tuple, Mapping[str, Any]],
    b: Mapping[tuple, Mapping[str, Any]],
) -> Hashable:
    """What makes a paired test on the units ``keys`` this test: its ``context`` (the table's
    cell: axis and level, or task) and every unit's two episodes, exactly. Two tests with the same
    identity ran on the same data (a controller and its bit-identical twin, each against a third)
    and are one hypothesis test (:func:`evaluation.stats.statistics.holm_adjusted`'s ``same``); the
    order of the two sides does not matter (McNemar's test is symmetric)."""
    keys = list(keys)
    forward = tuple((key, signature(a[key]), signature(b[key])) for key in keys)
    backward = tuple((key, sb, sa) for key, sa, sb in forward)
    return (context, min(forward, backward))
