"""Training a learned policy on a benchmark suite (``--suite koopnav-bench-v1``): the train
split's layouts under the benchmark's own settings, the checkpoint chosen on the validation
split, the test split refused by name (issue 60, docs/benchmark.md#learned-policies).

Both trainers (``python -m baselines.sb3.train`` and ``python -m baselines.marl.benchmarl_train``) use the
one :class:`SuiteTraining` of their run:

- **Training layouts.** :meth:`SuiteTraining.env_kwargs`: ``map="suite:<name>/train"`` (each reset
  draws a layout of the split from the env's generator) with the slip and env settings of the
  benchmark's run (:func:`evaluation.experiments.protocols.suite_protocol`: high slip, starts perturbed by
  5 cm, its time limit and goal tolerance), so that a policy trains under the conditions its
  test-suite row is measured in.
- **Checkpoint selection.** :meth:`SuiteTraining.score` runs a saved checkpoint as its registered
  controller (``rl-ppo-set``, ``rl-ppo`` or ``ippo`` with ``policy_root`` the checkpoint) on the
  first ``layouts`` layouts of the validation split through the tuner's one call into the
  evaluator (:func:`evaluation.tune.configuration.evaluate_configuration`): the episodes the
  benchmark itself would run there. :func:`choose` keeps the best by :data:`SELECTION_RULE`;
  :func:`keep_chosen` copies it to ``OUT/<task>/`` (so ``OUT`` is a policy root) and writes the
  selection record ``OUT/selection.json`` last.
- **Held out.** :meth:`SuiteTraining.check` calls :func:`koopman_envs.suites.check_split_allowed`
  (the tuner's check) for ``"training"`` and ``"checkpoint selection"`` before any work;
  :func:`refuse_held_out_map` refuses an env ``map`` naming the test split however it is given.
"""

from __future__ import annotations

import argparse
import functools
import json
import os
import shutil
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from koopman_envs import SUITE_PREFIX, SUITES, check_split_allowed, env_keyword, load_suite, parse_suite_map
from koopman_envs.checks import check_choice, check_int
from koopman_envs.files import write_atomic
from koopman_envs.params import PLANTS, SLIP_NAMES

__all__ = [
    "DEFAULT_VALIDATION_LAYOUTS",
    "SELECTION_FILE",
    "SELECTION_RULE",
    "CheckpointScore",
    "SuiteTraining",
    "add_suite_options",
    "choose",
    "suite_from_args",
    "keep_chosen",
    "refuse_held_out_map",
    "summarize",
]

#: validation layouts every checkpoint is scored on, by default (the split's first N)
DEFAULT_VALIDATION_LAYOUTS = 50
#: the selection record a suite run writes beside its chosen policy (``OUT/selection.json``)
SELECTION_FILE = "selection.json"
#: how the kept checkpoint is chosen (recorded in the selection record)
SELECTION_RULE = (
    "the highest success rate on the validation layouts; ties: the lower mean final distance "
    "(over the episodes, of the team's mean distance to the targets at the end [m]); then the later checkpoint"
)


@dataclass(frozen=True)
class CheckpointScore:
    """One checkpoint's result on the validation layouts.

    Attributes
    ----------
    step : int
        Robot-steps (SB3) or frames (BenchMARL) trained when it was saved.
    root : str
        Its policy root (a folder holding ``<task>/``).
    successes, episodes, errors : int
        Successful, run and raising episodes (an episode that raised is a failure).
    mean_final_distance : float or None
        Mean over the episodes with poses of the team's mean final distance to the targets [m].
    """

    step: int
    root: str
    successes: int
    episodes: int
    errors: int
    mean_final_distance: float | None

    @property
    def success_rate(self) -> float:
        return self.successes / self.episodes if self.episodes else 0.0

    def order(self) -> tuple[float, float, int]:
        """The sort key of :data:`SELECTION_RULE` (larger is better):
        :func:`~evaluation.episodes.records.selection_key`, the later checkpoint winning a tie."""
        from evaluation.episodes.records import selection_key

        return selection_key(self.success_rate, self.mean_final_distance, self.step)

    def as_dict(self) -> dict[str, Any]:
        return {**asdict(self), "success_rate": self.success_rate}


def summarize(
    step: int, root: str | os.PathLike[str], records: Sequence[Mapping[str, Any]]
) -> CheckpointScore:
    """A checkpoint's :class:`CheckpointScore` from its validation episode records."""
    distances = [
        sum(r["final_distance"]) / len(r["final_distance"]) for r in records if r.get("final_distance")
    ]
    return CheckpointScore(
        step=int(step),
        root=str(root),
        successes=sum(1 for r in records if r.get("success") is True),
        episodes=len(records),
        errors=sum(1 for r in records if r.get("status") == "error"),
        mean_final_distance=sum(distances) / len(distances) if distances else None,
    )


