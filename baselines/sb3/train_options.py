"""The command line of ``python -m baselines.sb3.train``: its options and the tables they draw on.

Kept apart from :mod:`baselines.sb3.train` (the training run) so that each module has one job.
"""

from __future__ import annotations

import argparse
import dataclasses
from typing import Any

from baselines.sb3.vec_env import FEATURE_SETS, LAYOUTS
from baselines.suite_training import SuiteTraining, add_suite_options
from koopman_envs import TASKS, keyword_argument
from koopman_envs.checks import CLI_JSON_CHARS, parse_json
from koopman_envs.settings import UNCERTAINTY_PRESETS

__all__ = [
    "POLICIES",
    "TASK_OF",
    "TIMESTEPS",
    "TRAIN_MAPS",
    "build_parser",
    "env_options",
    "plant_and_slips",
    "suite_options",
]

DESCRIPTION = "Train a stable-baselines3 policy on a KoopNav task."
TASK_OF = {spec.env_id: name for name, spec in TASKS.items()}  # the task table's names
# training layouts (map="random"): target reaching also sees crossing paths and Map 2's obstacle
# count, so that the policy meets both evaluation maps' situations in training
TRAIN_MAPS = {
    "KoopNav-TargetReaching-v0": {"n_obstacles": 5, "swap_targets": 0.5},
    "KoopNav-Formation-v0": {},
}
# the budgets of the shipped policies (robot-steps; ~20-25 min each on 2 cores)
TIMESTEPS = {"KoopNav-TargetReaching-v0": 14_000_000, "KoopNav-Formation-v0": 12_000_000}
POLICIES = ("mlp", "set")


def json_value(text: str) -> Any:
    """A JSON option value, its size and nesting bounded (argparse names the option when this
    raises ``ValueError``)."""
    return parse_json(text, "a JSON option value", max_chars=CLI_JSON_CHARS)


def rollout_count(text: str) -> int:
    """A whole number of rollouts >= 0 (argparse names the option when this raises)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number of rollouts (0: never)") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"{value} is negative; allowed: 0 (never) or more rollouts")
    return value


def env_options(parser: argparse.ArgumentParser) -> None:
    """The training envs' options: layouts, seed, checkpoints, time limit, uncertainty."""
    parser.add_argument(
        "--random-map",
        type=json_value,
        default=None,
        help="RandomMapConfig fields as JSON (default: the task's TRAIN_MAPS entry)",
    )
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--eval-freq",
        type=lambda s: int(s.replace("_", "")),
        default=2_000_000,
        help="steps between checkpoints (each also evaluated: on the paper maps, on held-out random "
        "layouts (set policy), or on the validation layouts (--suite))",
    )
    parser.add_argument(
        "--max-episode-steps",
        type=int,
        default=None,
        help="time limit of a training episode [periods] (default 400; with --suite the benchmark's)",
    )
    parser.add_argument(
        "--uncertainty",
        default="nominal",
        choices=list(UNCERTAINTY_PRESETS),
        help="runtime-uncertainty preset of every training and validation env (pose noise, radio, "
        "actuation delay; the curriculum keeps its own slip) (default nominal)",
    )
    parser.add_argument(
        "--movers",
        type=json_value,
        default=None,
        help="moving obstacles of every training and validation env: the movers keyword as JSON, "
        'e.g. \'{"count": 6, "behaviour": "waypoints"}\' (set policies; default: none)',
    )
    parser.add_argument(
        "--mover-slots", type=int, default=4, help="set policy with --movers: mover slots (default 4)"
    )
    parser.add_argument(
        "--resume-every",
        type=rollout_count,
        default=10,
        metavar="N",
        help="PPO: write the resume checkpoint OUT/resume.ckpt every N rollouts (atomically; 0: never; "
        "default 10)",
    )
    parser.add_argument(
        "--resume",
        action="store_true",
        help="continue the interrupted run in OUT from OUT/resume.ckpt, bit for bit as if it had never "
        "stopped (the same options; a foreign, torn or other run's file is refused by name)",
    )


