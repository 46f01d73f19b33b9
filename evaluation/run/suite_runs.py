"""Runs on a benchmark suite (``--suite koopnav-bench-v1 --split test``, ``RunSpec(suite=...)``):
which layouts a run takes, the episodes they make, what the run records about its suite, and how
its reports group episodes by layout.

A suite run's map axis is, for each task, that task's split of the suite
(``map="suite:<name>/<split>"``, :mod:`koopman_envs.suites`). Every selected layout ``l`` runs
``episodes`` episodes ``j``, and the unit (l, j) has a trial index and a seed of its own, fixed by
(l, j) alone (:func:`unit_trial`): every controller meets the same (layout, seed) units, a run on a
prefix of the split (``--layouts 50``) is a subset of the full run, and so is a run with fewer
episodes per layout. The layout is handed to the env with the reset option ``layout``; the seed
draws the rest (slip, start perturbation).
"""

from __future__ import annotations

import argparse
from collections.abc import Mapping, Sequence
from typing import Any

from koopman_envs import (
    SPLITS,
    SUITE_PREFIX,
    SUITES,
    Suite,
    SuiteLayout,
    check_split_allowed,
    load_suite,
    task_for_env,
)
from koopman_envs.checks import check_choice

__all__ = [
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
]

#: the fields a suite run's episode records carry beyond every record's (None elsewhere)
LAYOUT_FIELDS = ("layout", "layout_family", "layout_tier", "suite")


def suite_map(name: str, split: str) -> str:
    """The env ``map`` value of a suite split: ``suite:<name>/<split>``."""
    return f"{SUITE_PREFIX}{name}/{split}"


def suite_for(env_id: str, name: str, split: str) -> Suite:
    """The split ``split`` of suite ``name`` for the task of ``env_id`` (loaded and verified once
    per process by :func:`koopman_envs.suites.load_suite`)."""
    return load_suite(name, task_for_env(env_id).name, split)


def layout_slice(value: Any) -> Any:
    """The normal form of a run's layout selection: ``None`` (the whole split), ``N`` (the first N
    layouts), ``"a:b"`` or ``(a, b)`` (layouts a to b-1) -> ``(a, b)``, an int pair or None.

    A value of another form is returned as it is, for :func:`check_suite_run` to name (a
    dataclass's normalisation must not raise: :meth:`RunSpec.validate` names bad values).
    """
    if value is None or isinstance(value, bool):
        return value
    if isinstance(value, int):
        return (0, value)
    if isinstance(value, str):
        text = value.strip()
        first, colon, stop = text.partition(":")
        try:
            return (int(first or 0), int(stop)) if colon else (0, int(text))
        except ValueError:
            return value  # named by check_suite_run
    if isinstance(value, Sequence) and len(value) == 2 and all(isinstance(v, int) for v in value):
        return (int(value[0]), int(value[1]))
    return value  # named by check_suite_run


def check_suite_run(spec: Any, max_episodes: int) -> None:
    """Refuse a run's bad suite settings, naming the value and what is allowed.

    Parameters
    ----------
    spec : RunSpec
        The run (typed ``Any`` here: :mod:`evaluation.run.spec` imports this module; its ``suite``, ``split``, ``layouts``, ``envs``, ``maps``, ``random_maps`` and
        ``episodes``, episodes per layout in a suite run).
    max_episodes : int
        The most episodes a cell may plan.

    Raises
    ------
    ValueError
        ``split`` or ``layouts`` without ``suite``; an unknown suite or split; ``suite`` with
        ``random_maps`` or with maps other than the suite's split; a selection that is not a
        slice of every task's split; more episodes per cell than ``max_episodes``.
    """
    name, episodes = spec.suite, spec.episodes
    layouts: Any = spec.layouts  # the normal form of layout_slice, or a bad value to name
    if name is None:
        for field in ("split", "layouts"):
            if getattr(spec, field) is not None:
                raise ValueError(
                    f"{field}={getattr(spec, field)!r} needs suite= (a benchmark suite, one of "
                    f"{list(SUITES)}); without one the maps are the map axis"
                )
        return
    check_choice("suite", name, list(SUITES))
    split = str(check_choice("split", spec.split, SPLITS))
    check_split_allowed(split, "evaluation")
    if spec.random_maps is not None:
        raise ValueError(
            f"suite={name!r} and random_maps={spec.random_maps!r} cannot be combined: a suite run's maps "
            "are the suite's layouts; run the random layouts without suite="
        )
    own = suite_map(name, split)
    for env_id, maps in spec.maps.items():
        if tuple(maps) != (own,):
            raise ValueError(
                f"suite={name!r} and maps={list(maps)} for {env_id} cannot be combined: a suite run's map "
                f"axis is the suite's split ({own!r}); leave maps out, or run the maps without suite="
            )
    for env_id in spec.envs:
        suite = suite_for(env_id, name, split)
        size = len(suite)
        if layouts is not None:
            valid = (
                isinstance(layouts, tuple)
                and len(layouts) == 2
                and all(isinstance(v, int) and not isinstance(v, bool) for v in layouts)
                and 0 <= layouts[0] < layouts[1] <= size
            )
            if not valid:
                raise ValueError(
                    f"layouts={_shown(layouts)} is not a selection of {suite.label} ({size} layouts); "
                    f"allowed: N in [1, {size}] (the first N) or a slice a:b with 0 <= a < b <= {size}"
                )
        chosen = size if layouts is None else layouts[1] - layouts[0]
        if chosen * episodes > max_episodes:
            raise ValueError(
                f"episodes={episodes} per layout on {chosen} layouts of {suite.label} make "
                f"{chosen * episodes} episodes per cell; allowed: at most {max_episodes} (fewer "
                "layouts with --layouts, or fewer episodes)"
            )


