"""Experiments made of runs: the named protocols, presets of :class:`~evaluation.run.spec.RunSpec`
(:mod:`~evaluation.experiments.protocols`), the NMPC design-factor ablation and its report
(:mod:`~evaluation.experiments.ablation`), ``--sweep``: one run per level of an env setting
(:mod:`~evaluation.experiments.sweep`), the sim-to-sim protocol's two runs read back per friction level
(:mod:`~evaluation.experiments.sim2sim`), and the learned policies' training seeds on the test split
(:mod:`~evaluation.experiments.seeds`, a command: ``python -m evaluation.experiments.seeds``) and
their publication read back (:mod:`~evaluation.experiments.seeds_published`), and where ``--ship``
ships a chosen seed (:mod:`~evaluation.experiments.seeds_shipping`).

The package is their face: the public names of its modules (their ``__all__``), importable from
here (tests/test_architecture.py checks the list), except those of the seeds command, which are
read from :mod:`evaluation.experiments.seeds` (its ``main`` and ``aggregate`` would be ambiguous here).
The names of :mod:`~evaluation.experiments.seeds_published` are imported when first read
(:func:`__getattr__`): that module imports the seeds command's, and a package that imported it
would make ``python -m evaluation.experiments.seeds`` run a module already imported (runpy's
RuntimeWarning, and two copies of its globals).
"""

from __future__ import annotations

from typing import Any

from evaluation.experiments.ablation import (
    ABLATION_TITLE,
    DEFAULT_LEVELS,
    FACTORS,
    MainEffects,
    ablation_configs,
    ablation_markdown,
    check_factors,
    main_effects,
    main_effects_family,
    main_effects_table,
    power_note,
)
from evaluation.experiments.protocols import (
    CROWD_COUNTS,
    CROWD_REFERENCE,
    LIDAR_AXES,
    LIDAR_MOVERS,
    PAPER_EXACT,
    PROTOCOLS,
    QUICK_SLIPS,
    QUICK_START_NOISE,
    START_NOISE,
    SUITE_EPISODES,
    TASK_MAPS,
    ablation_protocol,
    crowd_protocol,
    lidar_protocol,
    paper_protocol,
    protocol,
    quick_protocol,
    suite_protocol,
)
from evaluation.experiments.seeds_shipping import (
    V0_FOLDER_SUFFIX,
    check_shippable,
    keep_former,
    shipped_folder,
)
from evaluation.experiments.sim2sim import (
    FINE_TUNED,
    PLANTS,
    Level,
    against_source,
    level_data,
    shortfall,
    slip_levels,
    transfers,
)
from evaluation.experiments.sweep import (
    MANIFEST,
    MAX_SWEEP_LEVELS,
    SweepAxis,
    add_sweep_options,
    check_levels,
    level_aliases,
    load_sweep,
    parse_sweep,
    refuse_sweep_clash,
    run_sweep,
    write_manifest,
)

__all__ = [
    "DRIVER",
    "PublishedSeeds",
    "planned_seeds",
    "V0_FOLDER_SUFFIX",
    "check_shippable",
    "keep_former",
    "shipped_folder",
    "read_publication",
    "FINE_TUNED",
    "PLANTS",
    "Level",
    "against_source",
    "level_data",
    "shortfall",
    "slip_levels",
    "transfers",
    "ABLATION_TITLE",
    "DEFAULT_LEVELS",
    "FACTORS",
    "MainEffects",
    "ablation_configs",
    "ablation_markdown",
    "check_factors",
    "main_effects",
    "main_effects_family",
    "main_effects_table",
    "power_note",
    "CROWD_COUNTS",
    "CROWD_REFERENCE",
    "crowd_protocol",
    "LIDAR_AXES",
    "LIDAR_MOVERS",
    "lidar_protocol",
    "PAPER_EXACT",
    "PROTOCOLS",
    "QUICK_SLIPS",
    "QUICK_START_NOISE",
    "START_NOISE",
    "SUITE_EPISODES",
    "TASK_MAPS",
    "ablation_protocol",
    "paper_protocol",
    "protocol",
    "quick_protocol",
    "suite_protocol",
    "MANIFEST",
    "MAX_SWEEP_LEVELS",
    "SweepAxis",
    "add_sweep_options",
    "check_levels",
    "level_aliases",
    "load_sweep",
    "parse_sweep",
    "refuse_sweep_clash",
    "run_sweep",
    "write_manifest",
]

#: the names read from :mod:`~evaluation.experiments.seeds_published` on first use
_SEEDS_PUBLISHED = frozenset({"DRIVER", "PublishedSeeds", "planned_seeds", "read_publication"})


def __getattr__(name: str) -> Any:
    """The names of :mod:`~evaluation.experiments.seeds_published`, imported on first use (the
    module docstring says why)."""
    if name in _SEEDS_PUBLISHED:
        from evaluation.experiments import seeds_published

        return getattr(seeds_published, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
