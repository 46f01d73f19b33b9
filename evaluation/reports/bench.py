"""What docs/bench_results.md computes from the test suite's two publications (docs/make_bench_md.py
lays it out): each mode's run read back with its pending (task, controller)s
(:func:`load_mode`, :class:`BenchMode`), the headline families' planned power and pending pairs,
the leaderboards' cells, the paper track's table and which verdicts changed from the paper track
to the test split (:func:`verdict_changes`, :data:`VERDICT_RULE`).

The two modes are the runs of data/publish.sh (:data:`BENCH_RUNS`): ``charged``, the decision time
charged to the robots (``--realtime``), and ``free``. A (task, controller) whose episodes are not
all in its publication is pending, and left out of every table and test until it is complete.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import controllers
from evaluation.episodes.distinct import episode_identity
from evaluation.reports.publications import extracted_archive
from evaluation.reports.published import results_from_log
from evaluation.reports.results import Results
from evaluation.reports.sections.blocks import rate_cell
from evaluation.reports.sections.runs import task_label
from evaluation.reports.sections.suite_tables import paired_csv
from evaluation.stats.designs import Design, pooled_families, reference_design
from evaluation.stats.families import detectable_difference
from evaluation.stats.progress import Progress, planned_episodes
from koopman_envs import TIERS

__all__ = [
    "BENCH_RUNS",
    "BenchMode",
    "BenchProgress",
    "VERDICT_RULE",
    "check_same_suite",
    "declared_tasks",
    "family_pending",
    "headline_families",
    "headline_rows",
    "leaderboard_cells",
    "load_mode",
    "page_pairs",
    "paper_track_rows",
    "paper_variants_note",
    "pairs_file",
    "planned_power",
    "ranked_controllers",
    "verdict",
    "verdict_changes",
]

#: the runs of data/publish.sh behind the two modes (their commands are there), and their titles
BENCH_RUNS = {
    "charged": ("bench_test_realtime", "Compute charged"),
    "free": ("bench_test", "Free compute"),
}
#: the discordance the headline family's planned power is stated at (docs/benchmark.md's sizing)
PLANNED_DISCORDANCE = 0.3
#: the family-wise error rate a Holm-corrected p is read against on both sides of the verdict table
ALPHA = 0.05
#: the verdict table's rule (:func:`verdict`), stated on the page
VERDICT_RULE = (
    f"A difference is significant where its Holm-corrected p is below {ALPHA} within its own family "
    "(the test split's: the page's design, named under its success table; the paper track's: every "
    "pair of its controllers in every task as one family, exact McNemar). Verdict: *same* when both are "
    "significant with the same sign; *sign flipped* when both are significant with opposite signs; "
    "*significant only on the paper track* or *only on the test split* when one is; *neither "
    "significant* when neither is (absence of evidence on both, whatever the signs); *not tested* "
    "when a side has no corrected p."
)


@dataclass(frozen=True)
class BenchProgress(Progress):
    """How far one (task, controller) of a run is: ``done`` of ``planned`` episodes of that task
    (:class:`~evaluation.stats.progress.Progress`, counted per task), with the page's wording."""

    def text(self) -> str:
        """The page's cell for a (task, controller) not complete yet: ``pending: N of M episodes``."""
        return f"pending: {self.done:,} of {self.planned:,} episodes"


@dataclass(frozen=True)
class BenchMode:
    """One mode's publication: where it is, its complete records as results (None: not
    published yet) and the progress of every (task, controller) its header declares."""

    name: str
    path: Path
    results: Results | None
    progress: dict[tuple[str, str], BenchProgress]

    @property
    def run(self) -> str:
        """The data/publish.sh run behind this mode (:data:`BENCH_RUNS`): ``bench_test_realtime``
        for ``charged``, ``bench_test`` for ``free``."""
        return BENCH_RUNS[self.name][0]

    def declared(self) -> dict[str, list[str]]:
        """Task -> the controllers the run's header declares for it, in its order."""
        out: dict[str, list[str]] = {}
        for env_id, label in self.progress:
            out.setdefault(env_id, []).append(label)
        return out

    def pending(self, env_id: str, controller: str) -> str | None:
        """Why (task, controller) has no row yet, or None when it has one."""
        if not self.progress:
            return "pending: not published yet"
        state = self.progress.get((env_id, controller))
        if state is None:
            return "not in this run"
        return None if state.complete else state.text()


