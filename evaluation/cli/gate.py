"""The baseline gate and the badge on the command line (``--baseline``, ``--fail-if-worse``,
``--badge``): what is checked before any episode (the run's configuration against the baseline's,
the planned episodes' pairs with it) and after the run (the paired comparison written beside the
report, the controllers that pair too few times)."""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from evaluation.episodes import json_safe
from evaluation.reports import (
    GateOptions,
    PairKey,
    Results,
    compare_runs,
    comparison_markdown,
    coverage_failures,
    distinct_pairs,
    gate_failures,
    pair_keys,
    refuse_incomparable,
)
from evaluation.run import EpisodeSpec
from koopman_envs.checks import did_you_mean
from koopman_envs.files import write_atomic

__all__ = ["compare_with_baseline", "config_check", "plan_check", "uncovered_controllers"]


def config_check(
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


def plan_check(
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


def compare_with_baseline(
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


def uncovered_controllers(
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
