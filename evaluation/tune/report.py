"""``--report``: the expected-best curves of several studies and the table of what tuning gained;
and each controller's tuning budget as docs/bench_results.md states it (:func:`tuning_budget_rows`,
:func:`decision`)."""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import controllers
from controllers.tuning import STUDIES_DIR, STUDY_FILE, study_budget
from evaluation.reports.sections import suite_heading
from evaluation.run.suite_runs import suite_config
from evaluation.stats.layout_tests import sign_flip_p_text
from evaluation.tune.configuration import tasks_of
from evaluation.tune.confirm import CONFIRMATION_FILE
from evaluation.tune.log import read_study
from evaluation.tune.scoring import expected_max_curve
from koopman_envs import TASKS
from koopman_envs.checks import parse_json
from koopman_envs.files import MAX_TEXT_BYTES, read_text, write_atomic


@dataclass(frozen=True)
class StudySummary:
    """One study as the report shows it."""

    controller: str
    task: str
    budget: dict[str, Any]
    scores: list[float]
    #: the suite tuned on, as every report prints it (:func:`~evaluation.reports.sections.suite_heading`)
    suite: str = ""
    #: its name, version and each task's split label with its hash, for the figure's title
    suite_short: str = ""

    @property
    def defaults_score(self) -> float:
        return self.scores[0]

    @property
    def best_score(self) -> float:
        return max(self.scores)


def load_summary(folder: str | os.PathLike[str]) -> StudySummary:
    """The summary of the study logged in ``folder`` (read only: a torn line is left in place)."""
    header, trials, _ = read_study(Path(folder) / STUDY_FILE, repair=False)
    if not trials:
        raise ValueError(f"{folder}: the study has no finished trial yet")
    heading, short = _suite_text(folder, header)
    return StudySummary(
        header["controller"], header["task"], header["budget"], [t.score for t in trials], heading, short
    )


def _suite_text(folder: str | os.PathLike[str], header: dict[str, Any]) -> tuple[str, str]:
    """A study's suite: the heading every report prints (name, version, split, layouts, each
    task's label with its hash) and its short form; ``ValueError`` when the suite's data no
    longer hashes to the labels the study recorded."""
    labels = list(header["suites"])
    name = labels[0].split("/")[0]
    budget = header["budget"]
    config = suite_config(
        [TASKS[task].env_id for task in tasks_of(header["task"])],
        name,
        header["split"],
        (0, budget["layouts_per_task"]),
        budget["episodes_per_layout"],
    )
    now = [entry["label"] for entry in config["tasks"].values()]
    if now != labels:
        raise ValueError(f"{folder}: the study ran on {labels}, but the suite's data now is {now}")
    short = f"{name} (version {config['version']}):\n" + ", ".join(label.split("/", 1)[1] for label in labels)
    return suite_heading({"suite": config}), short


def report_markdown(studies: Sequence[StudySummary]) -> str:
    """The table of ``--report``: the suites tuned on (name, version, hash), then controller,
    budget, the defaults' score, the best, the gain."""
    suites = list(dict.fromkeys(s.suite for s in studies if s.suite))
    rows = [
        *(f"{heading}." for heading in suites),
        *([""] if suites else []),
        "| controller | task | budget (configurations x layouts x episodes) | defaults' score | best score | gain |",
        "|---|---|---|---|---|---|",
    ]
    for s in studies:
        b = s.budget
        budget = (
            f"{len(s.scores)} of {b['configurations']} x {b['layouts_per_task']} x {b['episodes_per_layout']}"
        )
        rows.append(
            f"| `{s.controller}` | {s.task} | {budget} | {s.defaults_score:.3f} | {s.best_score:.3f} "
            f"| {s.best_score - s.defaults_score:+.3f} |"
        )
    return "\n".join(rows) + "\n"


#: the configuration counts the expected-best table shows (beside each study's own N)
CURVE_POINTS = (1, 2, 4, 8, 16)


def expected_best_markdown(studies: Sequence[StudySummary], points: Sequence[int] = CURVE_POINTS) -> str:
    """The curves of :func:`report_figure` as a table: per study, the expected best validation
    score of n configurations (:func:`~evaluation.tune.scoring.expected_max_curve`) at each of
    ``points`` and at its own N (the number of trials it ran; below its best score, which a draw
    of N with replacement misses); ``-`` where the study ran fewer than n trials.

    Raises
    ------
    ValueError
        ``points`` empty, or holding a count below 1 or twice (named).
    """
    counts = list(points)
    if not counts:
        raise ValueError("points is empty; allowed: configuration counts of at least 1")
    for n in counts:
        if isinstance(n, bool) or not isinstance(n, int) or n < 1:
            raise ValueError(f"points holds {n!r}; allowed: whole configuration counts of at least 1")
    if len(set(counts)) != len(counts):
        raise ValueError(f"points={counts} names a count twice; allowed: distinct counts")
    rows = [
        "| controller | task | " + " | ".join(f"n = {n}" for n in counts) + " | n = N (its trials) |",
        "|---|---|" + "---|" * (len(counts) + 1),
    ]
    for s in studies:
        curve = expected_max_curve(s.scores)
        cells = [f"{curve[n - 1]:.3f}" if n <= len(curve) else "-" for n in counts]
        rows.append(
            f"| `{s.controller}` | {s.task} | "
            + " | ".join(cells)
            + f" | {curve[-1]:.3f} (N = {len(curve)}) |"
        )
    return "\n".join(rows) + "\n"


