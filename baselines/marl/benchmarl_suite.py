"""``python -m baselines.marl.benchmarl_train --suite NAME``: IPPO trained on a benchmark suite's train
layouts, its checkpoint chosen on the validation layouts (:mod:`baselines.suite_training`).

BenchMARL keeps no policy per iteration that the ``ippo`` controller could play, so
:class:`SuiteCheckpoints` (a BenchMARL callback) exports the actor every ``--eval-freq`` frames
after the iteration's training (``OUT/checkpoints/frames_<F>/<task>/``: ``policy.npz`` and
``metadata.json``, as the final export) and scores it on the validation layouts through the
evaluator; the final policy is scored too, and the best is kept in ``OUT/<task>/``.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from benchmarl.experiment.callback import Callback

from baselines.suite_training import CheckpointScore, SuiteTraining, refuse_held_out_map, suite_from_args
from koopman_envs.files import write_atomic

__all__ = ["SuiteCheckpoints", "suite_training", "write_export"]

#: the algorithms a suite run trains: those with a registered controller to score checkpoints
SUITE_ALGORITHMS = ("ippo",)
#: env keywords a suite run sets itself (the layouts and the benchmark's settings)
_SUITE_KEYWORDS = ("map", "slip", "start_noise", "goal_tolerance", "max_episode_steps")


def write_export(folder: Path, arrays: dict[str, np.ndarray], metadata: dict[str, Any]) -> None:
    """Write an exported policy (``policy.npz`` and ``metadata.json``) to ``folder``, each file
    whole or not at all."""
    folder.mkdir(parents=True, exist_ok=True)
    write_atomic(folder / "policy.npz", lambda tmp: np.savez(tmp, **arrays))  # type: ignore[arg-type]
    write_atomic(folder / "metadata.json", json.dumps(metadata, indent=1) + "\n")


def suite_training(args: argparse.Namespace, parser: argparse.ArgumentParser) -> SuiteTraining | None:
    """The run's :class:`SuiteTraining` with ``--suite`` (None without), checked before any
    work; a suite run's env keywords go into ``args.env_kwargs`` and its time limit into
    ``args.max_cycles``. In every run, an env ``map`` naming a test split (in ``--env-kwargs`` or
    a stage) is refused by name: the tuner's check."""
    try:
        refuse_held_out_map(args.env_kwargs)
        for stage in args.stages or ():
            refuse_held_out_map(stage.get("env", {}))
    except ValueError as exc:
        parser.error(str(exc))
    training = suite_from_args(args, args.task, parser)
    if training is None:
        return None
    if args.algorithm not in SUITE_ALGORITHMS:
        parser.error(
            f"--suite trains --algorithm {' or '.join(SUITE_ALGORITHMS)} (a registered controller scores its "
            f"checkpoints), not {args.algorithm!r}"
        )
    if args.curriculum or args.stages:
        parser.error(
            "--suite trains on the suite's layouts in one stage; leave out --curriculum and --stages"
        )
    given = sorted(set(args.env_kwargs) & set(_SUITE_KEYWORDS))
    if given:
        parser.error(
            f"--suite sets {', '.join(given)} itself (the benchmark's settings); leave them out of --env-kwargs"
        )
    if not args.eval_freq > 0:
        parser.error(f"--eval-freq={args.eval_freq!r}: allowed > 0")
    env = training.env_kwargs()
    if args.max_cycles is None:
        args.max_cycles = env["max_episode_steps"]
    args.env_kwargs = {**{k: v for k, v in env.items() if k != "max_episode_steps"}, **args.env_kwargs}
    return training


class SuiteCheckpoints(Callback):
    """Every ``every`` frames (after the iteration's training), the policy exported to
    ``OUT/checkpoints/frames_<F>/<task>/`` and scored on the validation layouts.

    Parameters
    ----------
    training : SuiteTraining
        The run's suite settings.
    out : Path
        The run's ``--out``.
    every : int
        Frames between checkpoints.
    export : callable
        ``export(policy) -> (arrays, metadata)``: the actor's arrays and the metadata the
        controller reads (:func:`baselines.marl.benchmarl_train.export_policy`).
    controller : str
        The registered controller that plays the export (``"ippo"``).
    """

    def __init__(
        self,
        training: SuiteTraining,
        out: Path,
        every: int,
        export: Callable[[Any], tuple[dict[str, np.ndarray], dict[str, Any]]],
        controller: str,
    ) -> None:
        super().__init__()
        self.training, self.out, self.every = training, out, every
        self.export, self.controller = export, controller
        self.next_at = every
        self.scores: list[CheckpointScore] = []

    def on_train_end(self, training_td: Any, group: str) -> None:
        frames = int(self.experiment.total_frames)
        if frames >= self.next_at:
            while self.next_at <= frames:
                self.next_at += self.every
            self.checkpoint(self.experiment.policy, frames)

    def resume_state(self) -> dict[str, Any]:
        """What a resume checkpoint keeps of this callback (:mod:`baselines.marl.benchmarl_resume`)."""
        return {"next_at": self.next_at, "scores": list(self.scores)}

    def set_resume_state(self, state: dict[str, Any]) -> None:
        """Continue from :meth:`resume_state`."""
        self.next_at, self.scores = int(state["next_at"]), list(state["scores"])

    def checkpoint(self, policy: Any, frames: int) -> CheckpointScore:
        """Export ``policy`` as checkpoint ``frames_<frames>`` and score it; printed on one line."""
        root = self.out / "checkpoints" / f"frames_{frames}"
        arrays, metadata = self.export(policy)
        write_export(root / self.training.task, arrays, {**metadata, "frames": frames})
        score = self.training.score(self.controller, {"policy_root": str(root)}, frames, root)
        self.scores.append(score)
        distance = "-" if score.mean_final_distance is None else f"{score.mean_final_distance:.3f} m"
        print(
            f"{frames:>10,d} frames  validation success ({self.training.labels['selection']}, "
            f"{score.episodes} episodes) {score.success_rate:.2f}, mean final distance {distance}",
            flush=True,
        )
        return score

    def finish(self, policy: Any, frames: int) -> list[CheckpointScore]:
        """The scores of every checkpoint, the final policy's included (scored here unless the
        last checkpoint was taken at ``frames``)."""
        if not self.scores or self.scores[-1].step != frames:
            self.checkpoint(policy, frames)
        return self.scores
