"""The evaluation of one configuration: the tuner's one call into the evaluator."""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

from koopman_envs import TASKS, check_split_allowed
from koopman_envs.checks import check_choice

if TYPE_CHECKING:
    from evaluation.run.spec import RunSpec

#: the suite tuned on (its ``validation`` split)
SUITE = "koopnav-bench-v1"
#: ``--task``: one task, or both (one configuration scored on the layouts of both)
TASK_CHOICES = (*TASKS, "both")
#: the slip of every tuning episode: the benchmark's own setting (the quick board's high slip,
#: :func:`evaluation.experiments.protocols.suite_protocol`), so a configuration is tuned on validation layouts
#: under the conditions its test-suite row is measured in
DEFAULT_SLIP = "high"

Evaluator = Callable[..., list[dict[str, Any]]]


def tasks_of(task: str) -> tuple[str, ...]:
    """The tasks of ``--task`` (``"both"``: every task), ``ValueError`` naming the allowed ones."""
    check_choice("task", task, TASK_CHOICES)
    return tuple(TASKS) if task == "both" else (task,)


def configuration_spec(
    controller: str,
    options: Mapping[str, Any],
    task: str,
    split: str,
    layouts: Sequence[int],
    episodes: int,
    seed: int,
    *,
    suite: str = SUITE,
    slip: str = DEFAULT_SLIP,
    env_kwargs: Mapping[str, Any] | None = None,
    purpose: str = "tuning",
) -> RunSpec:
    """The run of one configuration on layouts of a suite split, unvalidated: the benchmark's own
    run (:func:`evaluation.experiments.protocols.suite_protocol`) narrowed to this configuration.

    Every layout runs ``episodes`` episodes, episode j of layout l seeded
    ``seed + j * len(split) + l`` as in any suite run (:mod:`evaluation.run.suite_runs`), so that a
    tuning episode is the episode the evaluator would run. The parameters are
    :func:`evaluate_configuration`'s; :meth:`~evaluation.run.spec.RunSpec.validate` checks the
    rest of the run (slip, env keywords, controller, layouts), the evaluator's own checks.

    Raises
    ------
    ValueError
        The test split for ``purpose`` (:func:`check_split_allowed`), an unknown task, or layouts
        that are not a contiguous range.
    """
    from evaluation.experiments.protocols import suite_protocol

    check_split_allowed(split, purpose)
    tasks = tasks_of(task)
    selected = sorted(int(i) for i in layouts)
    if not selected or selected != list(range(selected[0], selected[-1] + 1)):
        raise ValueError(
            f"layouts={list(layouts)!r}: the tuner runs a contiguous range of layouts, e.g. [0, 1, 2]"
        )
    protocol = suite_protocol(suite, split)
    return protocol.replace(
        envs=tuple(TASKS[name].env_id for name in tasks),
        controllers={controller: (controller, dict(options))},
        slips=(slip,),
        episodes=episodes,
        seed=seed,
        layouts=(selected[0], selected[-1] + 1),
        env_kwargs={**protocol.env_kwargs, **dict(env_kwargs or {})},
    )


def evaluate_configuration(
    controller: str,
    options: Mapping[str, Any],
    task: str,
    split: str,
    layouts: Sequence[int],
    episodes: int,
    seed: int,
    *,
    suite: str = SUITE,
    slip: str = DEFAULT_SLIP,
    env_kwargs: Mapping[str, Any] | None = None,
    workers: int = 1,
    purpose: str = "tuning",
    out: str | os.PathLike[str] | None = None,
) -> list[dict[str, Any]]:
    """The episode records of one configuration on layouts of a suite split: the tuner's one
    call into the evaluator (and the learned policies' trainers', which score their checkpoints
    with it: ``purpose="checkpoint selection"``).

    The benchmark's own run (:func:`evaluation.experiments.protocols.suite_protocol`: perturbed starts, the
    NMPCs on the real-time iteration) on the given layouts of ``split``, for this one
    configuration: every layout runs ``episodes`` episodes, episode j of layout l seeded
    ``seed + j * len(split) + l`` as in any suite run (:mod:`evaluation.run.suite_runs`), the layout
    handed to the env's reset, so that a tuning episode is the episode the evaluator would run.

    Parameters
    ----------
    controller : str
        A registered controller or preset.
    options : mapping
        Its options for this configuration.
    task : str
        ``"target_reaching"``, ``"formation"`` or ``"both"``.
    split : str
        ``"train"`` or ``"validation"``; ``"test"`` is refused (held out) for ``purpose``.
    layouts : sequence of int
        Layout indices of the split (the same for every task).
    episodes : int
        Episodes per layout.
    seed : int
        The first episode seed.
    suite : str
        The suite's name.
    slip : str
        The slip setting of every episode.
    env_kwargs : mapping, optional
        Further ``gym.make`` keywords (e.g. ``max_episode_steps``).
    workers : int
        Worker processes of the evaluator.
    purpose : str
        What the episodes are for, one of :data:`koopman_envs.suites.HELD_OUT_PURPOSES`
        (``"tuning"``, ``"checkpoint selection"``, ...): :func:`check_split_allowed` refuses the
        test split for it by name before any episode.
    out : path, optional
        A directory for the run's episode log (``out/episodes.jsonl``), resumed when it exists:
        only the episodes missing from it run. A log of another run (its header differs: another
        configuration, layouts, seed, ...) is refused by name
        (:class:`~evaluation.episodes.runlog.LogError`), never mixed.

    Returns
    -------
    list of dict
        The episode records (:mod:`evaluation.episodes.records`), each with ``suite`` (the split's label,
        its hash included) and ``layout`` (the index) added.
    """
    from evaluation.execution.runner import evaluate

    spec = configuration_spec(
        controller,
        options,
        task,
        split,
        layouts,
        episodes,
        seed,
        suite=suite,
        slip=slip,
        env_kwargs=env_kwargs,
        purpose=purpose,
    )
    return list(evaluate(spec, workers=workers, out=out, resume=out is not None).records)
