"""KoopNav evaluator: run every controller on every cell, report success rates and final distances.

``python evaluate.py`` runs the quick default leaderboard (both tasks, their paper maps under
high slip, every registered controller, 2 episodes per cell from perturbed starts, the NMPCs on
the real-time iteration), prints a compact leaderboard and writes the full report (Markdown,
JSON, CSV, HTML, figures) to ``results/`` (``results-2/``, ``results-3/``, ... when it holds an
earlier run, so that the command can be run again). ``python evaluate.py --paper`` runs the paper's
protocol (SPEC section 5: 10 trials per cell) and prints tables 1-5. From Python::

    from evaluation import RunSpec, evaluate
    spec = RunSpec(envs="KoopNav-Formation-v0", controllers=["koopman-nmpc", "consensus"], maps=["map3"],
                   slips=["nominal", "high"], episodes=5, seed=0)
    print(evaluate(spec).to_markdown())

This file is the command line; the work is done by the ``evaluation`` package, one folder per
concept (docs/layout.md), each imported here through its face: ``evaluation.run`` (``RunSpec``:
the run, its checks and its episodes), ``evaluation.execution`` (workers; process pool, Ray,
progress, Ctrl-C; ``evaluate``), ``evaluation.episodes`` (records, the resumable log),
``evaluation.stats`` (cells, intervals, paired comparisons, robustness profiles),
``evaluation.reports`` (``Results``: reports, figures, the leaderboard page; the baseline gate,
thresholds, the badge), ``evaluation.experiments`` (protocols, the ablation, ``--sweep``),
``evaluation.cli`` (the options) and ``evaluation.exit_codes``.

Episodes run in worker processes; each episode's seed depends only on the base seed and its
index in the cell, so results do not depend on the worker count. Each finished episode is
appended to ``OUT/episodes.jsonl`` at once; ``--resume`` continues an interrupted run. An
episode that raises is recorded with its error and the others go on; the exit codes are one table,
:data:`evaluation.exit_codes.EXIT_CODES` (``--help`` lists it): 2 bad input, 3 episodes raised,
101 a ``--check`` floor missed, and so on.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import controllers
from evaluation.cli import (
    CommandLineRun,
    build_parser,
    parse_env_kwargs,
    program_name,
    run_from_args,
    spec_from_args,
    split_words,
)
from evaluation.episodes import (
    DEFAULT_OUT,
    DEGRADED_FAILURE_SHARE,
    ensure_output_dir,
    is_degraded,
    json_safe,
    output_directory,
)
from evaluation.execution import RunInterrupted, evaluate, sigterm_stops_the_run, usable_controllers
from evaluation.exit_codes import (
    BAD_INPUT_EXIT,
    EPISODES_RAISED_EXIT,
    EXIT_CODES,
    FAILED_CHECK_EXIT,
    FAILED_GATE_EXIT,
    INTERNAL_ERROR_EXIT,
    INTERRUPTED_EXIT,
    SUCCESS_EXIT,
    UNWRITABLE_OUT_EXIT,
    report_internal_error,
    worst,
)
from evaluation.experiments import (
    ablation_markdown,
    check_levels,
    level_aliases,
    load_sweep,
    paper_protocol,
    parse_sweep,
    quick_protocol,
    run_sweep,
    write_manifest,
)
from evaluation.reports import (
    SCHEMA_VERSION,
    GateOptions,
    PairKey,
    Results,
    ThresholdCheck,
    check_thresholds,
    compare_runs,
    comparison_markdown,
    coverage_failures,
    distinct_pairs,
    gate_failures,
    is_published,
    load_baseline,
    load_thresholds,
    pair_keys,
    refuse_incomparable,
    terminal_overview,
    unpack_hint,
    write_badge,
    write_profiles,
)
from evaluation.run import EpisodeSpec, RunSpec, split_slips
from evaluation.stats import Cell, profiles
from koopman_envs.checks import check_choice, did_you_mean
from koopman_envs.files import write_atomic

__all__ = [
    "BAD_INPUT_EXIT",
    "Cell",
    "EPISODES_RAISED_EXIT",
    "EXIT_CODES",
    "FAILED_CHECK_EXIT",
    "FAILED_GATE_EXIT",
    "INTERNAL_ERROR_EXIT",
    "INTERRUPTED_EXIT",
    "SUCCESS_EXIT",
    "UNWRITABLE_OUT_EXIT",
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
    # the command line's pieces (evaluation.cli), where they always were
    "build_parser",
    "parse_env_kwargs",
    "program_name",
    "spec_from_args",
    "split_slips",
    "split_words",
]


def _print_options(name: str) -> int:
    """``--options NAME``: the controller's option table (bad input for an unknown name)."""
    try:
        table = controllers.options(name)
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return BAD_INPUT_EXIT
    print(f"{table.name}: {table.doc}\n\n{table.markdown()}")
    return SUCCESS_EXIT


