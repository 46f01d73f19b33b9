"""Episode records: what a record's ``status`` means (the statuses, which of them ran, and when a
finished episode counts as degraded) and the plain-JSON form records are written in. Every
reader of records asks here, so that the rule is one.

- ``"ok"``: the episode ran to its end and its controller decided normally.
- ``"degraded"``: it ran to its end, but the controller's optimizer failed in more than
  :data:`DEGRADED_FAILURE_SHARE` of its decisions (each failure fell back to the previous plan or a
  safe command). Its outcome counts like any other, and the report counts such episodes per
  controller, so that a broken calibration or solver cannot pass as a normal run.
- ``"error"``: the episode raised; its record holds the error and no outcome.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

from koopman_envs import FAMILIES, TIERS, CollisionKind

__all__ = [
    "DEGRADED_FAILURE_SHARE",
    "RAN",
    "STATUSES",
    "finished_status",
    "is_degraded",
    "json_safe",
    "ran",
    "record_problem",
    "selection_key",
    "shown_value",
]

STATUSES = ("ok", "degraded", "error")
#: statuses of episodes that ran to their end (their outcome counts)
RAN = ("ok", "degraded")
#: share of a controller's decisions in an episode whose solver failure makes the episode degraded
#: (ours: the committed CI baseline's highest share is 2%, so a quarter means something broke)
DEGRADED_FAILURE_SHARE = 0.25


def ran(record: Mapping[str, Any]) -> bool:
    """Whether an episode ran to its end (``ok`` or ``degraded``; not ``error``)."""
    return record.get("status") in RAN


def is_degraded(record: Mapping[str, Any]) -> bool:
    """Whether an episode ran with its solver failing in too many decisions."""
    return record.get("status") == "degraded"


def finished_status(failures: int, decisions: int) -> str:
    """``"degraded"`` when more than :data:`DEGRADED_FAILURE_SHARE` of ``decisions`` failed, else ``"ok"``."""
    return "degraded" if decisions > 0 and failures > DEGRADED_FAILURE_SHARE * decisions else "ok"


def json_safe(value: Any) -> Any:
    """A record (or any value) as plain JSON: NaN and inf become null (JSON has no such numbers),
    tuples become lists."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    return value


# --------------------------------------------------------------------------- the record schema
# One schema for every reader of records (the resume log, a baseline, a sweep level): a record
# is refused by the first field that breaks it, named with its value and what is allowed, so that
# a torn or foreign record never reaches a table. docs/results.schema.json describes the same
# fields for outside readers; tests/test_records.py holds the two together.


# (records are read from JSON: numbers arrive as int or float, never as numpy scalars)
def _is_int(value: Any, minimum: int | None = None) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and (minimum is None or value >= minimum)


def _is_number(value: Any, minimum: float | None = None) -> bool:
    return (
        isinstance(value, (int, float))
        and not isinstance(value, bool)
        and math.isfinite(value)
        and (minimum is None or value >= minimum)
    )


def _numbers(value: Any, minimum: float | None = None) -> bool:
    return isinstance(value, list) and all(_is_number(v, minimum) for v in value)


def _non_negative_numbers(value: Any) -> bool:
    return _numbers(value, 0.0)


#: the collision kinds a record names (joined with "+" when several happened at once)
_COLLISION_KINDS = tuple(CollisionKind.NAMES.values())


def _collision(value: Any) -> bool:
    if value is None:
        return True
    parts = value.split("+") if isinstance(value, str) else []
    return bool(parts) and all(p in _COLLISION_KINDS for p in parts) and len(set(parts)) == len(parts)


def _text(value: Any) -> bool:
    return isinstance(value, str) and value != ""


