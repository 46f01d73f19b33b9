"""The evaluator: a run as data (:class:`RunSpec`, presets in :mod:`evaluation.experiments.protocols`),
:func:`evaluate` to run it, and its parts, one folder per concept, imports pointing down only
(docs/layout.md; tests/test_architecture.py fails on an upward import):

- :mod:`evaluation.episodes`: an episode's record, which records are distinct, the episode log;
- :mod:`evaluation.run`: a run as data (configurations, slip text, suite runs, one episode, ``RunSpec``);
- :mod:`evaluation.stats`: intervals, tests, cells, suite tables, ``RunData``, robustness profiles;
- :mod:`evaluation.reports`: ``Results`` and its formats, published archives, the baseline gate, floors;
- :mod:`evaluation.execution`: workers, backends, :func:`evaluate`;
- :mod:`evaluation.experiments`: the protocols, the ablation, ``--sweep``, the training seeds;
- :mod:`evaluation.tune`: the tuner (``python -m evaluation.tune``);
- the command lines at the root: :mod:`evaluation.cli` (``evaluate.py``'s options),
  :mod:`evaluation.exit_codes` (the one table of exit codes), ``python -m evaluation.forget``,
  ``python -m evaluation.archive``.

``evaluate.py`` is the evaluator's command line.
"""

from evaluation.execution.runner import evaluate
from evaluation.run.spec import RunSpec

__all__ = ["RunSpec", "evaluate"]
