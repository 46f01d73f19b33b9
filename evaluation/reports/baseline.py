"""Compare a run with an earlier one (``--baseline``) and gate on a significant loss (``--fail-if-worse``).

Every episode of the run is paired with the baseline's episode of the same env, controller label,
map, slip and seed (the seeds depend only on the base seed and an episode's index in its cell,
so two runs of the same protocol share them). Per task and controller the comparison gives both
success rates, the paired difference (run minus baseline) with Newcombe's 95% interval and the
exact McNemar p-value, and the mean paired difference of the team's final distance [cm] with a
bootstrap interval. Cells or controllers on one side only are listed, never dropped silently.

A baseline whose settings differ in anything that changes outcomes (env settings, calibration,
map files, the package version that holds the dynamics) is refused with the differing keys
named, as ``--resume`` refuses a log of another run. Its episode records are checked field by
field on reading (:func:`evaluation.episodes.records.record_problem`, the schema the resume log uses), and
read once (:func:`evaluation.episodes.distinct.read_once`): an episode recorded twice alike counts once,
one recorded twice with different outcomes is refused by name, whatever the order of the two.

The gate fails closed: a stale baseline must not turn it off. Before any episode runs, and again
on the episodes that ran, every controller of the run must pair at least
:attr:`GateOptions.min_pairs` episodes with the baseline, and (unless the run names its
controllers) every controller of the baseline must be in the run; otherwise
:func:`coverage_failures` says why (no episodes of that controller in the baseline, its
episodes there all raised, other seeds or cells) and the evaluator exits 2. On the episodes that
ran, pairs are counted distinct (:func:`distinct_pairs`): seeds whose two episodes repeat an
earlier seed's bit for bit are one pair, for the minimum as for every test.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from evaluation.episodes.distinct import distinct_units, read_once
from evaluation.episodes.records import ran, record_problem
from evaluation.reports.publications import is_split, unpack_hint
from evaluation.reports.published import is_archive
from evaluation.reports.sections import markdown_cell, markdown_text, task_label
from evaluation.stats.statistics import bootstrap_mean_interval, paired_comparison
from koopman_envs.checks import parse_json
from koopman_envs.files import MAX_LOG_BYTES, read_text

__all__ = [
    "ALL_TASKS",
    "GateOptions",
    "PairKey",
    "pair_keys",
    "compare_runs",
    "comparison_markdown",
    "coverage_failures",
    "distinct_pairs",
    "gate_failures",
    "load_baseline",
    "refuse_incomparable",
]

#: schema versions of results.json this module reads
READABLE_SCHEMAS = (2,)

#: the env id of a comparison row that pools a controller's pairs over every task of the run
ALL_TASKS = "all tasks"

#: what pairs an episode with its partner in the other run, per controller: (env id, map, slip, seed)
PairKey = tuple[str, str, str, int]

#: paired final distances closer than this [cm] (10 micrometres, far below what a robot's
#: localisation resolves) are one distance: another CPU's BLAS kernels round the NMPCs' arithmetic
#: otherwise, which moves final poses by 1e-12 to 1e-5 cm, and twenty such crumbs of one sign put
#: a bootstrap interval "above 0" with no change at all (the gate then read one episode that
#: ended elsewhere as a significant increase)
DISTANCE_RESOLUTION_CM = 1e-3

#: config keys whose difference changes outcomes: a baseline must match them
OUTCOME_KEYS = ("env_settings", "calibration", "map_files", "random_maps")


def load_baseline(path: str | Path, what: str = "baseline") -> dict[str, Any]:
    """The results document of ``path`` (a results.json, or a run directory holding one).

    Raises ``ValueError`` naming the file (as ``what``: a baseline, a sweep level) when it is
    missing, not a regular file of at most :data:`koopman_envs.files.MAX_LOG_BYTES` (a FIFO, a
    device: refused unread), a published archive (with how to use one), not UTF-8 JSON, not a
    KoopNav results document, or of a schema version this package cannot read. Its episodes are
    read once (:func:`evaluation.episodes.distinct.read_once`): one recorded twice alike counts once, one
    recorded twice with different outcomes is refused
    (:class:`~evaluation.episodes.distinct.ConflictingRecords`, a ``ValueError``) naming the file, the
    episode, both places and the fields that differ.
    """
    path = Path(path)
    if is_archive(path) or is_split(path):
        raise ValueError(
            f"{what} {str(path)!r} is a published archive (episode logs), not a results.json or a run "
            f"directory: unpack it ({unpack_hint(path)}), write its run's results.json with the run's "
            "command and --resume --out DIR/NAME (data/publish.sh lists it; every episode is logged, so "
            "none runs again), then pass DIR/NAME"
        )
    file = path / "results.json" if path.is_dir() else path
    # a regular file of bounded size (--baseline /dev/zero read until MemoryError, a FIFO forever)
    text = read_text(file, MAX_LOG_BYTES, what=what, expected="a KoopNav results.json (UTF-8 JSON)")
    try:
        doc = parse_json(text, f"{what} {str(file)!r}")
    except json.JSONDecodeError as exc:
        raise ValueError(f"{what} {str(file)!r} is not JSON ({exc.msg}, line {exc.lineno})") from None
    if not isinstance(doc, dict) or not {"schema_version", "config", "episodes"} <= set(doc):
        raise ValueError(
            f"{what} {str(file)!r} is not a KoopNav results document (no schema_version, config, episodes)"
        )
    if doc["schema_version"] not in READABLE_SCHEMAS:
        raise ValueError(
            f"{what} {str(file)!r} has schema_version={doc['schema_version']!r}; this version reads "
            f"{list(READABLE_SCHEMAS)}"
        )
    problem = _document_problem(doc)
    if problem is not None:
        raise ValueError(
            f"{what} {str(file)!r} is not a results document as KoopNav writes it: {problem}; "
            "nothing was compared (rerun the baseline, or restore the file from version control)"
        )
    episodes = doc["episodes"]
    doc["episodes"] = read_once(
        episodes, f"{what} {str(file)!r}", [f"episodes[{index}]" for index in range(len(episodes))]
    )
    return doc


def _document_problem(doc: dict[str, Any]) -> str | None:
    """Why the fields a comparison reads are not as KoopNav writes them (None when they are)."""
    if not isinstance(doc["config"], dict):
        return f"'config' is a JSON {type(doc['config']).__name__}, not an object"
    if not isinstance(doc.get("package_version"), str):
        return f"'package_version' is {doc.get('package_version')!r}, not a version string"
    episodes = doc["episodes"]
    if not isinstance(episodes, list):
        return f"'episodes' is a JSON {type(episodes).__name__}, not a list of episode records"
    for index, record in enumerate(episodes):
        problem = record_problem(record)
        if problem is not None:
            key = record.get("key") if isinstance(record, dict) else None
            return f"episodes[{index}]" + (f" ({key!r})" if isinstance(key, str) else "") + f": {problem}"
    return None


def refuse_incomparable(config: dict[str, Any], package_version: str, baseline: dict[str, Any]) -> None:
    """Raise ``ValueError`` naming every outcome-changing setting in which the run and the baseline differ."""
    theirs = baseline["config"]
    differing = [
        key
        for key in OUTCOME_KEYS
        if json.dumps(config.get(key), sort_keys=True, default=str)
        != json.dumps(theirs.get(key), sort_keys=True, default=str)
    ]
    if baseline.get("package_version") != package_version:
        differing.append("package_version")
    if differing:
        details = "; ".join(
            f"{key}: baseline {baseline.get(key) if key == 'package_version' else theirs.get(key)!r}, "
            f"now {package_version if key == 'package_version' else config.get(key)!r}"
            for key in differing
        )
        raise ValueError(
            f"the baseline was run with other settings ({details}); its episodes cannot be paired with these"
        )


def _outcomes(records: list[dict[str, Any]], side: str) -> dict[tuple[str, str], dict[tuple, dict[str, Any]]]:
    """(env id, controller) -> (map, slip, seed) -> the record of each episode that ran on one
    ``side`` (each episode once: a conflicting repeat is refused, never overwritten)."""
    table: dict[tuple[str, str], dict[tuple, dict[str, Any]]] = {}
    for r in read_once(records, side):
        if ran(r):
            table.setdefault((r["env_id"], r["controller"]), {})[(r["map"], r["slip"], r["seed"])] = r
    return table


def _paired_units(
    mine: dict[tuple[str, str], dict[tuple, dict[str, Any]]],
    theirs: dict[tuple[str, str], dict[tuple, dict[str, Any]]],
) -> list[tuple[tuple[str, str], list[tuple]]]:
    """Per (env id, controller) on both sides, its distinct paired units (map, slip, seed): a seed
    whose episodes repeat an earlier seed's on both sides, bit for bit, is one pair, not two
    (:func:`evaluation.episodes.distinct.distinct_units`). What every count of pairs reads: the rows, the
    gate and its minimum of pairs."""
    out = []
    for key in sorted(set(mine) & set(theirs)):
        shared = distinct_units(sorted(set(mine[key]) & set(theirs[key])), mine[key], theirs[key])
        if shared:
            out.append((key, shared))
    return out


def distinct_pairs(records: list[dict[str, Any]], baseline_records: list[dict[str, Any]]) -> dict[str, int]:
    """Controller label -> how many distinct pairs its episodes form with the baseline's, over
    every task (the ``n`` of its rows in :func:`compare_runs`): ten seeds that repeat one episode
    on both sides are one pair, which no test can judge."""
    counts: dict[str, int] = {}
    for (_, label), units in _paired_units(
        _outcomes(records, "the run"), _outcomes(baseline_records, "the baseline")
    ):
        counts[label] = counts.get(label, 0) + len(units)
    return counts


def _team_cm(record: dict[str, Any]) -> float:
    return 100.0 * float(np.mean(record["final_distance"]))


def _tied(difference_cm: float) -> float:
    """A paired final-distance difference [cm], 0 below :data:`DISTANCE_RESOLUTION_CM`."""
    return 0.0 if abs(difference_cm) < DISTANCE_RESOLUTION_CM else difference_cm


def _paired_row(
    env_id: str, controller: str, run: list[dict[str, Any]], baseline: list[dict[str, Any]]
) -> dict[str, Any]:
    """One comparison row from the paired episode records of both sides (same order)."""
    pair = paired_comparison([bool(r["success"]) for r in run], [bool(r["success"]) for r in baseline])
    differences = [_tied(_team_cm(a) - _team_cm(b)) for a, b in zip(run, baseline)]
    low, high = bootstrap_mean_interval(differences)
    return {
        "env_id": env_id,
        "controller": controller,
        **pair.to_dict(),
        "distance_cm_difference": float(np.mean(differences)),
        "distance_cm_low": low,
        "distance_cm_high": high,
    }


def compare_runs(records: list[dict[str, Any]], baseline_records: list[dict[str, Any]]) -> dict[str, Any]:
    """Paired comparison of a run's episode records with a baseline's.

    Returns
    -------
    dict
        ``rows``: one per (env id, controller) present on both sides, then, for a controller
        compared on several tasks, one pooling its pairs over all of them (env id
        :data:`ALL_TASKS`); each with ``n`` pairs, the
        :class:`~evaluation.stats.statistics.PairedComparison` fields (``a`` = this run, ``b`` = the
        baseline), ``distance_cm_difference`` (mean of run minus baseline team final distance
        [cm] over the pairs) and its bootstrap ``distance_cm_low`` / ``distance_cm_high``;
        ``only_run`` / ``only_baseline``: ``[env id, controller, map, slip]`` cells without a
        partner on the other side. Every count is of distinct pairs (:func:`distinct_pairs`).

    Raises
    ------
    ConflictingRecords
        An episode recorded twice with different outcomes on one side
        (:func:`evaluation.episodes.distinct.read_once`).
    """
    mine, theirs = _outcomes(records, "the run"), _outcomes(baseline_records, "the baseline")
    rows = []
    pooled: dict[str, tuple[list[dict[str, Any]], list[dict[str, Any]]]] = {}
    for key, shared in _paired_units(mine, theirs):
        pairs = ([mine[key][k] for k in shared], [theirs[key][k] for k in shared])
        rows.append(_paired_row(key[0], key[1], *pairs))
        run_side, base_side = pooled.setdefault(key[1], ([], []))
        run_side += pairs[0]
        base_side += pairs[1]
    # a controller's episodes over every task of the run: the gate's most sensitive test of it
    tasks = {row["controller"]: sum(r["controller"] == row["controller"] for r in rows) for row in rows}
    rows += [_paired_row(ALL_TASKS, name, *pooled[name]) for name in sorted(pooled) if tasks[name] > 1]

    def cells(table: dict, other: dict) -> list[list[str]]:
        out = set()
        for key, episodes in table.items():
            for map_name, slip, seed in episodes:
                if (map_name, slip, seed) not in other.get(key, {}):
                    out.add((key[0], key[1], map_name, slip))
        return [list(c) for c in sorted(out)]

    return {"rows": rows, "only_run": cells(mine, theirs), "only_baseline": cells(theirs, mine)}


@dataclass(frozen=True)
class GateOptions:
    """When ``--fail-if-worse`` fails a run.

    Attributes
    ----------
    alpha : float
        Significance level of McNemar's test, 0 < alpha < 1 (default 0.05).
    delta : float
        Success-rate drop that matters, >= 0 (default 0.10 = 10 points): a drop fails when it
        is larger than ``delta`` and significant (McNemar p < ``alpha``).
    delta_cm : float
        Final-distance increase that matters [cm], >= 0 (default 1.0): fails when the mean
        paired increase exceeds it and its interval lies above 0.
    min_pairs : int
        Episodes each controller of the run must pair with the baseline, >= 1 (default 10):
        with fewer the gate cannot see a loss (McNemar's exact test needs at least 6 discordant
        pairs, all one way, to reach p < 0.05), so the run fails instead of passing on nothing.
    """

    alpha: float = 0.05
    delta: float = 0.10
    delta_cm: float = 1.0
    min_pairs: int = 10

    def __post_init__(self) -> None:
        a = self.alpha
        if isinstance(a, bool) or not isinstance(a, (int, float)) or not 0.0 < a < 1.0:
            raise ValueError(f"alpha={a!r} must lie in (0, 1)")
        for name in ("delta", "delta_cm"):
            value = getattr(self, name)
            if (
                isinstance(value, bool)
                or not isinstance(value, (int, float))
                or not math.isfinite(value)
                or value < 0
            ):
                raise ValueError(f"{name}={value!r} must be a finite number >= 0")
        n = self.min_pairs
        if isinstance(n, bool) or not isinstance(n, int) or n < 1:
            raise ValueError(f"min_pairs={n!r} must be an integer >= 1")


def pair_keys(records: Iterable[Mapping[str, Any]]) -> dict[str, set[PairKey]]:
    """Controller label -> the pairing keys of its episodes that ran (errors cannot pair)."""
    keys: dict[str, set[PairKey]] = {}
    for r in records:
        if ran(r):
            keys.setdefault(r["controller"], set()).add((r["env_id"], r["map"], r["slip"], r["seed"]))
    return keys


def _span(keys: Iterable[PairKey]) -> str:
    """The seeds and cells of a set of pairing keys, in a few words."""
    keys = list(keys)
    seeds = sorted({k[3] for k in keys})
    cells = sorted({f"{k[1]}/{k[2]}" for k in keys})
    seed_text = f"seeds {seeds[0]}-{seeds[-1]}" if len(seeds) > 1 else f"seed {seeds[0]}"
    return f"{seed_text} on {', '.join(cells[:4])}" + (
        f" and {len(cells) - 4} more cells" if len(cells) > 4 else ""
    )


def coverage_failures(
    run: Mapping[str, set[PairKey]],
    baseline_records: list[dict[str, Any]],
    options: GateOptions,
    *,
    run_names_its_controllers: bool,
    run_errors: Mapping[str, int] | None = None,
    distinct: Mapping[str, int] | None = None,
) -> list[str]:
    """Why the gate cannot judge this run against the baseline (empty list = it can).

    Parameters
    ----------
    run : mapping
        Controller label -> the pairing keys of the run's episodes (those planned, before the
        run; those that ran, after it).
    baseline_records : list of dict
        The baseline's episode records.
    options : GateOptions
        ``min_pairs``: the pairs each controller of the run needs.
    run_names_its_controllers : bool
        The run was given its controllers (``--controllers``): the baseline's other
        controllers are left out on purpose. Otherwise each of them must be in the run (a
        controller that vanished from the registry or could not be built is a failure).
    run_errors : mapping, optional
        Controller label -> episodes of the run that raised, to explain a shortfall.
    distinct : mapping, optional
        After the run: controller label -> its distinct pairs with the baseline
        (:func:`distinct_pairs`). Pairs whose episodes repeat an earlier seed's on both sides,
        bit for bit, count once: ten copies of one episode are one pair, too few to judge.
    """
    baseline_records = read_once(baseline_records, "the baseline")
    theirs = pair_keys(baseline_records)
    failures = []
    if not theirs:
        errors = sum(not ran(r) for r in baseline_records)
        return [
            f"the baseline has no episode that ran ({len(baseline_records)} records, {errors} of them "
            "errors): there is nothing to compare with; rerun it (bash .ci/leaderboard.sh --update)"
        ]
    for label in sorted(run):
        pairs = len(run[label] & theirs.get(label, set()))
        unique = pairs if distinct is None else distinct.get(label, 0)
        if unique >= options.min_pairs:
            continue
        why = (
            f"{label}: {pairs} episode(s) pair with the baseline, fewer than the minimum {options.min_pairs}"
        )
        baseline_errors = sum(r["controller"] == label and not ran(r) for r in baseline_records)
        if pairs >= options.min_pairs:
            why = (
                f"{label}: {pairs} episode(s) pair with the baseline but only {unique} of those pairs are "
                f"distinct, fewer than the minimum {options.min_pairs}"
            )
            reason = (
                "the others repeat an earlier seed's two episodes bit for bit (an identical rerun is not a "
                "sample); make the seeds' episodes differ (--start-noise, a random slip, --random-maps)"
            )
        elif label not in theirs:
            reason = (
                f"all {baseline_errors} of its baseline episodes raised"
                if baseline_errors
                else f"the baseline has no episodes of {label!r} (it has {sorted(theirs)})"
            )
        elif not run[label]:
            reason = "none of its episodes in this run ran"
        elif run[label] <= theirs[label]:
            reason = f"this run has only {len(run[label])} episode(s) of it; run more per cell (--episodes)"
        else:
            reason = f"the baseline ran it with {_span(theirs[label])}, this run with {_span(run[label])}"
        if run_errors and run_errors.get(label):
            reason += f"; {run_errors[label]} of its episodes in this run raised"
        failures.append(f"{why}: {reason}")
    if not run_names_its_controllers:
        failures += [
            f"the baseline's controller {label!r} is not in this run (not registered, or it could not "
            "be built here); name the controllers to gate with --controllers to leave it out"
            for label in sorted(set(theirs) - set(run))
        ]
    return failures


def gate_failures(comparison: dict[str, Any], options: GateOptions) -> list[str]:
    """Controllers significantly worse than the baseline (empty list = pass).

    Success: the drop is significant (McNemar p < ``alpha``) and larger than ``delta``.
    Final distance: the mean paired increase is larger than ``delta_cm`` and its interval lies
    above 0.

    A controller with fewer than ``min_pairs`` distinct pairs over its task rows is not judged
    (one distinct pair gives a zero-width interval, not evidence): :func:`coverage_failures`,
    given :func:`distinct_pairs`, says why the gate cannot judge it.
    """
    distinct: dict[str, int] = {}
    for r in comparison["rows"]:
        if r["env_id"] != ALL_TASKS:
            distinct[r["controller"]] = distinct.get(r["controller"], 0) + r["n"]
    failures = []
    for r in comparison["rows"]:
        if distinct[r["controller"]] < options.min_pairs:
            continue
        where = f"{r['controller']} on {r['env_id']} ({r['n']} paired episodes)"
        if r["difference"] < -options.delta and r["p_value"] < options.alpha:
            failures.append(
                f"{where}: success {100 * r['rate_b']:.0f}% -> {100 * r['rate_a']:.0f}%, "
                f"{100 * r['difference']:+.0f} points [{100 * r['low']:+.0f}, {100 * r['high']:+.0f}], "
                f"McNemar p = {r['p_value']:.3g}"
            )
        increase = r["distance_cm_difference"]
        if increase > options.delta_cm and r["distance_cm_low"] > 0:
            failures.append(
                f"{where}: final distance {increase:+.2f} cm [{r['distance_cm_low']:+.2f}, "
                f"{r['distance_cm_high']:+.2f}]"
            )
    return failures


def comparison_markdown(comparison: dict[str, Any], baseline_label: str) -> str:
    """The comparison as a Markdown section (table, then the one-sided cells)."""
    lines = [
        f"## Compared with the baseline ({markdown_text(baseline_label)})",
        "",
        "Run minus baseline on the episodes both ran (same env, controller, map, slip and seed): success with "
        "Newcombe's 95% interval and the exact McNemar p-value; team final distance with a 95% bootstrap interval.",
        "",
        "| Task | Controller | Pairs | Success baseline | Success run | Run - baseline [95% CI] | only run / only "
        "baseline | McNemar p | Final distance, run - baseline [cm] |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in comparison["rows"]:
        task = task_label(r["env_id"])
        p = "<0.001" if r["p_value"] < 0.001 else f"{r['p_value']:.3f}"
        lines.append(
            f"| {task} | {markdown_cell(r['controller'])} | {r['n']} | {100 * r['rate_b']:.0f}% | {100 * r['rate_a']:.0f}% | "
            f"{100 * r['difference']:+.0f} [{100 * r['low']:+.0f}, {100 * r['high']:+.0f}] | {r['only_a']} / "
            f"{r['only_b']} | {p} | {r['distance_cm_difference']:+.2f} [{r['distance_cm_low']:+.2f}, "
            f"{r['distance_cm_high']:+.2f}] |"
        )
    for side, label in (("only_run", "in this run only"), ("only_baseline", "in the baseline only")):
        if comparison[side]:
            lines += [
                "",
                f"Cells {label} (not compared): "
                + markdown_text(", ".join(f"{c[1]} {c[2]} {c[3]} ({c[0]})" for c in comparison[side])),
            ]
    return "\n".join(lines)
