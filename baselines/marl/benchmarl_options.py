"""The command line of ``python -m baselines.marl.benchmarl_train`` (:mod:`baselines.marl.benchmarl_train`):
its options, their defaults and the checks argparse makes while parsing."""

from __future__ import annotations

import argparse
import json
from typing import Any

from baselines.features.robot_features import FEATURE_SETS
from baselines.suite_training import add_suite_options
from koopman_envs.checks import CLI_JSON_CHARS, parse_json

__all__ = ["ALGORITHMS", "DESCRIPTION", "TASKS", "build_parser"]

DESCRIPTION = (
    "Train a multi-agent PPO policy (MAPPO or IPPO) with BenchMARL on a KoopNav task and export it "
    "for the mappo / ippo controllers (baselines.marl.marl_policy)."
)
TASKS = ("target_reaching", "formation")
ALGORITHMS = ("mappo", "ippo")


def _json_object(text: str) -> dict[str, Any]:
    """``--env-kwargs``: a JSON object (argparse names the option and the value when this raises)."""
    try:
        value = parse_json(text, "--env-kwargs", max_chars=CLI_JSON_CHARS)
    except json.JSONDecodeError as exc:
        raise argparse.ArgumentTypeError(f"not JSON ({exc})") from None
    if not isinstance(value, dict):
        raise argparse.ArgumentTypeError(
            f"a JSON object of env keywords is needed, not {type(value).__name__}"
        )
    return value


def _stage_list(text: str) -> list[dict[str, Any]]:
    """``--stages``: a JSON list of ``{"share": S, "env": {...}}`` whose shares sum to 1 (argparse
    names the option and the value when this raises)."""
    try:
        stages = parse_json(text, "--stages", max_chars=CLI_JSON_CHARS)
    except json.JSONDecodeError as exc:
        raise argparse.ArgumentTypeError(f"not JSON ({exc})") from None
    if not isinstance(stages, list) or not stages:
        raise argparse.ArgumentTypeError("a non-empty JSON list of stages is needed")
    for i, stage in enumerate(stages):
        if not isinstance(stage, dict) or set(stage) - {"share", "env", "name"} or "share" not in stage:
            raise argparse.ArgumentTypeError(
                f"stage {i}: {stage!r} is not an object with 'share' and optionally 'env' and 'name'"
            )
        share = stage["share"]
        if isinstance(share, bool) or not isinstance(share, (int, float)) or not share > 0:
            raise argparse.ArgumentTypeError(f"stage {i}: share={share!r} must be a number > 0")
        if not isinstance(stage.get("env", {}), dict):
            raise argparse.ArgumentTypeError(f"stage {i}: env={stage['env']!r} must be a JSON object")
    total = sum(stage["share"] for stage in stages)
    if abs(total - 1.0) > 1e-9:
        raise argparse.ArgumentTypeError(f"the stages' shares sum to {total!r}, not 1")
    return stages


def _add_ppo_options(parser: argparse.ArgumentParser) -> None:
    """The PPO settings where this command departs from BenchMARL's defaults (learning rate,
    initial spread, standardization, reward scale, GAE, the update schedule)."""
    parser.add_argument(
        "--lr",
        type=float,
        default=3e-4,
        help="Adam's learning rate (default 3e-4, the PPO policies'; BenchMARL's own default is 5e-5)",
    )
    parser.add_argument(
        "--initial-std",
        type=float,
        default=0.37,
        help="the actions' initial standard deviation before the tanh (default 0.37, the PPO "
        "policies' log-std -1; BenchMARL's own is 1.0)",
    )
    parser.add_argument(
        "--normalize-observations",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="standardize each observation entry by its mean and deviation under random actions "
        "on the training layouts (exported with the policy; default on)",
    )
    parser.add_argument(
        "--reward-scale",
        type=float,
        default=1.0,
        help="every reward times this before training (default 1: the env's scale)",
    )
    parser.add_argument(
        "--gae-lambda", type=float, default=0.9, help="GAE's lambda (default 0.9, BenchMARL's; SB3's is 0.95)"
    )
    parser.add_argument(
        "--normalize-advantage",
        action=argparse.BooleanOptionalAction,
        default=False,
        help="standardize the advantages of every minibatch, as SB3's PPO does (default off, BenchMARL's)",
    )
    parser.add_argument(
        "--entropy-coef",
        type=float,
        default=0.0,
        help="weight of the actions' entropy in the loss (default 0, BenchMARL's and SB3's)",
    )
    parser.add_argument(
        "--frames-per-batch",
        type=lambda s: int(s.replace("_", "")),
        default=60_000,
        help="frames collected per iteration (default 60,000)",
    )
    parser.add_argument(
        "--minibatch-size",
        type=lambda s: int(s.replace("_", "")),
        default=4_000,
        help="frames per PPO minibatch (default 4,000; a frame holds every robot's step)",
    )
    parser.add_argument(
        "--epochs", type=int, default=10, help="PPO passes over each iteration's frames (default 10)"
    )


