"""Write docs/bench_results.md, and README.md's headline block, from the published test-suite runs
of koopnav-bench-v1 (issue 60: the README headline becomes the test suite's leaderboard, the paper
track after it).

Usage (the published page's arguments are in ``data/pages.json``)::

    python docs/make_bench_md.py --charged data/bench_test_realtime --free data/bench_test \\
        --paper data/paper.tar.xz --reference koopman-nmpc --out docs/bench_results.md

``--charged`` and ``--free`` are the publications of ``bash data/publish.sh bench_test_realtime``
(the decision time charged to the robots, ``--realtime``: the headline) and ``bench_test`` (free
compute, the idealised case beside it), each packed by ``bash data/publish.sh pack``; the two
runs may hold different controllers (a controller of one only is in that mode's tables only).
Every number is the evaluator's own (:class:`~evaluation.stats.run_data.RunData`:
``layout_summary``, ``suite_breakdown``; :func:`~evaluation.stats.suite_statistics.suite_tables`:
intervals over layouts, the paired tables with their families and power statements); this script
only lays them out. The page's primary test is its headline family per mode
(:func:`headline_families`), declared from the run's header: success of every controller against
``--reference`` pooled over both tasks (each (task, layout) its own cluster), Holm within it, with
what tuning gained (each tuned controller against its ``-v0``, pooled) as a family of its own. The
per-task paired tables are secondary, one family per table and mode, declared from the
run's header (:func:`page_pairs`): every controller against ``--reference``, and each tuned
controller against its ``-v0``; every pair of every table, each table corrected over every pair,
goes to ``bench_pairs.csv`` beside the page (:data:`PAIRS_FILE`), whose SHA-256 the page states.
Beside the leaderboard, which verdicts changed: each controller against ``--reference`` on the test
split and on the paper track, with a verdict by a stated rule (:func:`verdict_changes`,
:data:`VERDICT_RULE`). The tuning budget of each controller is its study in ``data/tuning/<name>/``
(:func:`controllers.tuning.studies.study_budget`).

A run may be partial (published progressively): a (task, controller) whose episodes are not all
in its publication is named as pending, with how many it has, and left out of every table and
test until it is complete; a publication not there yet makes its whole column pending. The page
opens with the headline block (:data:`HEADLINE`) that ``python docs/make_pages.py`` copies into
README.md (``"readme"`` in ``data/pages.json``); tests/test_prose_checks.py checks README's copy
against the page.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import subprocess
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # run from a checkout without installing

import controllers  # noqa: E402
from controllers.tuning import STUDIES_DIR, V0_SUFFIX, study_budget  # noqa: E402
from evaluation.episodes.distinct import distinct_records, episode_identity  # noqa: E402
from evaluation.exit_codes import BAD_INPUT_EXIT, SUCCESS_EXIT  # noqa: E402
from evaluation.reports.publications import extracted_archive  # noqa: E402
from evaluation.reports.published import results_from_log  # noqa: E402
from evaluation.reports.results import Results  # noqa: E402
from evaluation.reports.sections import markdown, markdown_table, suite_heading, task_label  # noqa: E402
from evaluation.reports.sections.blocks import p_cell, rate_cell  # noqa: E402
from evaluation.reports.sections.runs import SUITE_NOTE, suite_rows  # noqa: E402
from evaluation.reports.sections.suite_tables import (  # noqa: E402
    paired_csv,
    paired_note,
    paired_table,  # noqa: E402
    suite_sections,
)
from evaluation.stats.designs import pooled_reference_pairs, reference_pairs  # noqa: E402
from evaluation.stats.families import detectable_difference  # noqa: E402
from evaluation.stats.suite_statistics import OUTCOMES, measure_table, suite_tables  # noqa: E402
from evaluation.tune.confirm import CONFIRMATION_FILE  # noqa: E402
from koopman_envs import TIERS  # noqa: E402
from koopman_envs.files import write_atomic  # noqa: E402

__all__ = [
    "HEADLINE",
    "PAIRS_FILE",
    "Mode",
    "Progress",
    "decision",
    "headline",
    "headline_families",
    "load_mode",
    "page",
    "option_values",
    "page_pairs",
    "pairs_file",
    "pooled_families",
    "published_runs",
    "tuned_pairs",
    "verdict",
    "verdict_changes",
]

#: the name of the block README.md copies from the page (docs/make_pages.py, ``"readme"``)
HEADLINE = "bench-headline"
#: the runs of data/publish.sh behind the two modes (their commands are there), and their titles
RUNS = {
    "charged": ("bench_test_realtime", "Compute charged"),
    "free": ("bench_test", "Free compute"),
}
#: the file beside the page with every pair of every paired table (the page tests fewer): plain
#: CSV in the repository, whose next version git stores as a delta of this one (docs/benchmark.md)
PAIRS_FILE = "bench_pairs.csv"
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
class Progress:
    """How far one (task, controller) of a run is: ``done`` of ``planned`` episodes."""

    done: int
    planned: int

    @property
    def complete(self) -> bool:
        return self.done >= self.planned

    def text(self) -> str:
        return f"pending: {self.done:,} of {self.planned:,} episodes"


@dataclass(frozen=True)
class Mode:
    """One mode's publication: where it is, its complete records as results (None: not
    published yet) and the progress of every (task, controller) its header declares."""

    name: str
    path: Path
    results: Results | None
    progress: dict[tuple[str, str], Progress]

    @property
    def run(self) -> str:
        return RUNS[self.name][0]

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


def planned_episodes(config: Mapping[str, Any], env_id: str) -> int:
    """The episodes a suite run plans per (task, controller): its layouts x episodes per layout x slips."""
    suite = config["suite"]
    selected = suite.get("layouts")
    layouts = suite["tasks"][env_id]["size"] if selected is None else selected[1] - selected[0]
    return int(layouts) * int(suite["episodes_per_layout"]) * len(config["slips"])


def load_mode(name: str, path: str | Path) -> Mode:
    """A mode's publication read back (:func:`~evaluation.reports.publications.extracted_archive`),
    its records kept only for the (task, controller)s that ran every planned episode.

    Raises
    ------
    ValueError
        The publication is not a suite run, or is the other mode's (``--realtime`` or not).
    """
    path = Path(path)
    if not path.exists():  # not published yet: the whole column is pending
        return Mode(name, path, None, {})
    with extracted_archive(path) as run:
        results = results_from_log(run / "episodes.jsonl")
    config = results.config
    if not config.get("suite"):
        raise ValueError(
            f"{path}: not a suite run (its header has no suite); expected the run {RUNS[name][0]}"
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
        (env_id, label): Progress(len(done.get((env_id, label), ())), planned_episodes(config, env_id))
        for env_id in config["env_ids"]
        for label in config["controllers"]
    }
    kept = [r for r in results.records if progress[r["env_id"], r["controller"]].complete]
    return Mode(name, path, Results(kept, config) if kept else None, progress)


def check_same_suite(modes: Sequence[Mode]) -> None:
    """``ValueError`` unless every published mode ran the same suite selection (name, version,
    split, layouts, episodes per layout and each task's split hash): side by side, the two modes'
    rows must come from the same (layout, seed) units."""
    suites = {
        mode.path.as_posix(): mode.results.config["suite"] for mode in modes if mode.results is not None
    }
    if len({json.dumps(suite, sort_keys=True) for suite in suites.values()}) > 1:
        raise ValueError(f"the publications ran different suites, so their rows do not compare: {suites}")


def tuned_pairs(labels: Sequence[str]) -> list[tuple[str, str]]:
    """The (tuned controller, its ``-v0``) pairs of ``labels`` that hold both: what tuning gained,
    a part of the page's design (:func:`page_pairs`)."""
    tuned = [(label.removesuffix(V0_SUFFIX), label) for label in labels if label.endswith(V0_SUFFIX)]
    return [(a, b) for a, b in tuned if a in labels]


def published_runs(script: Path = ROOT / "data" / "publish.sh") -> dict[str, list[str]]:
    """data/publish.sh's runs as bash expands them: NAME -> evaluate.py's arguments (the script's
    definitions only; nothing is run)."""
    text = script.read_text(encoding="utf-8")
    definitions = text[: text.index("\nrun() {")]
    show = 'for name in "${!RUNS[@]}"; do printf "%s\\t%s\\n" "$name" "${RUNS[$name]}"; done'
    printed = subprocess.run(
        ["bash", "-c", f"{definitions}\n{show}", str(script)], capture_output=True, text=True, check=True
    ).stdout
    return {name: words.split() for name, words in (line.split("\t", 1) for line in printed.splitlines())}


def option_values(arguments: Sequence[str], option: str) -> list[str]:
    """The words after ``option`` in ``arguments`` up to the next option (``--controllers``' labels)."""
    start = list(arguments).index(option) + 1
    end = next((i for i in range(start, len(arguments)) if arguments[i].startswith("--")), len(arguments))
    return list(arguments[start:end])


def page_pairs(mode: Mode, reference: str) -> tuple[list[tuple[str, str, str]], str]:
    """The page's design for ``mode``'s paired tables, read from its header before any outcome
    (:func:`~evaluation.stats.designs.reference_pairs`): every controller against
    ``reference``, and each tuned controller against its ``-v0`` (what tuning gained) where the
    run has both; with the clause that names it. ``ValueError`` when the run lacks ``reference``."""
    labels = list(dict.fromkeys(label for _, label in mode.progress))
    tuned = tuned_pairs(labels)
    pairs = reference_pairs(mode.declared(), reference, tuned)
    design = f"each controller against {reference} within each task"
    if tuned:
        design += (
            ", and each tuned controller against its defaults before tuning ("
            + ", ".join(f"{a} vs {b}" for a, b in tuned)
            + ": what tuning gained)"
        )
    return pairs, design


def pooled_families(
    declared: Mapping[str, Sequence[str]], reference: str
) -> list[tuple[list[tuple[str, str, str]], str]]:
    """The headline families of a run declaring ``declared`` (task -> its controllers, from its
    header), success pooled over both tasks
    (:func:`~evaluation.stats.designs.pooled_reference_pairs`): first the headline, every
    controller declared in both tasks against ``reference``; then, where the run has tuned
    controllers and their ``-v0``, what tuning gained as a family of its own (another question,
    kept out of the headline's m). Each is (pairs, the clause that names it); empty for fewer
    than two tasks."""
    if len(declared) < 2:
        return []
    labels = list(dict.fromkeys(label for labels in declared.values() for label in labels))
    against = pooled_reference_pairs(declared, reference)
    families = [(against, f"each controller against {reference} over both tasks")]
    tuned = [p for p in pooled_reference_pairs(declared, reference, tuned_pairs(labels)) if p not in against]
    if tuned:
        clause = ", ".join(f"{a} vs {b}" for _, a, b in tuned)
        families.append((tuned, f"each tuned controller against its defaults over both tasks ({clause})"))
    return families


def headline_families(mode: Mode, reference: str) -> list[tuple[list[tuple[str, str, str]], str]]:
    """``mode``'s headline families (:func:`pooled_families`), read from its header before any
    outcome; empty for a mode not published yet."""
    return pooled_families(mode.declared(), reference)


def _planned_power(mode: Mode, m: int) -> float:
    """The detectable difference of a pooled family of ``m`` tests by the run's design: every task's
    planned layouts, its episodes per layout, at :data:`PLANNED_DISCORDANCE` and 80% power after
    Holm's first step."""
    config = mode.results.config if mode.results is not None else {}
    suite = config["suite"]
    per_layout = int(suite["episodes_per_layout"]) * len(config["slips"])
    layouts = sum(planned_episodes(config, env_id) // per_layout for env_id in config["env_ids"])
    return detectable_difference(
        layouts, per_layout, discordance=PLANNED_DISCORDANCE, family_size=m, alpha=ALPHA, power=0.8
    )


def _headline_family(mode: Mode, pairs: list[tuple[str, str, str]], design: str) -> list[str]:
    """One pooled family's table: the pairs of controllers complete in both tasks tested, the
    others named as pending (counted in m as p = 1), Holm within the family, its power."""
    assert mode.results is not None
    tasks = list(mode.declared())
    complete = {label for _, label in mode.progress if all(mode.pending(t, label) is None for t in tasks)}
    records = [r for r in mode.results.records if r["controller"] in complete]
    m = len(pairs)
    planned = _planned_power(mode, m)
    found = (
        f"it finds {100 * planned:.1f} points"
        if not math.isnan(planned)
        else "no difference is found with that power on so few layouts"
    )
    lines = [
        f"m = {m} tests, declared from the run's header. By the run's design, at 80% power after "
        f"Holm's first step and discordance psi = {PLANNED_DISCORDANCE}, {found} (docs/benchmark.md, "
        "Statistics, the sizing).",
        "",
    ]
    table = measure_table(records, OUTCOMES[0], pairs, design) if records else None
    if table is not None and table["rows"]:
        lines += [markdown_table(paired_table(table, OUTCOMES[0])), ""]
        family = table["family"]
        rejected = [t["comparison"] for t in family["tests"] if t["rejected"]]
        power = table["power"]["sentence"] if table["power"] is not None else ""
        lines += [
            f"{power} "
            + (
                f"Rejected at alpha = {family['alpha']:g} after Holm: {', '.join(rejected)}."
                if rejected
                else f"None rejected at alpha = {family['alpha']:g} after Holm."
            ),
            "",
        ]
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
    if pending:
        lines += [
            "Pending until both controllers are complete in both tasks (counted in m as p = 1): "
            + "; ".join(pending)
            + ".",
            "",
        ]
    return lines


def _headline_section(modes: Sequence[Mode], reference: str) -> list[str]:
    """The headline families of every published mode, before the per-task tables."""
    published = [mode for mode in modes if mode.results is not None]
    if not published:
        return []
    lines = [
        "## The headline family: success over both tasks",
        "",
        f"The page's primary test, per mode: success of each controller against {reference}, pooled "
        "over both tasks (a comparison's units are the (task, layout) units of both tasks that both "
        "controllers ran), declared from the run's header before any "
        "outcome and corrected with Holm within its own family. Each (task, layout) is its own "
        "cluster (layout 3 of one task and layout 3 of the other are two layouts): a minus "
        f"{reference} with the two-stage bootstrap interval over those layouts and the layout "
        "sign-flip test, as in every paired table. The tuned controllers against their `-v0` "
        "(what tuning gained, free compute) are a family of their own after it: another question "
        "than the headline's, so it does not spend the headline's power. The per-task tables of "
        "each mode (its section below) are secondary families.",
        "",
    ]
    for mode in modes:
        if mode.results is None:
            what = "not published yet" if not mode.progress else "no controller complete in both tasks yet"
            lines += [f"**{RUNS[mode.name][1]}**: pending, {what}.", ""]
            continue
        for pairs, design in headline_families(mode, reference):
            lines += [f"**{RUNS[mode.name][1]}: {design}**", "", *_headline_family(mode, pairs, design)]
    return lines


def pairs_file(modes: Sequence[Mode]) -> str | None:
    """:data:`PAIRS_FILE`'s text: every published mode's paired tables over every pair of its
    controllers, each table corrected over every pair (the evaluator's own,
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


def _summary(mode: Mode) -> dict[tuple[str, str], dict[str, Any]]:
    if mode.results is None:
        return {}
    return {(row["env_id"], row["controller"]): row for row in mode.results.layout_summary}


def _tiers(mode: Mode) -> dict[tuple[str, str, str], list[Any]]:
    if mode.results is None:
        return {}
    return {
        (row["env_id"], row["controller"], row["group"]): [row["success_rate"], row["success_ci"]]
        for row in mode.results.suite_breakdown()
        if row["by"] == "layout_tier"
    }


def _tasks(modes: Sequence[Mode]) -> list[str]:
    return list(dict.fromkeys(env_id for mode in modes for env_id, _ in mode.progress))


def _ranked(modes: Sequence[Mode], env_id: str) -> list[str]:
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


def _rate(summary: Mapping[tuple[str, str], Any], mode: Mode, env_id: str, label: str, key: str) -> str:
    row = summary.get((env_id, label))
    if row is None:
        return mode.pending(env_id, label) or "-"
    return rate_cell(row[key]["value"], row[key]["ci"])


def _scope(modes: Sequence[Mode]) -> str:
    """What the runs are, from the first published mode's header."""
    for mode in modes:
        if mode.results is not None:
            return suite_heading(mode.results.config)
    return "Suite koopnav-bench-v1, split test"


def headline(modes: Sequence[Mode], paper: Results | None, paper_path: str = "data/paper.tar.xz") -> str:
    """README's headline block: per task the test split's leaderboard (success, compute charged,
    per tier, free compute beside it), then the paper track's success per controller."""
    charged, free = modes
    lines = [
        f"<!-- begin {HEADLINE}: written by `python docs/make_pages.py docs/bench_results.md` "
        "from the committed data (docs/make_bench_md.py); an edit by hand fails the tests -->"
    ]
    if not any(mode.progress for mode in modes):  # neither run published yet
        runs = " and ".join(f"`{mode.path.as_posix()}`" for mode in modes)
        lines += [
            f"**The held-out test split of koopnav-bench-v1**: pending, {runs} are not published yet "
            f"(`bash data/publish.sh {' '.join(mode.run for mode in modes)}`, then `bash data/publish.sh pack`).",
            "",
            *paper_track(paper, paper_path),
            f"<!-- end {HEADLINE} -->",
        ]
        return "\n".join(lines) + "\n"
    lines += [
        "**The held-out test split of koopnav-bench-v1.** "
        + _scope(modes)
        + ". No controller was tuned or trained on it; every one runs its shipped defaults, high slip. "
        "Success with 95% intervals over layouts (the wider of Wilson's and the two-stage bootstrap, "
        "layouts then episodes); the decision time charged to the robots (`--realtime`), by layout "
        "tier, and free compute beside it.",
        "",
    ]
    summaries = {mode.name: _summary(mode) for mode in modes}
    tiers = _tiers(charged)
    # the headline's rows are the headline run's controllers (a controller of the free run only,
    # a -v0, is on the page's leaderboard, not here); before it is published, the free run's
    headline_run = charged if charged.progress else free
    for env_id in _tasks(modes):
        lines += [
            f"| {task_label(env_id)} | Compute charged | " + " | ".join(TIERS) + " | Free compute |",
            "|---|---|" + "---|" * len(TIERS) + "---|",
        ]
        for label in [c for c in _ranked(modes, env_id) if (env_id, c) in headline_run.progress]:
            by_tier = [
                rate_cell(*tiers[env_id, label, tier]) if (env_id, label, tier) in tiers else ""
                for tier in TIERS
            ]
            lines.append(
                f"| {label} | {_rate(summaries['charged'], charged, env_id, label, 'success')} | "
                + " | ".join(by_tier)
                + f" | {_rate(summaries['free'], free, env_id, label, 'success')} |"
            )
        lines.append("")
    lines += paper_track(paper, paper_path)
    lines.append(f"<!-- end {HEADLINE} -->")
    return "\n".join(lines) + "\n"


def _paper_variants_note(config: Mapping[str, Any]) -> str:
    """What the run's ``*-paper`` rows are (the paper's control logic, not its exact controller):
    their options as the run recorded them, and whether they kept soft constraints (the option
    left at its registered default, or set)."""
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


def paper_track(paper: Results | None, path: str = "data/paper.tar.xz") -> list[str]:
    """The paper track's lines: success per controller and task on the paper's protocol
    (``paper``, read from ``path``; None: not published)."""
    if paper is None:
        return [f"**The paper track**: pending, `{path}` is not published.", ""]
    config = paper.config
    slips = ", ".join(config["slips"])
    lines = [
        f"**The paper track**: the paper's protocol on its own maps (each task's two hand-made maps; "
        f"slip {slips}; {config['episodes']} episodes per cell; IPOPT; free compute), on which ORCA's "
        "and DWA's hand-set defaults were chosen. Each row ran with the defaults of the code it was "
        "published from: the hand-set ones (now `NAME-v0`) for a controller whose tuned preset came "
        "later (docs/benchmark.md). Success with 95% intervals." + _paper_variants_note(config),
        "",
    ]
    board = paper.leaderboard()
    tasks = [t for t in config["env_ids"] if any(row["env_id"] == t for row in board)]
    rows = {(row["env_id"], row["controller"]): row for row in board}
    labels = dict.fromkeys(row["controller"] for row in board if row["env_id"] == tasks[0])
    labels.update(dict.fromkeys(row["controller"] for row in board))
    lines += [
        "| Controller | " + " | ".join(task_label(t) for t in tasks) + " |",
        "|---|" + "---|" * len(tasks),
    ]
    for label in labels:
        cells = [
            rate_cell(rows[t, label]["success_rate"], rows[t, label]["success_ci"])
            if (t, label) in rows
            else "-"
            for t in tasks
        ]
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return lines + [""]


def _runs_section(modes: Sequence[Mode]) -> list[str]:
    lines = ["## The runs", ""]
    for mode in modes:
        run, title = RUNS[mode.name]
        command = f"the run `{run}` of data/publish.sh"
        if not mode.progress:
            lines.append(
                f"- **{title}** ({command}): pending, `{mode.path.as_posix()}` is not published yet "
                f"(`bash data/publish.sh {run}`, then `bash data/publish.sh pack`)."
            )
            continue
        pending = [
            f"{task_label(e)} {c} ({p.text().removeprefix('pending: ')})"
            for (e, c), p in mode.progress.items()
            if not p.complete
        ]
        episodes = 0 if mode.results is None else len(distinct_records(mode.results.records))
        lines.append(
            f"- **{title}** ({command}, `{mode.path.as_posix()}`): {episodes:,} distinct episodes of complete rows"
            + (f"; pending: {'; '.join(pending)}." if pending else "; every row complete.")
        )
        if mode.results is not None:
            compute = mode.results.config.get("compute")
            machine = f" Decision times measured on {compute['machine']}." if compute else ""
            lines.append(f"  {suite_heading(mode.results.config)}.{machine}")
    return lines + [""]


def _leaderboard_section(modes: Sequence[Mode]) -> list[str]:
    charged, free = modes
    summaries = {mode.name: _summary(mode) for mode in modes}
    names = {o.key: o.label for o in OUTCOMES}
    lines = [
        "## Leaderboard: compute charged beside free compute",
        "",
        "Per task, ranked by success with compute charged. Each outcome with compute charged, then "
        "free: success; " + names["strict_success"] + "; success excusing the "
        "collisions no robot could avoid. Rates with the wider of Wilson's interval and the two-stage "
        "bootstrap over layouts, then episodes.",
        "",
    ]
    header = ["Controller"] + [
        f"{head}, {mode}"
        for head in ("Success", "Strict", "Excusing unavoidable")
        for mode in ("charged", "free")
    ]
    for env_id in _tasks(modes):
        rows = []
        for label in _ranked(modes, env_id):
            cells = [
                _rate(summaries[mode.name], mode, env_id, label, key)
                for key in ("success", "strict_success", "success_excusing_unavoidable")
                for mode in (charged, free)
            ]
            rows.append([label, *cells])
        lines += [f"**{task_label(env_id)}**", "", markdown_table((header, rows)), ""]
    return lines


def _breakdown_section(modes: Sequence[Mode]) -> list[str]:
    lines = ["## By layout tier and family", "", SUITE_NOTE, ""]
    for mode in modes:
        if mode.results is None:
            continue
        title = RUNS[mode.name][1]
        for by, what in (("layout_tier", "tier"), ("layout_family", "family")):
            lines += [f"**{title}, by {what}**", "", markdown_table(suite_rows(mode.results, by)), ""]
    return lines


def decision(label: str, verdict: str, studies: Path = STUDIES_DIR) -> str:
    """The study's decision (``verdict``) with what its recorded confirmation on fresh validation
    layouts (``studies/<label>/confirmation.json``, ``python -m evaluation.tune adopt --confirm``)
    made of an adoption: kept, or withdrawn, so that the controller ships its defaults. A decision
    with no confirmation recorded is the study's as it is."""
    record = studies / label / CONFIRMATION_FILE
    if verdict != "adopted" or not record.is_file():
        return verdict
    confirmation = json.loads(record.read_text(encoding="utf-8"))
    counts = (
        f"{confirmation['best_successes']} against the defaults' {confirmation['defaults_successes']} "
        f"of {confirmation['units']} fresh validation episodes, p = {float(confirmation['p_value']):.2g}"
    )
    if confirmation["confirmed"]:
        return f"adopted, confirmed ({counts})"
    return f"adopted by the study, withdrawn by the confirmation ({counts}): ships its defaults"


def tuning_budget(labels: Sequence[str], studies: Path = STUDIES_DIR) -> list[str]:
    """A table of each controller's tuning budget: its study (:func:`controllers.tuning.studies.study_budget`),
    or why it has none."""
    lines = [
        "## Tuning budget",
        "",
        "What each controller's shipped defaults cost to find: its study on the validation split "
        "(`data/tuning/<name>/`, docs/benchmark.md), every study with the same budget and objective.",
        "",
        "| Controller | Tuned on | Configurations run | Validation episodes per configuration | Episodes | Decision |",
        "|---|---|---|---|---|---|",
    ]
    for label in labels:
        budget = study_budget(label, studies)
        if budget is not None:
            lines.append(
                f"| {label} | {budget.split} | {budget.configurations_run} of {budget.configurations} | "
                f"{budget.episodes_per_configuration} | {budget.episodes_run:,} | "
                f"{decision(label, budget.verdict, studies)} |"
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
        lines.append(f"| {label} | - | 0 | - | 0 | {why} |")
    return lines + [""]


def _mode_tables(mode: Mode, reference: str) -> tuple[list[dict[str, Any]], str] | None:
    """``mode``'s tested tables on the page's design and the design's clause (None: no rows yet);
    computed once, the verdict table and the tested section both read them."""
    if mode.results is None:
        return None
    pairs, design = page_pairs(mode, reference)
    return suite_tables(mode.results.records, pairs, design), design


def _success_rows(tables: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """The rows of the success table among a mode's tested tables."""
    return next(list(table["rows"]) for table in tables if table["measure"] == OUTCOMES[0].key)


def _verdicts_section(
    modes: Sequence[Mode], tested: Mapping[str, Any], paper: Results | None, reference: str
) -> list[str]:
    """Per published mode, every controller paired with ``reference`` on both the test split and the
    paper track: the two differences, their corrected p and what became of the verdict."""
    lines = [
        "## Which verdicts changed: the test split against the paper track",
        "",
        f"Each controller against {reference}, success: its difference on the test split (the page's "
        "success table) and on the paper track (free compute; its rows ran with the defaults they "
        "were published with, the hand-set ones for a controller tuned later). " + VERDICT_RULE,
        "",
    ]
    if paper is None:
        return lines + ["The paper track is not published: nothing to compare with yet.", ""]
    header = [
        "Task",
        "Controller",
        "Test split a - ref",
        "Holm p",
        "Paper track a - ref",
        "Holm p",
        "Verdict",
    ]
    for mode in modes:
        if tested.get(mode.name) is None:
            continue
        rows = [
            [
                task_label(row["env_id"]),
                row["controller"],
                f"{100 * row['test'][0]:+.0f}",
                "-" if math.isnan(row["test"][1]) else p_cell(row["test"][1]),
                f"{100 * row['paper'][0]:+.0f}",
                "-" if math.isnan(row["paper"][1]) else p_cell(row["paper"][1]),
                row["verdict"],
            ]
            for row in verdict_changes(_success_rows(tested[mode.name][0]), paper.paired(), reference)
        ]
        table = (
            markdown_table((header, rows)) if rows else f"No controller is paired with {reference} on both."
        )
        lines += [f"**{RUNS[mode.name][1]}**", "", table, ""]
    return lines


def _tested_section(mode: Mode, tested: tuple[list[dict[str, Any]], str] | None) -> list[str]:
    if mode.results is None or tested is None:
        return []
    title = RUNS[mode.name][1]
    tables, design = tested
    text = markdown(suite_sections(mode.results, tables, paired_note(design))).replace("\n## ", "\n### ")
    secondary = (
        "The paired tables of this section are secondary families, within each task (the headline "
        "family, over both tasks, is above)."
    )
    return [
        f"## {title}: outcomes, metrics and paired tests",
        "",
        secondary,
        "",
        "### " + text.removeprefix("## "),
        "",
    ]


def _pairs_section(pairs: str) -> list[str]:
    rows = pairs.count("\n") - 1
    digest = hashlib.sha256(pairs.encode()).hexdigest()
    return [
        "## Every pair",
        "",
        "The paired tables below test the pairs this page reads: per mode and per table one family, "
        "declared from the run's header and corrected with Holm within it (named under each table). "
        f"Every pair of each mode's controllers, for every table, is in [{PAIRS_FILE}]({PAIRS_FILE}) "
        f"({rows:,} rows; SHA-256 `{digest}`), each table there one family over every pair within "
        "each task (its size in the column `m`): a larger family, so a pair's Holm p there is no "
        "smaller than on this page.",
        "",
    ]


def page(
    modes: Sequence[Mode],
    paper: Results | None,
    reference: str,
    studies: Path = STUDIES_DIR,
    paper_path: str = "data/paper.tar.xz",
    pairs: str | None = None,
) -> str:
    """The page's Markdown: the headline block, the runs, the leaderboard, which verdicts changed
    from the paper track (:func:`verdict_changes`; once a mode has rows), the breakdowns, the
    tuning budget, where every pair is (``pairs``: :data:`PAIRS_FILE`'s text, :func:`pairs_file`)
    and each mode's tested tables against ``reference`` (:func:`page_pairs`)."""
    labels = list(dict.fromkeys(c for mode in modes for _, c in mode.progress))
    lines = [
        "# koopnav-bench-v1: results on the held-out test split",
        "",
        "The primary controllers on the test split of koopnav-bench-v1 (docs/benchmark.md), which no "
        "controller was tuned or trained on, with the decision time charged to the robots (the "
        "headline) and with free compute beside it, where the hand-set defaults the tuned presets "
        "replaced (`-v0`) run too; the variants are on their own pages (docs/benchmark.md, "
        '"Running the benchmark", says which and why). Written by `docs/make_bench_md.py` from the '
        "committed publications; a (task, controller) still running is named as pending and left "
        "out of every table and test.",
        "",
        headline(modes, paper, paper_path).rstrip("\n"),
        "",
        *_runs_section(modes),
    ]
    tested = {mode.name: _mode_tables(mode, reference) for mode in modes}
    lines += _headline_section(modes, reference)
    if any(mode.results is not None for mode in modes):
        lines += _leaderboard_section(modes)
        lines += _verdicts_section(modes, tested, paper, reference)
        lines += _breakdown_section(modes)
    lines += tuning_budget(labels, studies) if labels else []
    lines += _pairs_section(pairs) if pairs is not None else []
    for mode in modes:
        lines += _tested_section(mode, tested[mode.name])
    return "\n".join(lines).rstrip("\n") + "\n"


def _paper(path: str | None) -> Results | None:
    if path is None or not Path(path).exists():
        return None
    with extracted_archive(path) as run:
        return results_from_log(run / "episodes.jsonl")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument(
        "--charged", required=True, help="the compute-charged publication, data/bench_test_realtime"
    )
    parser.add_argument("--free", required=True, help="the free-compute publication, data/bench_test")
    parser.add_argument("--paper", help="the paper track's publication, data/paper.tar.xz")
    parser.add_argument(
        "--reference",
        required=True,
        help="the controller the page's paired tables compare every other one with (koopman-nmpc)",
    )
    parser.add_argument(
        "--studies", type=Path, default=STUDIES_DIR, help="the tuning studies (default data/tuning)"
    )
    parser.add_argument("--out", required=True, help="the page to write, e.g. docs/bench_results.md")
    parser.add_argument("--figures", help="accepted for docs/make_pages.py; the page has no figures")
    args = parser.parse_args(argv)
    try:
        modes = [load_mode("charged", args.charged), load_mode("free", args.free)]
        check_same_suite(modes)
        pairs = pairs_file(modes)
        paper_path = args.paper or "data/paper.tar.xz"
        text = page(modes, _paper(args.paper), args.reference, args.studies, paper_path, pairs)
    except ValueError as exc:  # a publication that is not as KoopNav packs it, or the wrong run
        print(f"error: {exc}", file=sys.stderr)
        return BAD_INPUT_EXIT
    if pairs is not None:
        write_atomic(Path(args.out).with_name(PAIRS_FILE), pairs)
    write_atomic(args.out, text)
    missing = [m.path.as_posix() for m in modes if m.results is None and not m.progress]
    print(f"wrote {args.out}" + (f" (pending: {', '.join(missing)} not published yet)" if missing else ""))
    return SUCCESS_EXIT


if __name__ == "__main__":
    raise SystemExit(main())