def _config_check(
    args: argparse.Namespace, baseline: dict[str, Any] | None
) -> Callable[[dict[str, Any]], None]:
    """What needs the run's configuration, checked before any episode (baseline, badge)."""

    def check(config: dict[str, Any]) -> None:
        import koopman_envs

        if baseline is not None:
            refuse_incomparable(config, koopman_envs.__version__, baseline)
        if args.badge and args.badge not in config["controllers"]:
            raise ValueError(
                f"--badge {args.badge!r} is not a controller of this run; it runs "
                f"{config['controllers']}{did_you_mean(args.badge, config['controllers'])}"
            )

    return check


def _plan_check(
    args: argparse.Namespace, baseline: dict[str, Any] | None, gate: GateOptions
) -> Callable[[Sequence[EpisodeSpec]], None]:
    """``--fail-if-worse``: refuse, before any episode, a run that too few episodes of the
    baseline pair with (other seeds, cells or controllers: a stale baseline)."""

    def check(plan: Sequence[EpisodeSpec]) -> None:
        if baseline is None or not args.fail_if_worse:
            return
        planned: dict[str, set[PairKey]] = {}
        for episode in plan:
            planned.setdefault(episode.controller, set()).add(
                (episode.env_id, episode.map, episode.slip, episode.seed)
            )
        failures = coverage_failures(
            planned, baseline["episodes"], gate, run_names_its_controllers=bool(args.controllers)
        )
        if failures:
            raise ValueError(
                f"--fail-if-worse cannot judge this run against the baseline {args.baseline!r}: "
                + "; ".join(failures)
                + f" (no episode was run; --min-pairs sets the minimum, now {gate.min_pairs})"
            )

    return check


def _write_ablation(args: argparse.Namespace, results: Results, wall: float) -> Path:
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


def _compare(
    args: argparse.Namespace, results: Results, baseline: dict[str, Any], gate: GateOptions
) -> tuple[str, list[str]]:
    """``--baseline``: the paired comparison (written beside the report) and, with
    ``--fail-if-worse``, the controllers significantly worse than the baseline."""
    comparison = compare_runs(results.records, baseline["episodes"])
    text = comparison_markdown(comparison, args.baseline)
    write_atomic(Path(args.out, "baseline_comparison.md"), text + "\n")
    write_atomic(
        Path(args.out, "baseline_comparison.json"), json.dumps(json_safe(comparison), indent=1) + "\n"
    )
    return text, gate_failures(comparison, gate) if args.fail_if_worse else []