def load_mode(name: str, path: str | Path) -> BenchMode:
    """A mode's publication read back (:func:`~evaluation.reports.publications.extracted_archive`),
    its records kept only for the (task, controller)s that ran every planned episode.

    Parameters
    ----------
    name : str
        The mode, a key of :data:`BENCH_RUNS`.
    path : str or Path
        Its publication; a path that does not exist is a mode not published yet.

    Returns
    -------
    BenchMode
        The mode with its complete records and every declared (task, controller)'s progress.

    Raises
    ------
    ValueError
        The publication is not a suite run, or is the other mode's (``--realtime`` or not).
    """
    path = Path(path)
    if not path.exists():  # not published yet: the whole column is pending
        return BenchMode(name, path, None, {})
    with extracted_archive(path) as run:
        results = results_from_log(run / "episodes.jsonl")
    config = results.config
    if not config.get("suite"):
        raise ValueError(
            f"{path}: not a suite run (its header has no suite); expected the run {BENCH_RUNS[name][0]}"
        )
    if bool(config.get("compute")) != (name == "charged"):
        wanted = "charged (--realtime)" if name == "charged" else "free (no --realtime)"
        raise ValueError(
            f"{path}: its decision time is {'' if config.get('compute') else 'not '}charged; --{name} needs compute {wanted}"
        )
    done: dict[tuple[str, str], set[tuple]] = {}  # every episode logged, once (its identity)
    for record in results.records:
        done.setdefault((record["env_id"], record["controller"]), set()).add(episode_identity(record))
    progress = {
        (env_id, label): BenchProgress(len(done.get((env_id, label), ())), planned_episodes(config, env_id))
        for env_id in config["env_ids"]
        for label in config["controllers"]
    }
    kept = [r for r in results.records if progress[r["env_id"], r["controller"]].complete]
    return BenchMode(name, path, Results(kept, config) if kept else None, progress)


def check_same_suite(modes: Sequence[BenchMode]) -> None:
    """Check that every published mode ran the same suite selection (name, version, split, layouts,
    episodes per layout and each task's split hash): side by side, the two modes' rows must come
    from the same (layout, seed) units.

    Raises
    ------
    ValueError
        The publications ran different suites (naming each one's).
    """
    suites = {
        mode.path.as_posix(): mode.results.config["suite"] for mode in modes if mode.results is not None
    }
    if len({json.dumps(suite, sort_keys=True) for suite in suites.values()}) > 1:
        raise ValueError(f"the publications ran different suites, so their rows do not compare: {suites}")


def declared_tasks(modes: Sequence[BenchMode]) -> list[str]:
    """Every task either mode's header declares, in their order."""
    return list(dict.fromkeys(env_id for mode in modes for env_id, _ in mode.progress))


def page_pairs(mode: BenchMode, reference: str) -> Design:
    """``mode``'s design for its per-task paired tables, read from its header
    (:func:`~evaluation.stats.designs.reference_design`); ``ValueError`` when the run lacks
    ``reference``."""
    return reference_design(mode.declared(), reference)


def headline_families(mode: BenchMode, reference: str) -> list[Design]:
    """``mode``'s headline families (:func:`~evaluation.stats.designs.pooled_families`), read from
    its header before any outcome; empty for a mode not published yet."""
    return pooled_families(mode.declared(), reference)