def choose(scores: Sequence[CheckpointScore]) -> CheckpointScore:
    """The checkpoint :data:`SELECTION_RULE` keeps (``ValueError`` when there is none)."""
    if not scores:
        raise ValueError(
            "no checkpoint was scored; nothing to choose from (is --eval-freq above the budget?)"
        )
    return max(scores, key=CheckpointScore.order)


def refuse_held_out_map(env_kwargs: Mapping[str, Any], purpose: str = "training") -> None:
    """``ValueError`` (the tuner's check, by name) when ``env_kwargs["map"]`` is a suite's test
    split: no option of a trainer reaches the held-out layouts."""
    value = env_kwargs.get("map")
    if isinstance(value, str) and value.startswith(SUITE_PREFIX):
        name, split = parse_suite_map(value)
        check_split_allowed(split, purpose, f"map={value!r}")


@dataclass(frozen=True)
class SuiteTraining:
    """A training run on a benchmark suite: where it trains, and how its checkpoint is chosen.

    Attributes
    ----------
    suite : str
        A suite of :data:`koopman_envs.suites.SUITES`.
    task : str
        ``"target_reaching"`` or ``"formation"``.
    split : str
        The split trained on (``"train"``; ``"test"`` is refused).
    selection_split : str
        The split checkpoints are chosen on (``"validation"``; ``"test"`` is refused).
    layouts : int
        Checkpoints are scored on the selection split's first ``layouts`` layouts.
    episodes : int
        Episodes per layout (episode j of layout l seeded ``seed + j * len(split) + l``).
    seed : int
        The first episode seed of the scoring run.
    plant : str
        What the robots are in training and scoring (:data:`koopman_envs.params.PLANTS`; default
        the kinematic plant, the benchmark's).
    slips : tuple of str
        The slip levels trained and scored on: the training envs are split evenly between them
        and a checkpoint plays every validation layout at each. Empty (default): the benchmark's
        one slip.
    """

    suite: str
    task: str
    split: str = "train"
    selection_split: str = "validation"
    layouts: int = DEFAULT_VALIDATION_LAYOUTS
    episodes: int = 1
    seed: int = 0
    plant: str = PLANTS[0]
    slips: tuple[str, ...] = ()

    def check(self) -> None:
        """``ValueError`` naming a bad setting: the test split first (the tuner's check, for
        ``"training"`` and ``"checkpoint selection"``), before any file or episode."""
        check_split_allowed(self.split, "training")
        check_split_allowed(self.selection_split, "checkpoint selection")
        check_choice("suite", self.suite, list(SUITES))
        size = len(load_suite(self.suite, self.task, self.selection_split))
        check_int("validation layouts", self.layouts, 1, maximum=size)
        check_int("validation episodes", self.episodes, 1, maximum=100)
        check_int("seed", self.seed, 0)
        env_keyword("plant").resolve(self.plant)
        for slip in self.slips:
            check_choice("slips", slip, SLIP_NAMES)
        if len(set(self.slips)) != len(self.slips):
            raise ValueError(f"slips={list(self.slips)!r} names a level twice; give each once")

    @property
    def labels(self) -> dict[str, str]:
        """The labels (with their hashes) of the training and the selection split."""
        return {
            "train": load_suite(self.suite, self.task, self.split).label,
            "selection": load_suite(self.suite, self.task, self.selection_split).label,
        }

    @property
    def slip_levels(self) -> tuple[str, ...]:
        """The slip levels trained and scored on: :attr:`slips`, or the benchmark's one."""
        if self.slips:
            return self.slips
        from evaluation.experiments.protocols import suite_protocol

        protocol = suite_protocol(self.suite, self.split)
        if len(protocol.slips) != 1:  # the benchmark runs one slip; a mixture would need a choice
            raise ValueError(f"suite_protocol runs slips {list(protocol.slips)}; training takes one")
        return tuple(protocol.slips)

    def plant_kwargs(self) -> dict[str, Any]:
        """The ``plant`` keyword when it is not the default (so that a kinematic run's keywords,
        and the records and metadata that hold them, stay as they were before it existed)."""
        return {} if self.plant == PLANTS[0] else {"plant": self.plant}

    def env_kwargs(self, slip: str | None = None) -> dict[str, Any]:
        """The training envs' keywords at slip level ``slip`` (default the first of
        :attr:`slip_levels`): the training split as the map, the plant, and the env settings of
        the benchmark's run (:func:`evaluation.experiments.protocols.suite_protocol`)."""
        from evaluation.experiments.protocols import suite_protocol
        from evaluation.run.suite_runs import suite_map

        levels = self.slip_levels
        if slip is not None:
            check_choice("slip", slip, levels)
        protocol = suite_protocol(self.suite, self.split)
        return {
            "map": suite_map(self.suite, self.split),
            "slip": levels[0] if slip is None else slip,
            **protocol.env_settings(),
            **self.plant_kwargs(),
        }

    def score(
        self, controller: str, options: Mapping[str, Any], step: int, root: str | os.PathLike[str]
    ) -> CheckpointScore:
        """Run the checkpoint in ``root`` (``options`` of ``controller``, its ``policy_root``
        included) on the selection layouts through the evaluator; its :class:`CheckpointScore`."""
        from evaluation.tune.configuration import evaluate_configuration

        records = [
            record
            for slip in self.slip_levels  # the same layouts and seeds at every level: paired
            for record in evaluate_configuration(
                controller,
                options,
                self.task,
                self.selection_split,
                range(self.layouts),
                self.episodes,
                self.seed,
                suite=self.suite,
                slip=slip,
                env_kwargs=self.plant_kwargs(),
                purpose="checkpoint selection",
            )
        ]
        return summarize(step, root, records)

    def as_dict(self) -> dict[str, Any]:
        """What the policy's metadata and the selection record hold of the run's suite."""
        return {
            **asdict(self),
            "labels": self.labels,
            "env": self.env_kwargs(),
            "episodes_per_checkpoint": self.layouts * self.episodes * len(self.slip_levels),
        }


