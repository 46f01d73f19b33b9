"""The evaluator's command line (``python evaluate.py``, ``koopnav-evaluate``), one module per
concept:

- :mod:`~evaluation.cli.options`: the options, one function per group, examples of the common
  commands and the exit codes in ``--help``;
- :mod:`~evaluation.cli.run_args`: the run the parsed options ask for (a protocol preset with the
  given options replacing its fields, the sweep axes and the reference), the options only read;
- :mod:`~evaluation.cli.command`: :func:`main`: check the input, run, report, the one exit code;
- :mod:`~evaluation.cli.gate`: ``--baseline`` and ``--fail-if-worse``, before and after the run;
- :mod:`~evaluation.cli.sweeps`: ``--sweep`` and ``--sweep-report``.

``evaluate.py`` is its entry point. The package is their face: the public names of its modules
(their ``__all__``), importable from here.
"""

from __future__ import annotations

from evaluation.cli.command import main, print_options, print_summary, run_command, verdict, write_ablation
from evaluation.cli.gate import compare_with_baseline, config_check, plan_check, uncovered_controllers
from evaluation.cli.options import EXAMPLES, build_parser, program_name
from evaluation.cli.run_args import (
    CommandLineRun,
    parse_env_kwargs,
    run_from_args,
    spec_from_args,
    split_words,
)
from evaluation.cli.sweeps import run_sweep_command, sweep_report

__all__ = [
    "EXAMPLES",
    "CommandLineRun",
    "build_parser",
    "compare_with_baseline",
    "config_check",
    "main",
    "parse_env_kwargs",
    "plan_check",
    "print_options",
    "print_summary",
    "program_name",
    "run_command",
    "run_from_args",
    "run_sweep_command",
    "spec_from_args",
    "split_words",
    "sweep_report",
    "uncovered_controllers",
    "verdict",
    "write_ablation",
]
