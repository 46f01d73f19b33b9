"""Run or resume a study: the seeded sampler, trial 0 the defaults, the best configuration and its preset."""

from __future__ import annotations

import json
import os
import sys
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import controllers
from controllers.tuning import BEST_FILE, STUDY_FILE, TUNED_KIND, Search, study_record, trial_rank
from evaluation.episodes.records import json_safe
from evaluation.episodes.runlog import (
    LogError,
    ensure_output_dir,
    open_append_locked,
)
from evaluation.tune.configuration import Evaluator, evaluate_configuration
from evaluation.tune.log import StudySettings, Trial, read_study
from evaluation.tune.scoring import OBJECTIVE, objective
from koopman_envs.checks import import_optional
from koopman_envs.files import write_atomic


def _optuna() -> Any:
    """The ``optuna`` module, or ``ImportError`` naming the extra that installs it."""
    return import_optional("optuna", "the tuner needs Optuna: pip install -e '.[tune]'")


def _distribution(search: Search) -> Any:
    """The Optuna distribution of a search."""
    from optuna.distributions import CategoricalDistribution, FloatDistribution, IntDistribution

    if search.choices is not None:
        return CategoricalDistribution(list(search.choices))
    assert search.low is not None and search.high is not None  # Search.__post_init__
    if search.integer:
        return IntDistribution(int(search.low), int(search.high), log=search.log)
    return FloatDistribution(float(search.low), float(search.high), log=search.log)


def _tuned(controller: str) -> tuple[dict[str, Search], dict[str, Any]]:
    """The searches of ``controller`` and the point of its current defaults (trial 0)."""
    from controllers.tuning.presets import PRESETS

    spec = controllers.options(controller)
    search = spec.tunable()
    if not search:
        why = next((f": {p.untuned}" for p in PRESETS if p.name == controller and p.untuned), "")
        raise ValueError(
            f"controller {controller!r} declares no tunable options (a TUNABLE table){why}; allowed: a "
            "controller or preset whose options show a 'tuned over' entry in `python evaluate.py --options NAME`"
        )
    return search, {name: s.point(name, spec.default(name)) for name, s in search.items()}


def _say(message: str, enabled: bool) -> None:
    if enabled:
        print(message, file=sys.stderr, flush=True)


def run_study(
    settings: StudySettings,
    out: str | os.PathLike[str],
    *,
    resume: bool = False,
    workers: int = 1,
    progress: bool = False,
    evaluator: Evaluator = evaluate_configuration,
) -> list[Trial]:
    """Run (or resume) a study and write ``OUT/best.json`` and ``OUT/<controller>.json``.

    Parameters
    ----------
    settings : StudySettings
        The study.
    out : path
        Its directory (``study.jsonl``, ``best.json``, the preset).
    resume : bool
        Continue the study logged in ``out`` (its header must be this study's).
    workers : int
        Worker processes of every evaluation.
    progress : bool
        One line per trial on stderr.
    evaluator : callable
        The evaluation of one configuration (:func:`evaluate_configuration`'s signature).

    Returns
    -------
    list of Trial
        Every trial, in order (the logged ones first).

    Raises
    ------
    ValueError
        A bad setting (the test split by name), before any episode; a log that exists without
        ``resume`` or cannot be resumed (:class:`~evaluation.episodes.runlog.LogError`).
    ImportError
        Optuna is not installed (the ``tune`` extra).
    KeyboardInterrupt
        Ctrl-C: the finished trials are in the log, ``resume=True`` continues.
    """
    settings.check(workers)  # the whole run, before anything is written
    _optuna()
    search, defaults = _tuned(settings.controller)
    header = settings.header(search, defaults)
    log = ensure_output_dir(out) / STUDY_FILE
    handle = open_append_locked(log, "study log")
    try:
        done: list[Trial] = []
        if log.stat().st_size > 0:
            if not resume:
                raise ValueError(
                    f"{log} exists: pass --resume to continue that study, or choose another --out"
                )
            _, done, notes = read_study(log, header)
            for note in notes:
                _say(f"note: {note}", True)
        else:
            handle.write(json.dumps(header) + "\n")
            handle.flush()
        trials = _sample(settings, search, defaults, done, handle, workers, progress, evaluator)
    finally:
        handle.close()
    write_best(out, header, trials)
    return trials


