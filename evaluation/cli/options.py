"""The evaluator's options (``python evaluate.py``), one function per group, with examples of the
common commands and the exit codes in ``--help`` (:mod:`evaluation.exit_codes`);
:mod:`evaluation.cli.run_args` reads the parsed options into a run."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import controllers
from controllers.mpc.config import NLP_SOLVERS, SOLVERS
from evaluation.episodes.runlog import DEFAULT_OUT
from evaluation.exit_codes import BAD_INPUT_EXIT, FAILED_CHECK_EXIT, FAILED_GATE_EXIT, exit_codes_help
from evaluation.experiments.protocols import QUICK_START_NOISE, TASK_MAPS
from evaluation.experiments.sweep import add_sweep_options
from evaluation.reports.baseline import GateOptions
from evaluation.run.configs import FALLBACK_NONE
from evaluation.run.suite_runs import add_suite_options
from koopman_envs.params import PARAMS, PLANTS, SLIP_NAMES

__all__ = ["EXAMPLES", "build_parser", "program_name"]


def program_name() -> str:
    """How the user called the evaluator: ``koopnav-evaluate`` (the installed script) or
    ``python evaluate.py``, for usage lines and resume hints."""
    invoked = Path(sys.argv[0]).name if sys.argv and sys.argv[0] else ""
    return "koopnav-evaluate" if invoked.startswith("koopnav-evaluate") else "python evaluate.py"


#: the common commands, shown by ``--help``: (the options, what the command does); each parses and
#: makes a run (tests/test_cli.py), and each writes under its ``--out`` unless it names a path
EXAMPLES: tuple[tuple[str, str], ...] = (
    ("", "the quick leaderboard: every controller, both tasks"),
    ("--controllers consensus dwa nominal-nmpc --episodes 10", "three controllers, 10 per cell"),
    ("--env KoopNav-Formation-v0 --maps map3 --slips nominal high", "one task, chosen map and slips"),
    ("--paper --out results_paper", "the paper's protocol: 3 slips, 10 per cell, IPOPT"),
    ("--sweep comm.drop=0,0.2,0.5 --controllers consensus nominal-nmpc", "a robustness profile"),
    ("--out results --resume", "continue an interrupted run"),
    ("--baseline .ci/baseline/results.json --fail-if-worse --episodes 10", "CI: 102 if worse"),
    ("--ablation --out results_ablation", "the ablation (its report: OUT/ablation.md)"),
    ("--options koopman-nmpc", "a controller's options, then exit"),
)


def examples_help() -> str:
    """:data:`EXAMPLES` as the first part of ``--help``'s epilog, each under the program's name."""
    rows = [" ".join(filter(None, [program_name(), options])) for options, _ in EXAMPLES]
    width = min(max(map(len, rows)), 62)  # a longer command pushes its own comment only
    lines = [f"  {row:<{width}}  # {what}" for row, (_, what) in zip(rows, EXAMPLES, strict=True)]
    return "examples:\n" + "\n".join(lines)


def build_parser() -> argparse.ArgumentParser:
    """The evaluator's command line, one argument group per function below."""
    epilog = examples_help() + "\n\n" + exit_codes_help()
    parser = argparse.ArgumentParser(
        prog=program_name(),
        description="KoopNav evaluator: run every controller on every cell, report success rates and final distances.",
        epilog=epilog,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    _what_to_run(parser.add_argument_group("what to run"))
    _env_settings(parser.add_argument_group("env settings"))
    _controller_options(parser.add_argument_group("controllers"))
    _output_options(parser.add_argument_group("output"))
    _execution_options(parser.add_argument_group("execution"))
    _ci_options(parser.add_argument_group("CI"))
    return parser


def _what_to_run(what: argparse._ArgumentGroup) -> None:
    """The "what to run" options."""
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
    add_suite_options(what)
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
        help="trials per cell (default 2; 10 with --paper, 20 with --ablation); with --suite, episodes "
        "per layout (default 1)",
    )
    what.add_argument(
        "--seed", type=int, default=0, help="base seed; trial i of a cell uses seed + i (default 0)"
    )
    add_sweep_options(what)
    _protocols(what.add_mutually_exclusive_group())


def _protocols(protocol: argparse._MutuallyExclusiveGroup) -> None:
    """The named protocols, one at a time."""
    protocol.add_argument("--paper", action="store_true", help="the paper's protocol (SPEC section 5), IPOPT")
    protocol.add_argument(
        "--paper-strict",
        action="store_true",
        help="the paper's protocol with the paper's controllers exactly: hard constraints, IPOPT, no estimator, no stall resolution",
    )
    protocol.add_argument(
        "--crowd",
        metavar="BEHAVIOUR",
        help="navigation among movers: every controller on the paper maps and 20 random layouts, 20 "
        "trials per cell, swept over 0, 4, 8 and 16 movers of BEHAVIOUR (constant, waypoints or "
        "crowd; docs/movers.md) (default: no movers)",
    )
    protocol.add_argument(
        "--lidar",
        action="store_true",
        help="navigating on what the robots see: every controller that perceives, on the paper maps "
        "and 20 random layouts among 4 constant movers, 20 trials per cell, swept over exact state, "
        "the lidar with the map known and the lidar only (docs/perception.md)",
    )
    protocol.add_argument(
        "--ablation",
        nargs="*",
        metavar="FACTOR",
        help="ablation of the NMPC's design factors (default all: model margins constraints) on the "
        "paper maps under high slip; writes --ablation-out",
    )


