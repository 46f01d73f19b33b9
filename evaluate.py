"""KoopNav evaluator: run every controller on every cell, report success rates and final distances.

``python evaluate.py`` runs the quick default leaderboard (both tasks, their paper maps under
high slip, every registered controller, 2 episodes per cell from perturbed starts, the NMPCs on
the real-time iteration), prints a compact leaderboard and writes the full report (Markdown,
JSON, CSV, HTML, figures) to ``results/`` (``results-2/``, ``results-3/``, ... when it holds an
earlier run, so that the command can be run again). ``python evaluate.py --paper`` runs the paper's
protocol (SPEC section 5: 10 trials per cell) and prints tables 1-5. From Python::

    from evaluation import RunSpec, evaluate
    spec = RunSpec(envs="KoopNav-Formation-v0", controllers=["koopman-nmpc", "consensus"], maps=["map3"],
                   slips=["nominal", "high"], episodes=5, seed=0)
    print(evaluate(spec).to_markdown())

This file is only the entry point: the command line is :mod:`evaluation.cli` (the options, the
run they ask for, the command, the baseline gate, ``--sweep``), and the work is done by the rest of
the ``evaluation`` package, one folder per concept (docs/layout.md). The names below are
re-exported where they always were (``import evaluate; evaluate.main([...])``).

Episodes run in worker processes; each episode's seed depends only on the base seed and its
index in the cell, so results do not depend on the worker count. Each finished episode is
appended to ``OUT/episodes.jsonl`` at once; ``--resume`` continues an interrupted run. An
episode that raises is recorded with its error and the others go on; the exit codes are one table,
:data:`evaluation.exit_codes.EXIT_CODES` (``--help`` lists it): 2 bad input, 3 episodes raised,
101 a ``--check`` floor missed, and so on.
"""

from __future__ import annotations

from evaluation.cli import build_parser, main, parse_env_kwargs, program_name, spec_from_args, split_words
from evaluation.execution import RunInterrupted, evaluate, usable_controllers
from evaluation.exit_codes import (
    BAD_INPUT_EXIT,
    EPISODES_RAISED_EXIT,
    EXIT_CODES,
    FAILED_CHECK_EXIT,
    FAILED_GATE_EXIT,
    INTERNAL_ERROR_EXIT,
    INTERRUPTED_EXIT,
    SUCCESS_EXIT,
    UNWRITABLE_OUT_EXIT,
)
from evaluation.experiments import paper_protocol, quick_protocol
from evaluation.reports import SCHEMA_VERSION, Results, check_thresholds
from evaluation.run import EpisodeSpec, RunSpec, split_slips
from evaluation.stats import Cell

__all__ = [
    "BAD_INPUT_EXIT",
    "Cell",
    "EPISODES_RAISED_EXIT",
    "EXIT_CODES",
    "FAILED_CHECK_EXIT",
    "FAILED_GATE_EXIT",
    "INTERNAL_ERROR_EXIT",
    "INTERRUPTED_EXIT",
    "SUCCESS_EXIT",
    "UNWRITABLE_OUT_EXIT",
    "EpisodeSpec",
    "Results",
    "RunInterrupted",
    "RunSpec",
    "SCHEMA_VERSION",
    "check_thresholds",
    "evaluate",
    "main",
    "paper_protocol",
    "quick_protocol",
    "usable_controllers",
    # the command line's pieces (evaluation.cli), where they always were
    "build_parser",
    "parse_env_kwargs",
    "program_name",
    "spec_from_args",
    "split_slips",
    "split_words",
]


if __name__ == "__main__":
    raise SystemExit(main())