#: field -> (check, what is allowed), for every record whatever its status
_COMMON_SCHEMA: dict[str, tuple[Callable[[Any], bool], str]] = {
    "key": (_text, "a non-empty string"),
    "status": (lambda v: v in STATUSES, f"one of {list(STATUSES)}"),
    "env_id": (_text, "a non-empty string"),
    "controller": (_text, "a non-empty string"),
    "map": (_text, "a non-empty string"),
    "slip": (_text, "a non-empty string"),
    "trial": (lambda v: _is_int(v, 0), "an integer >= 0"),
    "seed": (lambda v: _is_int(v, 0), "an integer >= 0"),
}
#: field -> (check, what is allowed), required in an episode that ran (``ok`` / ``degraded``)
_OUTCOME_SCHEMA: dict[str, tuple[Callable[[Any], bool], str]] = {
    "success": (lambda v: isinstance(v, bool), "true or false"),
    "collision": (_collision, f"null or the collision's kinds joined with '+', of {list(_COLLISION_KINDS)}"),
    "steps": (lambda v: _is_int(v, 0), "an integer >= 0"),
    "final_distance": (
        lambda v: _numbers(v, 0.0) and len(v) > 0,
        "a non-empty list of finite numbers >= 0 (one per robot, metres)",
    ),
    "solver_failures": (lambda v: _is_int(v, 0), "an integer >= 0"),
}
#: field -> (check, what is allowed), checked when the record holds the field
_OPTIONAL_SCHEMA: dict[str, tuple[Callable[[Any], bool], str]] = {
    # recorded since the fault rule and the strict success (records written before lack them)
    "strict_success": (lambda v: isinstance(v, bool), "true or false"),
    "success_excusing_unavoidable": (lambda v: isinstance(v, bool), "true or false"),
    "collision_at_fault": (lambda v: isinstance(v, bool), "true or false"),
    "clearance_min_m": (lambda v: v is None or _is_number(v), "null or a finite number (metres)"),
    "truncated": (lambda v: isinstance(v, bool), "true or false"),
    "time_to_goal": (lambda v: v is None or _is_number(v, 0.0), "null or a finite number >= 0 (seconds)"),
    "final_poses": (
        lambda v: isinstance(v, list) and all(_numbers(p) and len(p) == 3 for p in v),
        "a list of [x, y, heading] triples of finite numbers",
    ),
    "path_length": (_non_negative_numbers, "a list of finite numbers >= 0"),
    "control_effort": (_non_negative_numbers, "a list of finite numbers >= 0"),
    "formation_rms": (lambda v: v is None or _is_number(v, 0.0), "null or a finite number >= 0"),
    "straight_distance": (_non_negative_numbers, "a list of finite numbers >= 0"),
    "min_clearance": (
        lambda v: (
            isinstance(v, dict)
            and set(v) <= {"obstacle", "robot", "mover"}
            and all(x is None or _is_number(x) for x in v.values())
        ),
        "an object with keys of ['obstacle', 'robot', 'mover'], each null or a finite number (metres)",
    ),
    "accel_rms": (_non_negative_numbers, "a list of finite numbers >= 0"),
    # recorded since the suite's metric tables (records written before lack them)
    "jerk_rms": (
        lambda v: v is None or _non_negative_numbers(v),
        "null or a list of finite numbers >= 0 (one per robot, m/s^3)",
    ),
    "near_obstacle_share": (
        lambda v: _non_negative_numbers(v) and all(x <= 1.0 for x in v),
        "a list of numbers within [0, 1] (one per robot)",
    ),
    "path_ratio": (lambda v: v is None or _is_number(v, 0.0), "null or a finite number >= 0"),
    "decisions": (lambda v: _is_int(v, 0), "an integer >= 0"),
    "deadline_misses": (lambda v: _is_int(v, 0), "an integer >= 0"),
    "late_periods": (lambda v: _is_number(v, 0.0), "a finite number >= 0 (control periods)"),
    "compute_scale": (lambda v: _is_number(v, 0.0), "a finite number >= 0 (0: free compute)"),
    "angular_accel_rms": (_non_negative_numbers, "a list of finite numbers >= 0"),
    "mover_trajectory": (
        lambda v: (
            isinstance(v, list)
            and all(isinstance(r, list) and all(_numbers(p) and len(p) == 2 for p in r) for r in v)
        ),
        "a list, per step, of one [x, y] pair of finite numbers per mover (metres)",
    ),
    "solve_ms_median": (lambda v: v is None or _is_number(v, 0.0), "null or a finite number >= 0"),
    "solve_ms_p95": (lambda v: v is None or _is_number(v, 0.0), "null or a finite number >= 0"),
    "wall_seconds": (lambda v: _is_number(v, 0.0), "a finite number >= 0"),
    "error": (lambda v: isinstance(v, str), "a string"),
    # a suite run's episode (evaluation.run.suite_runs); records of other runs have none of these
    "layout": (lambda v: _is_int(v, 0), "an integer >= 0 (the layout's index in its suite split)"),
    "layout_family": (lambda v: v in FAMILIES, f"one of {list(FAMILIES)}"),
    "layout_tier": (lambda v: v in TIERS, f"one of {list(TIERS)}"),
    "suite": (_text, "a non-empty string (the suite split's label, <name>/<task>/<split>@<sha256 prefix>)"),
}