def _uncovered(
    args: argparse.Namespace, results: Results, baseline: dict[str, Any], gate: GateOptions
) -> list[str]:
    """``--fail-if-worse`` after the run: the controllers whose episodes that ran pair too few
    times with the baseline (episodes that raised cannot pair; repeats of one episode pair once)."""
    errors: dict[str, int] = {}
    for record in results.failed_episodes:
        errors[record["controller"]] = errors.get(record["controller"], 0) + 1
    run = pair_keys(results.records)
    for label in [c["label"] for c in results.config["controller_configs"]]:
        run.setdefault(label, set())  # a controller whose every episode raised
    return coverage_failures(
        run,
        baseline["episodes"],
        gate,
        run_names_its_controllers=bool(args.controllers),
        run_errors=errors,
        distinct=distinct_pairs(results.records, baseline["episodes"]),
    )


def _print_summary(
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


def _run_sweep(args: argparse.Namespace, run: CommandLineRun, words: list[str]) -> int:
    """``--sweep``: every level's run in its own directory, then the robustness profiles."""
    for option in ("baseline", "check", "badge", "ablation"):
        if getattr(args, option):
            raise ValueError(f"--sweep does not combine with --{option}; run them separately")
    spec, reference = run.spec, run.reference
    axes = [parse_sweep(text) for text in run.sweep]
    labels = [c.label for c in spec.controllers] if spec.controllers is not None else None
    if reference and labels is not None:
        check_choice("--reference", reference, labels, sep=" ", among="the controllers")
    if len({axis.key for axis in axes}) < len(axes):
        raise ValueError(f"--sweep: an axis is given twice ({[a.key for a in axes]})")
    if not args.resume:
        existing = [
            d for a in axes for v in a.levels if (d := a.level_dir(args.out, v) / "episodes.jsonl").exists()
        ]
        if existing:
            raise ValueError(
                f"{existing[0]} exists: pass --resume to continue that sweep, or choose another --out"
            )
    check_levels(spec, axes)
    ensure_output_dir(args.out)
    aliases = level_aliases(spec, axes)
    command = " ".join([program_name(), *(w for w in words if w != "--resume")])
    write_manifest(args.out, axes, reference, command, aliases)
    start = time.perf_counter()
    done = run_sweep(
        spec,
        axes,
        args.out,
        workers=args.workers,
        backend=args.backend,
        resume=args.resume,
        progress=not args.quiet,
        batch=args.batch,
    )
    axes_profiles = profiles(done, reference)
    paths = write_profiles(axes_profiles, args.out, command)
    if not args.quiet or args.full_report:
        print(terminal_overview(axes_profiles))
    runs = {id(results): results for levels in done.values() for _, results in levels}  # aliases once
    episodes = sum(len(results.records) for results in runs.values())
    print(
        f"\n{episodes} episodes in {time.perf_counter() - start:.1f} s; wrote {', '.join(map(str, paths.values()))}"
    )
    # as a run without --sweep: episodes that raised, at any level, are counted and named
    failed = 0
    for axis in axes:
        for level, results in done[axis.key]:
            if id(results) in runs and results.failed_episodes:
                runs.pop(id(results))
                failed += len(results.failed_episodes)
                print(
                    f"{len(results.failed_episodes)} episode(s) raised at {axis.key}={level}; see "
                    f"{axis.level_dir(args.out, level) / 'results.md'}",
                    file=sys.stderr,
                )
    if failed:
        print(f"{failed} episode(s) raised in the sweep", file=sys.stderr)
    return EPISODES_RAISED_EXIT if failed else SUCCESS_EXIT


def _sweep_report(out: str, reference: str | None) -> int:
    """``--sweep-report OUT``: the robustness report of the levels of the sweep in ``OUT``
    finished so far (a long sweep can be read while it runs); bad input for a sweep that cannot
    be read back, or no level finished yet."""
    try:
        if is_published(out):  # its report would go where the archive is: a file, or data/NAME/
            raise ValueError(
                f"--sweep-report {out!r} is a published archive; the report is written into a sweep's "
                f"directory: unpack it ({unpack_hint(out)}) and pass DIR/NAME, or build its page "
                "with docs/make_robustness_md.py, which reads archives"
            )
        done, missing, manifest = load_sweep(out)
        if not done:
            raise ValueError(f"no level of the sweep in {out!r} has finished yet")
        note = f" (levels not finished: {', '.join(missing)})" if missing else ""
        paths = write_profiles(
            profiles(done, reference or manifest.get("reference")),
            out,
            manifest.get("command", "") + note,
        )
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return BAD_INPUT_EXIT
    except OSError as exc:  # the report cannot be written into OUT
        print(f"error: {exc}", file=sys.stderr)
        return UNWRITABLE_OUT_EXIT
    if missing:  # named, never dropped silently
        print(f"levels not finished, left out: {', '.join(missing)}", file=sys.stderr)
    print(f"wrote {', '.join(map(str, paths.values()))}")
    return SUCCESS_EXIT


def _verdict(
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


def _run(args: argparse.Namespace, argv: list[str] | None) -> int:
    """Everything after parsing: check the input, run, report, and return the exit code."""
    words = list(sys.argv[1:] if argv is None else argv)
    try:
        given, args.out = args.out, output_directory(args.out, args.resume)
        if given is None and args.out != DEFAULT_OUT:  # the same command run again: a new directory
            print(
                f"note: {DEFAULT_OUT}/ holds an earlier run, so this one writes to {args.out}/ (--out DIR "
                f"chooses the directory; --resume continues the run in {DEFAULT_OUT}/)",
                file=sys.stderr,
            )
            words += ["--out", args.out]  # so that a resume hint names this run's directory
        run = run_from_args(args)
        if run.sweep:
            return _run_sweep(args, run, words)
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
            config_check=_config_check(args, baseline),
            plan_check=_plan_check(args, baseline, gate),
        )
        wall = time.perf_counter() - start
        results.config["wall_seconds"] = wall
        paths = results.write(args.out)
        if args.badge:
            paths["badge"] = write_badge(results, args.badge, Path(args.out) / "badge.svg")
        if args.ablation is not None:
            paths["ablation"] = _write_ablation(args, results, wall)
        threshold_check = check_thresholds(results, thresholds, strict=args.strict) if thresholds else None
        comparison, worse = _compare(args, results, baseline, gate) if baseline is not None else ("", [])
        uncovered = (
            _uncovered(args, results, baseline, gate) if baseline is not None and args.fail_if_worse else []
        )
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return BAD_INPUT_EXIT
    except OSError as exc:  # --out unwritable up front (OutputNotWritable), or a report write that failed
        print(f"error: {exc}", file=sys.stderr)
        return UNWRITABLE_OUT_EXIT
    except RunInterrupted as exc:
        again = " ".join([program_name(), *words, *([] if "--resume" in words else ["--resume"])])
        print(f"\n{exc}; continue with: {again}", file=sys.stderr)
        return INTERRUPTED_EXIT
    _print_summary(args, results, paths, comparison, wall)
    return _verdict(args, results, threshold_check, worse, uncovered)


def main(argv: list[str] | None = None) -> int:
    """The command line; returns the exit code (:data:`evaluation.exit_codes.EXIT_CODES`).

    An exception that is neither bad input (``ValueError``), an unwritable output (``OSError``)
    nor an interruption is a fault of KoopNav: its traceback is printed with a line saying so,
    and the code is 1, which no other outcome uses."""
    args = build_parser().parse_args(argv)
    try:
        if args.options:
            return _print_options(args.options)
        if args.sweep_report is not None:
            return _sweep_report(args.sweep_report, args.reference)
        with sigterm_stops_the_run():
            return _run(args, argv)
    except KeyboardInterrupt:  # Ctrl-C or SIGTERM before the run started (a run's own is RunInterrupted)
        print("\ninterrupted before any episode ran", file=sys.stderr)
        return INTERRUPTED_EXIT
    except Exception:  # noqa: BLE001 - every other exception is a bug, reported as one
        return report_internal_error(program_name())


if __name__ == "__main__":
    raise SystemExit(main())
