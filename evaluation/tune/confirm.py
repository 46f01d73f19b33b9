"""``python -m evaluation.tune adopt NAME --confirm N``: the adoption rule's winner checked on
validation layouts the study never ran (the winner's curse).

A study picks the best of its configurations on the same validation episodes it then compares
the best with trial 0 on, so the best's margin is biased upward (the maximum of noisy scores).
The confirmation reruns the best configuration and the defaults (trial 0) on the next ``N``
layouts of the same split per task (layouts K to K+N-1, K the study's ``layouts_per_task``:
``--confirm 75`` after a 25-layout study runs layouts 25-99), with the study's seed, slip, env
settings and episodes per layout, both on the same (layout, seed) units, and tests the paired
differences with the layout-level sign-flip test
(:func:`evaluation.stats.layout_tests.layout_sign_flip_test`). :data:`CONFIRMATION_RULE` says
when the adoption stands. The record is ``data/tuning/NAME/confirmation.json``.
"""

from __future__ import annotations

import json
import os
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from controllers.tuning import STUDIES_DIR, finished_study, trial_rank
from evaluation.episodes.records import json_safe
from evaluation.stats.layout_tests import layout_sign_flip_test
from evaluation.tune.configuration import Evaluator, evaluate_configuration
from koopman_envs.checks import check_int
from koopman_envs.files import write_atomic

__all__ = ["CONFIRMATION_FILE", "CONFIRMATION_LEVEL", "CONFIRMATION_RULE", "Confirmation", "confirm"]

#: the record of a study's confirmation, beside its log
CONFIRMATION_FILE = "confirmation.json"
#: the sign-flip test's level (one test per adopted study: no correction)
CONFIRMATION_LEVEL = 0.05
CONFIRMATION_RULE = (
    "an adopted study's best configuration stays adopted only if, rerun with the defaults on the "
    "validation layouts the study did not use, it has more successes than the defaults there and "
    f"the layout-level sign-flip test of the paired differences gives p < {CONFIRMATION_LEVEL}"
)


@dataclass(frozen=True)
class Confirmation:
    """A study's best configuration against its defaults on fresh validation layouts.

    Attributes
    ----------
    controller : str
        The controller or preset the study tuned.
    best_trial : int
        The study's best trial (the one the adoption rule compared with trial 0).
    layouts : (int, int)
        The layouts run per task, ``first`` to ``stop - 1``.
    units : int
        The paired (layout, seed) units of both tasks.
    best_successes, defaults_successes : int
        Successes of each on those units (an episode that raised is a failure).
    p_value : float
        The two-sided layout-level sign-flip test of the paired differences.
    exact : bool
        Whether every sign pattern was enumerated.
    """

    controller: str
    best_trial: int
    layouts: tuple[int, int]
    units: int
    best_successes: int
    defaults_successes: int
    p_value: float
    exact: bool

    @property
    def confirmed(self) -> bool:
        """:data:`CONFIRMATION_RULE`."""
        return self.best_successes > self.defaults_successes and self.p_value < CONFIRMATION_LEVEL

    def __str__(self) -> str:
        return (
            f"{self.controller}: {'confirmed' if self.confirmed else 'not confirmed'} on validation layouts "
            f"{self.layouts[0]}-{self.layouts[1] - 1}: trial {self.best_trial} {self.best_successes}/"
            f"{self.units} against the defaults' {self.defaults_successes}/{self.units}, sign-flip "
            f"p = {self.p_value:.4g}"
        )


def _outcomes(records: list[dict[str, Any]]) -> dict[tuple[str, int, int], bool]:
    """Success by (split label, layout, seed) unit."""
    return {(str(r["suite"]), int(r["layout"]), int(r["seed"])): r.get("success") is True for r in records}


def confirm(
    name: str,
    layouts: int,
    studies: str | os.PathLike[str] = STUDIES_DIR,
    *,
    workers: int = 1,
    evaluator: Evaluator = evaluate_configuration,
) -> Confirmation:
    """Rerun the best configuration and the defaults of ``name``'s finished study on the next
    ``layouts`` validation layouts per task, test the paired differences, and write the record
    ``studies/NAME/confirmation.json``.

    Raises
    ------
    ValueError
        A study that is missing, torn or unfinished (:func:`controllers.tuning.finished_study`),
        ``layouts`` not an integer >= 1, or more layouts than the split holds after the study's
        (the evaluator's check, naming the selection), before any episode.
    """
    layouts = check_int("layouts", layouts, 1, note="fresh validation layouts per task")
    header, trials = finished_study(name, studies)
    best, defaults = max(trials, key=trial_rank), trials[0]
    budget = header["budget"]
    first = int(budget["layouts_per_task"])
    run = {
        "task": header["task"],
        "split": header["split"],
        "layouts": list(range(first, first + layouts)),
        "episodes": int(budget["episodes_per_layout"]),
        "seed": int(header["seed"]),
        "suite": header["suites"][0].split("/")[0],
        "slip": header["slip"],
        "env_kwargs": dict(header.get("env_kwargs") or {}),
    }

    def episodes(options: dict[str, Any]) -> dict[tuple[str, int, int], bool]:
        return _outcomes(
            evaluator(
                name,
                options,
                run["task"],
                run["split"],
                run["layouts"],
                run["episodes"],
                run["seed"],
                suite=run["suite"],
                slip=run["slip"],
                env_kwargs=run["env_kwargs"],
                workers=workers,
            )
        )

    a, b = episodes(dict(best["options"])), episodes(dict(defaults["options"]))
    units = sorted(set(a) & set(b))
    by_layout: dict[tuple[str, int], list[float]] = {}
    for unit in units:
        by_layout.setdefault(unit[:2], []).append(float(a[unit]) - float(b[unit]))
    p_value, exact = layout_sign_flip_test(list(by_layout.values()))
    result = Confirmation(
        name,
        int(best["trial"]),
        (first, first + layouts),
        len(units),
        sum(a[u] for u in units),
        sum(b[u] for u in units),
        p_value,
        exact,
    )
    record = {**asdict(result), "confirmed": result.confirmed, "rule": CONFIRMATION_RULE, "run": run}
    write_atomic(Path(studies) / name / CONFIRMATION_FILE, json.dumps(json_safe(record), indent=2) + "\n")
    return result
