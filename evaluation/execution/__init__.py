"""Running a run: one episode or one batch in a worker (:mod:`~evaluation.execution.worker`),
where episodes run (this process, a process pool or Ray), progress and Ctrl-C
(:mod:`~evaluation.execution.backends`), and :func:`~evaluation.execution.runner.evaluate`:
check a :class:`~evaluation.run.spec.RunSpec`, plan it, run it on a backend, log it, return its
:class:`~evaluation.reports.results.Results`.

The package is their face: the public names of its modules (their ``__all__``), importable from
here (tests/test_architecture.py checks the list).
"""

from __future__ import annotations

from evaluation.execution.backends import (
    BACKENDS,
    BATCH,
    Progress,
    RunInterrupted,
    run_episodes,
    sigterm_stops_the_run,
    stop_on_sigterm,
    work_units,
)
from evaluation.execution.runner import evaluate, schedule, usable_controllers
from evaluation.execution.worker import CalibrationError, batch_cell, episode_record, run_batch, runs_in_batch

__all__ = [
    "CalibrationError",
    "batch_cell",
    "episode_record",
    "run_batch",
    "runs_in_batch",
    "BACKENDS",
    "BATCH",
    "Progress",
    "RunInterrupted",
    "run_episodes",
    "sigterm_stops_the_run",
    "stop_on_sigterm",
    "work_units",
    "evaluate",
    "schedule",
    "usable_controllers",
]
