"""The benchmark suites as data: their definitions, the stored layouts, their hashes, the loader.

A suite (``koopnav-bench-v1``) has, per task, three frozen splits (``train``, ``validation``,
``test``) drawn from disjoint, declared seed ranges (:data:`SUITES`). Each split is a gzipped JSON
file in ``koopman_envs/suites/data/<suite>/<task>/<split>.json.gz``, and its sha256 (of the
canonical serialisation, :func:`content_hash`) is recorded in the suite's ``manifest.json``;
:func:`load_suite` checks it and refuses a torn or edited file by name. The files are made, and
checked against the generator, by ``python -m koopman_envs.suites.build``.

Versioning rule: a suite's layouts never change under its name. A change to the generator, the
measures or the tiers that changes any stored layout, or to the dynamics or the tasks that
changes a reference rollout (tests/test_suites.py), makes a new suite (``koopnav-bench-v2``).
"""

from __future__ import annotations

import functools
import gzip
import hashlib
import json
import os
import zlib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from koopman_envs.checks import check_choice, did_you_mean
from koopman_envs.params import PARAMS
from koopman_envs.sim.maps.map_spec import MapSpec
from koopman_envs.suites.families import FAMILIES
from koopman_envs.suites.measures import TIER_THRESHOLDS, TIERS
from koopman_envs.tasks.base import TASKS

__all__ = [
    "HELD_OUT_PURPOSES",
    "PURPOSES",
    "SPLITS",
    "SUITES",
    "SUITE_PREFIX",
    "SplitDefinition",
    "Suite",
    "SuiteDefinition",
    "SuiteLayout",
    "check_split_allowed",
    "content_hash",
    "load_suite",
    "parse_suite_map",
    "read_manifest",
    "read_split_document",
    "suite_maps",
]

#: the splits of every suite, in order
SPLITS = ("train", "validation", "test")
#: what a split may be read for; the test split only for the last two
PURPOSES = ("tuning", "training", "calibration", "checkpoint selection", "evaluation", "reporting")
#: the purposes the test split is refused for (held-out discipline, issue 60)
HELD_OUT_PURPOSES = ("tuning", "training", "calibration", "checkpoint selection")
#: the prefix of a suite given as an env's ``map``: ``map="suite:koopnav-bench-v1/test"``
SUITE_PREFIX = "suite:"


@dataclass(frozen=True)
class SplitDefinition:
    """One split of a suite: its seed range and how many layouts it takes per task.

    Attributes
    ----------
    name : str
        One of :data:`SPLITS`.
    seeds : (int, int)
        The half-open seed range [first, stop): the split takes the first ``size`` accepted
        seeds in it, balanced across the families.
    size : int
        Layouts per task.
    """

    name: str
    seeds: tuple[int, int]
    size: int


@dataclass(frozen=True)
class SuiteDefinition:
    """What a suite is made of (its stored data is checked against this by the build script).

    Attributes
    ----------
    name : str
        The suite's name, its version included (``koopnav-bench-v1``).
    version : int
        The version number in the name.
    splits : tuple of SplitDefinition
        Train, validation and test, with disjoint seed ranges.
    n_obstacles : int
        Obstacles of every layout.
    n_robots : int
        Robots of every layout (an env may use the first N of them).
    tier_thresholds : dict
        Per task, the difficulty cuts between the tiers (derived from its train split once,
        declared: :data:`~koopman_envs.suites.measures.TIER_THRESHOLDS` for v1).
    tasks : tuple of str
        The tasks with data.
    """

    name: str
    version: int
    splits: tuple[SplitDefinition, ...]
    tier_thresholds: dict[str, tuple[float, float]]
    n_obstacles: int = 24
    n_robots: int = PARAMS.n_robots
    tasks: tuple[str, ...] = tuple(TASKS)

    def split(self, name: str) -> SplitDefinition:
        """The split called ``name`` (``ValueError`` naming the allowed ones otherwise)."""
        check_choice("split", name, SPLITS)
        return next(s for s in self.splits if s.name == name)


#: the suites, by name (sizes per task; train 500 is ~0.4 MB gzipped for both tasks)
SUITES: dict[str, SuiteDefinition] = {
    "koopnav-bench-v1": SuiteDefinition(
        "koopnav-bench-v1",
        1,
        (
            SplitDefinition("train", (0, 1_000_000), 500),
            SplitDefinition("validation", (1_000_000, 2_000_000), 100),
            SplitDefinition("test", (2_000_000, 3_000_000), 200),
        ),
        TIER_THRESHOLDS,
    ),
}


