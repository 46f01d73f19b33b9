"""A study's settings and its log (``OUT/study.jsonl``): the header, the trial lines, the reader."""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from controllers.tuning import STUDY_KIND, Search, trial_problem
from evaluation.episodes.records import json_safe
from evaluation.episodes.runlog import (
    LogError,
    cut_torn,
    parse_lines,
    split_lines,
)
from evaluation.run.spec import RunSpec
from evaluation.tune.configuration import DEFAULT_SLIP, SUITE, configuration_spec, tasks_of
from evaluation.tune.scoring import OBJECTIVE
from koopman_envs import check_split_allowed, load_suite
from koopman_envs.checks import check_int, differing_settings, parse_json
from koopman_envs.files import MAX_LOG_BYTES, read_bounded


@dataclass(frozen=True)
class StudySettings:
    """One study: what is tuned, on what, with which budget.

    Attributes
    ----------
    controller : str
        A registered controller or preset with tunable options.
    task : str
        One of :data:`TASK_CHOICES`.
    trials, layouts, episodes : int
        The budget: configurations, layouts per task (the split's first ``layouts``), episodes
        per layout.
    seed : int
        The sampler's seed and the first episode seed.
    split : str
        ``"validation"`` (default) or ``"train"``; ``"test"`` is refused.
    slip : str
        The slip setting of every episode.
    env_kwargs : dict
        Further ``gym.make`` keywords (e.g. ``{"max_episode_steps": 100}``).
    suite : str
        The suite's name.
    """

    controller: str
    task: str
    trials: int
    layouts: int
    episodes: int
    seed: int
    split: str = "validation"
    slip: str = DEFAULT_SLIP
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    suite: str = SUITE

    def check(self, workers: int = 1) -> None:
        """``ValueError`` naming a bad setting, before anything is read or written: the test split
        first, then the study's own bounds, then the whole run of a configuration (slip, env
        keywords, controller, layouts, ``workers``) by the evaluator's own checks
        (:meth:`~evaluation.run.spec.RunSpec.validate`), so that a study that would fail at its
        first trial leaves no log behind."""
        check_split_allowed(self.split, "tuning")  # an unknown split too, naming the allowed ones
        tasks_of(self.task)
        check_int("trials", self.trials, 1, maximum=100_000)
        check_int("layouts", self.layouts, 1)
        check_int("episodes", self.episodes, 1, maximum=10_000)
        self.run_spec().validate(workers)

    def run_spec(self, options: Mapping[str, Any] | None = None) -> RunSpec:
        """The run of one configuration (``options``; default the controller's defaults) of this
        study: what every trial hands to the evaluator (:func:`configuration_spec`)."""
        return configuration_spec(
            self.controller,
            dict(options or {}),
            self.task,
            self.split,
            self.layout_indices,
            self.episodes,
            self.seed,
            suite=self.suite,
            slip=self.slip,
            env_kwargs=self.env_kwargs,
        )

    @property
    def layout_indices(self) -> list[int]:
        """The layouts of every trial: the split's first ``layouts`` (balanced across the
        families, which the split's seeds cycle through)."""
        return list(range(self.layouts))

    @property
    def episodes_per_trial(self) -> int:
        """Episodes of one configuration."""
        return len(tasks_of(self.task)) * self.layouts * self.episodes

    def header(self, search: Mapping[str, Search], defaults: Mapping[str, Any]) -> dict[str, Any]:
        """The study log's first line (plain JSON): everything a resume must match."""
        # check() has refused a selection larger than a split (the evaluator's check_suite_run)
        suites = [load_suite(self.suite, name, self.split).label for name in tasks_of(self.task)]
        return json_safe(
            {
                "kind": STUDY_KIND,
                "controller": self.controller,
                "task": self.task,
                "split": self.split,
                "suites": suites,
                "seed": self.seed,
                "slip": self.slip,
                "env_kwargs": dict(sorted(self.env_kwargs.items())),
                "budget": {
                    "configurations": self.trials,
                    "layouts_per_task": self.layouts,
                    "episodes_per_layout": self.episodes,
                    "episodes_per_configuration": self.episodes_per_trial,
                    "episodes": self.trials * self.episodes_per_trial,
                },
                "objective": OBJECTIVE,
                "sampler": f"optuna TPESampler(seed={self.seed}); trial 0 the defaults",
                "search": {name: str(s) for name, s in search.items()},
                "defaults": dict(defaults),
            }
        )


@dataclass(frozen=True)
class Trial:
    """One finished trial, as its line of the study log holds it."""

    number: int
    params: dict[str, Any]
    options: dict[str, Any]
    score: float
    successes: int
    episodes: int
    record: dict[str, Any]


def read_study(
    path: str | os.PathLike[str], header: Mapping[str, Any] | None = None, *, repair: bool = True
) -> tuple[dict[str, Any], list[Trial], list[str]]:
    """The header and the finished trials of a study log, with notes on what was repaired.

    Parameters
    ----------
    path : path
        The study's ``study.jsonl``.
    header : mapping, optional
        The header the log must have (a resume's); None: any study header.
    repair : bool
        Cut a torn last line (one a kill left without its newline) off the file.

    Raises
    ------
    LogError
        Not a study log, a header of another study (naming the settings that differ), a line
        that is not a trial, or trials out of order: each named by file and line; nothing is
        changed in the file then.
    """
    data = read_bounded(path, MAX_LOG_BYTES, what="study log")
    lines, torn = split_lines(data)
    if not lines:
        raise LogError(
            f"{path}: no complete header line; it is not a study log (move it aside to start afresh)"
        )
    try:
        found = parse_json(lines[0], f"{path} line 1")
    except ValueError:
        found = None
    if not isinstance(found, dict) or found.get("kind") != STUDY_KIND:
        raise LogError(f"{path} is not a KoopNav study log (line 1 is not a {STUDY_KIND!r} header)")
    if header is not None and found != header:
        what = differing_settings(found, header)
        raise LogError(
            f"{path} belongs to another study ({what}); resume with the same settings or use "
            "another --out; nothing was changed"
        )
    records, places, bad = parse_lines(lines[1:], trial_problem)
    for i, (record, place) in enumerate(zip(records, places)):
        if record["trial"] != i:
            bad.append(f"{place}: trial {record['trial']!r} where trial {i} was expected")
            break
    if bad:
        raise LogError(f"{path} cannot be resumed: " + "; ".join(bad[:10]) + "; nothing was changed")
    notes = []
    if torn:
        if repair:
            cut_torn(path, data, torn)
        notes.append(
            f"{path}: dropped 1 incomplete trial (line {len(lines) + 1}, {len(torn)} bytes cut by the "
            "interruption); it will be run again"
        )
    trials = [
        Trial(r["trial"], r["params"], r["options"], float(r["score"]), r["successes"], r["episodes"], r)
        for r in records
    ]
    return found, trials, notes
