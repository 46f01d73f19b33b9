"""KoopNav evaluator: run every controller on every cell, report success rates and final distances.

``python evaluate.py`` runs the quick default leaderboard (both tasks, their paper maps under
high slip, every registered controller, 2 episodes per cell from perturbed starts, the NMPCs on
the real-time iteration), prints a compact leaderboard and writes the full report (Markdown,
JSON, CSV, HTML, figures) to ``results/``. ``python evaluate.py --paper`` runs the paper's
protocol (SPEC section 5: 10 trials per cell) and prints tables 1-5. From Python::

    from evaluation import RunSpec, evaluate
    spec = RunSpec(envs="KoopNav-Formation-v0", controllers=["koopman-nmpc", "consensus"], maps=["map3"],
                   slips=["nominal", "high"], episodes=5, seed=0)
    print(evaluate(spec).to_markdown())

This file is the command line; the work is done by the ``evaluation`` package, one job per
module: ``spec`` (``RunSpec``: the run, its checks and its episodes), ``plan`` (one episode), ``worker`` (one episode), ``backends``
(process pool, Ray, progress, Ctrl-C), ``runlog`` (the resumable log), ``runner``
(``evaluate``), ``aggregate`` and ``statistics`` (cells, intervals, paired comparisons),
``results`` and ``html`` (reports, figures, the leaderboard page), ``protocols``,
``thresholds`` and ``ablation``.

Episodes run in worker processes; each episode's seed depends only on the base seed and its
index in the cell, so results do not depend on the worker count. Each finished episode is
appended to ``OUT/episodes.jsonl`` at once; ``--resume`` continues an interrupted run. An
episode that raises is recorded with its error, the others go on, and the exit code is the
number of failed episodes (capped at 100); a failed ``--check`` exits with 101.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import sys
import threading
import time
from pathlib import Path
from typing import Any

import controllers
from controllers.mpc.config import SOLVERS
from evaluation.ablation import ablation_markdown, check_factors
from evaluation.aggregate import Cell
from evaluation.backends import RunInterrupted
from evaluation.badge import write_badge
from evaluation.baseline import (
    GateOptions,
    compare_runs,
    comparison_markdown,
    gate_failures,
    load_baseline,
    refuse_incomparable,
)
from evaluation.configs import split_controller_list
from evaluation.plan import EpisodeSpec
from evaluation.protocols import (
    QUICK_START_NOISE,
    TASK_MAPS,
    ablation_protocol,
    paper_protocol,
    quick_protocol,
)
from evaluation.records import DEGRADED_FAILURE_SHARE, is_degraded, json_safe
from evaluation.results import SCHEMA_VERSION, Results
from evaluation.runner import evaluate, usable_controllers
from evaluation.slip_text import split_slips
from evaluation.spec import RunSpec
from evaluation.thresholds import check_thresholds
from koopman_envs.params import PARAMS, SLIP_NAMES
from koopman_envs.suggest import did_you_mean

__all__ = [
    "Cell",
    "EpisodeSpec",
    "Results",
    "RunInterrupted",
    "RunSpec",
    "SCHEMA_VERSION",
    "check_thresholds",
    "evaluate",
    "main",
    "paper_protocol",
    "quick_protocol",
    "usable_controllers",
]

FAILED_CHECK_EXIT = 101
FAILED_GATE_EXIT = 102  # --fail-if-worse: a controller significantly worse than the baseline
INTERRUPTED_EXIT = 130  # the shell's code for a run stopped by Ctrl-C (128 + SIGINT)


# --------------------------------------------------------------------------- list arguments
def split_words(words: list[str] | None) -> list[str] | None:
    """``["a,b", "c"]`` -> ``["a", "b", "c"]``: comma-separated lists work like spaced ones."""
    if words is None:
        return None
    return [piece.strip() for word in words for piece in word.split(",") if piece.strip()]


def parse_env_kwargs(words: list[str] | None) -> dict[str, Any]:
    """``["n_robots=5", "goal_tolerance=0.05"]`` -> dict (values parsed as JSON, else text)."""
    kwargs: dict[str, Any] = {}
    for word in words or []:
        key, eq, value = word.partition("=")
        if not eq or not key.strip().isidentifier():
            raise ValueError(f"--env-kwargs {word!r} is not key=value (a Python identifier as key)")
        try:
            kwargs[key.strip()] = json.loads(value)
        except json.JSONDecodeError:
            kwargs[key.strip()] = value
    return kwargs


# --------------------------------------------------------------------------- CLI
#: exit codes of the command line, as ``--help`` lists them
EXIT_CODES = (
    ("0", "every episode ran (and --check, if given, passed)"),
    ("1-100", "that many episodes raised (capped at 100); the others' results are written"),
    ("2", "bad input (named on stderr) before any episode ran"),
    (str(FAILED_CHECK_EXIT), "a --check threshold failed"),
    (str(FAILED_GATE_EXIT), "--fail-if-worse: a controller is significantly worse than the --baseline"),
    (str(INTERRUPTED_EXIT), "interrupted (Ctrl-C or SIGTERM); continue with --resume"),
)


def program_name() -> str:
    """How the user called the evaluator: ``koopnav-evaluate`` (the installed script) or
    ``python evaluate.py``, for usage lines and resume hints."""
    invoked = Path(sys.argv[0]).name if sys.argv and sys.argv[0] else ""
    return "koopnav-evaluate" if invoked.startswith("koopnav-evaluate") else "python evaluate.py"


def _parser() -> argparse.ArgumentParser:
    epilog = "exit codes:\n" + "\n".join(f"  {code:<6} {meaning}" for code, meaning in EXIT_CODES)
    parser = argparse.ArgumentParser(
        prog=program_name(),
        description=__doc__.split("\n")[0],
        epilog=epilog,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    what = parser.add_argument_group("what to run")
    what.add_argument(
        "--env",
        "--envs",
        dest="env",
        nargs="+",
        metavar="ENV_ID",
        help=f"environment ids (default: {' '.join(TASK_MAPS)})",
    )
    what.add_argument(
        "--maps",
        nargs="+",
        metavar="MAP",
        help="maps: shipped names, random, or paths of JSON map files (default: each task's paper "
        "maps: map1 map2 / map3 map4)",
    )
    what.add_argument(
        "--random-maps",
        type=int,
        metavar="K",
        help="add a 'random' map row with K seeded layouts per cell, the same for every controller "
        "(default: none)",
    )
    what.add_argument(
        "--slips",
        nargs="+",
        metavar="SLIP",
        help=f"{' '.join(SLIP_NAMES)}, or per-robot lambdas like 0,0.1,0.2, one setting per word "
        "(default: high; all three levels with --paper)",
    )
    what.add_argument(
        "--episodes",
        type=int,
        metavar="N",
        help="trials per cell (default 2; 10 with --paper, 20 with --ablation)",
    )
    what.add_argument(
        "--seed", type=int, default=0, help="base seed; trial i of a cell uses seed + i (default 0)"
    )
    protocol = what.add_mutually_exclusive_group()
    protocol.add_argument("--paper", action="store_true", help="the paper's protocol (SPEC section 5), IPOPT")
    protocol.add_argument(
        "--paper-strict",
        action="store_true",
        help="the paper's protocol with its exact NMPC: hard constraints, 0.015 m margins",
    )
    protocol.add_argument(
        "--ablation",
        nargs="*",
        metavar="FACTOR",
        help="ablation of the NMPC's design factors (default all: model margins constraints) on the "
        "paper maps under high slip; writes --ablation-out",
    )

    env = parser.add_argument_group("env settings")
    env.add_argument(
        "--tolerance", type=float, metavar="M", help=f"goal tolerance [m] (default {PARAMS.goal_tolerance})"
    )
    env.add_argument(
        "--max-episode-steps",
        type=int,
        metavar="T",
        help=f"time limit [control periods] (default {PARAMS.max_episode_steps})",
    )
    env.add_argument(
        "--start-noise",
        type=float,
        metavar="R",
        help=f"seeded start perturbation [m, rad] (default {QUICK_START_NOISE}; 0 with --paper and "
        "--ablation, which keep the maps' starts)",
    )
    env.add_argument(
        "--env-kwargs",
        nargs="+",
        metavar="KEY=VALUE",
        help="further env keywords for every episode, e.g. n_robots=5 goal_tolerance=0.05 (values "
        "parsed as JSON; default: none)",
    )

    ctrl = parser.add_argument_group("controllers")
    ctrl.add_argument(
        "--controllers",
        nargs="+",
        metavar="NAME[:KEY=VALUE,...]",
        help=f"controller configurations (default: every registered one: "
        f"{' '.join(controllers.available())})",
    )
    ctrl.add_argument(
        "--solver",
        choices=list(SOLVERS),
        help="optimizer of every NMPC configuration that does not name its own: rti (real-time "
        "iteration, one structured QP per period), ipopt (the paper's, solved to convergence) or "
        "fatrop (default: rti for the quick leaderboard's own controllers, ipopt with --paper, "
        "--paper-strict, --ablation, else each controller's own: ipopt)",
    )
    ctrl.add_argument(
        "--calibration-budget",
        type=int,
        default=PARAMS.calibration_budget,
        metavar="N",
        help=f"team-transitions every controller may simulate to calibrate (default: the paper's "
        f"{PARAMS.calibration_budget:,})",
    )
    ctrl.add_argument(
        "--calibration-seed",
        type=int,
        default=0,
        metavar="S",
        help="seed of the calibration plant and data (default 0)",
    )

    output = parser.add_argument_group("output")
    output.add_argument("--out", default="results", help="output directory (default: results)")
    output.add_argument(
        "--full-report",
        action="store_true",
        help="print the whole Markdown report (paired comparisons, per-cell tables) instead of the "
        "compact leaderboard; the files always hold it",
    )
    output.add_argument(
        "--gifs", action="store_true", help="record trial 0 of every cell as OUT/animations/*.gif"
    )
    output.add_argument(
        "--ablation-out",
        default=str(Path(__file__).parent / "docs" / "ablation.md"),
        help="where --ablation writes its report (default: docs/ablation.md)",
    )
    output.add_argument("--quiet", action="store_true", help="no progress bar")
    output.add_argument(
        "--badge",
        metavar="CONTROLLER",
        help="write OUT/badge.svg: CONTROLLER's success rate over the run with its 95%% interval, "
        "for a README (default: no badge)",
    )

    run = parser.add_argument_group("execution")
    run.add_argument("--workers", type=int, metavar="N", help="worker processes (default: all cores)")
    run.add_argument(
        "--backend",
        choices=["process", "ray"],
        default="process",
        help="process pool or a Ray cluster (default: process)",
    )
    run.add_argument("--resume", action="store_true", help="continue the run logged in --out")

    ci = parser.add_argument_group("CI")
    ci.add_argument(
        "--check",
        metavar="THRESHOLDS",
        help=f"TOML thresholds; exit {FAILED_CHECK_EXIT} if a cell falls below (default: no check)",
    )
    ci.add_argument(
        "--strict",
        action="store_true",
        help="with --check: a rule whose controller cannot be built here (an optional extra not "
        "installed) fails instead of being skipped",
    )
    ci.add_argument(
        "--baseline",
        metavar="BASE",
        help="results.json (or run directory) of an earlier run: pair every episode with its episode "
        "of the same env, controller, map, slip and seed and report the differences (default: none)",
    )
    ci.add_argument(
        "--fail-if-worse",
        action="store_true",
        help=f"with --baseline: exit {FAILED_GATE_EXIT} when a controller's success drops by more than "
        "--delta with McNemar p < --alpha, or its final distance grows by more than --delta-cm "
        "with a bootstrap interval above 0",
    )
    defaults = GateOptions()
    ci.add_argument(
        "--alpha",
        type=float,
        default=defaults.alpha,
        help=f"significance level of the gate, in (0, 1) (default {defaults.alpha})",
    )
    ci.add_argument(
        "--delta",
        type=float,
        default=defaults.delta,
        help=f"success-rate drop the gate cares about, >= 0 (default {defaults.delta}: "
        f"{100 * defaults.delta:.0f} points)",
    )
    ci.add_argument(
        "--delta-cm",
        type=float,
        default=defaults.delta_cm,
        help=f"final-distance increase the gate cares about [cm], >= 0 (default {defaults.delta_cm})",
    )
    return parser


def _stop_on_sigterm(signum: int, frame: Any) -> None:
    """SIGTERM (``kill``, a CI timeout) stops a run like Ctrl-C: the worker pool is terminated
    (no orphan workers keep computing) and the log stays resumable."""
    raise KeyboardInterrupt


def _spec_from_args(args: argparse.Namespace) -> RunSpec:
    """The run the command line asks for: a protocol preset with the given options replacing its fields."""
    if args.ablation is not None:
        spec = ablation_protocol(check_factors(args.ablation))
    elif args.paper or args.paper_strict:
        spec = paper_protocol(strict=args.paper_strict)
    else:
        spec = quick_protocol()
    changes: dict[str, Any] = {}
    if args.env:
        changes["envs"] = split_words(args.env)
    if args.maps:
        changes["maps"] = split_words(args.maps)
    if args.controllers:
        # a protocol's solver goes with its own controller list; controllers named on the command
        # line keep their own defaults unless --solver says otherwise
        changes.update(controllers=split_controller_list(args.controllers), solver=None)
    if args.solver:
        changes["solver"] = args.solver
    if args.slips:
        changes["slips"] = split_slips(args.slips)
    if args.episodes is not None:
        changes["episodes"] = args.episodes
    # the env settings: the preset's, then the dedicated options, then --env-kwargs (which win)
    env_kwargs = dict(spec.env_kwargs)
    for option, keyword in (
        ("tolerance", "goal_tolerance"),
        ("max_episode_steps", "max_episode_steps"),
        ("start_noise", "start_noise"),
    ):
        if getattr(args, option) is not None:
            env_kwargs[keyword] = getattr(args, option)
    env_kwargs.update(parse_env_kwargs(args.env_kwargs))
    return spec.replace(
        **changes,
        env_kwargs=env_kwargs,
        seed=args.seed,
        calibration_budget=args.calibration_budget,
        calibration_seed=args.calibration_seed,
        random_maps=args.random_maps,
        gifs=args.gifs,
    )


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, _stop_on_sigterm)
    try:
        spec = _spec_from_args(args)
        baseline = load_baseline(args.baseline) if args.baseline else None
        gate = GateOptions(args.alpha, args.delta, args.delta_cm)
        if args.fail_if_worse and baseline is None:
            raise ValueError(
                "--fail-if-worse needs --baseline BASE (an earlier run's results.json or directory)"
            )

        def config_check(config: dict[str, Any]) -> None:
            """What needs the run's configuration, checked before any episode."""
            import koopman_envs

            if baseline is not None:
                refuse_incomparable(config, koopman_envs.__version__, baseline)
            if args.badge and args.badge not in config["controllers"]:
                raise ValueError(
                    f"--badge {args.badge!r} is not a controller of this run; it runs "
                    f"{config['controllers']}{did_you_mean(args.badge, config['controllers'])}"
                )

        start = time.perf_counter()
        results = evaluate(
            spec,
            workers=args.workers,
            backend=args.backend,
            out=args.out,
            resume=args.resume,
            progress=not args.quiet,
            config_check=config_check,
        )
        wall = time.perf_counter() - start
        results.config["wall_seconds"] = wall
        paths = results.write(args.out)
        if args.badge:
            paths["badge"] = write_badge(results, args.badge, Path(args.out) / "badge.svg")
        if args.ablation is not None:
            command = "python evaluate.py --ablation " + " ".join(args.ablation) if args.ablation else ""
            command = (command or "python evaluate.py --ablation") + (
                f" --episodes {args.episodes}" if args.episodes else ""
            )
            report = ablation_markdown(results, args.ablation, command=command.strip())
            report += (
                f"\n{len(results.records)} episodes in {wall:.0f} s on {results.config['workers']} workers.\n"
            )
            Path(args.ablation_out).parent.mkdir(parents=True, exist_ok=True)
            Path(args.ablation_out).write_text(report, encoding="utf-8")
            paths["ablation"] = Path(args.ablation_out)
        threshold_check = check_thresholds(results, args.check, strict=args.strict) if args.check else None
        problems = threshold_check.problems if threshold_check else []
        comparison_text, worse = "", []
        if baseline is not None:
            comparison = compare_runs(results.records, baseline["episodes"])
            comparison_text = comparison_markdown(comparison, args.baseline)
            Path(args.out, "baseline_comparison.md").write_text(comparison_text + "\n", encoding="utf-8")
            Path(args.out, "baseline_comparison.json").write_text(
                json.dumps(json_safe(comparison), indent=1) + "\n", encoding="utf-8"
            )
            worse = gate_failures(comparison, gate) if args.fail_if_worse else []
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except RunInterrupted as exc:
        words = list(sys.argv[1:] if argv is None else argv)
        again = " ".join([program_name(), *words, *([] if "--resume" in words else ["--resume"])])
        print(f"\n{exc}; continue with: {again}", file=sys.stderr)
        return INTERRUPTED_EXIT
    print(results.to_markdown() if args.full_report else results.terminal_summary(paths))
    if comparison_text:
        print("\n" + comparison_text)
    summary_file = os.environ.get("GITHUB_STEP_SUMMARY")
    if summary_file:  # a GitHub Actions job summary: appended, never overwritten
        with open(summary_file, "a", encoding="utf-8") as handle:
            handle.write(
                "## KoopNav leaderboard\n\n"
                + results.leaderboard_table()
                + "\n\n"
                + (comparison_text + "\n\n" if comparison_text else "")
            )
    print(
        f"\n{len(results.records)} episodes in {wall:.1f} s; wrote {', '.join(str(p) for p in paths.values())} "
        f"and {Path(args.out) / 'figures'}/"
    )
    failed = results.failed_episodes
    if failed:
        print(f"{len(failed)} episode(s) raised; see {paths['markdown']}", file=sys.stderr)
    degraded = [r for r in results.records if is_degraded(r)]
    if degraded:
        print(
            f"{len(degraded)} episode(s) degraded (solver failed in more than "
            f"{DEGRADED_FAILURE_SHARE:.0%} of their periods); see {paths['markdown']}",
            file=sys.stderr,
        )
    if problems:
        print("threshold check failed:\n" + "\n".join(f"  - {p}" for p in problems), file=sys.stderr)
        return FAILED_CHECK_EXIT
    if worse:
        print("worse than the baseline:\n" + "\n".join(f"  - {w}" for w in worse), file=sys.stderr)
        return FAILED_GATE_EXIT
    if args.fail_if_worse:
        print(f"baseline gate passed ({args.baseline}: no significant loss at alpha {args.alpha})")
    if threshold_check is not None:
        for line in threshold_check.skipped:
            print(f"threshold rule {line}", file=sys.stderr)
        print(f"threshold check passed ({args.check}, floors read as {threshold_check.reading})")
    return min(len(failed), 100)


if __name__ == "__main__":
    raise SystemExit(main())
