"""A run as data: controller configurations (:mod:`~evaluation.run.configs`), the slip settings
as text (:mod:`~evaluation.run.slip_text`), a benchmark suite's layouts as the map axis
(:mod:`~evaluation.run.suite_runs`), one episode of a run (:mod:`~evaluation.run.plan`) and the
run itself, checked, planned and signed for ``--resume`` (:class:`~evaluation.run.spec.RunSpec`), with
the digests of the learned controllers' weights (:mod:`~evaluation.run.weights`).
Nothing here runs an episode.

The package is their face: the public names of its modules (their ``__all__``), importable from
here (tests/test_architecture.py checks the list).
"""

from __future__ import annotations

from evaluation.run.configs import (
    ControllerConfig,
    check_label,
    controller_configs,
    parse_controller,
    split_controller_list,
    with_solver,
)
from evaluation.run.plan import (
    RANDOM_MAP,
    EpisodeSpec,
    MapFile,
    is_map_file,
    map_fingerprints,
    read_map_files,
    safe_file_name,
)
from evaluation.run.slip_text import is_lambda, slip_value, split_slips
from evaluation.run.spec import CELL_AXES, MAX_WORKERS, RECORDED_ENV_SETTINGS, RunSpec, with_env_setting
from evaluation.run.suite_runs import (
    LAYOUT_FIELDS,
    add_suite_options,
    check_suite_run,
    cluster_of,
    layout_slice,
    refuse_suite_clash,
    selected_layouts,
    suite_config,
    suite_for,
    suite_map,
    suite_units,
    unit_trial,
)
from evaluation.run.weights import files_digest, run_presets, run_weights

__all__ = [
    "files_digest",
    "run_presets",
    "run_weights",
    "ControllerConfig",
    "check_label",
    "controller_configs",
    "parse_controller",
    "split_controller_list",
    "with_solver",
    "is_lambda",
    "slip_value",
    "split_slips",
    "LAYOUT_FIELDS",
    "add_suite_options",
    "check_suite_run",
    "cluster_of",
    "layout_slice",
    "refuse_suite_clash",
    "selected_layouts",
    "suite_config",
    "suite_for",
    "suite_map",
    "suite_units",
    "unit_trial",
    "EpisodeSpec",
    "MapFile",
    "RANDOM_MAP",
    "is_map_file",
    "map_fingerprints",
    "read_map_files",
    "safe_file_name",
    "CELL_AXES",
    "MAX_WORKERS",
    "RECORDED_ENV_SETTINGS",
    "RunSpec",
    "with_env_setting",
]