def _add_suite_options(parser: argparse.ArgumentParser) -> None:
    """Training on a benchmark suite (:mod:`baselines.suite_training`; ``--algorithm ippo``)."""
    group = add_suite_options(parser, "one stage, the policy exported and scored every --eval-freq frames")
    group.add_argument(
        "--eval-freq",
        type=lambda s: int(s.replace("_", "")),
        default=1_000_000,
        help="with --suite: frames between scored checkpoints (default 1,000,000; the final policy is scored too)",
    )


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m baselines.marl.benchmarl_train", description=DESCRIPTION)
    parser.add_argument("--task", choices=TASKS, required=True)
    parser.add_argument("--algorithm", choices=ALGORITHMS, default="mappo")
    parser.add_argument("--frames", type=lambda s: int(s.replace("_", "")), default=6_000_000)
    parser.add_argument("--envs", type=int, default=300, help="environments in the batch (default 300)")
    parser.add_argument(
        "--max-cycles",
        type=int,
        default=None,
        help="periods per training episode (default 400; with --suite the benchmark's time limit)",
    )
    parser.add_argument(
        "--collision-penalty",
        type=float,
        default=10.0,
        help="extra penalty of the robot that collides (the PPO policies': 10)",
    )
    parser.add_argument(
        "--precision-shaping",
        type=float,
        default=5.0,
        help="weight of the log-distance potential (the PPO policies': 5)",
    )
    staged = parser.add_mutually_exclusive_group()
    staged.add_argument(
        "--curriculum",
        action="store_true",
        help="train stage by stage on the 3-robot part of the set policies' random-layout "
        "curriculum (baselines.curriculum), each stage resuming the last one's checkpoint",
    )
    staged.add_argument(
        "--stages",
        type=_stage_list,
        metavar="JSON",
        help="train stage by stage on the given layouts, each stage resuming the last one's "
        'checkpoint: a JSON list of {"share": S, "env": {...}} (shares of --frames summing to 1, '
        'env keywords over the task\'s), e.g. \'[{"share": 0.3, "env": {"random_map": '
        '{"n_obstacles": 0}}}, {"share": 0.7, "env": {}}]\'',
    )
    _add_ppo_options(parser)
    parser.add_argument(
        "--features",
        choices=("none", *FEATURE_SETS),
        default="none",
        help="append to each robot's block what the rl-ppo policies read beside it "
        "(baselines.features.robot_features: the target's bearing and log distance, with +headings the "
        "team-mates' relative headings; default none)",
    )
    parser.add_argument(
        "--env-kwargs",
        type=_json_object,
        default={},
        metavar="JSON",
        help='env keywords over the task\'s (a JSON object, e.g. \'{"n_robots": 1, "random_map": '
        "{\"n_obstacles\": 0}}'); they win over a curriculum stage's",
    )
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--threads", type=int, default=1, help="torch threads (default 1)")
    _add_suite_options(parser)
    parser.add_argument(
        "--resume-every",
        type=int,
        default=0,
        metavar="N",
        help="write the resume checkpoint OUT/resume.ckpt every N iterations (N x --frames-per-batch "
        "frames; atomically; default 0: never); one-stage runs only (not --curriculum or --stages)",
    )
    parser.add_argument(
        "--resume",
        action="store_true",
        help="continue the interrupted run in OUT from OUT/resume.ckpt, bit for bit as if it had never "
        "stopped (the same options but --out, --resume-every; baselines.marl.benchmarl_resume)",
    )
    parser.add_argument("--out", required=True)
    return parser
