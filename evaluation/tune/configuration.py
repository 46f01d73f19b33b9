"""The evaluation of one configuration: the tuner's one call into the evaluator."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from koopman_envs.checks import check_choice
from koopman_envs.suites import check_split_allowed, load_suite
from koopman_envs.tasks.base import TASKS

#: the suite tuned on (its ``validation`` split)
SUITE = "koopnav-bench-v1"
#: ``--task``: one task, or both (one configuration scored on the layouts of both)
TASK_CHOICES = (*TASKS, "both")
#: the slip of every tuning episode (ours): each episode draws its own levels up to beyond
#: ``high`` (koopman_envs.params.RANDOM_SLIP_MAX), so that a configuration is tuned for the whole
#: range the benchmark reports rather than for one setting
DEFAULT_SLIP = "random"

Evaluator = Callable[..., list[dict[str, Any]]]


def tasks_of(task: str) -> tuple[str, ...]:
    """The tasks of ``--task`` (``"both"``: every task), ``ValueError`` naming the allowed ones."""
    check_choice("task", task, TASK_CHOICES)
    return tuple(TASKS) if task == "both" else (task,)


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
) -> list[dict[str, Any]]:
    """The episode records of one configuration on layouts of a suite split: the tuner's one
    call into the evaluator.

    Every layout runs ``episodes`` episodes, seeds ``seed .. seed + episodes - 1``. Today each
    layout is written to a map file and run as a map of a :class:`~evaluation.spec.RunSpec`
    (the evaluator passes no reset options, so ``reset(options={"layout": i})`` on
    ``map="suite:..."`` is out of its reach); when the evaluator runs suites itself
    (``RunSpec(suite=..., split=..., layouts=...)``), this function is where the tuner switches.

    Parameters
    ----------
    controller : str
        A registered controller or preset.
    options : mapping
        Its options for this configuration.
    task : str
        ``"target_reaching"``, ``"formation"`` or ``"both"``.
    split : str
        ``"train"`` or ``"validation"``; ``"test"`` is refused (held out).
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

    Returns
    -------
    list of dict
        The episode records (:mod:`evaluation.records`), each with ``suite`` (the split's label,
        its hash included) and ``layout`` (the index) added.
    """
    from evaluation.runner import evaluate
    from evaluation.spec import RunSpec

    check_split_allowed(split, "tuning")
    tasks = tasks_of(task)
    with tempfile.TemporaryDirectory(prefix="koopnav-tune-") as folder:
        maps: dict[str, list[str]] = {}
        where: dict[tuple[str, str], tuple[str, int, str]] = {}
        for name in tasks:
            loaded = load_suite(suite, name, split)
            env_id = TASKS[name].env_id
            maps[env_id] = []
            for index in layouts:
                layout = loaded.layout(index)
                path = os.path.join(folder, name, f"{layout.id}.json")
                os.makedirs(os.path.dirname(path), exist_ok=True)
                layout.spec.save(path)
                maps[env_id].append(path)
                where[(env_id, path)] = (loaded.label, int(index), layout.id)
        spec = RunSpec(
            envs=tuple(maps),
            controllers={controller: (controller, dict(options))},
            maps=maps,
            slips=(slip,),
            episodes=episodes,
            seed=seed,
            env_kwargs=dict(env_kwargs or {}),
        )
        records = evaluate(spec, workers=workers).records
    out = []
    for record in records:
        label, index, name = where[(record["env_id"], record["map"])]
        # the layout's id for the temporary file's path, which is gone
        out.append({**record, "map": name, "suite": label, "layout": index})
    return out
