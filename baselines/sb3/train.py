"""Train a stable-baselines3 policy on a KoopNav task.

``python -m baselines.sb3.train --env KoopNav-Formation-v0 --out runs/formation``

Trains PPO on the native vector env with random maps and random slip levels per episode (so
that the policy generalizes to the evaluation maps instead of memorizing them), with normalized
observations and rewards (SB3's ``VecNormalize``) and actions in [-1, 1]. By default one policy
is shared by every robot (``--layout robot``, see :mod:`baselines.sb3.vec_env`), with training-side
shaping (per-robot collision credit, a log-distance potential) recorded in the metadata. Logs go
to ``OUT/progress.csv`` (no TensorBoard); checkpoints to ``OUT/checkpoints``; every
``--eval-freq`` steps the deterministic policy is evaluated on the task's paper maps at nominal
slip. The final ``OUT`` holds ``policy.zip``, ``obs_norm.npz`` and ``metadata.json`` (the files
``rl-ppo`` loads).

``--suite koopnav-bench-v1`` trains on the task's ``train`` layouts of the benchmark suite under
the benchmark's settings instead (high slip, 5 cm start noise, its time limit; no curriculum),
scores every checkpoint on the ``validation`` layouts through the evaluator, and keeps the best
in ``OUT/<task>/`` (a policy root: ``rl-ppo-set:policy_root=OUT``) with the selection record
``OUT/selection.json``; ``--split test`` is refused by name (:mod:`baselines.suite_training`).
"""

from __future__ import annotations

import argparse
import platform
import sys
import time
from pathlib import Path
from typing import Any, cast

import gymnasium as gym
import numpy as np

import koopman_envs
from baselines.curriculum import PARTS, STAGES, stage_parts
from baselines.features.set_features import SetFeatureConfig
from baselines.sb3 import resume_state
from baselines.sb3.fine_tune import copy_weights, mismatches
from baselines.sb3.policy import ObsNorm, norm_of, save_policy
from baselines.sb3.select import evaluate_policy_on_maps
from baselines.sb3.train_options import TASK_OF, TIMESTEPS, TRAIN_MAPS, build_parser, plant_and_slips
from baselines.sb3.vec_env import KoopNavSB3VecEnv, MixtureVecEnv, split_envs
from baselines.suite_training import CheckpointScore, SuiteTraining, choose, keep_chosen, suite_from_args
from evaluation.exit_codes import BAD_INPUT_EXIT, SUCCESS_EXIT


