"""Train a multi-agent PPO policy (MAPPO or IPPO) with BenchMARL on a KoopNav task and export it
for the ``mappo`` / ``ippo`` controllers (:mod:`baselines.marl.marl_policy`).

    python -m baselines.marl.benchmarl_train --task target_reaching --algorithm mappo \\
        --frames 6_000_000 --out runs/mappo_tr

BenchMARL trains on the task's batched vector env (:mod:`baselines.marl.torchrl_env`) with its own
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
import functools
import json
import platform
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from baselines.marl import benchmarl_resume
from baselines.marl.benchmarl_options import ALGORITHMS, build_parser
from baselines.resume import RESUME_FILE, ResumeRefused
from baselines.suite_training import choose, keep_chosen
from evaluation.exit_codes import BAD_INPUT_EXIT, SUCCESS_EXIT
from koopman_envs.checks import check_choice
from koopman_envs.files import write_atomic


def _features(args: argparse.Namespace) -> str | None:
    return None if args.features == "none" else str(args.features)


def experiment(
    task: Any,
    config: Any,
    algorithm: str = "mappo",
    seed: int = 0,
    initial_std: float | None = None,
    gae_lambda: float | None = None,
    normalize_advantage: bool = False,
    entropy_coef: float | None = None,
    callbacks: list[Any] | None = None,
    experiment_class: Any = None,
) -> Any:
    """A BenchMARL experiment of ``algorithm`` (``"mappo"`` or ``"ippo"``) on a KoopNav ``task``
    with BenchMARL's default networks (MLP for the actor and the critic) and ``config`` (an
    ``ExperimentConfig``): the one place this project builds one. ``initial_std``: the actions'
    standard deviation before the tanh at the start (BenchMARL's default 1.0 when None);
    ``gae_lambda``: GAE's lambda (BenchMARL's 0.9 when None); ``normalize_advantage``: standardize
    every minibatch's advantages (SB3's PPO does; BenchMARL's losses do not); ``entropy_coef``: the
    entropy bonus's weight (BenchMARL's 0 when None); ``callbacks``: BenchMARL callbacks of the run;
    ``experiment_class``: a subclass of BenchMARL's ``Experiment`` to build (a resumable run's,
    :class:`baselines.marl.benchmarl_resumable.ResumableExperiment`), ``Experiment`` when None."""
    from benchmarl.algorithms import IppoConfig, MappoConfig
    from benchmarl.experiment import Experiment
    from benchmarl.models.mlp import MlpConfig

    check_choice("algorithm", algorithm, ALGORITHMS)
    algorithm_config = (MappoConfig if algorithm == "mappo" else IppoConfig).get_from_yaml()
    if initial_std is not None:
        if not initial_std > 0:
            raise ValueError(f"initial_std={initial_std!r} must be > 0")
        algorithm_config.scale_mapping = f"biased_softplus_{initial_std}"
    if gae_lambda is not None:
        if not 0 <= gae_lambda <= 1:
            raise ValueError(f"gae_lambda={gae_lambda!r} must be in [0, 1]")
        algorithm_config.lmbda = gae_lambda
    if entropy_coef is not None:
        if not entropy_coef >= 0:
            raise ValueError(f"entropy_coef={entropy_coef!r} must be >= 0")
        algorithm_config.entropy_coef = entropy_coef
    run = (Experiment if experiment_class is None else experiment_class)(
        task=task,
        algorithm_config=algorithm_config,
        model_config=MlpConfig.get_from_yaml(),
        critic_model_config=MlpConfig.get_from_yaml(),
        seed=seed,
        config=config,
        callbacks=callbacks,
    )
    if normalize_advantage:  # BenchMARL builds its ClipPPOLoss with normalize_advantage=False
        for loss in run.losses.values():
            loss.normalize_advantage = True
    return run


#: the curriculum part whose team size MAPPO trains on (an MLP actor takes one team size)
CURRICULUM_TEAM = 3


def _staged(
    stages: list[tuple[str, float, dict[str, Any]]], frames: int
) -> list[tuple[str, int, dict[str, Any]]]:
    """(name, cumulative frames at its end, env keywords) from (name, share, env keywords): the
    last stage ends at ``frames`` exactly, whatever the rounding."""
    plan, done = [], 0.0
    for name, share, env_kwargs in stages:
        done += share
        plan.append((name, int(round(done * frames)), env_kwargs))
    plan[-1] = (plan[-1][0], frames, plan[-1][2])
    return plan


def curriculum_plan(task: str, frames: int) -> list[tuple[str, int, dict[str, Any]]]:
    """(stage name, cumulative frames at its end, env keywords) of every stage of the set
    policies' curriculum (:data:`baselines.curriculum.STAGES`) for its 3-robot part, with the
    stages' shares of ``frames``; the last stage ends at ``frames`` exactly."""
    from baselines.curriculum import PARTS, STAGES, stage_parts

    part = [n for n, _ in PARTS].index(CURRICULUM_TEAM)
    return _staged([(st.name, st.share, stage_parts(task, st)[part][2]) for st in STAGES[task]], frames)


