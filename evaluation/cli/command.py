"""The evaluator's command (``python evaluate.py``, ``koopnav-evaluate``): parse, check the input,
run, write the reports, and return the one exit code (:data:`evaluation.exit_codes.EXIT_CODES`)."""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import controllers
from evaluation.cli.gate import compare_with_baseline, config_check, plan_check, uncovered_controllers
from evaluation.cli.options import build_parser, program_name
from evaluation.cli.run_args import run_from_args
from evaluation.cli.sweeps import run_sweep_command, sweep_report
from evaluation.episodes import DEFAULT_OUT, DEGRADED_FAILURE_SHARE, is_degraded, output_directory
from evaluation.execution import RunInterrupted, evaluate, sigterm_stops_the_run
from evaluation.exit_codes import (
    BAD_INPUT_EXIT,
    EPISODES_RAISED_EXIT,
    FAILED_CHECK_EXIT,
    FAILED_GATE_EXIT,
    INTERRUPTED_EXIT,
    SUCCESS_EXIT,
    UNWRITABLE_OUT_EXIT,
    report_internal_error,
    worst,
)
from evaluation.experiments import ablation_markdown
from evaluation.reports import (
    GateOptions,
    Results,
    ThresholdCheck,
    check_thresholds,
    load_baseline,
    load_thresholds,
    write_badge,
)
from koopman_envs.files import write_atomic

__all__ = ["main", "print_options", "print_summary", "run_command", "verdict", "write_ablation"]


def main(argv: list[str] | None = None) -> int:
    """The command line; returns the exit code (:data:`evaluation.exit_codes.EXIT_CODES`).

    An exception that is neither bad input (a ``ValueError`` before any episode ran), an unwritable
    output (an ``OSError`` making ``--out`` or writing a report) nor an interruption is a fault of
    KoopNav: its traceback is printed with a line saying so, and the code is 1, which no other
    outcome uses (a ``ValueError`` raised after the run is one of those)."""
    args = build_parser().parse_args(argv)
    try:
        if args.options:
            return print_options(args.options)
        if args.sweep_report is not None:
            return sweep_report(args.sweep_report, args.reference)
        with sigterm_stops_the_run():
            return run_command(args, argv)
    except KeyboardInterrupt:  # Ctrl-C or SIGTERM before the run started (a run's own is RunInterrupted)
        print("\ninterrupted before any episode ran", file=sys.stderr)
        return INTERRUPTED_EXIT
    except Exception:  # noqa: BLE001 - every other exception is a bug, reported as one
        return report_internal_error(program_name())


def run_command(args: argparse.Namespace, argv: list[str] | None) -> int:
    """Everything after parsing: check the input, run, report, and return the exit code."""
    words = list(sys.argv[1:] if argv is None else argv)
    try:
        given = args.out
        # the directory chosen, in a copy of the options: the caller's stay as parsed
        args = argparse.Namespace(**{**vars(args), "out": output_directory(args.out, args.resume)})
        if given is None and args.out != DEFAULT_OUT:  # the same command run again: a new directory
            print(
                f"note: {DEFAULT_OUT}/ holds an earlier run, so this one writes to {args.out}/ (--out DIR "
                f"chooses the directory; --resume continues the run in {DEFAULT_OUT}/)",
                file=sys.stderr,
            )
            words += ["--out", args.out]  # so that a resume hint names this run's directory
        run = run_from_args(args)
        if run.sweep:
            return run_sweep_command(args, run, words)
        spec = run.spec
        # checked before any episode
        thresholds = load_thresholds(args.check) if args.check else None
        baseline = load_baseline(args.baseline) if args.baseline else None
        gate = GateOptions(args.alpha, args.delta, args.delta_cm, args.min_pairs)
        if args.fail_if_worse and baseline is None:
            raise ValueError(
                "--fail-if-worse needs --baseline BASE (an earlier run's results.json or directory)"
            )
        start = time.perf_counter()
        results = evaluate(
            spec,
            workers=args.workers,
            backend=args.backend,
            out=args.out,
            resume=args.resume,
            progress=not args.quiet,
            batch=args.batch,
            config_check=config_check(args, baseline),
            plan_check=plan_check(args, baseline, gate),
        )
        wall = time.perf_counter() - start
    except ValueError as exc:  # the input, refused before any episode ran (2 means that only)
        print(f"error: {exc}", file=sys.stderr)
        return BAD_INPUT_EXIT
    except OSError as exc:  # --out unwritable up front (OutputNotWritable)
        print(f"error: {exc}", file=sys.stderr)
        return UNWRITABLE_OUT_EXIT
    except RunInterrupted as exc:
        again = " ".join([program_name(), *words, *([] if "--resume" in words else ["--resume"])])
        print(f"\n{exc}; continue with: {again}", file=sys.stderr)
        return INTERRUPTED_EXIT
    # after the run: a report that cannot be written is 103; any other exception here is no input's
    # fault but KoopNav's (main reports it as an internal error, 1), never "bad input" (2)
    results.config["wall_seconds"] = wall
    try:
        paths = results.write(args.out)
        if args.badge:
            paths["badge"] = write_badge(results, args.badge, Path(args.out) / "badge.svg")
        if args.ablation is not None:
            paths["ablation"] = write_ablation(args, results, wall)
    except OSError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return UNWRITABLE_OUT_EXIT
    threshold_check = check_thresholds(results, thresholds, strict=args.strict) if thresholds else None
    comparison, worse = (
        compare_with_baseline(args, results, baseline, gate) if baseline is not None else ("", [])
    )
    uncovered = (
        uncovered_controllers(args, results, baseline, gate)
        if baseline is not None and args.fail_if_worse
        else []
    )
    print_summary(args, results, paths, comparison, wall)
    return verdict(args, results, threshold_check, worse, uncovered)


