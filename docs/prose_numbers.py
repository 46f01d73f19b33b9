"""The numbers a page's prose states, computed from the committed data (issue 60: prose that
cannot drift): the published runs a page reads (:class:`Runs`) and the placeholder functions that
print one number each (``{{ kn paper orca task=formation slip=high }}`` -> ``17/20``).

``docs/make_prose_md.py`` expands a page template's placeholders with these functions and those
of ``docs/prose_tables.py`` (the tables); its docstring says how a placeholder is written. Each
function takes the runs, its arguments and its options, and prints with the evaluator's own
statistics (the run's pairing, Newcombe's interval, McNemar's exact test, the Holm family of the
run's page), so a number on the page is what the page of its run says.
"""

from __future__ import annotations

import json
import sys
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # run from a checkout without installing


from evaluation.episodes.distinct import distinct_records  # noqa: E402
from evaluation.episodes.records import ran  # noqa: E402
from evaluation.experiments.ablation import FACTORS, main_effects  # noqa: E402
from evaluation.experiments.sweep import load_sweep  # noqa: E402
from evaluation.reports.publications import extracted_archive  # noqa: E402
from evaluation.reports.published import results_from_log  # noqa: E402
from evaluation.reports.results import Results  # noqa: E402
from evaluation.reports.sections.blocks import level_text, p_cell, rate_cell  # noqa: E402
from evaluation.stats.aggregate import paired_comparisons  # noqa: E402
from evaluation.stats.robustness import AxisProfile, LevelCost, level_costs, profiles  # noqa: E402
from evaluation.stats.statistics import wilson_interval  # noqa: E402

__all__ = [
    "FILTERED",
    "FILTERS",
    "NUMBERS",
    "TASKS",
    "Options",
    "Runs",
    "check_args",
    "episodes_of",
    "interval_text",
    "parse_runs",
    "signed_points",
    "successes",
]

#: the filters a placeholder may name, and the record field each one reads; a value may list
#: several, comma-separated (``trial=0,1,2``)
FILTERS = {"task": "env_id", "map": "map", "slip": "slip", "trial": "trial"}
#: a placeholder's options (its filters, a table's lists) by name
Options = dict[str, str]
#: ``task=`` shorthands
TASKS = {"target": "KoopNav-TargetReaching-v0", "formation": "KoopNav-Formation-v0"}


def parse_runs(items: Sequence[str]) -> dict[str, Path]:
    """``["paper=data/paper.tar.xz", ...]`` as {name: archive}; ``ValueError`` naming an item
    that is not ``NAME=PATH`` or a name given twice."""
    runs: dict[str, Path] = {}
    for item in items:
        name, sep, path = item.partition("=")
        if not sep or not name or not path:
            raise ValueError(f"run {item!r} is not NAME=PATH (e.g. paper=data/paper.tar.xz)")
        if name in runs:
            raise ValueError(f"run {name!r} is given twice")
        runs[name] = Path(path)
    return runs


@dataclass
class _Sweep:
    """A published sweep: its levels with two or more finished (what its page shows), its manifest."""

    levels: dict[str, list[tuple[Any, Results]]]
    manifest: dict[str, Any]

    @cached_property
    def profiles(self) -> list[AxisProfile]:
        # the page's own family: every axis with two finished levels, its reference the manifest's
        return profiles(self.levels, self.manifest.get("reference"))

    @cached_property
    def costs(self) -> list[LevelCost]:
        return level_costs(self.levels)