class Trainer:
    """One training run: its environments, model, checkpoint scoring and metadata, in the order
    ``main`` calls them (the order fixes what the seed draws, so it does not change)."""

    def __init__(
        self, args: argparse.Namespace, parser: argparse.ArgumentParser, argv: list[str] | None
    ) -> None:
        self.args, self.argv = args, argv
        self.out = Path(args.out)
        self.random_map = TRAIN_MAPS[args.env] if args.random_map is None else args.random_map
        if args.timesteps is None:
            args.timesteps = TIMESTEPS[args.env]
        self.n_envs = args.n_envs if args.algo == "ppo" else min(args.n_envs, 8)
        self.task = TASK_OF[args.env]
        self.set_config: SetFeatureConfig | None = None
        if args.policy == "set":
            if args.algo != "ppo" or args.layout != "robot":
                parser.error("--policy set trains PPO in the robot layout")
            try:
                movers = args.mover_slots if args.movers else 0
                self.set_config = SetFeatureConfig(
                    args.neighbours, args.obstacles, args.sensing_radius, movers
                )
            except ValueError as exc:
                parser.error(str(exc))
        if not np.isfinite(args.mover_shaping) or args.mover_shaping < 0:
            parser.error(f"--mover-shaping {args.mover_shaping} must be a finite number >= 0")
        if args.mover_shaping and (not args.movers or args.layout != "robot"):
            parser.error(
                f"--mover-shaping {args.mover_shaping} needs --movers and the robot layout "
                f"(got {'no --movers' if not args.movers else '--layout ' + args.layout})"
            )
        self.suite = self._suite(args, parser)
        if args.max_episode_steps is None:
            args.max_episode_steps = (
                400 if self.suite is None else self.suite.env_kwargs()["max_episode_steps"]
            )
        self.history: list[dict] = []
        #: a suite run's checkpoints as scored on the validation layouts, in order
        self.scores: list[CheckpointScore] = []
        #: the policy this run was fine-tuned from (``--init-from``), recorded in the metadata
        self.init_source: dict[str, Any] | None = None
        #: earlier sessions' wall time [s], this one's start, the steps each resumed session began at
        self.wall_before, self.session_start, self.resumed_from = 0.0, time.perf_counter(), list[int]()

    def _suite(self, args: argparse.Namespace, parser: argparse.ArgumentParser) -> SuiteTraining | None:
        """The run's :class:`SuiteTraining` with ``--suite`` (None without), checked before any
        work: the test split is refused by name (the tuner's check), as are the options a suite
        run's layouts replace."""
        suite = suite_from_args(args, self.task, parser)
        clashes = [
            f"--{o.replace('_', '-')}" for o in ("random_map", "movers") if getattr(args, o) is not None
        ]
        if suite is not None and clashes:
            parser.error(
                f"--suite {args.suite} cannot be combined with {', '.join(clashes)}: a suite run trains on "
                "the suite's layouts under the benchmark's settings"
            )
        return plant_and_slips(args, suite, self.n_envs, parser)

    @property
    def controller(self) -> tuple[str, dict[str, Any]]:
        """The registered controller that plays this run's policies, and its options but the root
        (``threads=None``: scoring a checkpoint leaves the training's torch threads alone)."""
        if self.set_config is not None:
            return "rl-ppo-set", {"threads": None}
        return "rl-ppo", {"algo": self.args.algo, "threads": None}

    def make_venv(self, stage: int) -> KoopNavSB3VecEnv | MixtureVecEnv:
        """The training env: one vector env (the suite's training layouts with ``--suite``), or
        the curriculum stage's parts side by side."""
        args = self.args
        shared = {
            "layout": args.layout,
            "collision_penalty": args.collision_penalty if args.layout == "robot" else 0.0,
            "precision_shaping": args.precision_shaping if args.layout == "robot" else 0.0,
            "mover_shaping": args.mover_shaping,
            "max_episode_steps": args.max_episode_steps,
            "uncertainty": args.uncertainty,
            **({"movers": args.movers} if args.movers else {}),
        }
        if self.suite is not None:  # its layouts, plant, settings (--max-episode-steps wins); a part per slip
            observe = {"set_config": self.set_config} if self.set_config else {"features": args.features}
            parts = [{**self.suite.env_kwargs(slip), **shared} for slip in self.suite.slip_levels]
            return split_envs(args.env, self.n_envs, args.seed, parts, **observe)
        if self.set_config is None:
            return KoopNavSB3VecEnv(
                args.env,
                self.n_envs,
                seed=args.seed,
                features=args.features,
                map="random",
                slip="random",
                random_map=self.random_map,
                **shared,
            )
        # part i of stage s seeds its envs from seed + 10_000 s + 1_000 i: no layout repeats
        return MixtureVecEnv(
            [
                KoopNavSB3VecEnv(
                    args.env,
                    k,
                    seed=args.seed + 10_000 * stage + 1_000 * i,
                    set_config=self.set_config,
                    **shared,
                    **kw,
                )
                for i, (_, k, kw) in enumerate(stage_parts(self.task, STAGES[self.task][stage]))
            ]
        )

    def wrap(self, raw: KoopNavSB3VecEnv | MixtureVecEnv) -> Any:
        """``raw`` monitored (episode return, length, success in the CSV log) and normalized."""
        from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

        monitored = VecMonitor(raw, info_keywords=("is_success",))
        # set observations are scaled by hand (a running normalization would also move the masks)
        return VecNormalize(
            monitored, norm_obs=self.set_config is None, norm_reward=True, clip_obs=10.0, gamma=0.99
        )

    def build_model(self, venv: Any, resuming: bool = False) -> Any:
        """PPO (or SAC) on ``venv``, logging CSV into the run's folder; ``resuming``: without a
        seed and without ``--init-from`` (the resume checkpoint's state replaces both)."""
        from stable_baselines3 import PPO, SAC
        from stable_baselines3.common.logger import configure

        args = self.args
        # a narrow initial action noise: the goal tolerance (0.1 m) asks for fine control, and wide
        # noise mostly produces early collisions
        policy_kwargs: dict = {"net_arch": args.net, "log_std_init": args.log_std_init}
        if self.set_config is not None:
            from baselines.sb3.set_encoder import SetEncoder

            policy_kwargs["features_extractor_class"] = SetEncoder
            policy_kwargs["features_extractor_kwargs"] = {
                "set_config": self.set_config.as_dict(),
                "width": args.set_width,
            }
        model: PPO | SAC
        if args.algo == "ppo":
            model = PPO(
                "MlpPolicy",
                venv,
                n_steps=args.n_steps,
                batch_size=args.batch_size,
                n_epochs=5,
                learning_rate=3e-4,
                gamma=0.99,
                gae_lambda=0.95,
                clip_range=0.2,
                ent_coef=0.0,
                policy_kwargs=policy_kwargs,
                # a seed would also reseed the restored env's and spaces' generators
                seed=None if resuming else args.seed,
                device="cpu",
                verbose=0,
            )
            model.seed = args.seed
        else:
            model = SAC(
                "MlpPolicy",
                venv,
                learning_rate=3e-4,
                buffer_size=500_000,
                batch_size=256,
                train_freq=1,
                gradient_steps=1,
                policy_kwargs={"net_arch": args.net},
                seed=args.seed,
                device="cpu",
                verbose=0,
            )
        model.set_logger(configure(str(self.out), ["csv"]))
        if self.args.init_from is not None and not resuming:
            self.initialize_from(model, Path(self.args.init_from))
        return model

    def _init_requirements(self) -> dict[str, Any]:
        """What a policy to fine-tune from must share with this run: metadata key -> this run's value."""
        args = self.args
        required = {key: self.identity[key] for key in ("algo", "layout", "features", "task")}
        required["net_arch"] = args.net
        if self.set_config is not None:
            required["set_config"] = self.set_config.as_dict()
            required["set_width"] = args.set_width
        return required

    def initialize_from(self, model: Any, directory: Path) -> None:
        """Copy the weights of the policy in ``directory`` into ``model`` (fine-tuning).

        The policy is loaded without running its pickles and must match this run's task, policy
        kind, features and network (:mod:`baselines.sb3.fine_tune`: a set policy may grow mover
        slots); a mismatch is refused by name before any training.
        """
        from baselines.sb3.policy import load_policy

        loaded, _, metadata = load_policy(directory, self.task, self.args.algo)
        wrong = mismatches(metadata, self._init_requirements())
        if wrong:
            raise ValueError(
                f"--init-from {directory}: the policy does not fit this run ({'; '.join(wrong)})"
            )
        grown = copy_weights(model.policy, loaded.policy)
        self.init_source = {
            "grown": grown,
            "path": str(directory),
            "uncertainty": metadata.get("uncertainty", "nominal"),
            "trained_timesteps": metadata.get("trained_timesteps"),
            "command": metadata.get("command"),
        }

    @property
    def identity(self) -> dict[str, Any]:
        """What every saved policy (checkpoint or final) records: enough to load and to validate it."""
        args = self.args
        identity = {
            "algo": args.algo,
            "layout": args.layout,
            "features": "set" if self.set_config is not None else args.features,
            "env_id": args.env,
            "task": self.task,
            "uncertainty": args.uncertainty,
        }
        if args.movers:
            identity["movers"] = args.movers
        if self.set_config is not None:
            identity["set_config"] = self.set_config.as_dict()
        elif self.suite is None:
            identity["random_map"] = self.random_map
        if self.suite is not None:  # and the plant unless kinematic (no key, as before it existed)
            identity.update(trained_on=self.suite.labels["train"], **self.suite.plant_kwargs())
        return identity

    def score(self, model: Any, policy_norm: ObsNorm, episodes_per_map: int = 2) -> tuple[str, float]:
        """What a checkpoint is scored on: the paper maps (mlp) or held-out layouts (set)."""
        args = self.args
        if self.set_config is None:
            label = "eval success (nominal, paper maps)"
            return label, evaluate_policy_on_maps(
                model, policy_norm, args.env, args.layout, args.features, episodes_per_map
            )
        from baselines.sb3.select import set_validation_success

        return "validation success (held-out random layouts)", set_validation_success(
            model, dict(policy_norm), self.identity, episodes_per_cell=args.validation_episodes
        )

    def suite_checkpoint(self, model: Any, venv: Any, timesteps: int) -> str:
        """Save the policy as checkpoint ``step_<timesteps>/<task>/`` (a policy root) and score it
        on the suite's validation layouts through the evaluator; one line."""
        root = self.out / "checkpoints" / f"step_{timesteps}"
        save_policy(root / self.task, model, venv, {**self.identity, "timesteps": timesteps})
        name, options = self.controller
        assert self.suite is not None  # called for suite runs only
        score = self.suite.score(name, {**options, "policy_root": str(root)}, timesteps, root)
        self.scores.append(score)
        label = f"validation success ({self.suite.labels['selection']}, {score.episodes} episodes)"
        self.history.append({"timesteps": timesteps, "scored_on": label, **score.as_dict()})
        model.logger.record("eval/success_rate", score.success_rate)
        distance = "-" if score.mean_final_distance is None else f"{score.mean_final_distance:.3f} m"
        return f"{timesteps:>10,d} steps  {label} {score.success_rate:.2f}, mean final distance {distance}"

    def checkpoint(self, model: Any, venv: Any, timesteps: int) -> str:
        """Score the policy now, record it in the history and save it as a checkpoint; one line."""
        if self.suite is not None:
            return self.suite_checkpoint(model, venv, timesteps)
        label, rate = self.score(model, norm_of(venv))
        self.history.append({"timesteps": timesteps, "scored_on": label, "success_rate": rate})
        model.logger.record("eval/success_rate", rate)
        save_policy(
            self.out / "checkpoints" / f"step_{timesteps}",
            model,
            venv,
            {**self.identity, "timesteps": timesteps},
        )
        return f"{timesteps:>10,d} steps  {label} {rate:.2f}"

    def learn(self, model: Any, venv: Any, resumed: dict[str, Any] | None = None) -> Any:
        """Train (stage by stage on the curriculum for the set policy); returns the last env.
        ``resumed``: the trainer's state of a resume checkpoint, to continue from."""
        from baselines.sb3.training_callbacks import PeriodicCheckpoints

        args = self.args
        venv_now, where = [venv], {"stage": 0, "start": 0}  # where: the stage trained, its first step
        callback = PeriodicCheckpoints(
            args.eval_freq,
            lambda steps: self.checkpoint(model, venv_now[0], steps),
            args.resume_every if args.algo == "ppo" else 0,  # SAC's replay buffer is not saved
            lambda: resume_state.save(self, model, venv_now[0], callback.state(), where),
        )
        if resumed is not None:
            callback.set_state(resumed["callback"])
            where.update(resumed["where"])
        # a suite run trains on the suite's layouts alone: no curriculum, one stage of the budget
        stages = STAGES[self.task] if self.set_config is not None and self.suite is None else ()
        plan = [(s.name, round(s.share * args.timesteps)) for s in stages] or [("", args.timesteps)]
        for index, (name, steps) in enumerate(plan):
            if resumed is not None and index <= where["stage"]:
                if index == where["stage"]:  # the checkpoint's stage: its env is the restored one
                    left = where["start"] + steps - model.num_timesteps  # SB3 counts on from its count
                    print(f"stage {name or 'all'}: resumed, {left:,} robot-steps left", flush=True)
                    model.learn(total_timesteps=left, callback=callback, reset_num_timesteps=False)
                continue
            if index:
                # the next stage's layouts; the reward scale learnt so far carries over
                returns = venv_now[0].ret_rms
                venv_now[0].close()  # the finished stage's envs
                venv_now[0] = self.wrap(self.make_venv(index))
                venv_now[0].ret_rms = returns
                model.set_env(venv_now[0])  # forces a reset: every episode starts on the new stage
            where.update(stage=index, start=int(model.num_timesteps))
            if name:
                print(f"stage {name}: {steps:,} robot-steps", flush=True)
            model.learn(total_timesteps=steps, callback=callback, reset_num_timesteps=index == 0)
        return venv_now[0]

    def metadata(
        self, model: Any, venv: Any, team_size: int | None, wall: float, final_rate: float
    ) -> dict[str, Any]:
        """What the final policy's ``metadata.json`` records."""
        import stable_baselines3
        import torch

        args = self.args
        metadata = {
            **self.identity,
            "collision_penalty": args.collision_penalty,
            "precision_shaping": args.precision_shaping,
            "mover_shaping": args.mover_shaping,
            "n_robots": team_size,
            "command": "python -m baselines.sb3.train "
            + " ".join(self.argv if self.argv is not None else sys.argv[1:]),
            "seed": args.seed,
            "timesteps": args.timesteps,
            "trained_timesteps": int(model.num_timesteps),  # whole rollouts: a little over the request
            "n_envs": venv.num_envs if self.set_config is not None else self.n_envs,  # set: sub-envs = robots
            "net_arch": args.net,
            "wall_seconds": round(wall, 1),
            "robot_steps_per_second": round(model.num_timesteps / wall),
            # sessions resumed from a resume checkpoint (bit for bit as one uninterrupted run)
            "resumed_from_timesteps": self.resumed_from,
            "eval_history": self.history,
            "initialized_from": self.init_source,
            "versions": {
                "koopnav": koopman_envs.__version__,
                "stable_baselines3": stable_baselines3.__version__,
                "torch": torch.__version__,
                "numpy": np.__version__,
                "gymnasium": gym.__version__,
                "python": platform.python_version(),
            },
        }
        if self.suite is not None:
            metadata["suite"] = self.suite.as_dict()
            metadata["validation_success_rate"] = final_rate
            if self.set_config is not None:
                metadata["set_width"] = args.set_width
        elif self.set_config is None:
            metadata["eval_success_rate_nominal_paper_maps"] = final_rate
        else:
            metadata["set_width"] = args.set_width
            metadata["curriculum"] = {
                "parts": [list(p) for p in PARTS],
                "stages": [stage.as_dict() for stage in STAGES[self.task]],
            }
            metadata["validation_success_rate"] = final_rate
        return metadata


