"""Train a multi-agent PPO policy (MAPPO or IPPO) with BenchMARL on a KoopNav task and export it
for the ``mappo`` / ``ippo`` controllers (:mod:`baselines.marl_policy`).

    python -m baselines.benchmarl_train --task target_reaching --algorithm mappo \\
        --frames 6_000_000 --out runs/mappo_tr

BenchMARL trains on the task's batched vector env (:mod:`baselines.torchrl_env`) with its own
algorithm and network defaults (MLP 256x256 with Tanh, parameters shared by the robots, a
centralised critic for MAPPO) except the batch settings below, which the vector env makes
cheap: ``--envs`` environments, 60,000 frames per iteration, 10 PPO epochs of 4,000-frame
minibatches, and the learning rate (``--lr``, default 3e-4 as for the PPO policies: at
BenchMARL's 5e-5 no episode had arrived after 1.4 M frames of the curriculum's first stage). The env: 3 robots, random layouts, random slip, ``--max-cycles`` periods per
episode, KoopNav's rewards plus the training terms the PPO policies train with
(:mod:`baselines.shaping`: ``--collision-penalty``, ``--precision-shaping``; 0 and 0 for the
env's reward alone). ``--out`` receives BenchMARL's run folder
(its CSV logs and checkpoint) and the export: ``policy.npz`` (the actor's weights and the
action bounds, numpy arrays only: loaded without pickle) and ``metadata.json`` (the command,
seed, frames, wall time, versions and the evaluation curve).
"""

from __future__ import annotations

import argparse
import csv
import json
import platform
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from baselines.robot_features import FEATURE_SETS

TASKS = ("target_reaching", "formation")
ALGORITHMS = ("mappo", "ippo")


def _json_object(text: str) -> dict[str, Any]:
    """``--env-kwargs``: a JSON object (argparse names the option and the value when this raises)."""
    try:
        value = json.loads(text)
    except json.JSONDecodeError as exc:
        raise argparse.ArgumentTypeError(f"not JSON ({exc})") from None
    if not isinstance(value, dict):
        raise argparse.ArgumentTypeError(
            f"a JSON object of env keywords is needed, not {type(value).__name__}"
        )
    return value


