"""``--sweep`` and ``--sweep-report`` on the command line: every level's run in its own
directory, then the robustness profiles; the report of a sweep's levels finished so far."""

from __future__ import annotations

import argparse
import sys
import time

from evaluation.cli.options import program_name
from evaluation.cli.run_args import CommandLineRun
from evaluation.episodes import ensure_output_dir
from evaluation.exit_codes import BAD_INPUT_EXIT, EPISODES_RAISED_EXIT, SUCCESS_EXIT, UNWRITABLE_OUT_EXIT
from evaluation.experiments import (
    check_levels,
    level_aliases,
    load_sweep,
    parse_sweep,
    run_sweep,
    write_manifest,
)
from evaluation.reports import is_published, terminal_overview, unpack_hint, write_profiles
from evaluation.stats import profiles
from koopman_envs.checks import check_choice

__all__ = ["run_sweep_command", "sweep_report"]


def run_sweep_command(args: argparse.Namespace, run: CommandLineRun, words: list[str]) -> int:
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


def sweep_report(out: str, reference: str | None) -> int:
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