@dataclass(frozen=True, eq=False)
class SuiteLayout:
    """One stored layout of a suite.

    Attributes
    ----------
    index : int
        Its position in the split (``reset(options={"layout": index})``).
    id : str
        ``"<split>-<index>"`` (three digits), the name of its map.
    family : str
        One of :data:`~koopman_envs.suites.families.FAMILIES`.
    seed : int
        The layout seed it was drawn from.
    spec : MapSpec
        Its obstacles, starts and targets (named by ``id``).
    measures : dict
        ``gap`` [m], ``tortuosity``, ``density``, ``difficulty``
        (:mod:`koopman_envs.suites.measures`).
    tier : str
        One of :data:`~koopman_envs.suites.measures.TIERS`.
    """

    index: int
    id: str
    family: str
    seed: int
    spec: MapSpec
    measures: dict[str, float]
    tier: str


@dataclass(frozen=True, eq=False)
class Suite:
    """One split of a suite for one task, as loaded and verified (:func:`load_suite`).

    Attributes
    ----------
    name : str
        The suite's name (``koopnav-bench-v1``).
    version : int
        Its version.
    task : str
        ``"target_reaching"`` or ``"formation"``.
    split : str
        One of :data:`SPLITS`.
    sha256 : str
        The hash of the split's canonical serialisation, as the manifest records it.
    seeds : (int, int)
        The split's declared seed range [first, stop).
    layouts : tuple of SuiteLayout
        The layouts, in order.
    n_obstacles : int
        Obstacles of every layout.
    """

    name: str
    version: int
    task: str
    split: str
    sha256: str
    seeds: tuple[int, int]
    layouts: tuple[SuiteLayout, ...] = field(repr=False)
    n_obstacles: int

    @property
    def label(self) -> str:
        """``<name>/<task>/<split>@<first 12 hex of sha256>``: what a report prints."""
        return f"{self.name}/{self.task}/{self.split}@{self.sha256[:12]}"

    @property
    def map_name(self) -> str:
        """The env ``map`` value of this split: ``suite:<name>/<split>``."""
        return f"{SUITE_PREFIX}{self.name}/{self.split}"

    def __len__(self) -> int:
        return len(self.layouts)

    def layout(self, index: int) -> SuiteLayout:
        """Layout ``index`` (``ValueError`` naming the allowed range otherwise)."""
        if isinstance(index, bool) or not isinstance(index, (int, np.integer)) or not 0 <= index < len(self):
            raise ValueError(
                f"layout={index!r} is not a layout of {self.label}; allowed: an integer in "
                f"[0, {len(self) - 1}]"
            )
        return self.layouts[int(index)]

    def require_split_for(self, purpose: str) -> None:
        """Refuse this split for ``purpose`` when it is held out (:func:`check_split_allowed`)."""
        check_split_allowed(self.split, purpose, self.label)


def check_split_allowed(split: str, purpose: str, label: str | None = None) -> None:
    """Refuse the test split for tuning, training, calibration and checkpoint selection.

    Parameters
    ----------
    split : str
        One of :data:`SPLITS`.
    purpose : str
        One of :data:`PURPOSES`.
    label : str, optional
        The suite's label, for the message.

    Raises
    ------
    ValueError
        An unknown split or purpose (naming the allowed ones), or ``split="test"`` for a purpose
        of :data:`HELD_OUT_PURPOSES`.
    """
    check_choice("split", split, SPLITS)
    check_choice("purpose", purpose, PURPOSES)
    if split == "test" and purpose in HELD_OUT_PURPOSES:
        what = label or "the test split"
        raise ValueError(
            f"split='test' is held out: {what} may not be used for {purpose}; use 'train' or "
            f"'validation' for {', '.join(HELD_OUT_PURPOSES)}; 'test' is for "
            f"{' and '.join(p for p in PURPOSES if p not in HELD_OUT_PURPOSES)} only"
        )


def suite_maps() -> tuple[str, ...]:
    """Every suite split as an env ``map`` value (``suite:<name>/<split>``)."""
    return tuple(f"{SUITE_PREFIX}{name}/{split}" for name in SUITES for split in SPLITS)


def parse_suite_map(text: str) -> tuple[str, str]:
    """The (suite name, split) of a ``map="suite:<name>/<split>"`` value.

    Raises
    ------
    ValueError
        Not of that form, or an unknown suite or split (naming the allowed values).
    """
    body = text[len(SUITE_PREFIX) :] if text.startswith(SUITE_PREFIX) else text
    name, _, split = body.partition("/")
    if name not in SUITES or split not in SPLITS:
        raise ValueError(
            f"map={text!r} is not a suite split; allowed: {list(suite_maps())}{did_you_mean(text, suite_maps())}"
        )
    return name, split


def content_hash(document: dict[str, Any]) -> str:
    """sha256 (hex) of a split document's canonical serialisation: JSON with sorted keys, no
    whitespace, ASCII only, no NaN (the same bytes on every machine and Python version)."""
    text = json.dumps(document, sort_keys=True, separators=(",", ":"), ensure_ascii=True, allow_nan=False)
    return hashlib.sha256(text.encode("ascii")).hexdigest()