def add_suite_options(parser: argparse.ArgumentParser, what: str) -> argparse._ArgumentGroup:
    """Both trainers' ``--suite``, ``--split`` and ``--validation-layouts`` (``what``: how that
    trainer trains on the suite, for ``--suite``'s help); the group, for options of its own."""
    group = parser.add_argument_group("benchmark suite (docs/benchmark.md#learned-policies)")
    group.add_argument(
        "--suite",
        metavar="NAME",
        default=None,
        help=f"train on a benchmark suite ({', '.join(SUITES)}): the task's --split layouts under the "
        f"benchmark's settings (high slip, 5 cm start noise, its time limit), {what}; the best "
        "checkpoint on the validation layouts kept in OUT/<task>/ with OUT/selection.json",
    )
    group.add_argument(
        "--split",
        default=None,
        help="with --suite: the split trained on (default train; test is refused: held out)",
    )
    group.add_argument(
        "--validation-layouts",
        type=int,
        default=DEFAULT_VALIDATION_LAYOUTS,
        help="with --suite: validation layouts every checkpoint is scored on (the split's first N; "
        f"default {DEFAULT_VALIDATION_LAYOUTS})",
    )
    return group


def suite_from_args(
    args: argparse.Namespace, task: str, parser: argparse.ArgumentParser
) -> SuiteTraining | None:
    """A trainer's :class:`SuiteTraining` from the options of :func:`add_suite_options` (None
    without ``--suite``), checked: a bad setting, the test split first, ends the command through
    ``parser.error`` (exit 2) naming it, before any work."""
    if args.suite is None:
        if args.split is not None:
            parser.error("--split needs --suite NAME")
        return None
    training = SuiteTraining(args.suite, task, args.split or "train", layouts=args.validation_layouts)
    try:
        training.check()
    except ValueError as exc:
        parser.error(str(exc))
    return training


def keep_chosen(
    out: str | os.PathLike[str],
    training: SuiteTraining,
    scores: Sequence[CheckpointScore],
    metadata: Mapping[str, Any],
    command: str,
) -> CheckpointScore:
    """Copy the checkpoint :func:`choose` keeps to ``OUT/<task>/`` (its files, its
    ``metadata.json`` replaced by ``metadata`` with the selection added) and write the selection
    record ``OUT/selection.json`` last (each file atomically); the chosen score."""
    chosen = choose(scores)
    source = Path(chosen.root) / training.task
    target = Path(out) / training.task
    target.mkdir(parents=True, exist_ok=True)
    record = {
        "command": command,
        "rule": SELECTION_RULE,
        "suite": training.as_dict(),
        "chosen": chosen.as_dict(),
        "checkpoints": [s.as_dict() for s in scores],
    }
    for path in sorted(source.iterdir()):
        if path.is_file() and path.name != "metadata.json":
            write_atomic(target / path.name, functools.partial(shutil.copyfile, path))
    selected = {**metadata, "selection": record}
    write_atomic(target / "metadata.json", json.dumps(selected, indent=1) + "\n")
    write_atomic(Path(out) / SELECTION_FILE, json.dumps(record, indent=1) + "\n")
    return chosen