def _shown(layouts: Any) -> str:
    """A selection as the user gave it: ``a:b`` for a slice."""
    if isinstance(layouts, tuple) and len(layouts) == 2:
        return f"{layouts[0]}:{layouts[1]}"
    return repr(layouts)


def selected_layouts(
    env_id: str, name: str, split: str, layouts: tuple[int, int] | None
) -> list[SuiteLayout]:
    """The layouts a run takes from the task's split, in order."""
    suite = suite_for(env_id, name, split)
    first, stop = (0, len(suite)) if layouts is None else layouts
    return list(suite.layouts[first:stop])


def suite_units(
    env_id: str, name: str, split: str, layouts: tuple[int, int] | None, episodes: int
) -> list[tuple[int, dict[str, Any]]]:
    """The episodes of a suite run's cell: (trial index, layout fields of the record) of
    episode j on every selected layout, layout by layout (:func:`unit_trial`)."""
    suite = suite_for(env_id, name, split)
    return [
        (
            unit_trial(lay.index, j, len(suite)),
            {"layout": lay.index, "layout_family": lay.family, "layout_tier": lay.tier, "suite": suite.label},
        )
        for lay in selected_layouts(env_id, name, split, layouts)
        for j in range(episodes)
    ]


def unit_trial(layout: int, episode: int, split_size: int) -> int:
    """The trial index of episode ``episode`` on layout ``layout`` of a split of ``split_size``
    layouts: ``episode * split_size + layout``. Fixed by (layout, episode) alone, so that a run
    on a slice of the split, or with fewer episodes per layout, runs a subset of the full run's
    units; the episode's seed is the run's seed plus this index."""
    return episode * split_size + layout


def suite_config(
    envs: Sequence[str], name: str, split: str, layouts: tuple[int, int] | None, episodes: int
) -> dict[str, Any]:
    """What ``results.json`` records of a suite run (and ``--resume`` checks): the suite's name,
    version and split, the selection, episodes per layout, and per task the split's label and
    full sha256."""
    tasks = {}
    for env_id in envs:
        suite = suite_for(env_id, name, split)
        tasks[env_id] = {"label": suite.label, "sha256": suite.sha256, "size": len(suite)}
    return {
        "name": name,
        "version": SUITES[name].version,
        "split": split,
        "layouts": None if layouts is None else list(layouts),
        "episodes_per_layout": episodes,
        "tasks": tasks,
    }


def cluster_of(record: Mapping[str, Any]) -> Any:
    """What an episode's outcome is clustered by in an interval: its layout in a suite run (the
    layouts are the sample; episodes on one layout share it), else its trial's seed (a trial's
    seed fixes its layout, start and slip draws in every cell)."""
    if record.get("layout") is not None:
        return ("layout", record.get("map"), record["layout"])
    return ("seed", record.get("seed"))


# --------------------------------------------------------------------------- the command line
def add_suite_options(what: argparse._ArgumentGroup) -> None:
    """The evaluator's ``--suite``, ``--split`` and ``--layouts`` options."""
    what.add_argument(
        "--suite",
        metavar="NAME",
        help=f"a benchmark suite ({', '.join(SUITES)}; docs/benchmark.md): each task's map axis becomes "
        "its --split of the suite, every layout run --episodes times (default 1 per layout), high slip; "
        "not with --maps, --random-maps or a protocol (default: no suite)",
    )
    what.add_argument("--split", choices=list(SPLITS), help="with --suite: the split to run (default: test)")
    what.add_argument(
        "--layouts",
        metavar="N|A:B",
        help="with --suite: the first N layouts of each split, or layouts A to B-1, for a quick run "
        "(default: every layout)",
    )


#: the options that set a run's maps, which a suite run's layouts replace
_MAP_OPTIONS = ("maps", "random_maps", "paper", "paper_strict", "crowd", "lidar", "ablation")


def refuse_suite_clash(args: argparse.Namespace) -> None:
    """``--suite`` with an option that sets the maps (``--maps``, ``--random-maps``, a protocol),
    or ``--split`` / ``--layouts`` without ``--suite``: ``ValueError`` naming them (bad input)."""
    if args.suite is None:
        given = [f"--{name}" for name in ("split", "layouts") if getattr(args, name) is not None]
        if given:
            raise ValueError(f"{' and '.join(given)} need --suite NAME (one of {list(SUITES)})")
        return
    clashes = [
        "--" + option.replace("_", "-")
        for option in _MAP_OPTIONS
        if getattr(args, option) not in (None, False)
    ]
    if clashes:
        raise ValueError(
            f"--suite {args.suite} cannot be combined with {', '.join(clashes)}: a suite run's maps are "
            "the suite's layouts (each task's --split); run the others without --suite"
        )
