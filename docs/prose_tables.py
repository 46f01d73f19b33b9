"""The tables a page's prose shows, computed from the committed data (issue 60): placeholder
functions (``docs/make_prose_md.py``) that print a Markdown table, each placed alone on a line
(``{{ success_table paper koopman-nmpc orca }}``), with the numbers of
``docs/prose_numbers.py`` and the evaluator's cell formats.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the page scripts beside this one

from make_results_md import PAPER  # noqa: E402  (the paper's own tables, SPEC section 5)
from prose_numbers import Options, Runs, check_args, ci, episodes_of, successes  # noqa: E402

from evaluation.experiments.ablation import FACTORS  # noqa: E402
from evaluation.reports.results import Results  # noqa: E402
from evaluation.reports.sections import markdown_table, task_label  # noqa: E402
from evaluation.reports.sections.blocks import count_cell, rate_cell  # noqa: E402
from evaluation.stats.statistics import wilson_interval  # noqa: E402

__all__ = ["TABLES", "factor_table", "paper_cells", "run_table", "scale_table", "slip_table", "success_table"]


def _names(args: Sequence[str], what: str) -> list[str]:
    if not args:
        raise ValueError(f"{what} needs the controllers it shows")
    return list(args)


def success_table(runs: Runs, args: Sequence[str], options: Options) -> str:
    """``success_table RUN CONTROLLER...``: one row per task, one column per controller: success
    pooled over the task's maps and slips with the leaderboard's 95% interval (the wider of
    Wilson's and the trial-cluster bootstrap's), as the run's page ranks them."""
    run = runs.run(args[0])
    names = _names(args[1:], "success_table")
    rows = {(r["env_id"], r["controller"]): r for r in run.leaderboard()}
    table = []
    for env_id in run.config["env_ids"]:
        cells = []
        for name in names:
            row = rows.get((env_id, name))
            cells.append("-" if row is None else rate_cell(row["success_rate"], row["success_ci"]))
        table.append([task_label(env_id), *cells])
    return markdown_table((["Task", *names], table))


def slip_table(runs: Runs, args: Sequence[str], options: Options) -> str:
    """``slip_table RUN CONTROLLER...``: one row per controller, one column per task and slip
    level: successes of the cell's episodes pooled over its maps, ``12/20``."""
    run = runs.run(args[0])
    columns = [(env_id, slip) for env_id in run.config["env_ids"] for slip in run.config["slips"]]
    table = []
    for name in _names(args[1:], "slip_table"):
        counts = [successes(run, name, {"task": env_id, "slip": slip}) for env_id, slip in columns]
        table.append([name, *(f"{k}/{n}" for k, n in counts)])
    header = ["Controller", *(f"{task_label(env_id)}, {slip}" for env_id, slip in columns)]
    return markdown_table((header, table))


def paper_cells(runs: Runs, args: Sequence[str], options: Options) -> str:
    """``paper_cells RUN CONTROLLER``: per map (rows) and slip level (columns), the controller's
    successes against the paper's own table (:data:`PAPER`), ``10/10 (paper 0/10)``."""
    check_args("paper_cells", args, 2)
    run, name = runs.run(args[0]), args[1]
    slips = run.config["slips"]
    table = []
    for env_id, maps in run.config["maps"].items():
        for map_name in maps:
            if (name, map_name) not in PAPER:
                continue
            cells = []
            for slip in slips:
                k, n = successes(run, name, {"task": env_id, "map": map_name, "slip": slip})
                theirs = PAPER[(name, map_name)][slip].split()[0]
                cells.append(f"{k}/{n} (paper {theirs})")
            table.append([f"{task_label(env_id)}, {map_name}", *cells])
    return markdown_table((["Map", *slips], table))


def _runs_option(options: Options, what: str) -> list[str]:
    if "runs" not in options:
        raise ValueError(f"{what} needs runs=NAME,NAME,... (the rows)")
    return options["runs"].split(",")


def run_table(runs: Runs, args: Sequence[str], options: Options) -> str:
    """``run_table CONTROLLER... runs=A,B``: one row per run (its cells pooled), one column per
    controller: the success rate with its 95% Wilson interval."""
    names = _names(args, "run_table")
    table = []
    for name in _runs_option(options, "run_table"):
        run = runs.run(name)
        cells = [ci(runs, [name, controller], {}) for controller in names]
        per = successes(run, names[0], {})[1]
        where = ", ".join(f"{task_label(e)} {', '.join(m)}" for e, m in run.config["maps"].items())
        table.append([f"{where}, slip {', '.join(run.config['slips'])} ({per} per controller)", *cells])
    return markdown_table((["Cells", *names], table))


def scale_table(runs: Runs, args: Sequence[str], options: Options) -> str:
    """``scale_table CONTROLLER... runs=A,B times=C,D``: one row per run (a team size N: its
    ``n_robots``), one column per controller: successes with the 95% Wilson interval, and for the
    controllers named by ``times`` the median and 95th percentile of the decision time per step
    [ms] over the cell."""
    names = _names(args, "scale_table")
    timed = set(options.get("times", "").split(","))
    table = []
    for name in _runs_option(options, "scale_table"):
        run = runs.run(name)
        n_robots = (run.config.get("env_settings") or {}).get("n_robots", 3)
        row = [f"{n_robots} ({run.config['episodes']})"]
        for controller in names:
            if controller not in run.config["controllers"]:
                row.append("not run")
                continue
            k, n = successes(run, controller, {})
            text = count_cell(k, n, wilson_interval(k, n))
            cells = Results(episodes_of(run, controller, {}), run.config).cells
            if controller in timed and len(cells) == 1:
                text += f", {cells[0].solve_ms_median:.0f} / {cells[0].solve_ms_p95:.0f} ms"
            row.append(text)
        table.append(row)
    return markdown_table((["N (seeds)", *names], table))


def factor_table(runs: Runs, args: Sequence[str], options: Options) -> str:
    """``factor_table ABLATION``: the ablation's configurations as rows (margins x constraints)
    and the model's two levels as columns: success over every map with its 95% Wilson interval."""
    check_args("factor_table", args, 1)
    models = list(FACTORS["model"])
    table = []
    for margins in FACTORS["margins"]:
        for constraints in FACTORS["constraints"]:
            row = [f"{margins} margins, {constraints} constraints"]
            for model in models:
                row.append(
                    ci(runs, [args[0], f"model={model} margins={margins} constraints={constraints}"], {})
                )
            table.append(row)
    return markdown_table((["Configuration", *(f"{m} model" for m in models)], table))


#: every table function by name
TABLES = {
    f.__name__: f for f in (success_table, slip_table, paper_cells, run_table, scale_table, factor_table)
}