def print_options(name: str) -> int:
    """``--options NAME``: the controller's option table (bad input for an unknown name)."""
    try:
        table = controllers.options(name)
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return BAD_INPUT_EXIT
    print(f"{table.name}: {table.doc}\n\n{table.markdown()}")
    return SUCCESS_EXIT


def write_ablation(args: argparse.Namespace, results: Results, wall: float) -> Path:
    """``--ablation``: the ablation report, written to ``--ablation-out`` (default OUT/ablation.md)."""
    command = "python evaluate.py --ablation " + " ".join(args.ablation) if args.ablation else ""
    command = (command or "python evaluate.py --ablation") + (
        f" --episodes {args.episodes}" if args.episodes else ""
    )
    if args.ablation_out is not None:  # a page published elsewhere: its regeneration names it
        command += f" --ablation-out {args.ablation_out}"
    report = ablation_markdown(results, args.ablation, command=command.strip())
    report += f"\n{len(results.records)} episodes in {wall:.0f} s on {results.config['workers']} workers.\n"
    return write_atomic(args.ablation_out or Path(args.out, "ablation.md"), report)


def print_summary(
    args: argparse.Namespace, results: Results, paths: dict[str, Path], comparison: str, wall: float
) -> None:
    """The terminal's leaderboard, the GitHub job summary, and the counts of failed and degraded episodes."""
    print(results.to_markdown() if args.full_report else results.terminal_summary(paths))
    if comparison:
        print("\n" + comparison)
    summary_file = os.environ.get("GITHUB_STEP_SUMMARY")
    if summary_file:  # a GitHub Actions job summary: appended, never overwritten
        with open(summary_file, "a", encoding="utf-8") as handle:
            handle.write(
                "## KoopNav leaderboard\n\n"
                + results.leaderboard_table()
                + "\n\n"
                + (comparison + "\n\n" if comparison else "")
            )
    print(
        f"\n{len(results.records)} episodes in {wall:.1f} s; wrote {', '.join(str(p) for p in paths.values())} "
        f"and {Path(args.out) / 'figures'}/"
    )
    if results.failed_episodes:
        print(f"{len(results.failed_episodes)} episode(s) raised; see {paths['markdown']}", file=sys.stderr)
    degraded = [r for r in results.records if is_degraded(r)]
    if degraded:
        print(
            f"{len(degraded)} episode(s) degraded (solver failed in more than "
            f"{DEGRADED_FAILURE_SHARE:.0%} of their periods); see {paths['markdown']}",
            file=sys.stderr,
        )


def verdict(
    args: argparse.Namespace,
    results: Results,
    threshold_check: ThresholdCheck | None,
    worse: list[str],
    uncovered: list[str],
) -> int:
    """Print every outcome of a finished run (floors, gate, episodes that raised) and return the
    one exit code of highest priority (:func:`evaluation.exit_codes.worst`)."""
    codes = []
    problems = threshold_check.problems if threshold_check else []
    if problems:
        print("threshold check failed:\n" + "\n".join(f"  - {p}" for p in problems), file=sys.stderr)
        codes.append(FAILED_CHECK_EXIT)
    if uncovered:
        print(
            f"the baseline gate cannot judge this run ({args.baseline}):\n"
            + "\n".join(f"  - {u}" for u in uncovered),
            file=sys.stderr,
        )
    if worse:
        print("worse than the baseline:\n" + "\n".join(f"  - {w}" for w in worse), file=sys.stderr)
        codes.append(FAILED_GATE_EXIT)
    elif args.fail_if_worse and not uncovered:
        print(f"baseline gate passed ({args.baseline}: no significant loss at alpha {args.alpha})")
    if threshold_check is not None:
        for line in threshold_check.skipped:
            print(f"threshold rule {line}", file=sys.stderr)
        if not problems:
            print(f"threshold check passed ({args.check}, floors read as {threshold_check.reading})")
    if results.failed_episodes:  # counted in the summary printed before; the code says only "some"
        codes.append(EPISODES_RAISED_EXIT)
    code = worst(*codes)
    # a gate that cannot judge fails closed, as it does before the run: 102 and 101 say more
    return BAD_INPUT_EXIT if uncovered and code in (SUCCESS_EXIT, EPISODES_RAISED_EXIT) else code
