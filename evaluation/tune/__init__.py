"""The tuner of KoopNav-Bench (issue 60): every controller the same budget, objective and layouts.

One seeded Optuna study per controller searches the options its spec declares tunable
(``TUNABLE``: :attr:`controllers.option_spec.Option.search`) on the ``validation`` layouts of a
suite, never on ``test``::

    python -m evaluation.tune orca --task both --trials 50 --layouts 20 --episodes 2 --seed 0 --out runs/tune-orca
    python -m evaluation.tune --report runs/tune-orca runs/tune-dwa --out tuning.png

- **Budget.** N configurations (``--trials``) x K layouts (``--layouts``: the first K of the
  split, per task) x E episodes (``--episodes``: episode j of layout l seeded
  ``seed + j * len(split) + l``, as in any suite run), the same for every controller, recorded
  in the study's header. Every configuration runs on the same layouts and seeds (paired: common
  random numbers), in the benchmark's own run (:func:`evaluation.experiments.protocols.suite_protocol`:
  high slip, perturbed starts, the NMPCs on the real-time iteration).
- **Objective.** :func:`~evaluation.tune.scoring.objective`: the validation success rate, ties
  broken by the mean time to goal over the successes. With S successes of n episodes and u the
  mean over the successes of (time to goal / the episode's time limit),
  ``score = S / n + (1 - u) / (n + 1)`` (the second term 0 when S = 0): the tie-break lies in
  [0, 1 / (n + 1)], below the 1 / n between two success counts, so it orders configurations of
  equal success and never reorders others.
- **Held out.** :func:`check_split_allowed` refuses ``test`` for tuning by name before any work.
- **Trial 0** is the controller's current defaults, so the gain of tuning is measured against them.
- **Sampler.** ``optuna.samplers.TPESampler(seed=seed)``: the same seed gives the same sequence
  of configurations.
- **Record.** ``OUT/study.jsonl``: a header (controller, task, split, suite labels with their
  hashes, seed, budget, objective, search space), then one line per finished trial, flushed at
  once. ``--resume`` replays the logged trials through the sampler (the same configurations,
  checked) and continues; a torn last line is cut off, a header of another study refused.
- **Output.** ``OUT/best.json`` (the best configuration, its score, the defaults' score) and
  ``OUT/<controller>.json``, a tuned preset :mod:`controllers.tuning.presets` loads from
  ``controllers/tuned/`` (a ``--task both`` study's only: a controller's defaults serve both tasks).
- **Curves.** :func:`expected_max`: the expected best validation score against the number of
  configurations tried (Dodge et al. 2019), drawn for several studies by ``--report``.

The evaluation of one configuration is one function, :func:`evaluate_configuration`.
"""

from controllers.tuning import STUDY_FILE
from evaluation.tune.cli import main
from evaluation.tune.configuration import DEFAULT_SLIP, SUITE, TASK_CHOICES, evaluate_configuration, tasks_of
from evaluation.tune.log import StudySettings, Trial, read_study
from evaluation.tune.report import load_summary, report_figure, report_markdown
from evaluation.tune.scoring import OBJECTIVE, Score, expected_max, expected_max_curve, objective
from evaluation.tune.study import best_of, run_study, write_best

__all__ = [
    "DEFAULT_SLIP",
    "OBJECTIVE",
    "STUDY_FILE",
    "SUITE",
    "TASK_CHOICES",
    "Score",
    "StudySettings",
    "Trial",
    "best_of",
    "evaluate_configuration",
    "expected_max",
    "expected_max_curve",
    "load_summary",
    "main",
    "objective",
    "read_study",
    "report_figure",
    "report_markdown",
    "run_study",
    "tasks_of",
    "write_best",
]