def training_plan(args: argparse.Namespace) -> list[tuple[str, int, dict[str, Any]]] | None:
    """(stage name, cumulative frames at its end, env keywords) of a staged training
    (``--curriculum`` or ``--stages``), or None for one stage on the task's layouts."""
    if args.curriculum:
        return curriculum_plan(args.task, args.frames)
    if not args.stages:
        return None
    stages = [
        (str(stage.get("name", f"stage{i}")), stage["share"], dict(stage.get("env", {})))
        for i, stage in enumerate(args.stages)
    ]
    return _staged(stages, args.frames)


def _experiment(
    args: argparse.Namespace,
    folder: Path,
    env_kwargs: dict[str, Any] | None = None,
    frames: int | None = None,
    restore: Path | None = None,
    stats: tuple[np.ndarray, np.ndarray] | None = None,
    callbacks: list[Any] | None = None,
    resumable: bool = False,
) -> Any:
    """The BenchMARL experiment of ``args`` in ``folder``; ``restore``: BenchMARL's checkpoint to
    start from (a stage's) or a resumed run's :func:`baselines.marl.benchmarl_resume.marker`;
    ``resumable``: a resumable run's experiment, with a resume checkpoint every ``--resume-every``
    iterations (:mod:`baselines.marl.benchmarl_resume`)."""
    import torch
    from benchmarl.experiment import ExperimentConfig

    from baselines.marl.benchmarl_task import KoopNavTask

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
    config.on_policy_collected_frames_per_batch = args.frames_per_batch
    config.on_policy_n_envs_per_worker = args.envs
    config.on_policy_n_minibatch_iters = args.epochs
    config.on_policy_minibatch_size = args.minibatch_size
    # an evaluation every 10 iterations
    config.evaluation, config.evaluation_interval, config.evaluation_episodes = (
        True,
        10 * args.frames_per_batch,
        20,
    )
    config.render, config.loggers, config.create_json = False, ["csv"], True
    config.save_folder, config.checkpoint_at_end = str(folder), True
    config.restore_file = None if restore is None else str(restore)
    if resumable:
        config.checkpoint_interval = args.resume_every * args.frames_per_batch
    return experiment(
        task,
        config,
        args.algorithm,
        args.seed,
        args.initial_std,
        args.gae_lambda,
        args.normalize_advantage,
        args.entropy_coef,
        callbacks,
        _resumable_class() if resumable else None,
    )


def _resumable_class() -> Any:
    from baselines.marl.benchmarl_resumable import ResumableExperiment

    return ResumableExperiment


def _last_checkpoint(folder: Path) -> Path:
    """The newest checkpoint BenchMARL wrote under ``folder`` (its run folder's checkpoints/)."""
    files = list(folder.glob("*/checkpoints/checkpoint_*.pt"))
    if not files:
        raise RuntimeError(f"BenchMARL wrote no checkpoint under {folder}")
    return max(files, key=lambda path: int(path.stem.rsplit("_", 1)[1]))


def _statistics(args: argparse.Namespace) -> tuple[np.ndarray, np.ndarray] | None:
    """The observation statistics of the layouts the policy ends its training on (the last
    stage's, or the task's random layouts), or None without
    ``--normalize-observations``: every stage standardizes with the same figures."""
    if not args.normalize_observations:
        return None
    from baselines.marl.benchmarl_task import _ENV_IDS
    from baselines.marl.torchrl_env import observation_statistics

    return observation_statistics(_ENV_IDS[args.task], features=_features(args), **_final_env(args))


def _final_env(args: argparse.Namespace) -> dict[str, Any]:
    """The env keywords of the layouts the training ends on (the last stage of ``--curriculum`` or
    ``--stages``, or the task's defaults), with ``--env-kwargs`` over them."""
    from baselines.marl.benchmarl_task import TASK_CONFIGS

    plan = training_plan(args)
    if plan is not None:
        base = {k: v for k, v in TASK_CONFIGS[args.task].items() if k not in ("max_cycles", "vectorized")}
        env_kwargs = {**base, **plan[-1][2]} if args.stages else dict(plan[-1][2])
    else:
        env_kwargs = {
            k: v for k, v in TASK_CONFIGS[args.task].items() if k not in ("max_cycles", "vectorized")
        }
    return {**env_kwargs, **args.env_kwargs}


