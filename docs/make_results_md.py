"""Write docs/results.md from ``python evaluate.py --paper`` runs, beside the paper's tables.

Usage (every RESULTS a ``results.json`` or a published archive ``data/NAME.tar.xz``; the
published page's arguments are in ``data/pages.json``)::

    python docs/make_results_md.py RESULTS [RESULTS ...] [--ablation docs/ablation.md] \
        [--strict RESULTS] [--uncertainty RESULTS ...] [--scaling RESULTS ...] \
        [--notes docs/_intros/results_notes.md] [--figures DIR] --out docs/results.md

Cells of later files are added to those of the first (e.g. a separate ``--controllers rl-ppo``
run). Every rate carries its 95% Wilson interval, every mean distance its 95% bootstrap
interval; paired comparisons come from the runs themselves (same seeds for every controller).
The ``--intro`` and ``--notes`` files are templates (``docs/make_prose_md.py``): their
placeholders are filled from the published archives given, each named by its file
(``{{ kn paper orca task=formation slip=high }}``).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

# run from a checkout without installing; docs/ for its sibling modules when imported from elsewhere
sys.path[:0] = [str(Path(__file__).resolve().parents[1]), str(Path(__file__).resolve().parent)]

from policy_budgets import POLICIES, robot_steps  # noqa: E402

from evaluation.exit_codes import BAD_INPUT_EXIT  # noqa: E402
from evaluation.reports.baseline import load_baseline  # noqa: E402
from evaluation.reports.figures import save_success_figures  # noqa: E402
from evaluation.reports.publications import extracted_archive  # noqa: E402
from evaluation.reports.published import results_from_log  # noqa: E402
from evaluation.reports.results import Results, evaluate_command, pooled_results  # noqa: E402
from evaluation.reports.sections import controller_tables, markdown_table, paired_rows, task_label  # noqa: E402
from evaluation.reports.sections import paired_power_note as power_note  # noqa: E402
from koopman_envs.files import write_atomic  # noqa: E402

# The paper's numbers (SPEC section 5): SR and final distances [cm], robots 1-3.
PAPER = {
    ("koopman-nmpc", "map1"): {
        "nominal": "10/10 (0.9, 1.9, 1.9)",
        "low": "9/10 (3.1, 2.7, 6.6)",
        "high": "8/10 (1.9, 2.7, 6.6)",
    },
    ("koopman-nmpc", "map2"): {
        "nominal": "10/10 (2.8, 1.8, 2.3)",
        "low": "9/10 (5.0, 2.4, 6.4)",
        "high": "6/10 (4.9, 2.6, 4.8)",
    },
    ("nominal-nmpc", "map1"): {
        "nominal": "10/10 (1.8, 1.5, 15.6)",
        "low": "8/10 (1.3, 1.8, 3.5)",
        "high": "3/10 (1.1, 2.4, 4.0)",
    },
    ("nominal-nmpc", "map2"): {"nominal": "0/10", "low": "1/10 (2.4, 0.5, 3.4)", "high": "0/10"},
    ("koopman-nmpc", "map3"): {
        "nominal": "10/10 (0.9, 1.9, 1.9)",
        "low": "9/10 (1.7, 4.5, 3.9)",
        "high": "8/10 (1.7, 2.4, 1.1)",
    },
    ("koopman-nmpc", "map4"): {
        "nominal": "10/10 (2.5, 7.0, 7.5)",
        "low": "8/10 (2.6, 8.4, 9.6)",
        "high": "8/10 (3.0, 6.6, 13.5)",
    },
    ("nominal-nmpc", "map3"): {"nominal": "10/10 (0.5, 1.0, 1.1)", "low": "0/10", "high": "0/10"},
    ("nominal-nmpc", "map4"): {
        "nominal": "10/10 (1.7, 4.1, 3.8)",
        "low": "4/10 (2.0, 3.7, 8.6)",
        "high": "0/10",
    },
    ("consensus", "map3"): {
        "nominal": "10/10 (4.1, 76.3, 45.1)",
        "low": "9/10 (4.1, 148.3, 50.3)",
        "high": "9/10 (4.1, 158.3, 51.0)",
    },
    ("consensus", "map4"): {
        "nominal": "10/10 (7.4, 71.4, 82.6)",
        "low": "10/10 (7.4, 69.5, 113.2)",
        "high": "7/10 (7.4, 69.8, 90.9)",
    },
}
#: (title, env id, controller label) of each per-cell table, in page order
TABLES = [
    ("Table 1: Koopman-NMPC, target reaching", "KoopNav-TargetReaching-v0", "koopman-nmpc"),
    ("Table 2: nominal NMPC, target reaching", "KoopNav-TargetReaching-v0", "nominal-nmpc"),
    ("Table 3: Koopman-NMPC, formation", "KoopNav-Formation-v0", "koopman-nmpc"),
    ("Table 4: nominal NMPC, formation", "KoopNav-Formation-v0", "nominal-nmpc"),
    ("Table 5: consensus (collision avoidance on), formation", "KoopNav-Formation-v0", "consensus"),
]
#: the paper's control logic (no estimator, no stall resolution) in our soft-constrained NMPC, beside
#: Tables 1-4 (the paper's controllers exactly are ``--paper-strict``'s: evaluation.experiments.protocols.PAPER_EXACT)
PAPER_VARIANT = "-paper"
#: the rows not in the paper: (what, controller label), each for both tasks
EXTRA_TABLES = [
    ("consensus", "consensus"),
    ("RL baseline (rl-ppo)", "rl-ppo"),
    ("set-policy RL baseline (rl-ppo-set)", "rl-ppo-set"),
    ("classic baseline ORCA (orca)", "orca"),
    ("classic baseline DWA (dwa)", "dwa"),
    ("MPC with control barrier constraints (mpc-cbf)", "mpc-cbf"),
    ("multi-agent RL baseline, BenchMARL's IPPO (ippo)", "ippo"),
]
TASKS = {"KoopNav-TargetReaching-v0": "target reaching", "KoopNav-Formation-v0": "formation"}
#: the regenerate command of a run, and the pool of several (tests/test_results_page.py reads the first)
_command = evaluate_command
pool = pooled_results


def load_results(path: str) -> dict:
    """A run's results document: a ``results.json`` (read checked, :func:`load_baseline`), or a
    published archive (``data/NAME.tar.xz``, :mod:`evaluation.reports.published`) whose episode log is
    read back checked; its episodes each once, a conflicting repeat refused by name. The
    document's ``source`` is ``path``, for the messages of :func:`pool`."""
    if not path.endswith(".json"):  # a published archive (refused by name if it is not one)
        with extracted_archive(path) as run:
            doc = json.loads(results_from_log(run / "episodes.jsonl").to_json())
    else:
        doc = load_baseline(path, what="results")
    return {**doc, "source": path}


