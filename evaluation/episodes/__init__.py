"""The episodes a run leaves behind, the lowest floor of the evaluator: what an episode record's
status means and its plain-JSON form (:mod:`~evaluation.episodes.records`), which records are
distinct episodes (:mod:`~evaluation.episodes.distinct`), and the resumable episode log of a run
(:mod:`~evaluation.episodes.runlog`, with the digests of the weights its learned controllers play:
:mod:`~evaluation.episodes.log_weights`). Every other part of the evaluator reads records through
these three.

The package is their face: the public names of its modules (their ``__all__``), importable from
here (tests/test_architecture.py checks the list).
"""

from __future__ import annotations

from evaluation.episodes.distinct import (
    NOT_OUTCOME,
    ConflictingRecords,
    distinct_records,
    distinct_units,
    duplicates,
    episode_identity,
    outcome_fields,
    paired_identity,
    read_once,
    signature,
)
from evaluation.episodes.log_weights import (
    PRESETS_KEY,
    WEIGHTS_KEY,
    changed_weights,
    check_weights,
    signed_weights,
    unchecked_notes,
    weights_refusal,
    without_weights,
)
from evaluation.episodes.records import (
    DEGRADED_FAILURE_SHARE,
    RAN,
    STATUSES,
    finished_status,
    is_degraded,
    json_safe,
    ran,
    record_problem,
    selection_key,
    shown_value,
)
from evaluation.episodes.runlog import (
    DEFAULT_OUT,
    RESUME_KEYS,
    LogError,
    OutputNotWritable,
    RunLocked,
    cut_torn,
    ensure_output_dir,
    forget_controllers,
    open_append_locked,
    open_log,
    output_directory,
    parse_lines,
    read_log,
    run_signature,
    split_lines,
)

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
    "DEFAULT_OUT",
    "RESUME_KEYS",
    "PRESETS_KEY",
    "WEIGHTS_KEY",
    "changed_weights",
    "check_weights",
    "signed_weights",
    "unchecked_notes",
    "weights_refusal",
    "without_weights",
    "LogError",
    "OutputNotWritable",
    "RunLocked",
    "cut_torn",
    "ensure_output_dir",
    "forget_controllers",
    "open_append_locked",
    "open_log",
    "output_directory",
    "parse_lines",
    "read_log",
    "run_signature",
    "split_lines",
]
