"""The record of a tuning study and the rule that adopts its best configuration (issue 60).

A study (:mod:`evaluation.tune`) writes ``study.jsonl`` (a header, then one line per trial, trial
0 the controller's defaults) and ``best.json`` into its folder, ``data/tuning/<name>/`` for the
studies behind the shipped presets. :func:`finished_study` reads a finished one, refusing a
missing, torn or unfinished log, another controller's or task's, or one tuned on the test split;
:func:`adoption` decides by :data:`ADOPTION_RULE` whether its best configuration becomes the
shipped default (:mod:`controllers.tuning.presets` applies only what it adopts;
``python -m evaluation.tune adopt NAME`` installs it).
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from koopman_envs import check_split_allowed
from koopman_envs.checks import parse_json
from koopman_envs.files import MAX_LOG_BYTES, read_text

__all__ = [
    "ADOPTION_RULE",
    "BEST_FILE",
    "SHIPPED_TASK",
    "STUDIES_DIR",
    "STUDY_FILE",
    "STUDY_KIND",
    "TRIAL_FIELDS",
    "Adoption",
    "StudyBudget",
    "adoption",
    "finished_study",
    "study_adoption",
    "study_budget",
    "study_record",
    "trial_problem",
    "trial_rank",
]

#: the task of a study whose preset may ship: a controller's defaults serve every task
SHIPPED_TASK = "both"
#: where the studies behind the tuned presets are committed: ``<name>/`` holds the study of
#: ``<name>`` (the repository's ``data/tuning/``, as ``bash data/tuning/run.sh`` writes it)
STUDIES_DIR = Path(__file__).resolve().parents[2] / "data" / "tuning"
#: a study's log and its summary, as :mod:`evaluation.tune` writes them into the study's folder
STUDY_FILE = "study.jsonl"
BEST_FILE = "best.json"
#: the ``kind`` of a study log's header line
STUDY_KIND = "koopnav-study"
#: the fields of a trial's line (:func:`trial_problem`)
TRIAL_FIELDS = (
    "trial",
    "params",
    "options",
    "score",
    "successes",
    "episodes",
    "errors",
    "mean_time_to_goal",
    "layouts",
    "seeds",
    "wall_seconds",
    "budget_so_far",
)


def trial_problem(record: Any) -> str | None:
    """Why ``record`` is not a trial line of a study log (None when it is one): the one rule for
    the tuner's reader (:func:`evaluation.tune.read_study`) and the shipped presets' check."""
    if not isinstance(record, dict):
        return "not a JSON object"
    missing = [k for k in TRIAL_FIELDS if k not in record]
    if missing:
        return f"not a trial record (no {', '.join(missing)})"
    if not isinstance(record["params"], dict) or not isinstance(record["score"], (int, float)):
        return "a trial record whose params are not an object or whose score is not a number"
    return None


def study_record(header: Mapping[str, Any], configurations_run: int) -> dict[str, Any]:
    """The record of its study that a tuned preset carries (``"study"``): the split, suites,
    seed and budget of the study log's ``header``, and how many configurations it ran.

    :func:`evaluation.tune.write_best` writes it and :func:`controllers.tuning.presets.check_study`
    compares a preset's with its log's, so both build it here, in this key order.
    """
    record = {k: header.get(k) for k in ("split", "suites", "seed", "budget")}
    record["configurations_run"] = configurations_run
    return record


def _study_lines(preset: str, log: Path) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """The header and the trial lines of a study log, refused when missing or torn."""
    if not log.is_file():
        raise ValueError(
            f"{preset}: its study {log} is missing; a tuned preset ships with the study that chose it "
            f"({STUDY_FILE} and {BEST_FILE} in {log.parent})"
        )
    text = read_text(log, MAX_LOG_BYTES, what="study log", expected="JSON lines")
    if not text.endswith("\n"):
        # a kill mid-write leaves the last line without its newline: the study did not finish
        raise ValueError(
            f"{preset}: its study {log} is torn (the last line has no newline); finish it with "
            "`python -m evaluation.tune ... --resume` before shipping its preset"
        )
    lines = [parse_json(line, f"{log} line {i}") for i, line in enumerate(text.splitlines(), 1)]
    header, trials = lines[0], lines[1:]
    if not isinstance(header, dict) or header.get("kind") != STUDY_KIND:
        raise ValueError(f"{preset}: {log} is not a study log (line 1 is not a {STUDY_KIND!r} header)")
    for i, trial in enumerate(trials):
        problem = trial_problem(trial)
        if problem is None and trial["trial"] != i:
            problem = f"trial {trial['trial']!r} where trial {i} was expected"
        if problem is not None:
            raise ValueError(f"{preset}: {log} line {i + 2}: {problem}")
    return header, trials


#: the adoption rule (issue 60), declared before any study's preset is adopted: :func:`adoption`
ADOPTION_RULE = (
    "a study's best configuration becomes the shipped default only if it has strictly more "
    "validation successes than the defaults (its trial 0) had in the same study, on the same "
    "layouts, seeds and budget; a tie or a loss keeps the defaults"
)


@dataclass(frozen=True)
class Adoption:
    """The adoption rule's decision on one finished study (:func:`adoption`).

    Attributes
    ----------
    controller : str
        The controller or preset the study tuned.
    adopted : bool
        Whether its best configuration becomes the shipped default.
    best_trial : int
        The study's best trial (the highest score, the earliest among equals).
    best_successes, defaults_successes : int
        The validation successes of the best trial and of trial 0 (the defaults).
    episodes : int
        The validation episodes of each of them.
    """

    controller: str
    adopted: bool
    best_trial: int
    best_successes: int
    defaults_successes: int
    episodes: int

    @property
    def verdict(self) -> str:
        """``adopted``, or why the defaults are kept (``a tie`` or ``a loss``)."""
        if self.adopted:
            return "adopted"
        return (
            "defaults kept ("
            + ("a tie" if self.best_successes == self.defaults_successes else "a loss")
            + ")"
        )

    def __str__(self) -> str:
        return (
            f"{self.controller}: {self.verdict}: trial {self.best_trial} {self.best_successes}/{self.episodes} "
            f"validation successes against the defaults' {self.defaults_successes}/{self.episodes}"
        )


def trial_rank(trial: Mapping[str, Any]) -> tuple[float, int]:
    """The order of a study's trial records: the highest score first, the earliest among equals
    (so trial 0, the defaults, wins a tie)."""
    return trial["score"], -trial["trial"]


def adoption(controller: str, trials: Sequence[Mapping[str, Any]]) -> Adoption:
    """Decide by :data:`ADOPTION_RULE` whether a study's best configuration is adopted.

    Parameters
    ----------
    controller : str
        The controller or preset the study tuned (named in the decision and the errors).
    trials : sequence of dict
        The study log's trial records in order (``trial``, ``score``, ``successes``,
        ``episodes``, ``layouts``, ``seeds``), trial 0 the defaults.

    Returns
    -------
    Adoption
        Adopted when the best trial has strictly more successes than trial 0.

    Raises
    ------
    ValueError
        No trial, a trial without integer successes and episodes, or a best trial that did not
        run trial 0's layouts, seeds and number of episodes (then the two are not comparable).
    """
    if not trials:
        raise ValueError(f"{controller}: a study without trials adopts nothing")
    for trial in trials:
        if not all(type(trial.get(k)) is int for k in ("successes", "episodes")):
            raise ValueError(
                f"{controller}: trial {trial.get('trial')!r} has no integer successes and episodes"
            )
    defaults, best = trials[0], max(trials, key=trial_rank)
    for key in ("episodes", "layouts", "seeds"):
        if best.get(key) != defaults.get(key):
            raise ValueError(
                f"{controller}: trial {best['trial']} ran {key}={best.get(key)!r}, the defaults' trial 0 "
                f"{defaults.get(key)!r}; the adoption rule compares the two on the same episodes"
            )
    return Adoption(
        controller,
        best["successes"] > defaults["successes"],
        best["trial"],
        best["successes"],
        defaults["successes"],
        defaults["episodes"],
    )


def finished_study(name: str, studies: str | os.PathLike[str]) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """The header and trials of ``studies/<name>/``'s log, refused unless it is a finished
    ``task=both`` study of ``name`` on a split tuning may use
    (:func:`controllers.tuning.presets.check_study` says how)."""
    log = Path(studies) / name / STUDY_FILE
    header, trials = _study_lines(name, log)
    if header.get("controller") != name:
        raise ValueError(
            f"{name}: its study {log} is of another controller: controller={header.get('controller')!r}"
        )
    if header.get("task") != SHIPPED_TASK:
        raise ValueError(f"{name}: its study {log} has task={header.get('task')!r}, not {SHIPPED_TASK!r}")
    split = header.get("split")
    try:
        check_split_allowed(str(split), "tuning")
    except ValueError as error:
        raise ValueError(f"{name}: its study {log} was tuned on split={split!r}: {error}") from None
    wanted = header.get("budget", {}).get("configurations")
    if len(trials) != wanted:
        raise ValueError(
            f"{name}: its study {log} is unfinished: {len(trials)} of configurations={wanted!r} trials"
        )
    return header, trials


def study_adoption(name: str, studies: str | os.PathLike[str] = STUDIES_DIR) -> Adoption:
    """The :func:`adoption` decision on the finished study of ``name`` in ``studies``
    (refused as :func:`controllers.tuning.presets.check_study` refuses a study that is missing, torn, unfinished or not
    ``name``'s held-out ``task=both`` study)."""
    return adoption(name, finished_study(name, studies)[1])


@dataclass(frozen=True)
class StudyBudget:
    """The tuning budget one controller had: what its study declared and how much of it ran
    (:func:`study_budget`), for the pages that report results beside it ("Show Your Work",
    Dodge et al. 2019).

    Attributes
    ----------
    controller : str
        The controller or preset the study tuned.
    split : str
        The split it was tuned on (``validation`` or ``train``; never ``test``).
    configurations : int
        The configurations the study declared (its budget), trial 0 the defaults.
    configurations_run : int
        The trials its log holds.
    episodes_per_configuration : int
        The validation episodes each configuration ran (both tasks).
    verdict : str
        The adoption rule's decision (:attr:`Adoption.verdict`) on a finished study, else
        ``"unfinished"``.
    """

    controller: str
    split: str
    configurations: int
    configurations_run: int
    episodes_per_configuration: int
    verdict: str

    @property
    def finished(self) -> bool:
        """Whether every declared configuration ran."""
        return self.configurations_run == self.configurations

    @property
    def episodes_run(self) -> int:
        """The validation episodes the study ran so far."""
        return self.configurations_run * self.episodes_per_configuration


def study_budget(name: str, studies: str | os.PathLike[str] = STUDIES_DIR) -> StudyBudget | None:
    """The tuning budget of ``name``: its study in ``studies/<name>/``, finished or not; None when
    there is no study log (the controller was not tuned).

    Raises
    ------
    ValueError
        A log that is torn or not a study log, another controller's, or one tuned on a split
        tuning may not use (as :func:`finished_study`, which also refuses an unfinished one).
    """
    log = Path(studies) / name / STUDY_FILE
    if not log.exists():
        return None
    header, trials = _study_lines(name, log)
    if header.get("controller") != name:
        raise ValueError(f"{name}: its study {log} is of another controller: {header.get('controller')!r}")
    check_split_allowed(str(header.get("split")), "tuning")
    budget = header.get("budget", {})
    declared = int(budget.get("configurations", 0))
    finished = len(trials) == declared
    return StudyBudget(
        controller=name,
        split=str(header["split"]),
        configurations=declared,
        configurations_run=len(trials),
        episodes_per_configuration=int(budget.get("episodes_per_configuration", 0)),
        verdict=adoption(name, trials).verdict if finished else "unfinished",
    )