def _train_one(
    args: argparse.Namespace,
    out: Path,
    stats: tuple[np.ndarray, np.ndarray] | None,
    callbacks: list[Any],
    resumed: dict[str, Any] | None,
    session: benchmarl_resume.Session,
) -> Any:
    """A one-stage run, resumable (``--resume-every``) or resumed (``resumed``: the state of its
    resume checkpoint, :mod:`baselines.marl.benchmarl_resume`)."""
    folder = out / "benchmarl"
    resumable = args.resume_every > 0 or resumed is not None
    restore = None if resumed is None else benchmarl_resume.marker(folder, resumed["name"])
    run = _experiment(args, folder, restore=restore, stats=stats, callbacks=callbacks, resumable=resumable)
    if args.resume_every > 0:
        run.on_checkpoint = lambda now: benchmarl_resume.save(out, args, now, callbacks, session.extras())
    if resumed is None:
        run.run()
        return run
    benchmarl_resume.restore(run, resumed, callbacks)
    left = int(run.config.get_max_n_frames(run.on_policy)) - int(run.total_frames)
    print(f"resumed from {out / RESUME_FILE} at {int(run.total_frames):,} frames; {left:,} left", flush=True)
    try:  # Experiment.run without its seed_everything (the generators are the checkpoint's)
        run._collection_loop()
    except BaseException:
        run.close()
        raise
    return run


def _train(
    args: argparse.Namespace,
    out: Path,
    stats: tuple[np.ndarray, np.ndarray] | None,
    callbacks: list[Any] | None = None,
    resumed: dict[str, Any] | None = None,
    session: benchmarl_resume.Session | None = None,
) -> tuple[Any, list[dict[str, Any]]]:
    """Run the training (stage by stage with ``--curriculum`` or ``--stages``) into
    ``out/benchmarl``; the last experiment and the stages run (name, frames at the end, env
    keywords). ``callbacks``: of a one-stage run (a suite run's checkpoints); ``resumed``: the
    state of a one-stage run's resume checkpoint to continue from."""
    plan = training_plan(args)
    folder = out / "benchmarl"
    if plan is None:
        run = _train_one(
            args, out, stats, callbacks or [], resumed, session or benchmarl_resume.Session(resumed)
        )
        return run, []
    stages, restore, run = [], None, None
    for name, frames, env_kwargs in plan:
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
    """(frames, mean evaluation episode reward) from BenchMARL's CSV scalars; of a resumed run,
    an iteration logged by the interrupted session and again by the resumed one appears once (the
    resumed session's figure, the same)."""
    files = list(folder.glob("*/*/scalars/eval_reward_episode_reward_mean.csv"))
    if not files:
        return []
    with files[0].open() as handle:
        rows = {float(row[0]): float(row[1]) for row in csv.reader(handle) if row}
    return [[frames, reward] for frames, reward in sorted(rows.items())]


def export_metadata(args: argparse.Namespace, arrays: dict[str, np.ndarray]) -> dict[str, Any]:
    """What the ``mappo``/``ippo`` controllers read of an export's ``metadata.json`` besides its
    arrays (every checkpoint's and the final policy's)."""
    return {
        "algorithm": args.algorithm,
        "task": args.task,
        "n_robots": int(_final_env(args).get("n_robots", 3)),
        "observation_size": int(arrays["weight_0"].shape[1]),
        "features": _features(args),
        "arrays": sorted(arrays),
    }


def export_policy(
    args: argparse.Namespace, stats: tuple[np.ndarray, np.ndarray] | None, policy: Any
) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """The actor's arrays (:func:`export_actor`) and :func:`export_metadata`: a suite run's
    checkpoint export."""
    arrays = export_actor(policy, stats)
    return arrays, export_metadata(args, arrays)


def _metadata(
    args: argparse.Namespace,
    arrays: dict[str, np.ndarray],
    experiment: Any,
    stages: list[dict[str, Any]],
    wall: float,
    command: str,
    folder: Path,
    resumed_from: list[int] | None = None,
) -> dict[str, Any]:
    """The final export's ``metadata.json``: the controller's fields, the settings, the command,
    seed, frames, wall time (every session's), versions and BenchMARL's evaluation curve;
    ``resumed_from``: the frames each resumed session began at (``--resume``)."""
    import benchmarl
    import torch
    import torchrl

    return {
        **export_metadata(args, arrays),
        "env": {**_final_env(args), "max_cycles": args.max_cycles},
        "curriculum": {"stages": stages} if stages else None,
        "lr": args.lr,
        "initial_std": args.initial_std,
        "reward_scale": args.reward_scale,
        "gae_lambda": args.gae_lambda,
        "normalize_advantage": bool(args.normalize_advantage),
        "entropy_coef": args.entropy_coef,
        "ppo": {
            "frames_per_batch": args.frames_per_batch,
            "minibatch_size": args.minibatch_size,
            "epochs": args.epochs,
        },
        "normalize_observations": bool(args.normalize_observations),
        "shaping": {"collision_penalty": args.collision_penalty, "precision_shaping": args.precision_shaping},
        "command": command,
        "seed": args.seed,
        "frames": int(experiment.total_frames),
        "wall_seconds": round(wall, 1),
        "resumed_from_frames": list(resumed_from or []),
        "versions": {
            "benchmarl": benchmarl.__version__ if hasattr(benchmarl, "__version__") else "?",
            "torchrl": torchrl.__version__,
            "torch": torch.__version__,
            "python": platform.python_version(),
        },
        "eval_curve": _curve(folder),
    }