def _data(name: str, data: str | os.PathLike[str] | None) -> Any:
    """The data folder of suite ``name``: under ``data``, or the package's (a traversable)."""
    root: Any = resources.files("koopman_envs.suites").joinpath("data") if data is None else Path(data)
    return root.joinpath(name)


def read_manifest(name: str, data: str | os.PathLike[str] | None = None) -> dict[str, Any]:
    """The manifest of suite ``name`` (``ValueError`` naming the file if it cannot be read)."""
    path = _data(name, data).joinpath("manifest.json")
    try:
        manifest: dict[str, Any] = json.loads(path.read_text("utf-8"))
    except (OSError, ValueError) as exc:
        raise ValueError(f"suite {name!r}: manifest {path} cannot be read: {exc}") from None
    return manifest


def read_split_document(
    name: str, task: str, split: str, data: str | os.PathLike[str] | None = None
) -> tuple[dict[str, Any], str]:
    """The parsed document of a split file and its path (``ValueError`` naming the file when it
    is missing, torn or not JSON)."""
    path = _data(name, data).joinpath(task, f"{split}.json.gz")
    try:
        document: dict[str, Any] = json.loads(gzip.decompress(path.read_bytes()).decode("utf-8"))
    except (OSError, EOFError, zlib.error, UnicodeDecodeError, ValueError) as exc:
        raise ValueError(
            f"suite file {path} cannot be read ({type(exc).__name__}: {exc}); it is torn or edited: "
            "restore it (git checkout) or rebuild with python -m koopman_envs.suites.build --write"
        ) from None
    return document, str(path)


def _layout(index: int, record: dict[str, Any]) -> SuiteLayout:
    """A stored layout record as a :class:`SuiteLayout` (its map checked as every map is)."""
    spec = MapSpec(
        record["id"],
        record["obstacles"],
        record["starts"],
        record["targets"],
        description=f"{record['family']} layout, seed {record['seed']}",
    )
    return SuiteLayout(
        index, record["id"], record["family"], record["seed"], spec, record["measures"], record["tier"]
    )


@functools.cache
def load_suite(name: str, task: str, split: str, *, data: str | os.PathLike[str] | None = None) -> Suite:
    """Load one split of a suite for one task, verified against its manifest's hash.

    Loaded once per process (the result is frozen and kept).

    Parameters
    ----------
    name : str
        A suite of :data:`SUITES` (``"koopnav-bench-v1"``).
    task : str
        ``"target_reaching"`` or ``"formation"``.
    split : str
        ``"train"``, ``"validation"`` or ``"test"``.
    data : path, optional
        A folder holding suites' data in the package's layout (``<name>/manifest.json``,
        ``<name>/<task>/<split>.json.gz``); default: the package's own.

    Returns
    -------
    Suite
        Frozen; print its :attr:`Suite.label` beside any result computed on it.

    Raises
    ------
    ValueError
        An unknown name, task or split (naming the allowed values), or a split file whose
        content does not hash to the manifest's sha256 (naming the file).
    """
    check_choice("suite", name, list(SUITES))
    definition = SUITES[name]
    check_choice("task", task, list(definition.tasks))
    plan = definition.split(split)
    manifest = read_manifest(name, data)
    document, path = read_split_document(name, task, split, data)
    expected = manifest["splits"][f"{task}/{split}"]["sha256"]
    actual = content_hash(document)
    if actual != expected:
        raise ValueError(
            f"suite file {path} has sha256 {actual[:12]}... but the manifest records {expected[:12]}...: "
            "it was edited or is torn; restore it (git checkout), or, if the generator changed, build a new "
            "suite version (python -m koopman_envs.suites.build)"
        )
    layouts = tuple(_layout(i, record) for i, record in enumerate(document["layouts"]))
    _check_document(document, layouts, name, task, split, plan)
    return Suite(name, definition.version, task, split, actual, plan.seeds, layouts, definition.n_obstacles)


def _check_document(
    document: dict[str, Any],
    layouts: tuple[SuiteLayout, ...],
    name: str,
    task: str,
    split: str,
    plan: SplitDefinition,
) -> None:
    """A hashed document that disagrees with its definition (a mis-built suite) is refused."""
    first, stop = plan.seeds
    problems = [
        f"{key}={document.get(key)!r} (expected {want!r})"
        for key, want in (("suite", name), ("task", task), ("split", split), ("seed_range", [first, stop]))
        if document.get(key) != want
    ]
    if len(layouts) != plan.size:
        problems.append(f"{len(layouts)} layouts (expected {plan.size})")
    problems += [
        f"layout {lay.id}: seed {lay.seed} outside [{first}, {stop}), family {lay.family!r}, tier {lay.tier!r}"
        for lay in layouts
        if not first <= lay.seed < stop or lay.family not in FAMILIES or lay.tier not in TIERS
    ]
    if problems:
        raise ValueError(
            f"suite {name}/{task}/{split} disagrees with its definition: {'; '.join(problems[:5])}"
        )