def report_figure(studies: Sequence[StudySummary], path: str | os.PathLike[str]) -> None:
    """The expected best validation score against the configurations tried, one curve per study."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    for s in studies:
        curve = expected_max_curve(s.scores)
        ax.plot(range(1, len(curve) + 1), curve, marker="o", markersize=3, label=f"{s.controller} ({s.task})")
    ax.set_xlabel("configurations tried (n)")
    ax.set_ylabel("expected best validation score")
    ax.set_xscale("log")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(figure_title(studies), fontsize=8)
    fig.tight_layout()
    try:  # whole or not at all: the figure is published beside the report
        write_atomic(path, lambda tmp: fig.savefig(tmp, dpi=150))
    finally:
        plt.close(fig)


def figure_title(studies: Sequence[StudySummary]) -> str:
    """The curves' title: what they show, then each suite tuned on (name, version, hashes)."""
    suites = dict.fromkeys(s.suite_short for s in studies if s.suite_short)
    return "\n".join(["Expected best of n configurations (Dodge et al. 2019)", *suites])


def decision(label: str, verdict: str, studies: Path = STUDIES_DIR) -> str:
    """The study's decision with what its recorded confirmation made of an adoption.

    Parameters
    ----------
    label : str
        The controller whose study it is (``studies/<label>/``).
    verdict : str
        The study's decision (``adopted``, or why not).
    studies : Path
        The studies' folder (data/tuning).

    Returns
    -------
    str
        ``verdict`` as it is when it is no adoption or no confirmation on fresh validation layouts
        is recorded (``studies/<label>/confirmation.json``, ``python -m evaluation.tune adopt
        --confirm``); else the adoption kept, or withdrawn so that the controller ships its
        defaults, with the confirmation's counts.
    """
    record = studies / label / CONFIRMATION_FILE
    if verdict != "adopted" or not record.is_file():
        return verdict
    # bounded and depth-checked as every file KoopNav reads back: a torn or foreign record is
    # refused by name (a nested one raised RecursionError)
    text = read_text(record, MAX_TEXT_BYTES, what="confirmation record", expected="JSON")
    try:
        confirmation = parse_json(text, str(record))
        counts = (
            f"{int(confirmation['best_successes'])} against the defaults' "
            f"{int(confirmation['defaults_successes'])} of {int(confirmation['units'])} fresh validation "
            f"episodes, p {sign_flip_p_text(float(confirmation['p_value']), bool(confirmation['exact']))}"
        )
        confirmed = confirmation["confirmed"]
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(
            f"{record}: not a confirmation record ({type(exc).__name__}: {exc}); rerun "
            f"python -m evaluation.tune adopt {label} --confirm N to write it again"
        ) from None
    if not isinstance(confirmed, bool):
        raise ValueError(f"{record}: confirmed={confirmed!r}; allowed: true or false")
    if confirmed:
        return f"adopted, confirmed ({counts})"
    return f"adopted by the study, withdrawn by the confirmation ({counts}): ships its defaults"


def tuning_budget_rows(labels: Sequence[str], studies: Path = STUDIES_DIR) -> list[list[str]]:
    """Each controller's tuning budget: its study (:func:`controllers.tuning.studies.study_budget`),
    or why it has none.

    Parameters
    ----------
    labels : sequence of str
        The controllers, in the table's order.
    studies : Path
        The studies' folder (data/tuning).

    Returns
    -------
    list of list of str
        Per controller: its label, the split tuned on, the configurations run of those planned, the
        validation episodes per configuration, the episodes run and the :func:`decision`.
    """
    rows = []
    for label in labels:
        budget = study_budget(label, studies)
        if budget is not None:
            rows.append(
                [
                    label,
                    budget.split,
                    f"{budget.configurations_run} of {budget.configurations}",
                    f"{budget.episodes_per_configuration}",
                    f"{budget.episodes_run:,}",
                    decision(label, budget.verdict, studies),
                ]
            )
            continue
        try:
            tunable = bool(controllers.options(label).tunable())
        except ValueError:  # a label that is no registered controller (a variant of a run)
            tunable = False
        why = (
            "no study: its hand-set defaults"
            if tunable
            else "no tunable options declared (nothing for the tuner to search)"
        )
        rows.append([label, "-", "0", "-", "0", why])
    return rows
