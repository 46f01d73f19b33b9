"""``python -m evaluation.tune``: tune a controller, report on studies, or adopt a study's preset
(``python -m evaluation.tune adopt NAME``: :mod:`evaluation.tune.adopt`)."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from controllers.tuning import ADOPTION_RULE, BEST_FILE, STUDIES_DIR, TUNED_DIR
from evaluation.episodes.runlog import (
    OutputNotWritable,
)
from evaluation.exit_codes import BAD_INPUT_EXIT, INTERRUPTED_EXIT, SUCCESS_EXIT, UNWRITABLE_OUT_EXIT
from evaluation.tune.adopt import adopt, adopt_confirmed
from evaluation.tune.configuration import DEFAULT_SLIP, TASK_CHOICES
from evaluation.tune.confirm import CONFIRMATION_LOGS, CONFIRMATION_RULE
from evaluation.tune.log import StudySettings
from evaluation.tune.report import load_summary, report_figure, report_markdown
from evaluation.tune.study import best_of, run_study
from koopman_envs.files import write_atomic


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m evaluation.tune",
        description="Tune a controller's options on a suite's validation layouts (Optuna TPE, seeded), "
        "or draw the expected-best-score curves of several studies (--report).",
    )
    parser.add_argument(
        "controller", nargs="?", help="a registered controller or preset with tunable options"
    )
    parser.add_argument("--task", default="both", help=f"one of {list(TASK_CHOICES)} (default both)")
    parser.add_argument("--trials", type=int, default=50, help="configurations tried (N, default 50)")
    parser.add_argument("--layouts", type=int, default=20, help="layouts per task (K: the split's first K)")
    parser.add_argument("--episodes", type=int, default=2, help="episodes per layout (E)")
    parser.add_argument("--seed", type=int, default=0, help="sampler seed and first episode seed")
    parser.add_argument(
        "--split", default="validation", help="validation (default) or train; test is refused"
    )
    parser.add_argument(
        "--slip", default=DEFAULT_SLIP, help=f"slip of every episode (default {DEFAULT_SLIP})"
    )
    parser.add_argument("--max-episode-steps", type=int, default=None, help="episode step limit")
    parser.add_argument("--workers", type=int, default=1, help="worker processes per evaluation (default 1)")
    parser.add_argument("--out", required=True, help="study directory, or with --report the figure (PNG)")
    parser.add_argument("--resume", action="store_true", help="continue the study logged in --out")
    parser.add_argument("--report", nargs="+", metavar="DIR", help="study directories to draw and tabulate")
    return parser


def _adopt_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m evaluation.tune adopt",
        description=f"Apply the adoption rule to finished studies and install what it admits: {ADOPTION_RULE}.",
    )
    parser.add_argument("names", nargs="+", metavar="NAME", help="the tuned controllers (data/tuning/NAME/)")
    parser.add_argument(
        "--studies", default=str(STUDIES_DIR), help="the studies' folder (default data/tuning)"
    )
    parser.add_argument(
        "--tuned", default=str(TUNED_DIR), help="the installed presets' folder (default controllers/tuned)"
    )
    parser.add_argument(
        "--confirm",
        type=int,
        default=None,
        metavar="N",
        help="first rerun an adopted study's best and its defaults on the next N validation layouts per "
        f"task, and install the preset only if it is confirmed: {CONFIRMATION_RULE}",
    )
    parser.add_argument("--workers", type=int, default=1, help="worker processes of --confirm's runs")
    return parser


def _adopt_main(argv: Sequence[str]) -> int:
    """``python -m evaluation.tune adopt NAME ...``: one line per decision; exit 2 on a refusal."""
    args = _adopt_parser().parse_args(argv)
    code = SUCCESS_EXIT
    for name in args.names:
        try:
            if args.confirm is None:
                decision, confirmation = adopt(name, args.studies, args.tuned), None
            else:
                decision, confirmation = adopt_confirmed(
                    name, args.confirm, args.studies, args.tuned, workers=args.workers
                )
        except KeyboardInterrupt:
            if args.confirm is None:  # no episode runs: the preset is written whole or not at all
                print(f"interrupted: {name}: nothing adopted; the same command adopts it", file=sys.stderr)
                return INTERRUPTED_EXIT
            logs = Path(args.studies) / name / CONFIRMATION_LOGS
            print(
                f"interrupted: {name}'s finished confirmation episodes are in {logs}; the same command continues",
                file=sys.stderr,
            )
            return INTERRUPTED_EXIT
        except ValueError as exc:
            print(f"error: {exc}", file=sys.stderr)
            code = BAD_INPUT_EXIT
            continue
        installed = Path(args.tuned) / f"{name}.json"
        print(f"{decision}; " + (f"installed {installed}" if installed.is_file() else f"no {installed}"))
        if confirmation is not None:
            print(str(confirmation))
    return code


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m evaluation.tune``: see the module docstring. Returns the exit code."""
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv[:1] == ["adopt"]:
        return _adopt_main(argv[1:])
    args = _parser().parse_args(argv)
    try:
        if args.report:
            studies = [load_summary(folder) for folder in args.report]
            report_figure(studies, args.out)
            table = report_markdown(studies)
            write_atomic(Path(args.out).with_suffix(".md"), table)
            print(table, end="")
            return SUCCESS_EXIT
        if not args.controller:
            raise ValueError("a controller to tune is required (or --report DIR ...)")
        env_kwargs = {} if args.max_episode_steps is None else {"max_episode_steps": args.max_episode_steps}
        settings = StudySettings(
            args.controller,
            args.task,
            args.trials,
            args.layouts,
            args.episodes,
            args.seed,
            split=args.split,
            slip=args.slip,
            env_kwargs=env_kwargs,
        )
        trials = run_study(settings, args.out, resume=args.resume, workers=args.workers, progress=True)
    except OutputNotWritable as exc:
        print(f"error: {exc}", file=sys.stderr)
        return UNWRITABLE_OUT_EXIT
    except KeyboardInterrupt:
        print(f"interrupted: the finished trials are in {args.out}; --resume continues", file=sys.stderr)
        return INTERRUPTED_EXIT
    except (ValueError, ImportError) as exc:  # bad input, or the tune extra missing: named
        print(f"error: {exc}", file=sys.stderr)
        return BAD_INPUT_EXIT
    best = best_of(trials)
    print(
        f"best: trial {best.number}, score {best.score:.4f} (defaults {trials[0].score:.4f}); "
        f"{Path(args.out) / BEST_FILE}"
    )
    return SUCCESS_EXIT
