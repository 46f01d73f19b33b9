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

A confirmation resumes. Each of its two runs logs its episodes as it goes, into
``data/tuning/NAME/confirmation/best/episodes.jsonl`` and ``.../defaults/episodes.jsonl`` (the
evaluator's own run log, :func:`evaluation.episodes.runlog.open_log`), so that the same command
rerun after an interruption (Ctrl-C, a machine that ends) runs only the episodes missing from the
logs. A log of another run (another best configuration, layouts, seed or settings: its header
differs) is refused by name, never mixed; move the folder aside to start afresh. The record is
written atomically once both runs are complete; a record already there that matches the study's
best trial and its options (``best_options``), the layouts and the run settings is read instead
of rerunning anything (:attr:`Confirmation.recorded`).
"""

from __future__ import annotations

import json
import os
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from controllers.tuning import STUDIES_DIR, finished_study, trial_rank
from evaluation.episodes.records import json_safe
from evaluation.episodes.runlog import LogError
from evaluation.stats.layout_tests import layout_sign_flip_test, sign_flip_p_text
from evaluation.tune.configuration import Evaluator, evaluate_configuration
from koopman_envs.checks import check_int, parse_json
from koopman_envs.files import MAX_TEXT_BYTES, read_text, write_atomic

__all__ = [
    "CONFIRMATION_FILE",
    "CONFIRMATION_LOGS",
    "CONFIRMATION_LEVEL",
    "CONFIRMATION_RULE",
    "Confirmation",
    "confirm",
]

#: the record of a study's confirmation, beside its log
CONFIRMATION_FILE = "confirmation.json"
#: the folder of the confirmation's two episode logs (``best/``, ``defaults/``), beside its log
CONFIRMATION_LOGS = "confirmation"
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
    recorded : bool
        Read from a record written before (nothing rerun); not part of the record.
    """

    controller: str
    best_trial: int
    layouts: tuple[int, int]
    units: int
    best_successes: int
    defaults_successes: int
    p_value: float
    exact: bool
    recorded: bool = field(default=False, compare=False)

    @property
    def confirmed(self) -> bool:
        """:data:`CONFIRMATION_RULE`."""
        return self.best_successes > self.defaults_successes and self.p_value < CONFIRMATION_LEVEL

    def __str__(self) -> str:
        return (
            f"{self.controller}: {'confirmed' if self.confirmed else 'not confirmed'} on validation layouts "
            f"{self.layouts[0]}-{self.layouts[1] - 1}: trial {self.best_trial} {self.best_successes}/"
            f"{self.units} against the defaults' {self.defaults_successes}/{self.units}, sign-flip "
            f"p {sign_flip_p_text(self.p_value, self.exact, digits=4)}"
            + (f" (read from its {CONFIRMATION_FILE}, not rerun)" if self.recorded else "")
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

    The two runs log their episodes into ``studies/NAME/confirmation/best/`` and
    ``.../defaults/`` and resume from them: rerun after an interruption, only the missing episodes
    run. A record already written for this best trial and its options, these layouts and run
    settings is returned as it is (``recorded=True``), nothing rerun.

    Raises
    ------
    ValueError
        A study that is missing, torn or unfinished (:func:`controllers.tuning.finished_study`),
        ``layouts`` not an integer >= 1, or more layouts than the split holds after the study's
        (the evaluator's check, naming the selection), before any episode.
    LogError
        A ``ValueError``: a confirmation log of another run (another best trial, layouts, seed or
        settings), named with its file; nothing is mixed into it.
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

    folder = Path(studies) / name
    best_options = json_safe(dict(best["options"]))
    recorded = _recorded(folder / CONFIRMATION_FILE, name, int(best["trial"]), best_options, run)
    if recorded is not None:
        return recorded

    def episodes(options: dict[str, Any], which: str) -> dict[tuple[str, int, int], bool]:
        logs = folder / CONFIRMATION_LOGS / which
        try:
            records = evaluator(
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
                out=logs,
            )
        except LogError as exc:
            raise LogError(
                f"{name}: the confirmation's {which} log is of another run (another best trial, layouts, "
                f"seed or settings), not trial {best['trial'] if which == 'best' else 0} on layouts "
                f"{first}-{first + layouts - 1}: {exc}. Move {folder / CONFIRMATION_LOGS} aside to "
                "start this confirmation afresh"
            ) from exc
        return _outcomes(records)

    a, b = episodes(dict(best["options"]), "best"), episodes(dict(defaults["options"]), "defaults")
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
    record = {
        **asdict(result),
        "best_options": best_options,
        "confirmed": result.confirmed,
        "rule": CONFIRMATION_RULE,
        "run": run,
    }
    del record["recorded"]
    write_atomic(folder / CONFIRMATION_FILE, json.dumps(json_safe(record), indent=2) + "\n")
    return result


def _recorded(
    path: Path, name: str, best_trial: int, best_options: Any, run: dict[str, Any]
) -> Confirmation | None:
    """The confirmation recorded at ``path`` if it is of this study's best trial and its options,
    layouts and run settings (``run``), else None (no record, or one of another confirmation: it
    is rerun). A study redone can have its best at the same trial number with other options: the
    record's ``best_options`` must be these. A record written before it carried them (consensus's
    and dwa's committed ones) is matched without them."""
    if not path.is_file():
        return None
    try:
        record = parse_json(
            read_text(path, MAX_TEXT_BYTES, what="confirmation record", expected="JSON"), str(path)
        )
        result = Confirmation(
            str(record["controller"]),
            int(record["best_trial"]),
            (int(record["layouts"][0]), int(record["layouts"][1])),
            int(record["units"]),
            int(record["best_successes"]),
            int(record["defaults_successes"]),
            float(record["p_value"]),
            bool(record["exact"]),
            recorded=True,
        )
    except (ValueError, KeyError, TypeError, IndexError):
        return None  # torn or foreign: the confirmation runs (resuming its logs) and rewrites it
    same = (
        result.controller == name
        and result.best_trial == best_trial
        and record.get("best_options", best_options) == best_options
        and list(result.layouts) == [run["layouts"][0], run["layouts"][-1] + 1]
        and record.get("run") == json_safe(run)
        and record.get("rule") == CONFIRMATION_RULE
    )
    return result if same else None