def all_tables() -> list[tuple[str, str, str]]:
    """Every per-cell table of the page: the paper's five, each NMPC's paper variant, the rest."""
    out = list(TABLES)
    for title, env_id, controller in TABLES[:4]:
        out.append(
            (
                f"{title.split(':')[0]}, the paper's control logic (`{controller}{PAPER_VARIANT}`: "
                "no estimator, no stall resolution; soft constraints)",
                env_id,
                controller + PAPER_VARIANT,
            )
        )
    for what, controller in EXTRA_TABLES:
        for env_id, task in TASKS.items():
            if (env_id, controller) != ("KoopNav-Formation-v0", "consensus"):  # Table 5
                out.append((f"Not in the paper: {what}, {task}", env_id, controller))
    return out


def _ci(ci: list) -> str:
    return f"[{100 * ci[0]:.0f}-{100 * ci[1]:.0f}%]" if ci and ci[0] is not None else ""


def _dist(summary: dict) -> str:
    if not summary["runs"]:
        return "-"
    parts = []
    for mean, sd in summary["per_robot"]:
        parts.append(
            "-" if mean is None else (f"{mean:.1f}" if summary["runs"] == 1 else f"{mean:.1f}+-{sd:.1f}")
        )
    return ", ".join(parts)


def _team(summary: dict) -> str:
    if not summary["runs"] or summary["team_mean"] is None:
        return "-"
    return f"{summary['team_mean']:.1f} [{summary['team_low']:.1f}-{summary['team_high']:.1f}]"