def planned_power(mode: BenchMode, m: int) -> float:
    """The detectable difference of a pooled family of ``m`` tests by the run's design.

    Parameters
    ----------
    mode : BenchMode
        A published mode (its header gives every task's planned layouts and episodes per layout).
    m : int
        The family's size.

    Returns
    -------
    float
        The success difference found with 80% power after Holm's first step at
        :data:`PLANNED_DISCORDANCE` (NaN: none on so few layouts).
    """
    config = mode.results.config if mode.results is not None else {}
    suite = config["suite"]
    per_layout = int(suite["episodes_per_layout"]) * len(config.get("slips") or [None])
    layouts = sum(planned_episodes(config, env_id) // per_layout for env_id in config["env_ids"])
    return detectable_difference(
        layouts, per_layout, discordance=PLANNED_DISCORDANCE, family_size=m, alpha=ALPHA, power=0.8
    )


def family_pending(mode: BenchMode, pairs: Sequence[tuple[str, str, str]]) -> list[str]:
    """The pairs of a pooled family not tested yet: ``a vs b (label: task done of planned, ...)``
    for each pair one of whose controllers is not complete in every task of ``mode``."""
    tasks = list(mode.declared())
    pending = []
    for _, a, b in pairs:
        waiting = []
        for label in (a, b):
            states = {t: mode.progress.get((t, label)) for t in tasks}
            if all(state is not None and state.complete for state in states.values()):
                continue
            counts = ", ".join(
                f"{task_label(t)} {'not in this run' if state is None else f'{state.done:,} of {state.planned:,}'}"
                for t, state in states.items()
            )
            waiting.append(f"{label}: {counts} episodes")
        if waiting:
            pending.append(f"{a} vs {b} ({'; '.join(waiting)})")
    return pending


def pairs_file(modes: Sequence[BenchMode]) -> str | None:
    """The text of the page's CSV of every pair: every published mode's paired tables over every
    pair of its controllers, each table corrected over every pair (the evaluator's own,
    ``RunData.suite_tables``); None when no mode has a row yet."""
    runs = [(mode.run, mode.results.suite_tables) for mode in modes if mode.results is not None]
    return paired_csv(runs) if runs else None


def verdict(test: tuple[float, float], paper: tuple[float, float], alpha: float = ALPHA) -> str:
    """What became of one pair's verdict from the paper track to the test split (:data:`VERDICT_RULE`).

    Parameters
    ----------
    test, paper : (float, float)
        The pair's difference (a - reference, success share) and its Holm-corrected p on the test
        split and on the paper track; a NaN p: not tested there.
    alpha : float
        Family-wise error rate, ``0 < alpha < 1``.

    Returns
    -------
    str
        ``same``, ``sign flipped``, ``significant only on the paper track``, ``significant only on
        the test split``, ``neither significant`` or ``not tested``.
    """
    if not 0.0 < alpha < 1.0:
        raise ValueError(f"alpha={alpha!r} is not within (0, 1)")
    if math.isnan(test[1]) or math.isnan(paper[1]):
        return "not tested"
    on_test, on_paper = test[1] < alpha, paper[1] < alpha
    if on_test and on_paper:
        # a significant difference is never zero, so its sign is +1 or -1
        return "same" if math.copysign(1.0, test[0]) == math.copysign(1.0, paper[0]) else "sign flipped"
    if on_paper:
        return "significant only on the paper track"
    if on_test:
        return "significant only on the test split"
    return "neither significant"


def _against(rows: Sequence[Mapping[str, Any]], reference: str) -> dict[tuple[str, str], tuple[float, float]]:
    """(task, controller) -> (its difference to ``reference``, the corrected p) for every row that
    pairs a controller with ``reference``, turned so the difference is always controller - reference."""
    out = {}
    for row in rows:
        if row["b"] == reference:
            out[row["env_id"], row["a"]] = (float(row["difference"]), float(row["p_holm"]))
        elif row["a"] == reference:
            out[row["env_id"], row["b"]] = (-float(row["difference"]), float(row["p_holm"]))
    return out


def verdict_changes(
    test_rows: Sequence[Mapping[str, Any]],
    paper_rows: Sequence[Mapping[str, Any]],
    reference: str,
    alpha: float = ALPHA,
) -> list[dict[str, Any]]:
    """Per (task, controller) paired with ``reference`` on both the test split and the paper track,
    the two differences, their corrected p and the :func:`verdict`, in the test split's order.

    Parameters
    ----------
    test_rows : sequence of mapping
        The test split's success table rows (``env_id``, ``a``, ``b``, ``difference``, ``p_holm``:
        :func:`~evaluation.stats.suite_statistics.measure_table`).
    paper_rows : sequence of mapping
        The paper track's paired rows, the same fields (:meth:`~evaluation.stats.run_data.RunData.paired`).
    reference : str
        The controller both sides compare with; a row with ``reference`` as ``a`` is turned round.
    alpha : float
        Family-wise error rate, ``0 < alpha < 1``.

    Returns
    -------
    list of dict
        ``env_id``, ``controller``, ``test`` and ``paper`` (each ``(difference, p_holm)``) and ``verdict``.
    """
    paper = _against(paper_rows, reference)
    return [
        {
            "env_id": env_id,
            "controller": label,
            "test": test,
            "paper": paper[env_id, label],
            "verdict": verdict(test, paper[env_id, label], alpha),
        }
        for (env_id, label), test in _against(test_rows, reference).items()
        if (env_id, label) in paper
    ]


def _summary(mode: BenchMode) -> dict[tuple[str, str], dict[str, Any]]:
    if mode.results is None:
        return {}
    return {(row["env_id"], row["controller"]): row for row in mode.results.layout_summary}


def ranked_controllers(modes: Sequence[BenchMode], env_id: str) -> list[str]:
    """Every controller either mode declares for ``env_id``: those with a row by the headline mode's
    success (the first mode), then the others', then the pending ones, each by name among equals."""
    labels = dict.fromkeys(c for mode in modes for e, c in mode.progress if e == env_id)
    summaries = [_summary(mode) for mode in modes]

    def key(label: str) -> tuple:
        for index, summary in enumerate(summaries):
            row = summary.get((env_id, label))
            if row is not None:
                return (index, -row["success"]["value"], label)
        return (len(summaries), 0.0, label)

    return sorted(labels, key=key)


def _rate(mode: BenchMode, env_id: str, label: str, key: str) -> str:
    row = _summary(mode).get((env_id, label))
    if row is None:
        return mode.pending(env_id, label) or "-"
    return rate_cell(row[key]["value"], row[key]["ci"])


def headline_rows(modes: Sequence[BenchMode], env_id: str) -> list[list[str]]:
    """README's headline table of ``env_id``: per controller of the headline run (the charged
    one, or before it is published the free one), success with compute charged, per layout tier,
    then free; a pending cell says how far its run is."""
    charged, free = modes
    tiers = {
        (row["env_id"], row["controller"], row["group"]): [row["success_rate"], row["success_ci"]]
        for row in (charged.results.suite_breakdown() if charged.results is not None else [])
        if row["by"] == "layout_tier"
    }
    # the headline's rows are the headline run's controllers (a controller of the free run only,
    # a -v0, is on the page's leaderboard, not here); before it is published, the free run's
    headline_run = charged if charged.progress else free
    return [
        [
            label,
            _rate(charged, env_id, label, "success"),
            *(
                rate_cell(*tiers[env_id, label, tier]) if (env_id, label, tier) in tiers else ""
                for tier in TIERS
            ),
            _rate(free, env_id, label, "success"),
        ]
        for label in ranked_controllers(modes, env_id)
        if (env_id, label) in headline_run.progress
    ]


def leaderboard_cells(modes: Sequence[BenchMode], env_id: str) -> list[list[str]]:
    """The page's leaderboard of ``env_id``: per controller (:func:`ranked_controllers`) success,
    strict success and success excusing the unavoidable collisions, each charged then free."""
    return [
        [
            label,
            *(
                _rate(mode, env_id, label, key)
                for key in ("success", "strict_success", "success_excusing_unavoidable")
                for mode in modes
            ),
        ]
        for label in ranked_controllers(modes, env_id)
    ]


def paper_track_rows(paper: Results) -> tuple[list[str], list[list[str]]]:
    """The paper track's table: its tasks, and per controller (the first task's first) its success
    with the 95% interval in each task (``-`` where it did not run)."""
    board = paper.leaderboard()
    tasks = [t for t in paper.config["env_ids"] if any(row["env_id"] == t for row in board)]
    rows = {(row["env_id"], row["controller"]): row for row in board}
    labels = dict.fromkeys(row["controller"] for row in board if row["env_id"] == tasks[0])
    labels.update(dict.fromkeys(row["controller"] for row in board))
    cells = [
        [
            label,
            *(
                rate_cell(rows[t, label]["success_rate"], rows[t, label]["success_ci"])
                if (t, label) in rows
                else "-"
                for t in tasks
            ),
        ]
        for label in labels
    ]
    return tasks, cells


def paper_variants_note(config: Mapping[str, Any]) -> str:
    """What the run's ``*-paper`` rows are (the paper's control logic, not its exact controller):
    their options as the run recorded them, and whether they kept soft constraints (the option
    left at its registered default, or set); empty without such rows."""
    variants = [c for c in config.get("controller_configs", []) if c["label"].endswith("-paper")]
    if not variants:
        return ""
    options = sorted(
        {
            f"{k}={v}".replace("False", "false")
            for c in variants
            for k, v in c["options"].items()
            if k != "solver"
        }
    )
    soft = [
        c["label"]
        for c in variants
        if c["options"].get("soft_constraints", controllers.options(c["name"]).default("soft_constraints"))
    ]
    names = [f"`{c['label']}`" for c in variants]
    text = f" The {' and '.join(names)} rows are the paper's control logic ({', '.join(options)})"
    if soft:
        kept = (
            "they keep" if len(soft) == len(variants) else " and ".join(f"`{label}` keeps" for label in soft)
        )
        text += (
            f", but {kept} our soft constraints (exact-penalty slacks), not the paper's hard ones: "
            "`python evaluate.py --paper-strict` runs those (docs/hard_constraints.md)"
        )
    return text + "."
