"""The CBF safety filter: its time per step, and collisions with and without it under high slip.

Usage::

    python bench/safety_filter.py [--episodes 5] [--controllers consensus-free rl-ppo nominal-nmpc]
                                  [--workers 2] [--timing-episodes 3] [--filter safety_margin=0.1 ...]
                                  [--skip-timing] [--skip-collisions]

1. Time per step of the filter alone (``SafetyStats.filter_times``), for teams of 3 and 16 robots
   on seeded random maps (target reaching, ``map="random"``, the random-map generator's defaults),
   around ``consensus-free``, which drives straight for its targets and so keeps the filter busy.
2. Collisions on the paper maps (target reaching: map1, map2; formation: map3, map4) under high
   slip, each controller with and without the filter (``safe:<name>``), through the evaluator
   (``evaluation.execution.runner.evaluate``: same seeds, same calibration, the paper's starts), pooled over
   the four maps: collision and success counts with 95% Wilson intervals, and the relative
   reduction of collisions. ``rl-ppo`` is skipped when stable-baselines3 is missing.

Defaults are small (5 trials per cell: 20 episodes per controller); nominal-nmpc episodes take
5-20 s each on a 2-core machine. ``--episodes 20`` gives tighter intervals.
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

import gymnasium as gym
import numpy as np

import controllers
import koopman_envs  # noqa: F401  (registers the envs)
from evaluation import RunSpec, evaluate
from evaluation.episodes.records import ran
from evaluation.run.configs import parse_controller, split_controller_list
from evaluation.stats.statistics import wilson_interval
from koopman_envs import run_episode

TASKS = ("KoopNav-TargetReaching-v0", "KoopNav-Formation-v0")


def filter_step_times(
    n_robots: int, episodes: int, inner: str = "consensus-free"
) -> tuple[np.ndarray, float, str]:
    """Filter time per step [ms] over ``episodes`` random-map episodes, the share of robot-steps
    it changed, and the outcomes."""
    env = gym.make(TASKS[0], map="random", n_robots=n_robots, slip="high")
    times, changed, robot_steps, outcomes = [], 0, 0, []
    for seed in range(episodes):
        ctrl = controllers.make(f"safe:{inner}")
        result = run_episode(env, ctrl, seed=seed)
        stats = ctrl.stats()
        times += stats.filter_times
        changed += stats.changed_robots
        robot_steps += stats.steps * n_robots
        outcomes.append(result.outcome)
    return 1e3 * np.asarray(times), changed / max(robot_steps, 1), ", ".join(outcomes)


def _rate(k: int, n: int) -> str:
    low, high = wilson_interval(k, n)
    return f"{k}/{n} = {100 * k / n:.0f}% [{100 * low:.0f}-{100 * high:.0f}]" if n else "-"


def collision_table(names: list[str], filter_options: list[str], episodes: int, workers: int) -> None:
    """Run each controller configuration (``name`` or ``name:key=value,...``) with and without the
    filter on the paper maps under high slip and print collisions and successes, pooled over maps
    and tasks."""
    extra = (
        parse_controller("filter:" + ",".join(filter_options)).options if filter_options else ()
    )  # key=value parsing
    configs: dict[str, Any] = {}
    for text in names:
        config = parse_controller(text)
        configs[text] = (config.name, dict(config.options))
        configs[f"safe:{text}"] = (f"safe:{config.name}", {**dict(config.options), **dict(extra)})
    # both tasks on their paper maps (RunSpec's defaults)
    results = evaluate(
        RunSpec(controllers=configs, slips=["high"], episodes=episodes), workers=workers, progress=True
    )
    by_label: dict[str, list[dict[str, Any]]] = {}
    for rec in results.records:
        by_label.setdefault(rec["controller"], []).append(rec)
    print(
        f"\nPaper maps (map1, map2 target reaching; map3, map4 formation), high slip, {episodes} trials per cell"
        f"{'; filter options ' + ','.join(filter_options) if filter_options else ''}"
    )
    print(
        "| controller | episodes | collisions [95% CI] | success [95% CI] | kinds | changed steps | "
        "infeasible steps | filter ms median / p95 |"
    )
    print("|---|---|---|---|---|---|---|---|")
    counts = {}
    for label in configs:
        recs = [r for r in by_label.get(label, []) if ran(r)]
        errors = len(by_label.get(label, [])) - len(recs)
        n = len(recs)
        collided = [r["collision"] for r in recs if r["collision"]]
        successes = sum(bool(r["success"]) for r in recs)
        counts[label] = (len(collided), n)
        kinds = ", ".join(f"{k} {collided.count(k)}" for k in sorted(set(collided))) or "-"
        extra = [r.get("controller_extra") or {} for r in recs]
        steps = sum(r["steps"] for r in recs)
        if label.startswith("safe:") and extra:
            changed = f"{100 * sum(e['filter_changed'] for e in extra) / max(steps, 1):.0f}%"
            infeasible = str(sum(e["filter_infeasible"] for e in extra))
            timing = (
                f"{np.median([e['filter_ms_median'] for e in extra]):.3f} / "
                f"{np.median([e['filter_ms_p95'] for e in extra]):.3f}"
            )
        else:
            changed = infeasible = timing = "-"
        note = f" ({errors} errors)" if errors else ""
        print(
            f"| {label} | {n}{note} | {_rate(len(collided), n)} | {_rate(successes, n)} | {kinds} | {changed} | "
            f"{infeasible} | {timing} |"
        )
    print()
    for name in names:
        (raw, n_raw), (safe, n_safe) = counts[name], counts[f"safe:{name}"]
        if raw and n_raw and n_safe:
            reduction = 1 - (safe / n_safe) / (raw / n_raw)
            print(
                f"{name}: collisions {raw}/{n_raw} -> {safe}/{n_safe} with the filter ({100 * reduction:.0f}% fewer)"
            )
        else:
            print(f"{name}: collisions {raw}/{n_raw} -> {safe}/{n_safe} with the filter")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument(
        "--episodes", type=int, default=5, help="trials per (map, controller) cell (default 5)"
    )
    parser.add_argument("--controllers", nargs="+", default=["consensus-free", "rl-ppo", "nominal-nmpc"])
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--timing-episodes", type=int, default=3, help="random-map episodes per team size")
    parser.add_argument(
        "--filter",
        nargs="+",
        default=[],
        metavar="safety_KEY=VALUE",
        help="filter options for every safe: configuration, e.g. safety_margin=0.1",
    )
    parser.add_argument("--skip-timing", action="store_true")
    parser.add_argument("--skip-collisions", action="store_true")
    args = parser.parse_args()
    for option in args.filter:
        if not option.startswith("safety_") or "=" not in option:
            parser.error(f"--filter {option!r} is not safety_KEY=VALUE")
    if not args.skip_timing:
        print(
            "Filter time per step (the filter alone), target reaching on seeded random maps, high slip, "
            f"around consensus-free, {args.timing_episodes} episodes per team size"
        )
        print("| robots | steps | median [ms] | p95 [ms] | max [ms] | robot-commands changed | outcomes |")
        print("|---|---|---|---|---|---|---|")
        for n in (3, 16):
            times, changed, outcomes = filter_step_times(n, args.timing_episodes)
            print(
                f"| {n} | {times.size} | {np.median(times):.3f} | {np.percentile(times, 95):.3f} | "
                f"{times.max():.3f} | {100 * changed:.0f}% | {outcomes} |",
                flush=True,
            )
    if not args.skip_collisions:
        names = split_controller_list(args.controllers)
        usable = []
        for name in names:
            try:
                parse_controller(name).build()
            except (ImportError, ValueError, TypeError) as exc:
                print(f"note: {name} skipped ({exc})", file=sys.stderr)
                continue
            usable.append(name)
        collision_table(usable, args.filter, args.episodes, args.workers)


if __name__ == "__main__":
    main()