def build_parser() -> argparse.ArgumentParser:
    """The training command line (``python -m baselines.sb3.train``)."""
    parser = argparse.ArgumentParser(prog="python -m baselines.sb3.train", description=DESCRIPTION)
    parser.add_argument("--env", default="KoopNav-Formation-v0", choices=list(TASK_OF))
    parser.add_argument("--algo", default="ppo", choices=["ppo", "sac"])
    parser.add_argument(
        "--policy",
        default="mlp",
        choices=POLICIES,
        help="mlp: the 3-robot MLP over a fixed team (rl-ppo); set: the set encoder for any team size, on "
        "the curriculum of baselines.curriculum (rl-ppo-set-v0) or --suite's train layouts (rl-ppo-set)",
    )
    parser.add_argument("--neighbours", type=int, default=6, help="set policy: team-mate slots")
    parser.add_argument("--obstacles", type=int, default=6, help="set policy: obstacle slots")
    parser.add_argument("--sensing-radius", type=float, default=3.0, help="set policy: sensing radius [m]")
    parser.add_argument("--set-width", type=int, default=64, help="set policy: encoder width")
    parser.add_argument(
        "--timesteps",
        type=lambda s: int(s.replace("_", "")),
        default=None,
        help="robot-steps in the robot layout (default: the task's TIMESTEPS entry)",
    )
    parser.add_argument("--n-envs", type=int, default=128, help="simulated environments (PPO; mlp policy)")
    parser.add_argument("--n-steps", type=int, default=128, help="PPO rollout length per sub-env")
    parser.add_argument("--batch-size", type=int, default=2048, help="PPO minibatch size")
    parser.add_argument(
        "--validation-episodes",
        type=int,
        default=8,
        help="set policy: held-out layouts per validation cell when scoring a checkpoint",
    )
    parser.add_argument(
        "--layout",
        default="robot",
        choices=LAYOUTS,
        help="robot: one policy shared by every robot (default); team: centralized",
    )
    parser.add_argument(
        "--collision-penalty",
        type=float,
        default=10.0,
        help="robot layout: extra penalty for the robot that collides",
    )
    parser.add_argument(
        "--features",
        default="bearing+headings",
        choices=FEATURE_SETS,
        help="robot layout: what the shared policy sees beside its block",
    )
    parser.add_argument(
        "--precision-shaping",
        type=float,
        default=5.0,
        help="robot layout: weight of the log-distance potential term",
    )
    parser.add_argument(
        "--mover-shaping",
        type=float,
        default=0.0,
        help="robot layout with --movers: weight of the per-step cost of coming within "
        "0.5 m of a mover (baselines.shaping.MOVER_SHAPING_BAND; default 0: none)",
    )
    parser.add_argument("--log-std-init", type=float, default=-1.0, help="initial log std of PPO's actions")
    parser.add_argument("--threads", type=int, default=2, help="torch threads")
    parser.add_argument(
        "--init-from",
        default=None,
        metavar="DIR",
        help="start from the weights of a trained policy (a directory with policy.zip, obs_norm.npz "
        "and metadata.json of the same task, policy kind and network) instead of random ones: "
        "fine-tuning, e.g. under another --uncertainty",
    )
    parser.add_argument(
        "--net",
        type=lambda s: [int(w) for w in s.split(",")],
        default=[128, 128],
        help="hidden layer widths of actor and critic, e.g. 128,128",
    )
    env_options(parser)
    suite_options(parser)
    parser.add_argument("--out", required=True)
    return parser


def suite_options(parser: argparse.ArgumentParser) -> None:
    """The options of a suite run: both trainers' (:func:`add_suite_options`), then this one's
    ``--plant`` (the env keyword's own check) and ``--slips``."""
    group = add_suite_options(
        parser, "no curriculum, every --eval-freq checkpoint scored on the validation layouts"
    )
    # None: the env's default (kinematic), and a resume file written before the option existed fits
    plant = keyword_argument("plant")
    plant.update(default=None, help="with --suite: " + plant["help"])
    group.add_argument("--plant", metavar="PLANT", **plant)
    group.add_argument(
        "--slips",
        nargs="+",
        metavar="SLIP",
        default=None,
        help="with --suite: the slip levels trained and validated on (training envs split evenly "
        "between them; every validation layout played at each), e.g. nominal high, the sim-to-sim "
        "protocol's; default: the benchmark's (high)",
    )


def plant_and_slips(
    args: argparse.Namespace, suite: SuiteTraining | None, n_envs: int, parser: argparse.ArgumentParser
) -> SuiteTraining | None:
    """``suite`` with the plant and slip levels of :func:`plant_options`, checked before any work
    (a bad setting ends the command through ``parser.error`` naming it)."""
    # the curriculum draws kinematic slips ("random", "drift") that the physics plant has not
    given = [f"--{o}" for o in ("plant", "slips") if getattr(args, o) is not None]
    if not given:
        return suite
    if suite is None:
        parser.error(f"{' and '.join(given)} need --suite NAME (the curriculum runs the kinematic plant)")
    suite = dataclasses.replace(
        suite, plant=args.plant or suite.plant, slips=tuple(args.slips or suite.slips)
    )
    try:
        suite.check()
    except ValueError as exc:
        parser.error(str(exc))
    if n_envs < len(suite.slip_levels):
        parser.error(f"--n-envs {n_envs} is fewer than the {len(suite.slip_levels)} slip levels")
    return suite
