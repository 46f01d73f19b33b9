"""What the tuner searches and what it ships (issue 60): the search spaces, the studies' record and
adoption rule, and the presets table with the tuned defaults applied.

- :mod:`controllers.tuning.search_space`: :class:`Search`, the values the tuner tries for one
  option, declared in each controller's ``TUNABLE`` table;
- :mod:`controllers.tuning.studies`: a study's files (``data/tuning/<name>/``), read and checked,
  and :data:`ADOPTION_RULE`, which decides whether its best configuration ships;
- :mod:`controllers.tuning.presets`: the built-in controllers and their named presets as one
  table, the tuned defaults of ``controllers/tuned/<name>.json`` applied to it (``<name>-v0``
  keeps the defaults from before).

The tuner itself, which runs the studies and writes those files, is :mod:`evaluation.tune`.
"""

from controllers.tuning.presets import (
    CONTROLLERS,
    PRESETS,
    TUNED_DIR,
    TUNED_KIND,
    V0_SUFFIX,
    WEIGHT_VARIANTS,
    Preset,
    build_preset,
    builtin_names,
    check_study,
    is_comparison_variant,
    read_tuned,
    register_builtins,
    with_tuned,
)
from controllers.tuning.search_space import Search
from controllers.tuning.studies import (
    ADOPTION_RULE,
    BEST_FILE,
    SHIPPED_TASK,
    STUDIES_DIR,
    STUDY_FILE,
    STUDY_KIND,
    TRIAL_FIELDS,
    Adoption,
    StudyBudget,
    adoption,
    finished_study,
    study_adoption,
    study_budget,
    study_record,
    trial_problem,
    trial_rank,
)

__all__ = [
    "ADOPTION_RULE",
    "BEST_FILE",
    "CONTROLLERS",
    "PRESETS",
    "SHIPPED_TASK",
    "STUDIES_DIR",
    "STUDY_FILE",
    "STUDY_KIND",
    "TRIAL_FIELDS",
    "TUNED_DIR",
    "TUNED_KIND",
    "V0_SUFFIX",
    "WEIGHT_VARIANTS",
    "Adoption",
    "Preset",
    "Search",
    "StudyBudget",
    "adoption",
    "build_preset",
    "builtin_names",
    "check_study",
    "finished_study",
    "is_comparison_variant",
    "read_tuned",
    "register_builtins",
    "study_adoption",
    "study_budget",
    "study_record",
    "trial_problem",
    "trial_rank",
    "with_tuned",
]