@dataclass
class Runs:
    """The published runs a page reads, each loaded (checked) when first named."""

    archives: Mapping[str, Path]
    #: names that stand for several archives (refused when a placeholder names one)
    ambiguous: Mapping[str, Sequence[str]] = field(default_factory=dict)
    _loaded: dict[str, Results | _Sweep] = field(default_factory=dict)

    def _load(self, name: str) -> Results | _Sweep:
        if name in self.ambiguous:
            raise ValueError(f"run {name!r} names several archives {list(self.ambiguous[name])}")
        if name not in self.archives:
            raise ValueError(f"run {name!r} is not one of the page's runs {sorted(self.archives)}")
        if name not in self._loaded:
            with extracted_archive(ROOT / self.archives[name]) as directory:
                if (directory / "sweep.json").exists():
                    done, _, manifest = load_sweep(directory, from_logs=True)
                    shown = {key: levels for key, levels in done.items() if len(levels) >= 2}
                    self._loaded[name] = _Sweep(shown, manifest)
                else:
                    self._loaded[name] = results_from_log(directory / "episodes.jsonl")
        return self._loaded[name]

    def sweep(self, name: str) -> _Sweep:
        """The published sweep ``name``."""
        loaded = self._load(name)
        if not isinstance(loaded, _Sweep):
            raise ValueError(f"run {name!r} is not a sweep")
        return loaded

    def run(self, spec: str) -> Results:
        """A published run, or one level of a sweep (``NAME@KEY=LEVEL``)."""
        name, at, level = spec.partition("@")
        loaded = self._load(name)
        if isinstance(loaded, Results):
            if at:
                raise ValueError(f"run {name!r} is not a sweep: name it without a level")
            return loaded
        levels = {
            f"{key}={level_text(value)}": run for key, pairs in loaded.levels.items() for value, run in pairs
        }
        if level not in levels:
            raise ValueError(
                f"{spec!r}: {name!r} is a sweep; name one of its levels {sorted(levels)} as {name}@LEVEL"
            )
        return levels[level]


def _filters(options: Mapping[str, str]) -> Callable[[Mapping[str, Any]], bool]:
    # a filter's value may list several, comma-separated: ``trial=0,1,2``
    wanted = {
        FILTERS[key]: {TASKS.get(v, v) if key == "task" else v for v in value.split(",")}
        for key, value in options.items()
    }
    return lambda record: all(str(record[field_]) in values for field_, values in wanted.items())


def episodes_of(run: Results, controller: str | None, options: Mapping[str, str]) -> list[dict[str, Any]]:
    """The episodes that ran of ``controller`` (every one's with None) that pass the filters."""
    if controller is not None and controller not in run.config["controllers"]:
        raise ValueError(f"controller {controller!r} is not in the run; it has {run.config['controllers']}")
    keep = _filters(options)
    found = [r for r in run.records if ran(r) and keep(r) and controller in (None, r["controller"])]
    if not found:
        raise ValueError(f"no episode of {controller or 'any controller'} with {dict(options)}")
    return found


def successes(run: Results, controller: str, options: Mapping[str, str]) -> tuple[int, int]:
    """Successes and distinct episodes of ``controller`` (as the run's cells count them)."""
    cells = Results(episodes_of(run, controller, options), run.config).cells
    return sum(c.successes for c in cells), sum(c.valid for c in cells)


def _pair(run: Results, a: str, b: str, options: Mapping[str, str]) -> dict[str, Any]:
    """The paired comparison of ``a`` against ``b`` on their shared episodes (the run's own
    pairing, :func:`evaluation.stats.aggregate.paired_comparisons`), pooled over the filtered tasks."""
    records = [r for c in (a, b) for r in episodes_of(run, c, options)]
    rows = [row for row in paired_comparisons(records) if {row["a"], row["b"]} == {a, b}]
    if len(rows) != 1:
        raise ValueError(f"{a} and {b} pair in {len(rows)} tasks with {dict(options)}: name one with task=")
    row = rows[0]
    if row["a"] == a:
        return row
    return {**row, "difference": -row["difference"], "low": -row["high"], "high": -row["low"]}


def p_text(value: float, name: str = "Holm p") -> str:
    """A p-value in a sentence, as the tables print it (:func:`evaluation.reports.sections.blocks.p_cell`):
    ``Holm p = 0.013``, ``Holm p < 0.001``."""
    cell = p_cell(value)
    return f"{name} {cell[0]} {cell[1:]}" if cell.startswith("<") else f"{name} = {cell}"


def signed_points(value: float) -> str:
    """A difference in points with its sign, ``+15``."""
    return f"{100 * value:+.0f}"


def interval_text(difference: float, low: float, high: float) -> str:
    return f"{signed_points(difference)} [{signed_points(low)}, {signed_points(high)}]"


# --------------------------------------------------------------------------- inline numbers


def check_args(name: str, args: Sequence[str], n: int) -> None:
    if len(args) != n:
        raise ValueError(f"{name} takes {n} argument(s) besides the filters, got {list(args)}")


def episodes(runs: Runs, args: Sequence[str], options: Options) -> str:
    """``episodes RUN [CONTROLLER]``: the distinct episodes that ran, ``1,320``."""
    if len(args) not in (1, 2):
        raise ValueError(f"episodes takes RUN [CONTROLLER], got {list(args)}")
    return f"{len(episodes_of(runs.run(args[0]), args[1] if len(args) == 2 else None, options)):,}"


