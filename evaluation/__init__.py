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
- the command lines at the root: :mod:`evaluation.cli` (``evaluate.py``'s command line),
  :mod:`evaluation.exit_codes` (the one table of exit codes), ``python -m evaluation.forget``,
  ``python -m evaluation.archive``;
- :data:`MOVED_PATHS`: the previous release's documented module paths, which warn and give the
  new module until KoopNav 0.2.0.

``evaluate.py`` is the evaluator's command line.
"""

from evaluation.execution.runner import evaluate
from evaluation.run.spec import RunSpec
from koopman_envs.deprecation import register_moved_paths

__all__ = ["RunSpec", "evaluate"]

#: the previous release's module paths that docs/ named: the modules of its API page
#: (docs/api/evaluation.md) and the command ``python -m evaluation.seeds`` (docs/benchmark.md),
#: kept one release with a DeprecationWarning by koopman_envs.deprecation's import hook (no file at
#: the old path; CHANGELOG.md, Deprecated). The other moved root modules were never documented and
#: are gone (tests/test_architecture.py, REMOVED_PATHS).
MOVED_PATHS = {
    "evaluation.spec": "evaluation.run.spec",
    "evaluation.configs": "evaluation.run.configs",
    "evaluation.suite_runs": "evaluation.run.suite_runs",
    "evaluation.statistics": "evaluation.stats.statistics",
    "evaluation.clustered": "evaluation.stats.clustered",
    "evaluation.layout_tests": "evaluation.stats.layout_tests",
    "evaluation.families": "evaluation.stats.families",
    "evaluation.suite_statistics": "evaluation.stats.suite_statistics",
    "evaluation.results": "evaluation.reports.results",
    "evaluation.figures": "evaluation.reports.figures",
    "evaluation.thresholds": "evaluation.reports.thresholds",
    "evaluation.baseline": "evaluation.reports.baseline",
    "evaluation.report": "evaluation.reports.sections",
    "evaluation.runner": "evaluation.execution.runner",
    "evaluation.protocols": "evaluation.experiments.protocols",
    "evaluation.seeds": "evaluation.experiments.seeds",
}
register_moved_paths(MOVED_PATHS, commands=("evaluation.seeds",))