def record_problem(record: Any) -> str | None:
    """Why ``record`` is not an episode record as KoopNav writes it (None when it is one).

    Checks the types and ranges of every field a reader uses: the cell and trial fields of every
    record, the outcome of an episode that ran (``success`` a boolean, ``steps`` an integer >= 0,
    ``final_distance`` one finite distance >= 0 per robot, ...), the error text of one that
    raised, and that a success has no collision.

    Returns
    -------
    str or None
        The first problem, naming the field, its value and what is allowed.
    """
    if not isinstance(record, dict):
        return f"a JSON {type(record).__name__}, not an episode record"
    missing = [k for k in _COMMON_SCHEMA if k not in record]
    if missing:
        return f"an object without the episode fields {missing}"
    status = record["status"]
    required = dict(_COMMON_SCHEMA)
    if status in RAN:
        lacking = [k for k in _OUTCOME_SCHEMA if k not in record]
        if lacking:
            return f"a {status!r} record without {lacking}"
        required.update(_OUTCOME_SCHEMA)
    elif status == "error" and "error" not in record:
        return "an 'error' record without its 'error' text"
    for name, (valid, allowed) in {**required, **_OPTIONAL_SCHEMA}.items():
        if name in record and not valid(record[name]):
            return f"field {name!r} is {shown_value(record[name])}; allowed: {allowed}"
    if status in RAN:
        if record["success"] and record["collision"] is not None:
            return (
                f"field 'success' is true with collision {record['collision']!r} (a success has no collision)"
            )
        problem = _outcome_conflict(record)
        if problem is not None:
            return problem
        poses = record.get("final_poses")
        if poses is not None and len(poses) != len(record["final_distance"]):
            return (
                f"field 'final_poses' holds {len(poses)} robots and 'final_distance' "
                f"{len(record['final_distance'])} (one of each per robot)"
            )
    return None


#: (field, when it contradicts the outcome, why) for the fields recorded beside success
_OUTCOME_RULES: tuple[tuple[str, Callable[[Mapping[str, Any]], bool], str], ...] = (
    ("strict_success", lambda r: r["strict_success"] and not r["success"], "a strict success is a success"),
    (
        "success_excusing_unavoidable",
        lambda r: r["success"] and not r["success_excusing_unavoidable"],
        "a success is one with the unavoidable collisions excused",
    ),
    (
        "collision_at_fault",
        lambda r: r["collision_at_fault"] and r["collision"] is None,
        "a collision at fault is a collision",
    ),
)


def _outcome_conflict(record: Mapping[str, Any]) -> str | None:
    """The first field recorded beside success that contradicts it (each rule applies when the
    record holds the fields it reads)."""
    for name, broken, why in _OUTCOME_RULES:
        if name in record and broken(record):
            return (
                f"field {name!r} is {shown_value(record[name])} with success {record['success']!r} "
                f"and collision {record['collision']!r} ({why})"
            )
    return None


def shown_value(value: Any) -> str:
    """A field's value for a message: its repr, cut to 60 characters."""
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def selection_key(
    success_rate: float, mean_final_distance: float | None, tie_break: int
) -> tuple[float, float, int]:
    """The sort key (larger is better) of the learned policies' one selection rule, by which a
    trainer keeps a checkpoint (:func:`baselines.suite_training.choose`) and the seeds' driver
    ships a seed (:func:`evaluation.experiments.seeds.chosen_seed`): the higher validation success
    rate, then the lower mean final distance to the targets [m] (None, none measured: last), then
    the larger ``tie_break``.

    Parameters
    ----------
    success_rate : float
        Share of the validation episodes that succeeded.
    mean_final_distance : float or None
        Mean over the episodes of the team's mean final distance to the targets [m].
    tie_break : int
        The caller's last word: the checkpoint's step (the later wins), or ``-seed`` (the lower
        seed wins).
    """
    distance = math.inf if mean_final_distance is None else mean_final_distance
    return (success_rate, -distance, tie_break)
