"""The evaluator: a run as data (:class:`RunSpec`, presets in :mod:`evaluation.protocols`),
:func:`evaluate` to run it, and its parts (configurations, statistics, reports, ablations);
``evaluate.py`` is the command line."""

from evaluation.runner import evaluate
from evaluation.spec import RunSpec

__all__ = ["RunSpec", "evaluate"]
