"""A published seeds run read back, and the seeds the driver plans (issue 60, docs/seeds_results.md).

``bash data/publish.sh seeds`` runs ``python -m evaluation.experiments.seeds --out data/runs/seeds``
(one log per task, every finished training seed a controller ``<policy>@seed<k>``) and
``bash data/publish.sh pack`` packs it into ``data/seeds/``. :func:`read_publication` reads such a
run back, unpacked, with each seed's validation record from its seed folder, into the summaries
:func:`evaluation.experiments.seeds.evaluate_seeds` returns (the same :func:`~evaluation.experiments.seeds.aggregate`,
the same :func:`~evaluation.experiments.seeds.chosen_seed`), and :func:`planned_seeds` reads the
driver's default plan (``data/training/run.sh``), for the seeds not published yet.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from evaluation.episodes.log_weights import WEIGHTS_KEY
from evaluation.experiments.seeds import (
    DRIVER,
    FINISHED_FILE,
    POLICIES,
    REPORTS,
    SUITE,
    TRAINING_ROOT,
    SeedRun,
    aggregate,
    chosen_seed,
    finished_seeds,
    outcomes_by_label,
    planned_seeds,
)
from evaluation.run.configs import ControllerConfig
from evaluation.run.weights import run_weights
from evaluation.stats.progress import Progress, planned_episodes
from koopman_envs import TASKS

__all__ = ["DRIVER", "PublishedSeeds", "planned_seeds", "read_publication"]


@dataclass(frozen=True)
class PublishedSeeds:
    """A published seeds run read back (:func:`read_publication`).

    Attributes
    ----------
    split : str
        The suite split the seeds ran on (``test`` for the publication).
    summaries : list of dict
        One per (policy, task), as :func:`evaluate_seeds` returns them, over the seeds whose every
        planned episode is published (a partial seed is in ``progress`` only).
    progress : dict
        ``(policy, task, seed)`` -> its :class:`~evaluation.stats.progress.Progress`, for every
        seed the publication holds.
    episodes : int
        The records published.
    suites : dict
        Task -> the suite split's label (name, split and content hash).
    """

    split: str
    summaries: list[dict[str, Any]]
    progress: dict[tuple[str, str, int], Progress]
    episodes: int
    suites: dict[str, str]


#: a seed's controller label: ``<policy>@seed<k>`` (:attr:`SeedRun.label`)
_LABEL = re.compile(r"(?P<policy>[a-z][a-z0-9-]*)@seed(?P<seed>\d+)")


def _published_seed(where: str, entry: Any, task: str) -> tuple[str, int]:
    """The (policy, seed) of one controller of a seeds run's header; ``ValueError`` naming it when
    it is not a training seed's (its label, controller and ``policy_root`` as
    :func:`evaluate_seeds` writes them)."""
    label = entry.get("label") if isinstance(entry, dict) else None
    match = _LABEL.fullmatch(label) if isinstance(label, str) else None
    if match is None or match["policy"] not in POLICIES or entry.get("name") != match["policy"]:
        raise ValueError(
            f"{where}: controller {label!r} is not a training seed's (a label <policy>@seed<k>, the "
            f"controller <policy>, one of {list(POLICIES)}); not a seeds publication "
            "(python -m evaluation.experiments.seeds)"
        )
    policy, seed = match["policy"], int(match["seed"])
    root = (entry.get("options") or {}).get("policy_root")
    if not isinstance(root, str) or Path(root).parts[-3:] != (policy, task, f"seed{seed}"):
        raise ValueError(
            f"{where}: {label} plays policy_root {root!r}, not the seed folder "
            f"<root>/{policy}/{task}/seed{seed}; not a seeds publication (python -m evaluation.experiments.seeds)"
        )
    return policy, seed


def _check_weights(log: Path, config: dict[str, Any], run: SeedRun) -> None:
    """Refuse a published seed whose folder now holds other weights than its logged episodes
    played (the run's header records them: :mod:`evaluation.run.weights`): its validation record,
    read from that folder, is of a retrained seed and would stand beside the old seed's success.
    A log written before the digests were recorded has none and is not checked."""
    logged = ((config.get(WEIGHTS_KEY) or {}).get(run.label) or {}).get(run.task)
    if logged is None:
        return
    seed = ControllerConfig(run.label, run.policy, (("policy_root", str(run.folder)),))
    now = run_weights([seed], [TASKS[run.task].env_id]).get(run.label, {}).get(run.task)
    if now != logged:
        raise ValueError(
            f"{log}: {run.label} played policy files of sha256 {logged}, but its seed folder "
            f"{run.folder} now holds sha256 {now or 'none'} (retrained or replaced since the run): its "
            "validation record is not of the weights published. Rerun its episodes (python -m "
            f"evaluation.forget {run.label} -- RUN_DIR, then bash data/publish.sh seeds) or restore the folder"
        )


def read_publication(
    run_dir: str | os.PathLike[str], root: str | os.PathLike[str] = TRAINING_ROOT, *, n_boot: int = 4000
) -> PublishedSeeds:
    """A seeds run (``python -m evaluation.experiments.seeds --out RUN_DIR``: one log per task,
    ``RUN_DIR/<task>/episodes.jsonl``; a publication unpacked by
    :func:`evaluation.reports.publications.extracted_archive`) read back: per (policy, task) the
    seeds whose every planned episode is logged, with their validation records from their seed
    folders under ``root`` (``selection.json``), :func:`aggregate` (the same ``n_boot`` and seed
    as the command's) and :func:`chosen_seed`; the other seeds' progress.

    Raises
    ------
    ValueError
        Naming the file: anything else than one folder per task, a log of another task, suite or
        controllers than a seeds run's (:func:`evaluate_seeds`), a torn or foreign record
        (:func:`evaluation.reports.published.results_from_log`), splits that differ between the
        tasks, or a published seed whose folder under ``root`` is not a finished seed.
    """
    from evaluation.reports.published import results_from_log

    run_dir = Path(run_dir)
    # the command's own reports beside the logs (not published: a packed run has the logs only)
    entries = sorted(p for p in run_dir.iterdir() if p.name not in REPORTS) if run_dir.is_dir() else []
    foreign = [p.name for p in entries if p.name not in TASKS or not (p / "episodes.jsonl").is_file()]
    if not entries or foreign:
        raise ValueError(
            f"{run_dir}: holds {foreign or 'nothing'}; a seeds publication holds one run per task "
            f"({', '.join(TASKS)}), each <task>/episodes.jsonl (python -m evaluation.experiments.seeds)"
        )
    splits: dict[str, str] = {}
    summaries: list[dict[str, Any]] = []
    progress: dict[tuple[str, str, int], Progress] = {}
    suites: dict[str, str] = {}
    episodes = 0
    for folder in entries:
        task, log = folder.name, folder / "episodes.jsonl"
        results = results_from_log(log)
        config, records = results.config, results.records
        suite = config.get("suite") or {}
        if config.get("env_ids") != [TASKS[task].env_id] or suite.get("name") != SUITE:
            raise ValueError(
                f"{log}: a run of {config.get('env_ids')} on suite {suite.get('name')!r}, not of "
                f"{TASKS[task].env_id} on {SUITE} (its folder's task); not a seeds publication"
            )
        splits[task] = str(suite.get("split"))
        seeds = [_published_seed(str(log), c, task) for c in config.get("controller_configs") or []]
        planned = planned_episodes(config, TASKS[task].env_id)
        by_label = outcomes_by_label(records)
        episodes += len(records)
        complete: dict[str, list[SeedRun]] = {}
        for policy, seed in seeds:
            label = f"{policy}@seed{seed}"
            done = sum(len(v) for v in by_label.get(label, {}).values())
            progress[(policy, task, seed)] = Progress(done, planned)
            if done < planned:
                continue
            finished = {r.seed: r for r in finished_seeds(root, policy, task)}
            if seed not in finished:
                raise ValueError(
                    f"{log}: {label} is published, but {Path(root) / policy / task / f'seed{seed}'} is not a "
                    f"finished seed ({FINISHED_FILE} and selection.json): its validation record is read there"
                )
            _check_weights(log, config, finished[seed])
            complete.setdefault(policy, []).append(finished[seed])
        for policy, runs in complete.items():
            result = aggregate({r.seed: by_label[r.label] for r in runs}, n_boot=n_boot)
            label = next(r["suite"] for r in records if r["controller"] == runs[0].label)
            suites[task] = label
            summaries.append(
                {
                    "policy": policy,
                    "task": task,
                    "suite": label,
                    "runs": runs,
                    "aggregate": result,
                    "chosen": chosen_seed(runs),
                }  # fmt: skip
            )
    if len(set(splits.values())) > 1:
        raise ValueError(
            f"{run_dir}: its tasks ran on different splits {splits}; one publication is one split"
        )
    order = {policy: i for i, policy in enumerate(POLICIES)}
    summaries.sort(key=lambda s: (order[s["policy"]], list(TASKS).index(s["task"])))
    return PublishedSeeds(next(iter(splits.values())), summaries, progress, episodes, suites)
