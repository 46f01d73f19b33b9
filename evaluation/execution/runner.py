"""``evaluate``: check a :class:`~evaluation.run.spec.RunSpec`, plan it, run its episodes on a backend, log them, return the results."""

from __future__ import annotations

import json
import os
import sys
from collections.abc import Callable, Sequence
from typing import Any

import controllers as registry
from evaluation.episodes.records import json_safe
from evaluation.episodes.runlog import open_log
from evaluation.execution.backends import BACKENDS, BATCH, Progress, RunInterrupted, announce, run_episodes
from evaluation.reports.results import Results
from evaluation.run.plan import EpisodeSpec, read_map_files
from evaluation.run.spec import RunSpec
from koopman_envs.checks import check_choice, check_int

__all__ = ["evaluate", "schedule", "usable_controllers"]


def schedule(episodes: Sequence[EpisodeSpec]) -> list[EpisodeSpec]:
    """The episodes in the order the workers get them: the longest first, so that no worker
    idles at the end of a run.

    How long is what each controller's class declares,
    :attr:`~controllers.base.BaseController.episode_cost` (a wrapped controller's, behind its
    ``safe:`` or ``ekf:`` prefix: the wrapped one does the long work; 0 when the class is not
    known without building); episodes of equal cost keep their order. Records are put back in
    plan order, so that no record depends on this order.
    """
    costs: dict[str, int] = {}  # per configuration label (unique within a run)
    for episode in episodes:
        if episode.controller not in costs:
            kind = episode.config.controller_class(wrapped=True)
            costs[episode.controller] = int(getattr(kind, "episode_cost", 0))
    return sorted(episodes, key=lambda episode: -costs[episode.controller])


def usable_controllers(verbose: bool = True) -> list[str]:
    """Registered controllers that can be built here; the others are named on stderr.

    An optional controller (``rl-ppo`` without the ``[rl]`` extra or without trained policies)
    is skipped by the default run instead of failing every episode. The ``<name>-v0`` variants
    of the tuned presets are left out: they run when asked for by name.
    """
    usable = []
    for name in registry.available(variants=False):  # a -v0 variant runs when named only
        try:
            registry.make(name)
        except (ImportError, ValueError) as exc:
            if verbose:
                print(f"note: controller {name!r} skipped ({exc})", file=sys.stderr)
            continue
        usable.append(name)
    return usable


def evaluate(
    spec: RunSpec,
    *,
    workers: int | None = None,
    backend: str = "process",
    out: str | os.PathLike[str] | None = None,
    resume: bool = False,
    progress: bool = False,
    config_check: Callable[[dict[str, Any]], None] | None = None,
    plan_check: Callable[[Sequence[EpisodeSpec]], None] | None = None,
    batch: int = BATCH,
) -> Results:
    """Run every controller configuration of ``spec`` on every (env, map, slip) cell.

    Parameters
    ----------
    spec : RunSpec
        The run: envs, controllers, maps, slips, trials, seed, env settings, calibration
        (see :class:`~evaluation.run.spec.RunSpec`; :mod:`evaluation.experiments.protocols` has presets).
    workers : int, optional
        Worker processes (default: all cores).
    backend : str
        ``"process"`` or ``"ray"``.
    out : path, optional
        Directory for the JSONL episode log (and, from the CLI, the reports).
    resume : bool
        Continue the run logged in ``out`` (its settings must match).
    progress : bool
        Show a progress bar on stderr (and name the registered controllers skipped).
    config_check : callable, optional
        Called with the run's configuration (what results.json records under ``config``)
        before any episode; raising ``ValueError`` stops the run there (``--baseline`` refuses
        a baseline of other settings this way).
    plan_check : callable, optional
        Called with the planned episodes after ``config_check``, before any episode; raising
        ``ValueError`` stops the run there (``--fail-if-worse`` refuses a baseline that too few
        of them pair with this way).
    batch : int
        The most episodes of a cell that run together in the vector env when the controller
        decides for many teams at once (``acts_in_batch``: the learned policies); their records
        equal the one-by-one records but for the timing fields. 1 runs every episode alone.

    Returns
    -------
    Results

    Raises
    ------
    ValueError
        Any bad field or argument, before an episode starts.
    RunInterrupted
        Ctrl-C; the finished episodes are in ``out``'s log (resume with ``resume=True``).

    Examples
    --------
    >>> from evaluation import RunSpec, evaluate
    >>> spec = RunSpec(envs="KoopNav-Formation-v0", controllers=["consensus"], maps=["map3"],
    ...                slips=["high"], episodes=1, env_kwargs={"max_episode_steps": 20})
    >>> evaluate(spec, workers=1).leaderboard()[0]["controller"]
    'consensus'
    """
    if not isinstance(spec, RunSpec):
        raise TypeError(
            f"evaluate() takes a RunSpec, got {type(spec).__name__}; build one with "
            "RunSpec(envs=..., controllers=..., ...) or take a preset from evaluation.experiments.protocols"
        )
    workers = (os.cpu_count() or 1) if workers is None else workers
    check_choice("backend", backend, BACKENDS)
    check_int("batch", batch, minimum=1)
    if spec.gifs and out is None:
        raise ValueError("gifs=True needs an output directory (out=...) for the animations")
    # every user map file read once: the checks, the fingerprints recorded and the episodes all
    # use these texts (a file edited during the run changes none of them)
    map_files = read_map_files(spec.maps)
    spec.validate(workers, map_files)  # before the registry builds every controller below
    if spec.controllers is None:
        announce("checking which registered controllers can run here (the learned ones load torch)", progress)
        spec = spec.resolved(usable_controllers(progress))
        spec.validate(workers, map_files)  # the filled-in configurations too
    else:
        spec = spec.resolved()
    config = spec.config(workers, backend, map_files)
    plan = spec.episodes_plan(os.fspath(out) if out is not None else "", map_files)
    if config_check is not None:
        config_check(config)
    if plan_check is not None:
        plan_check(plan)
    expected = {episode.key: episode.record_fields() for episode in plan}
    log_file, done = open_log(out, config, resume, expected) if out is not None else (None, {})
    todo = schedule([episode for episode in plan if episode.key not in done])
    announce(
        f"{len(todo)} episodes to run"
        + (f" ({len(done)} already in the log)" if done else "")
        + f" on {workers} {backend} worker{'s' if workers != 1 else ''}; the first ones start the workers "
        "(imports, compiled kernels, controller models and their caches) and take longest",
        progress and bool(todo),
    )
    bar = Progress(len(todo), progress)
    records = dict(done)
    try:
        with run_episodes(todo, workers, backend, batch) as stream:
            for record in stream:
                records[record["key"]] = record
                if log_file is not None:
                    log_file.write(json.dumps(json_safe(record)) + "\n")
                    log_file.flush()
                bar.update(record)
    except KeyboardInterrupt:
        raise RunInterrupted(len(records), len(plan)) from None
    finally:
        bar.close()
        if log_file is not None:
            log_file.close()
    return Results([records[episode.key] for episode in plan], config)