def _env_settings(env: argparse._ArgumentGroup) -> None:
    """The "env settings" options."""
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
        help=f"seeded start perturbation [m, rad] (default {QUICK_START_NOISE} in every protocol, so "
        "that trials are distinct episodes; 0: the maps' exact starts, as the paper ran them)",
    )
    env.add_argument("--plant", choices=PLANTS, help="kinematic (default) or MuJoCo robots (docs/physics.md)")
    env.add_argument(
        "--env-kwargs",
        nargs="+",
        metavar="KEY=VALUE",
        help="further env keywords for every episode, e.g. n_robots=5 goal_tolerance=0.05 (values "
        "parsed as JSON; default: none)",
    )


def _controller_options(ctrl: argparse._ArgumentGroup) -> None:
    """The "controllers" options."""
    ctrl.add_argument(
        "--controllers",
        nargs="+",
        metavar="NAME[:KEY=VALUE,...]",
        help="controller configurations (default: every registered one but the tuned presets' -v0 "
        f"variants, which run when named: {' '.join(controllers.available(variants=False))})",
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
        "--fallback-solver",
        choices=[*NLP_SOLVERS, FALLBACK_NONE],
        help="NLP rescue of every NMPC configuration that names none, tried when its solver fails "
        "(default: each controller's own, none); none: no rescue, each period keeps its "
        "real-time budget (a real-time iteration's plan with a large slack is used as it is, a "
        "failed QP goes to the rest of the last plan). Under pose noise the rescue runs on up to "
        "one period in three at 0.3-2 s each",
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
    ctrl.add_argument(
        "--options",
        metavar="NAME",
        help="print the options of controller NAME (type, default, allowed values, what each does) and exit",
    )


def _directory(text: str) -> str:
    """``--out``: a directory path; empty text (which would write into the current directory) is
    refused by argparse with this message (exit 2)."""
    if not text.strip():
        raise argparse.ArgumentTypeError(f"{text!r} is empty; name the output directory (default: results)")
    return text


def _output_options(output: argparse._ArgumentGroup) -> None:
    """The "output" options."""
    output.add_argument(
        "--out",
        type=_directory,
        help=f"output directory (default: {DEFAULT_OUT}, or the first free of {DEFAULT_OUT}-2, "
        f"{DEFAULT_OUT}-3, ... when {DEFAULT_OUT} holds an earlier run; with --resume: {DEFAULT_OUT})",
    )
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
        "--realtime",
        action="store_true",
        help="compute-aware episodes: each controller's decision time is charged to its robots (a "
        "command acts from the period boundary after it is ready; longer than the period is a "
        "deadline miss); results then depend on the machine, which the report names",
    )
    output.add_argument(
        "--compute-scale",
        type=float,
        metavar="X",
        help="with compute-aware episodes (implies --realtime): charge X times the measured decision "
        "time, e.g. 5 to emulate an onboard computer five times slower than this one (default: 1 "
        "with --realtime; free compute without either)",
    )
    output.add_argument(
        "--ablation-out",
        metavar="FILE",
        help="where --ablation writes its report (default: OUT/ablation.md; the published page: "
        "docs/ablation.md)",
    )
    output.add_argument("--quiet", action="store_true", help="no progress bar")
    output.add_argument(
        "--badge",
        metavar="CONTROLLER",
        help="write OUT/badge.svg: CONTROLLER's success rate over the run with its 95%% interval, "
        "for a README (default: no badge)",
    )


def _execution_options(run: argparse._ArgumentGroup) -> None:
    """The "execution" options."""
    run.add_argument("--workers", type=int, metavar="N", help="worker processes (default: all cores)")
    run.add_argument(
        "--backend",
        choices=["process", "ray"],
        default="process",
        help="process pool or a Ray cluster (default: process)",
    )
    run.add_argument("--resume", action="store_true", help="continue the run logged in --out")
    batch_help = "episodes of a cell run together when the controller acts in batch (records as one by one)"
    run.add_argument(
        "--batch", type=int, default=64, metavar="N", help=f"{batch_help}; 1: alone (default: 64)"
    )


def _ci_options(ci: argparse._ArgumentGroup) -> None:
    """The "CI" options."""
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
        "--min-pairs",
        type=int,
        default=defaults.min_pairs,
        metavar="N",
        help=f"with --fail-if-worse: episodes each controller must pair with the baseline, >= 1; fewer "
        f"(other seeds, cells or controllers, or errors) exit {BAD_INPUT_EXIT} (default {defaults.min_pairs})",
    )
    ci.add_argument(
        "--delta-cm",
        type=float,
        default=defaults.delta_cm,
        help=f"final-distance increase the gate cares about [cm], >= 0 (default {defaults.delta_cm})",
    )