def _features(args: argparse.Namespace) -> str | None:
    return None if args.features == "none" else str(args.features)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m baselines.benchmarl_train", description=__doc__.split("\n\n")[0]
    )
    parser.add_argument("--task", choices=TASKS, required=True)
    parser.add_argument("--algorithm", choices=ALGORITHMS, default="mappo")
    parser.add_argument("--frames", type=lambda s: int(s.replace("_", "")), default=6_000_000)
    parser.add_argument("--envs", type=int, default=300, help="environments in the batch (default 300)")
    parser.add_argument(
        "--max-cycles", type=int, default=400, help="periods per training episode (default 400)"
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
    parser.add_argument(
        "--curriculum",
        action="store_true",
        help="train stage by stage on the 3-robot part of the set policies' random-layout "
        "curriculum (baselines.curriculum), each stage resuming the last one's checkpoint",
    )
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
        "--features",
        choices=("none", *FEATURE_SETS),
        default="none",
        help="append to each robot's block what the rl-ppo policies read beside it "
        "(baselines.robot_features: the target's bearing and log distance, with +headings the "
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
    parser.add_argument("--out", required=True)
    return parser


def experiment(
    task: Any,
    config: Any,
    algorithm: str = "mappo",
    seed: int = 0,
    initial_std: float | None = None,
    gae_lambda: float | None = None,
) -> Any:
    """A BenchMARL experiment of ``algorithm`` (``"mappo"`` or ``"ippo"``) on a KoopNav ``task``
    with BenchMARL's default networks (MLP for the actor and the critic) and ``config`` (an
    ``ExperimentConfig``): the one place this project builds one. ``initial_std``: the actions'
    standard deviation before the tanh at the start (BenchMARL's default 1.0 when None);
    ``gae_lambda``: GAE's lambda (BenchMARL's 0.9 when None)."""
    from benchmarl.algorithms import IppoConfig, MappoConfig
    from benchmarl.experiment import Experiment
    from benchmarl.models.mlp import MlpConfig

    if algorithm not in ALGORITHMS:
        raise ValueError(f"algorithm={algorithm!r} is not one of {list(ALGORITHMS)}")
    algorithm_config = (MappoConfig if algorithm == "mappo" else IppoConfig).get_from_yaml()
    if initial_std is not None:
        if not initial_std > 0:
            raise ValueError(f"initial_std={initial_std!r} must be > 0")
        algorithm_config.scale_mapping = f"biased_softplus_{initial_std}"
    if gae_lambda is not None:
        if not 0 <= gae_lambda <= 1:
            raise ValueError(f"gae_lambda={gae_lambda!r} must be in [0, 1]")
        algorithm_config.lmbda = gae_lambda
    return Experiment(
        task=task,
        algorithm_config=algorithm_config,
        model_config=MlpConfig.get_from_yaml(),
        critic_model_config=MlpConfig.get_from_yaml(),
        seed=seed,
        config=config,
    )


#: the curriculum part whose team size MAPPO trains on (an MLP actor takes one team size)
CURRICULUM_TEAM = 3


def curriculum_plan(task: str, frames: int) -> list[tuple[str, int, dict[str, Any]]]:
    """(stage name, cumulative frames at its end, env keywords) of every stage of the set
    policies' curriculum (:data:`baselines.curriculum.STAGES`) for its 3-robot part, with the
    stages' shares of ``frames``; the last stage ends at ``frames`` exactly."""
    from baselines.curriculum import PARTS, STAGES, stage_parts

    part = [n for n, _ in PARTS].index(CURRICULUM_TEAM)
    plan, done = [], 0.0
    for stage in STAGES[task]:
        done += stage.share
        _, _, env_kwargs = stage_parts(task, stage)[part]
        plan.append((stage.name, int(round(done * frames)), env_kwargs))
    plan[-1] = (plan[-1][0], frames, plan[-1][2])
    return plan


def _experiment(
    args: argparse.Namespace,
    folder: Path,
    env_kwargs: dict[str, Any] | None = None,
    frames: int | None = None,
    restore: Path | None = None,
    stats: tuple[np.ndarray, np.ndarray] | None = None,
) -> Any:
    import torch
    from benchmarl.experiment import ExperimentConfig

    from baselines.benchmarl_task import KoopNavTask

    torch.set_num_threads(args.threads)
    task = getattr(KoopNavTask, args.task.upper()).get_task()
    task.config.update(
        {
            "max_cycles": args.max_cycles,
            "vectorized": True,
            "collision_penalty": args.collision_penalty,
            "precision_shaping": args.precision_shaping,
            "reward_scale": args.reward_scale,
            **(env_kwargs or {}),
            **args.env_kwargs,
        }
    )
    if _features(args) is not None:
        task.config["features"] = _features(args)
    if stats is not None:
        task.config["observation_stats"] = [stats[0].tolist(), stats[1].tolist()]
    config = ExperimentConfig.get_from_yaml()
    config.max_n_frames, config.max_n_iters = args.frames if frames is None else frames, None
    config.lr = args.lr
    config.on_policy_collected_frames_per_batch = 60_000
    config.on_policy_n_envs_per_worker = args.envs
    config.on_policy_n_minibatch_iters, config.on_policy_minibatch_size = 10, 4_000
    config.evaluation, config.evaluation_interval, config.evaluation_episodes = True, 600_000, 20
    config.render, config.loggers, config.create_json = False, ["csv"], True
    config.save_folder, config.checkpoint_at_end = str(folder), True
    config.restore_file = None if restore is None else str(restore)
    return experiment(task, config, args.algorithm, args.seed, args.initial_std, args.gae_lambda)


def _last_checkpoint(folder: Path) -> Path:
    """The newest checkpoint BenchMARL wrote under ``folder`` (its run folder's checkpoints/)."""
    files = list(folder.glob("*/checkpoints/checkpoint_*.pt"))
    if not files:
        raise RuntimeError(f"BenchMARL wrote no checkpoint under {folder}")
    return max(files, key=lambda path: int(path.stem.rsplit("_", 1)[1]))


def _statistics(args: argparse.Namespace) -> tuple[np.ndarray, np.ndarray] | None:
    """The observation statistics of the layouts the policy ends its training on (the
    curriculum's last stage, or the task's random layouts), or None without
    ``--normalize-observations``: every stage standardizes with the same figures."""
    if not args.normalize_observations:
        return None
    from baselines.benchmarl_task import _ENV_IDS
    from baselines.torchrl_env import observation_statistics

    return observation_statistics(_ENV_IDS[args.task], features=_features(args), **_final_env(args))


def _final_env(args: argparse.Namespace) -> dict[str, Any]:
    """The env keywords of the layouts the training ends on (the curriculum's last stage, or the
    task's defaults), with ``--env-kwargs`` over them."""
    from baselines.benchmarl_task import TASK_CONFIGS

    if args.curriculum:
        env_kwargs = dict(curriculum_plan(args.task, args.frames)[-1][2])
    else:
        env_kwargs = {
            k: v for k, v in TASK_CONFIGS[args.task].items() if k not in ("max_cycles", "vectorized")
        }
    return {**env_kwargs, **args.env_kwargs}


def _train(
    args: argparse.Namespace, folder: Path, stats: tuple[np.ndarray, np.ndarray] | None
) -> tuple[Any, list[dict[str, Any]]]:
    """Run the training (stage by stage with ``--curriculum``); the last experiment and the
    stages run (name, frames at the end, env keywords)."""
    if not args.curriculum:
        run = _experiment(args, folder, stats=stats)
        run.run()
        return run, []
    stages, restore, run = [], None, None
    for name, frames, env_kwargs in curriculum_plan(args.task, args.frames):
        run = _experiment(args, folder, env_kwargs, frames, restore, stats)
        run.run()
        restore = _last_checkpoint(folder)
        stages.append({"name": name, "frames_end": frames, "env": env_kwargs})
    return run, stages


def export_actor(policy: Any, stats: tuple[np.ndarray, np.ndarray] | None = None) -> dict[str, np.ndarray]:
    """The deterministic actor of a BenchMARL MAPPO/IPPO policy (shared MLP parameters) as numpy
    arrays: ``weight_i``/``bias_i`` of its Linear layers in order (Tanh between them), the
    action bounds ``low``/``high`` of its TanhNormal head, and with ``stats`` the observation
    statistics it was trained with (``obs_mean``, ``obs_std``)."""
    state = policy.state_dict()
    layers = sorted(
        {key.rsplit(".", 1)[0] for key in state if key.endswith(".weight") and ".mlp.params." in key},
        key=lambda key: int(key.rsplit(".", 1)[1]),
    )
    arrays = {}
    for i, layer in enumerate(layers):
        arrays[f"weight_{i}"] = state[f"{layer}.weight"].detach().cpu().numpy()
        arrays[f"bias_{i}"] = state[f"{layer}.bias"].detach().cpu().numpy()
    head = policy.module[0].module[1]  # the ProbabilisticActor's distribution module
    kwargs = head.distribution_kwargs
    arrays["low"] = np.asarray(kwargs["low"].cpu().numpy()[0], dtype=np.float32)
    arrays["high"] = np.asarray(kwargs["high"].cpu().numpy()[0], dtype=np.float32)
    if stats is not None:
        arrays["obs_mean"], arrays["obs_std"] = (np.asarray(v, dtype=np.float32) for v in stats)
    return arrays


def _curve(folder: Path) -> list[list[float]]:
    """(frames, mean evaluation episode reward) from BenchMARL's CSV scalars."""
    files = list(folder.glob("*/*/scalars/eval_reward_episode_reward_mean.csv"))
    if not files:
        return []
    with files[0].open() as handle:
        return [[float(row[0]), float(row[1])] for row in csv.reader(handle) if row]


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    # every setting checked before any work starts (statistics, BenchMARL's experiment)
    for name, ok, allowed in (
        ("frames", args.frames > 0, "> 0"),
        ("envs", args.envs > 0, "> 0"),
        ("lr", args.lr > 0, "> 0"),
        ("initial-std", args.initial_std > 0, "> 0"),
        ("reward-scale", args.reward_scale > 0, "> 0"),
        ("gae-lambda", 0 <= args.gae_lambda <= 1, "in [0, 1]"),
    ):
        if not ok:
            parser.error(f"--{name}={getattr(args, name.replace('-', '_'))!r}: allowed {allowed}")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "benchmarl").mkdir(exist_ok=True)  # BenchMARL makes its run folder inside
    start = time.perf_counter()
    stats = _statistics(args)
    experiment, stages = _train(args, out / "benchmarl", stats)
    wall = time.perf_counter() - start
    arrays = export_actor(experiment.policy, stats)
    np.savez(out / "policy.npz", **arrays)  # type: ignore[arg-type]  # numpy's stub types **kwds as allow_pickle
    import benchmarl
    import torch
    import torchrl

    metadata = {
        "algorithm": args.algorithm,
        "task": args.task,
        "n_robots": int(_final_env(args).get("n_robots", 3)),
        "observation_size": int(arrays["weight_0"].shape[1]),
        "features": _features(args),
        "arrays": sorted(arrays),
        "env": {**_final_env(args), "max_cycles": args.max_cycles},
        "curriculum": {"stages": stages} if stages else None,
        "lr": args.lr,
        "initial_std": args.initial_std,
        "reward_scale": args.reward_scale,
        "gae_lambda": args.gae_lambda,
        "normalize_observations": bool(args.normalize_observations),
        "shaping": {"collision_penalty": args.collision_penalty, "precision_shaping": args.precision_shaping},
        "command": "python -m baselines.benchmarl_train " + " ".join(sys.argv[1:] if argv is None else argv),
        "seed": args.seed,
        "frames": int(experiment.total_frames),
        "wall_seconds": round(wall, 1),
        "versions": {
            "benchmarl": benchmarl.__version__ if hasattr(benchmarl, "__version__") else "?",
            "torchrl": torchrl.__version__,
            "torch": torch.__version__,
            "python": platform.python_version(),
        },
        "eval_curve": _curve(out / "benchmarl"),
    }
    (out / "metadata.json").write_text(json.dumps(metadata, indent=1) + "\n")
    print(f"{args.algorithm} on {args.task}: {metadata['frames']} frames in {wall:.0f} s; exported to {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
