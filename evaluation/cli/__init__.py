"""The evaluator's command line (``python evaluate.py``): its options
(:mod:`~evaluation.cli.options`: one function per group, examples and the exit codes in
``--help``) and how the parsed options make a run (:mod:`~evaluation.cli.run_args`: a protocol
preset with the given options replacing its fields, the sweep axes and the reference).
``evaluate.py`` runs it.

The package is their face: the public names of its modules (their ``__all__``), importable from here.
"""

from __future__ import annotations

from evaluation.cli.options import EXAMPLES, build_parser, program_name
from evaluation.cli.run_args import (
    CommandLineRun,
    parse_env_kwargs,
    run_from_args,
    spec_from_args,
    split_words,
)

__all__ = [
    "EXAMPLES",
    "CommandLineRun",
    "build_parser",
    "parse_env_kwargs",
    "program_name",
    "run_from_args",
    "spec_from_args",
    "split_words",
]