def finish_suite_run(run: Trainer, model: Any, venv: Any, team_size: int | None, wall: float) -> int:
    """A suite run's end: the final policy scored as the last checkpoint, the best checkpoint on
    the validation layouts kept in ``OUT/<task>/`` with the selection record ``OUT/selection.json``."""
    steps = int(model.num_timesteps)
    if not run.scores or run.scores[-1].step != steps:
        print(run.checkpoint(model, venv, steps), flush=True)
    best = choose(run.scores)
    metadata = run.metadata(model, venv, team_size, wall, best.success_rate)
    metadata["selected_timesteps"] = best.step
    chosen = keep_chosen(run.out, cast(SuiteTraining, run.suite), run.scores, metadata, metadata["command"])
    print(
        f"trained {run.args.algo} on {run.args.env} ({metadata['trained_on']}) for {steps:,} steps in "
        f"{wall:.0f} s; kept the checkpoint after {chosen.step:,} steps (validation success "
        f"{chosen.success_rate:.2f}); wrote {run.out / run.task} and {run.out / 'selection.json'}"
    )
    return SUCCESS_EXIT


def main(argv: list[str] | None = None) -> int:
    """Train and save a policy (see the module docstring); bad input (exit 2) without
    stable-baselines3 or with a policy to fine-tune that does not fit."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        import stable_baselines3  # noqa: F401 - only its presence is checked here
        import torch
    except ImportError:
        print(
            "error: training needs stable-baselines3: pip install torch==2.13.0 && pip install -e '.[rl]'",
            file=sys.stderr,
        )
        return BAD_INPUT_EXIT
    run = Trainer(args, parser, argv)
    run.out.mkdir(parents=True, exist_ok=True)
    # PPO's minibatch updates (most of the wall time) use --threads; same seed, same weights: PPO(seed=)
    # seeds Python, numpy and torch, and deterministic algorithms make torch refuse an op without a
    # deterministic kernel. Both restored afterwards: a caller's process keeps its own settings
    previous, previous_threads = torch.are_deterministic_algorithms_enabled(), torch.get_num_threads()
    torch.set_num_threads(args.threads)
    torch.use_deterministic_algorithms(True)
    try:
        return _train(run)
    finally:
        torch.use_deterministic_algorithms(previous)
        torch.set_num_threads(previous_threads)


def _train(run: Trainer) -> int:
    """Build the env and the model (or restore them, ``--resume``), train, score and save
    (``main``'s work once its checks passed)."""
    args = run.args
    resumed = None
    try:
        if args.resume:
            model, venv, resumed = resume_state.resume(run)
        else:
            venv = run.wrap(run.make_venv(0))
            model = run.build_model(venv)
    except ValueError as exc:  # a policy given to --init-from that does not fit; a refused resume file
        print(f"error: {exc}", file=sys.stderr)
        return BAD_INPUT_EXIT
    raw = resume_state.chain_of(venv)[-1]
    team_size = raw.n_robots if isinstance(raw, KoopNavSB3VecEnv) else None
    run.session_start = time.perf_counter()
    venv = run.learn(model, venv, resumed)
    wall = run.wall_before + time.perf_counter() - run.session_start
    if run.suite is not None:
        code = finish_suite_run(run, model, venv, team_size, wall)
    else:
        label, final_rate = run.score(model, norm_of(venv), episodes_per_map=5)
        save_policy(run.out, model, venv, run.metadata(model, venv, team_size, wall, final_rate))
        print(
            f"trained {args.algo} on {args.env} for {args.timesteps:,} steps in {wall:.0f} s; "
            f"{label} {final_rate:.2f}; wrote {run.out}"
        )
        code = SUCCESS_EXIT
    resume_state.finished(run.out)
    return code


if __name__ == "__main__":
    raise SystemExit(main())