def _check_settings(args: argparse.Namespace, parser: argparse.ArgumentParser) -> None:
    """Every numeric setting checked before any work starts (statistics, BenchMARL's experiment)."""
    for name, ok, allowed in (
        ("frames", args.frames > 0, "> 0"),
        ("envs", args.envs > 0, "> 0"),
        ("lr", args.lr > 0, "> 0"),
        ("initial-std", args.initial_std > 0, "> 0"),
        ("reward-scale", args.reward_scale > 0, "> 0"),
        ("gae-lambda", 0 <= args.gae_lambda <= 1, "in [0, 1]"),
        ("epochs", args.epochs > 0, "> 0"),
        ("resume-every", args.resume_every >= 0, ">= 0 (0: no resume checkpoint)"),
        ("entropy-coef", args.entropy_coef >= 0, ">= 0"),
        ("frames-per-batch", args.frames_per_batch % args.envs == 0, "a multiple of --envs"),
        ("minibatch-size", 0 < args.minibatch_size <= args.frames_per_batch, "in [1, --frames-per-batch]"),
    ):
        if not ok:
            parser.error(f"--{name}={getattr(args, name.replace('-', '_'))!r}: allowed {allowed}")


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    _check_settings(args, parser)
    if (args.resume or args.resume_every > 0) and (args.curriculum or args.stages):
        parser.error("--resume and --resume-every: one-stage runs only, not --curriculum or --stages")
    from baselines.marl.benchmarl_suite import SuiteCheckpoints, suite_training

    training = suite_training(args, parser)  # the test split refused by name, before any work
    if args.max_cycles is None:
        args.max_cycles = 400
    out = Path(args.out)
    resumed = None
    if args.resume:  # refused by name before any work
        try:
            resumed = benchmarl_resume.read(out, args)
        except ResumeRefused as exc:
            print(f"error: {exc}", file=sys.stderr)
            return BAD_INPUT_EXIT
    session = benchmarl_resume.Session(resumed)
    out.mkdir(parents=True, exist_ok=True)
    (out / "benchmarl").mkdir(exist_ok=True)  # BenchMARL makes its run folder inside
    command = "python -m baselines.marl.benchmarl_train " + " ".join(sys.argv[1:] if argv is None else argv)
    start = time.perf_counter()
    stats = _statistics(args)

    # a module-level function: BenchMARL pickles its callbacks
    export = functools.partial(export_policy, args, stats)
    checkpoints = (
        None if training is None else SuiteCheckpoints(training, out, args.eval_freq, export, args.algorithm)
    )
    experiment, stages = _train(
        args, out, stats, None if checkpoints is None else [checkpoints], resumed, session
    )
    wall = session.wall_before + time.perf_counter() - start
    arrays = export_actor(experiment.policy, stats)
    metadata = _metadata(
        args, arrays, experiment, stages, wall, command, out / "benchmarl", session.resumed_from
    )
    if checkpoints is not None and training is not None:
        scores = checkpoints.finish(experiment.policy, int(experiment.total_frames))
        best = choose(scores)
        metadata.update(
            suite=training.as_dict(), selected_frames=best.step, validation_success_rate=best.success_rate
        )
        keep_chosen(out, training, scores, metadata, command)
        (out / RESUME_FILE).unlink(missing_ok=True)  # finished: nothing is left to resume
        print(
            f"{args.algorithm} on {args.task} ({training.labels['train']}): {metadata['frames']} frames in "
            f"{wall:.0f} s; kept the export after {best.step:,} frames (validation success "
            f"{best.success_rate:.2f}) in {out / args.task}"
        )
        return SUCCESS_EXIT
    # whole or not at all: the policy is read back by the evaluator
    write_atomic(out / "policy.npz", lambda temporary: np.savez(temporary, **arrays))  # type: ignore[arg-type]  # numpy's stub types **kwds as allow_pickle
    write_atomic(out / "metadata.json", json.dumps(metadata, indent=1) + "\n")
    (out / RESUME_FILE).unlink(missing_ok=True)  # finished: nothing is left to resume
    print(f"{args.algorithm} on {args.task}: {metadata['frames']} frames in {wall:.0f} s; exported to {out}")
    return SUCCESS_EXIT


if __name__ == "__main__":
    raise SystemExit(main())