def kn(runs: Runs, args: Sequence[str], options: Options) -> str:
    """``kn RUN CONTROLLER``: successes of the episodes, ``12/20``."""
    check_args("kn", args, 2)
    k, n = successes(runs.run(args[0]), args[1], options)
    return f"{k}/{n}"


def rate(runs: Runs, args: Sequence[str], options: Options) -> str:
    """``rate RUN CONTROLLER``: the success rate, ``87%``."""
    check_args("rate", args, 2)
    k, n = successes(runs.run(args[0]), args[1], options)
    return f"{100 * k / n:.0f}%"


def ci(runs: Runs, args: Sequence[str], options: Options) -> str:
    """``ci RUN CONTROLLER``: the success rate with its 95% Wilson interval, ``87% [76-93]``."""
    check_args("ci", args, 2)
    k, n = successes(runs.run(args[0]), args[1], options)
    return rate_cell(k / n, wilson_interval(k, n))


def diff(runs: Runs, args: Sequence[str], options: Options) -> str:
    """``diff RUN A B``: A's success minus B's on their shared episodes in points, with
    Newcombe's 95% interval, ``+8 [-4, +21]``."""
    check_args("diff", args, 3)
    row = _pair(runs.run(args[0]), args[1], args[2], options)
    return interval_text(row["difference"], row["low"], row["high"])


def points(runs: Runs, args: Sequence[str], options: Options) -> str:
    """``points RUN A B``: A's success minus B's on their shared episodes, in points without
    sign, ``10`` (the prose says which way)."""
    check_args("points", args, 3)
    return f"{abs(100 * _pair(runs.run(args[0]), args[1], args[2], options)['difference']):.0f}"


def p(runs: Runs, args: Sequence[str], options: Options) -> str:
    """``p RUN A B``: the exact McNemar p of A against B on their shared episodes (unadjusted),
    ``p = 0.302`` (``p < 0.001`` below 0.001)."""
    check_args("p", args, 3)
    return p_text(_pair(runs.run(args[0]), args[1], args[2], options)["p_value"], "p")


def _family(run: Results) -> list[dict[str, Any]]:
    return run.paired()


def holm(runs: Runs, args: Sequence[str], options: Options) -> str:
    """``holm RUN A B task=T``: the Holm-adjusted p of A against B in the run's table of paired
    comparisons, ``Holm p = 1.000`` (every pair of the run's controllers in each task: the family its page corrects
    over)."""
    check_args("holm", args, 3)
    env_id = TASKS.get(options.get("task", ""), options.get("task"))
    rows = [
        r
        for r in _family(runs.run(args[0]))
        if {r["a"], r["b"]} == {args[1], args[2]} and env_id in (None, r["env_id"])
    ]
    if len(rows) != 1 or set(options) - {"task"}:
        raise ValueError(f"holm {list(args)} {dict(options)}: name the task (task=) and no other filter")
    return p_text(rows[0]["p_holm"])


def tests(runs: Runs, args: Sequence[str], options: Options) -> str:
    """``tests RUN [task=T]``: the paired tests in the run's table (its Holm family), ``110``."""
    check_args("tests", args, 1)
    env_id = TASKS.get(options.get("task", ""), options.get("task"))
    return str(sum(env_id in (None, r["env_id"]) for r in _family(runs.run(args[0]))))


def steps(runs: Runs, args: Sequence[str], options: Options) -> str:
    """``steps POLICY``: the training budget of a shipped policy (``baselines/policies/POLICY``:
    ``target_reaching``, ``formation``, ``set``, ``ippo``, ...) as its metadata record it, in
    millions: the SB3 policies' timesteps (team transitions), BenchMARL's frames times its robots
    (robot-steps); ``14 M``, ``24 M and 16 M`` (target reaching, formation) or ``18 M per task``."""
    check_args("steps", args, 1)
    base = ROOT / "baselines" / "policies" / args[0]
    single = base / "metadata.json"
    files = (
        [single]
        if single.exists()
        else [base / task / "metadata.json" for task in ("target_reaching", "formation")]
    )
    budgets = []
    for path in files:
        meta = json.loads(path.read_text(encoding="utf-8"))
        budget = meta["timesteps"] if "timesteps" in meta else meta["frames"] * meta["n_robots"]
        budgets.append(f"{budget / 1e6:.0f} M")
    if len(budgets) == 1:
        return budgets[0]
    return f"{budgets[0]} per task" if len(set(budgets)) == 1 else " and ".join(budgets)