def _sample(
    settings: StudySettings,
    search: Mapping[str, Search],
    defaults: Mapping[str, Any],
    done: Sequence[Trial],
    handle: Any,
    workers: int,
    progress: bool,
    evaluator: Evaluator,
) -> list[Trial]:
    """Ask the sampler for every trial, replaying the logged ones (their configurations
    checked against the log) and running the others."""
    optuna = _optuna()
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    study = optuna.create_study(direction="maximize", sampler=optuna.samplers.TPESampler(seed=settings.seed))
    study.enqueue_trial(dict(defaults))  # trial 0: the controller's current defaults
    distributions = {name: _distribution(s) for name, s in search.items()}
    trials: list[Trial] = []
    episodes = sum(t.episodes for t in done)
    for number in range(settings.trials):
        asked = study.ask(distributions)
        params = {name: asked.params[name] for name in search}
        if number < len(done):
            logged = done[number]
            if json_safe(params) != logged.params:
                raise LogError(
                    f"{STUDY_FILE}: trial {number} was logged with {logged.params}, but the sampler now "
                    f"proposes {json_safe(params)} (another Optuna version or search space?); resume "
                    "with the versions that wrote it, or use another --out"
                )
            study.tell(asked, logged.score)
            trials.append(logged)
            continue
        options = {name: search[name].value(value) for name, value in params.items()}
        trial = _run_trial(settings, number, params, options, episodes, workers, evaluator)
        episodes += trial.episodes
        # logged (and flushed) before the sampler hears of it: a kill now loses nothing told
        handle.write(json.dumps(trial.record) + "\n")
        handle.flush()
        study.tell(asked, trial.score)
        trials.append(trial)
        _say(
            f"trial {number}: score {trial.score:.4f} ({trial.successes}/{trial.episodes} successes)"
            + (" [defaults]" if number == 0 else ""),
            progress,
        )
    return trials


def _run_trial(
    settings: StudySettings,
    number: int,
    params: Mapping[str, Any],
    options: Mapping[str, Any],
    spent: int,
    workers: int,
    evaluator: Evaluator,
) -> Trial:
    """Evaluate one configuration on the study's layouts and seeds; its trial, with the line the
    log records (``spent``: the episodes of the trials before it)."""
    start = time.perf_counter()
    records = evaluator(
        settings.controller,
        options,
        settings.task,
        settings.split,
        settings.layout_indices,
        settings.episodes,
        settings.seed,
        suite=settings.suite,
        slip=settings.slip,
        env_kwargs=settings.env_kwargs,
        workers=workers,
    )
    score = objective(records)
    line = json_safe(
        {
            "trial": number,
            "params": dict(params),
            "options": dict(options),
            "score": score.value,
            "successes": score.successes,
            "episodes": score.episodes,
            "errors": score.errors,
            "mean_time_to_goal": score.mean_time_to_goal,
            "layouts": {
                label: sorted({r["layout"] for r in records if r["suite"] == label})
                for label in sorted({r["suite"] for r in records})
            },
            "seeds": sorted({int(r["seed"]) for r in records}),
            "wall_seconds": round(time.perf_counter() - start, 3),
            "budget_so_far": {"configurations": number + 1, "episodes": spent + score.episodes},
        }
    )
    return Trial(number, line["params"], line["options"], score.value, score.successes, score.episodes, line)


def best_of(trials: Sequence[Trial]) -> Trial:
    """The trial of the highest score (the earliest among equals: trial 0, the defaults, wins a tie)."""
    return max(trials, key=lambda t: trial_rank({"score": t.score, "trial": t.number}))


def write_best(out: str | os.PathLike[str], header: Mapping[str, Any], trials: Sequence[Trial]) -> None:
    """``OUT/best.json`` and the tuned preset ``OUT/<controller>.json`` of a study."""
    if not trials:
        return
    best, defaults = best_of(trials), trials[0]
    controller = header["controller"]
    summary = {
        "controller": controller,
        "task": header["task"],
        "split": header["split"],
        "suites": header["suites"],
        "seed": header["seed"],
        "budget": header["budget"],
        "configurations_run": len(trials),
        "objective": OBJECTIVE,
        "best": {
            "trial": best.number,
            "options": best.options,
            "score": best.score,
            "successes": best.successes,
            "episodes": best.episodes,
        },
        "defaults": {"options": defaults.options, "score": defaults.score, "successes": defaults.successes},
        "gain": best.score - defaults.score,
    }
    write_atomic(Path(out) / BEST_FILE, json.dumps(json_safe(summary), indent=2) + "\n")
    preset = {
        "kind": TUNED_KIND,
        "controller": controller,
        "task": header["task"],
        "options": best.options,
        "score": best.score,
        "defaults_score": defaults.score,
        "study": study_record(header, len(trials)),
    }
    write_atomic(Path(out) / f"{controller}.json", json.dumps(json_safe(preset), indent=2) + "\n")