def table(cells: dict, env_id: str, controller: str) -> list[str]:
    rows = [k for k in cells if k[0] == env_id and k[1] == controller]
    if not rows:
        return []
    lines = [
        "| Map | Slip | Success [95% CI] | SR [95% CI] | Robots 1-3, collision-free runs [cm] | "
        "Team, collision-free [cm] | Team, settled [cm] | Paper: SR (distances) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for key in rows:
        c = cells[key]
        valid = c["episodes"] - c["errors"]
        free, settled = c["final_distance_cm"]["collision_free"], c["final_distance_cm"]["settled"]
        paper = PAPER.get((controller.removesuffix(PAPER_VARIANT), key[2]), {}).get(key[3], "-")
        lines.append(
            f"| {key[2]} | {key[3]} | {c['successes']}/{valid} {_ci(c['success_ci'])} | "
            f"{c['collision_free']}/{valid} {_ci(c['collision_free_ci'])} | {_dist(free)} | {_team(free)} | "
            f"{_team(settled)} | {paper} |"
        )
    return lines


def _power_lines(pooled: Results) -> list[str]:
    """The power statement below a paired table (:func:`evaluation.reports.sections.paired_power_note`)."""
    return [] if (note := power_note(pooled)) is None else [note, ""]


def uncertainty_section(docs: list[dict]) -> list[str]:
    """The changing-uncertainty results (not in the paper): per group of runs over the same cells
    (a run and its ablation run, say), a leaderboard, paired comparisons and per-cell tables."""
    lines = [
        "## Changing uncertainty: slip zones, drifting and random slip (not in the paper)",
        "",
        "Maps 5 and 6 put a high-slip zone across the shortest route; `drift` redraws every robot's slip "
        "level at random times within the episode, `random` draws one level per episode "
        "([Slip](environments.md#slip), [Maps](environments.md#maps)). Same seeds for every controller "
        "in a group of cells, so the comparisons are paired; same calibration offer as above; no controller "
        "is told the slip, the zones or the "
        "schedule. Solve times come from runs made at different times on a shared 2-core machine (some "
        "beside other evaluations): compare them within one run, not across the rows of a pooled table. "
        "Runtime uncertainty beyond slip (localization noise, a lossy and late radio, actuation delay, "
        "lidar) has its own page: [Robustness results](robustness_results.md).",
        "",
    ]
    groups: dict[tuple, list[dict]] = {}
    for d in docs:
        key = tuple(sorted({(c["env_id"], c["map"], c["slip"]) for c in d["cells"]}))
        groups.setdefault(key, []).append(d)
    for key, members in groups.items():
        pooled = pool(members)
        seeds = max(c.episodes for c in pooled.cells)
        title = "; ".join(f"{task_label(env_id)} {m}, slip {slip}" for env_id, m, slip in key)
        lines += [
            f"### {title} ({seeds} seeds per cell)",
            "",
            "Regenerate: " + "; ".join(f"`{_command(d['config'])}`" for d in members) + ".",
            "",
            pooled.leaderboard_table(),
            "",
            "Paired comparisons (shared map, slip and seed; Newcombe's 95% interval, exact McNemar test):",
            "",
            markdown_table(paired_rows(pooled)),
            "",
            *_power_lines(pooled),
        ]
        for caption, table in controller_tables(pooled):
            lines += [f"**{caption}**", "", markdown_table(table), ""]
    return lines


def scaling_section(docs: list[dict]) -> list[str]:
    """Success, distances and decision time as the team grows: one run per team size N (its
    ``--env-kwargs n_robots=N``), one row per controller and N."""
    lines = [
        "## Scaling with the team size (not in the paper)",
        "",
        "Target reaching on seeded random maps (a new layout per seed: 4 obstacles, the team in a wedge "
        "and its targets the same wedge elsewhere; the generator's defaults), nominal slip, the same seeds "
        "for every controller at a given N, starts perturbed by 5 cm. The NMPCs run their default, the "
        "real-time iteration (nothing compiled). "
        "Solve times are each controller's decision time per control step (median and 95th percentile "
        "over every step of the cell) against the 100 ms control period; the machine has 2 cores, and "
        "other evaluations ran beside these ones. Seeds per N and the time limit of each run (600 periods unless "
        "the command says otherwise) are in the commands below; a collision or the time limit ends an episode "
        "as a failure.",
        "",
    ]
    lines += [
        "| N | Controller | Success [95% CI] | Collision-free [95% CI] | Team final dist., settled [cm] | "
        "Time to goal [s] | Decision median / p95 [ms] | Solver failures | Errors |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    commands = []
    ran: dict[int, set[str]] = {}
    for d in docs:
        ran.setdefault(d["config"]["env_settings"].get("n_robots", 3), set()).update(
            c["controller"] for c in d["cells"]
        )
    everyone = set().union(*ran.values())
    for d in sorted(docs, key=lambda d: d["config"]["env_settings"].get("n_robots", 3)):
        n = d["config"]["env_settings"].get("n_robots", 3)
        commands.append(f"`{_command(d['config'])}`")
        for c in d["cells"]:
            valid = c["episodes"] - c["errors"]
            settled = c["final_distance_cm"]["settled"]
            ttg = "-" if c.get("time_to_goal_s") is None else f"{c['time_to_goal_s']:.1f}"
            solve = (
                "-"
                if c["solve_ms_median"] is None
                else f"{c['solve_ms_median']:.1f} / {c['solve_ms_p95']:.1f}"
            )
            lines.append(
                f"| {n} | {c['controller']} | {c['successes']}/{valid} {_ci(c['success_ci'])} | "
                f"{c['collision_free']}/{valid} {_ci(c['collision_free_ci'])} | {_team(settled)} | {ttg} | "
                f"{solve} | {c['solver_failures']} | {c['errors']} |"
            )
    lines.append("")
    for n, names in sorted(ran.items()):
        if everyone - names:
            lines.append(
                f"Not in this table at N = {n}: {', '.join(sorted(everyone - names))} "
                "([Results with larger teams](paper.md#results-with-larger-teams) says why)."
            )
    lines += ["", "Regenerate: " + "; ".join(commands) + ".", ""]
    lines += [DISTRIBUTED_NOTE, ""]
    return lines


#: the distributed NMPC's scaling run (bench/scaling.py, whole episodes over 20 seeds per N)
DISTRIBUTED_NOTE = (
    "The distributed NMPC (`dmpc-nominal`: every robot its own NMPC, the others' plans as moving "
    "obstacles) on the same kind of maps, 20 seeds per N: 20/20 successes at N = 3, 6, 10 and 16 "
    "(16 robots: 15.1 ms median, 17.9 ms p95 per step), 18/20 at 24 and 32 (grid layouts), about 1 ms "
    "per robot at every N (the Koopman variants: 20/20 up to 16 robots, 17/20 at 24, 18/20 at 32, "
    "about 1.1 ms per robot); at 8 robots paired with the central nominal NMPC on 20 layouts, 20/20 vs "
    "15/20 (+25 points [+4, +47], McNemar p = 0.062). Table and commands: "
    "[Performance](performance.md#distributed-nmpc-3-to-32-robots)."
)


def _header(doc: dict) -> list[str]:
    budget = doc["config"]["calibration"]["budget"]
    noise = doc["config"].get("env_settings", {}).get("start_noise", 0.0)
    # the solver each NMPC record names (the protocol's, or --solver's)
    solvers = sorted({(r.get("controller_extra") or {}).get("solver") for r in doc["episodes"]} - {None})
    solver = ", ".join(f"`{s}`" for s in solvers) or "each controller's default"
    return [
        "# Paper protocol results",
        "",
        "Rebuilt from the committed episode logs (`data/*.tar.xz`) by `python docs/make_pages.py docs/results.md` "
        "(`docs/make_results_md.py` with the arguments listed in `data/pages.json`), byte for byte (`tests/test_published_pages.py`); "
        "the runs: `bash data/publish.sh paper` and the other runs its arguments name "
        "(`data/publish.sh` holds each run's evaluator command; resumable with `--resume`). "
        f"Package {doc['package_version']}.",
        "",
        "Protocol (SPEC section 5): 3 robots, maps 1-2 (target reaching) and 3-4 (formation), the three "
        f"slip settings, 10 trials per cell, trial i seeded i, the NMPCs solved by {solver}. Starts are "
        f"perturbed by up to {100 * noise:.0f} cm and {noise} rad (seeded), so the ten trials of a cell are "
        "ten distinct episodes even at nominal slip (the paper's exact starts made them one episode ten "
        "times); every controller meets the same starts and slip draws, so comparisons are paired. Every "
        "controller was offered the same calibration: the env's robots in an open field (slip means "
        f"hidden), {budget:,} team-transitions, seed 0. The evaluator hands no controller the slip setting.",
        "",
        "Tables 1-4 are the NMPCs as KoopNav ships them (the estimator front-end, a no-op here without "
        "localization noise or delay, and the stall resolution, [controllers](controllers.md)); the "
        "tables marked *the paper's control logic* run the NMPC without our front-end and stall "
        "resolution (`estimator=none, unstall=false`) on the same episodes, still with our soft "
        "constraints and our 0.015 m margin between robots: the paper's controllers exactly (hard "
        "constraints, no margin between robots) are `--paper-strict`'s, "
        "[below](#the-papers-exact-formulation).",
        "",
        "*Success*: every robot settled within 0.1 m of its target for 2 s without collision. *SR*: the "
        "paper's success rate (runs without collision). k/n with the 95% Wilson interval. Final distances "
        "per robot [cm], mean+-SD over the collision-free runs (the paper's convention, comparable with its "
        "column); *team*: mean over robots per run, then mean over runs with its 95% bootstrap interval, "
        "over collision-free runs and over settled runs. Ten trials per cell give wide intervals: a "
        "10/10 cell is compatible with a true rate of 72%. The paper's maps are not published, so ours are "
        "our own designs (SPEC section 5) and only the shape of the results is comparable.",
        "",
    ]


def _unequal_data(doc: dict) -> list[str]:
    budget = doc["config"]["calibration"]["budget"]
    metas = {task: POLICIES / task / "metadata.json" for task in ("target_reaching", "formation")}
    steps = {task: json.loads(meta.read_text())["timesteps"] for task, meta in metas.items() if meta.exists()}
    budgets = [f"{task.replace('_', ' ')} {n:,}" for task, n in steps.items()]
    if not steps:
        return []
    return [
        "**Unequal data, disclosed.** `rl-ppo` does not calibrate: its policies were trained beforehand on random "
        "maps with random slip levels, never on the paper maps (checkpoints chosen on held-out random layouts), "
        "with " + " and ".join(budgets) + " team-transitions in the task itself, "
        f"{min(steps.values()) / budget:.0f}-{max(steps.values()) / budget:.0f} times the {budget:,} open-field transitions the "
        "calibrating controllers may use; `rl-ppo-set` and `ippo` likewise ([RL baselines](rl.md)): the policies "
        f"of their rows, now `rl-ppo-set-v0` ({robot_steps('set_v0')}) and `ippo-v0` ({robot_steps('ippo_v0')}), "
        "robot-steps on random layouts. Their rows compare trained policies with model-based controllers; they "
        "are not an equal-data comparison. `orca` and `dwa` use no data; their settings were chosen on seeds 0-2 "
        "of the paper maps, which are also trials 0-2 here ([controllers](controllers.md#classic-baselines-orca-and-dwa)).",
        "",
    ]


def _pooled_sections(pooled: Results, figures: Path, out: Path) -> list[str]:
    lines = [
        "## Leaderboard (paper protocol, pooled over maps and slip levels)",
        "",
        "Ranked by success rate; 95% intervals (the wider of Wilson's and a cluster bootstrap over "
        "trials); final distance: team mean over settled runs with its 95% bootstrap interval.",
        "",
        pooled.leaderboard_table(),
        "",
    ]
    for path in save_success_figures(pooled, figures, prefix="paper_"):
        link = os.path.relpath(path, out.resolve().parent)
        lines += [f"![success rate by slip setting, {task_label(path.stem.rsplit('_', 1)[-1])}]({link})", ""]
    lines += [
        "## Paired comparisons (paper protocol)",
        "",
        "Pooled over each task's maps and slip levels; pairs share map, slip and seed. Difference of "
        "success rates with Newcombe's 95% interval for paired proportions; exact McNemar test, and its "
        "p-value Holm-corrected over every distinct test of the table (both tasks; a bit-identical "
        "twin's test counted once).",
        "",
        markdown_table(paired_rows(pooled)),
        "",
        *_power_lines(pooled),
    ]
    return lines


def _strict_section(path: str | None) -> list[str]:
    if not path:
        return [
            "## The paper's exact formulation",
            "",
            "Not run for this page: with hard constraints and the paper's margins the NMPCs hit IPOPT's "
            "iteration limit at many steps (about 0.4 s median per step and 162 solver failures in one "
            "Map 1 nominal episode of Koopman-NMPC on the 2-core machine, about 3 minutes per episode), so "
            "the full 360-episode `--paper-strict` protocol takes hours. The closest measured is the "
            "ablation's row *paper margins, hard constraints* (20 seeds per map, high slip; it keeps "
            "our stall resolution and margin between robots); why it fails: "
            "[hard_constraints.md](hard_constraints.md).",
            "",
        ]
    strict = load_results(path)
    scells = {(c["env_id"], c["controller"], c["map"], c["slip"]): c for c in strict["cells"]}
    lines = ["## The paper's exact formulation (`--paper-strict`: hard constraints, IPOPT, no estimator)", ""]
    for title, env_id, controller in TABLES[:4]:
        rows = table(scells, env_id, controller)
        if rows:
            lines += [f"### {title}", "", *rows, ""]
    failures: dict[str, int] = {}
    for c in strict["cells"]:
        failures[c["controller"]] = failures.get(c["controller"], 0) + c["solver_failures"]
    return lines + [
        "Solver failures over the strict run: " + ", ".join(f"{k} {v}" for k, v in failures.items()),
        "",
    ]


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument(
        "results", nargs="+", help="results.json files or published archives (data/NAME.tar.xz)"
    )
    parser.add_argument("--strict", help="results of `python evaluate.py --paper-strict`")
    parser.add_argument("--ablation", help="docs/ablation.md to link")
    parser.add_argument(
        "--uncertainty",
        nargs="+",
        default=[],
        help="results of the changing-uncertainty runs (slip zones, drift, random slip)",
    )
    parser.add_argument(
        "--scaling",
        nargs="+",
        default=[],
        help="results of the team-size runs (one per --env-kwargs n_robots=N)",
    )
    parser.add_argument(
        "--intro", type=Path, help="a Markdown file placed after the protocol (what the tables say)"
    )
    parser.add_argument(
        "--notes", type=Path, help="a Markdown file appended to the page (hand-written sections)"
    )
    parser.add_argument("--figures", help="where figures go (default: _static beside --out)")
    # no default page: the published one is a tracked file (docs/make_pages.py names it)
    parser.add_argument("--out", required=True, help="the page to write, e.g. docs/results.md")
    args = parser.parse_args()
    docs = [load_results(path) for path in args.results]
    doc = docs[0]
    cells = {(c["env_id"], c["controller"], c["map"], c["slip"]): c for d in docs for c in d["cells"]}
    lines = _header(doc) + _unequal_data(doc)
    # the intro and the notes are templates whose numbers are filled from every archive the page
    # reads (docs/make_prose_md.py; imported here: prose_tables imports this module)
    from make_prose_md import expand_template

    archives = [a for a in (*args.results, *args.uncertainty, *args.scaling) if a.endswith(".tar.xz")]
    if args.intro:
        lines += [expand_template(args.intro, archives).strip(), ""]
    for title, env_id, controller in all_tables():
        rows = table(cells, env_id, controller)
        if rows:
            lines += [f"## {title}", "", *rows, ""]
    # all files' episodes in one Results: every controller is paired with every other on the
    # shared (map, slip, seed) episodes, also across separate runs of the same protocol
    pooled = pool(docs)
    figures = Path(args.figures) if args.figures else Path(args.out).parent / "_static"
    lines += _pooled_sections(pooled, figures, Path(args.out))
    lines += _strict_section(args.strict)
    if args.ablation:
        lines += [
            "## Ablation",
            "",
            f"See [ablation.md]({Path(args.ablation).name}): which of learned model, "
            "widened margins and soft constraints decides the outcome under high slip.",
            "",
        ]
    if args.uncertainty:
        lines += uncertainty_section([load_results(path) for path in args.uncertainty])
    if args.scaling:
        lines += scaling_section([load_results(path) for path in args.scaling])
    if args.notes:
        lines += [expand_template(args.notes, archives).strip(), ""]
    write_atomic(args.out, "\n".join(lines) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    try:
        main()
    except ValueError as exc:  # a results file that is not as KoopNav writes it (the message names it)
        print(f"error: {exc}", file=sys.stderr)
        raise SystemExit(BAD_INPUT_EXIT) from None
