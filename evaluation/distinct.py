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
"""

from __future__ import annotations

import json
from collections.abc import Hashable, Iterable, Mapping, Sequence
from typing import Any

from evaluation.records import ran

__all__ = ["distinct_records", "distinct_units", "duplicates", "paired_identity", "signature"]


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
    and are one hypothesis test (:func:`evaluation.statistics.holm_adjusted`'s ``same``); the
    order of the two sides does not matter (McNemar's test is symmetric)."""
    keys = list(keys)
    forward = tuple((key, signature(a[key]), signature(b[key])) for key in keys)
    backward = tuple((key, sb, sa) for key, sa, sb in forward)
    return (context, min(forward, backward))