def _field(record: Mapping[str, Any], name: str) -> Any:
    if name in record:
        return record[name]
    extra = record.get("controller_extra") or {}
    if name in extra:
        return extra[name]
    raise ValueError(f"field {name!r} is in neither the episode record nor its controller_extra")


def median(runs: Runs, args: Sequence[str], options: Options) -> str:
    """``median RUN CONTROLLER FIELD``: the median over the episodes of a per-episode number (a
    record field, or one of ``controller_extra``: ``solve_ms_median``, ``estimator_ms_median``),
    to two significant digits, ``2.3``, ``0.14``."""
    check_args("median", args, 3)
    values = [_field(r, args[2]) for r in episodes_of(runs.run(args[0]), args[1], options)]
    numbers = [float(v) for v in values if v is not None]
    if not numbers:
        raise ValueError(f"no episode of {args[1]} records {args[2]!r}")
    return f"{float(np.median(numbers)):.2g}"


def misses(runs: Runs, args: Sequence[str], options: Options) -> str:
    """``misses RUN CONTROLLER [count]``: deadline misses over the decisions of the episodes
    (compute charged), ``10 of 17,594``; with ``count``, the misses alone, ``10``."""
    if len(args) not in (2, 3) or list(args[2:]) not in ([], ["count"]):
        raise ValueError(f"misses takes RUN CONTROLLER [count], got {list(args)}")
    found = episodes_of(runs.run(args[0]), args[1], options)
    missed, decided = (sum(int(r[key] or 0) for r in found) for key in ("deadline_misses", "decisions"))
    return f"{missed:,}" if len(args) == 3 else f"{missed:,} of {decided:,}"


def count(runs: Runs, args: Sequence[str], options: Options) -> str:
    """``count RUN CONTROLLER``: successes of the episodes alone, ``12`` (``kn``'s numerator,
    for prose that says ``40 -> 30 of 40``)."""
    check_args("count", args, 2)
    return str(successes(runs.run(args[0]), args[1], options)[0])


def collisions(runs: Runs, args: Sequence[str], options: Options) -> str:
    """``collisions RUN CONTROLLER KIND``: the episodes whose collision involves KIND
    (``obstacle``, ``mover``, ``robot``), ``31``; with ``failures`` as KIND, the episodes that
    did not succeed."""
    check_args("collisions", args, 3)
    found = distinct_records(episodes_of(runs.run(args[0]), args[1], options))
    if args[2] == "failures":
        return str(sum(not r["success"] for r in found))
    return str(sum(args[2] in (r["collision"] or "").split("+") for r in found))


# --------------------------------------------------------------------------- the ablation
def _effect(runs: Runs, args: Sequence[str]) -> dict[str, Any]:
    check_args("effect", args, 2)
    for effect in main_effects(runs.run(args[0])):
        if effect["factor"] == args[1]:
            return effect
    raise ValueError(f"factor {args[1]!r} is not one of {list(FACTORS)} with pairs in run {args[0]!r}")


def effect(runs: Runs, args: Sequence[str], options: Options) -> str:
    """``effect ABLATION FACTOR``: the factor's main effect, first level minus second, in points
    with its 95% interval over episode units (:func:`evaluation.experiments.ablation.main_effects`)."""
    e = _effect(runs, args)
    return interval_text(e["difference"], e["low"], e["high"])


def effect_p(runs: Runs, args: Sequence[str], options: Options) -> str:
    """``effect_p ABLATION FACTOR``: its sign-flip p over units, Holm-adjusted over the factors,
    ``Holm p < 0.001``."""
    return p_text(_effect(runs, args)["p_holm"])


#: every number function by name
NUMBERS = {
    f.__name__: f
    for f in (
        episodes,
        kn,
        rate,
        ci,
        diff,
        points,
        p,
        holm,
        tests,
        steps,
        median,
        misses,
        count,
        collisions,
        effect,
        effect_p,
    )
}
#: the functions that count filtered episodes (the others refuse a filter)
FILTERED = {
    "episodes",
    "kn",
    "rate",
    "ci",
    "diff",
    "points",
    "p",
    "holm",
    "tests",
    "median",
    "misses",
    "collisions",
    "count",
    "span",
}
