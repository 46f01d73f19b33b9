"""``evaluate``: plan a run, check it, run its episodes on a backend, log them, return the results."""

from __future__ import annotations

import json
import os
import sys
from typing import Any, Callable, Mapping, Sequence

import controllers as registry
from evaluation.backends import BACKENDS, Progress, RunInterrupted, run_episodes
from evaluation.configs import controller_configs
from evaluation.plan import RANDOM_MAP, env_settings, map_fingerprints, plan_episodes, validate_plan
from evaluation.protocols import TASK_MAPS
from evaluation.results import Results, json_safe
from evaluation.runlog import open_log
from koopman_envs.params import PARAMS, SLIP_SETTINGS
from koopman_envs.sim.maps import BUILTIN_MAPS

__all__ = ["evaluate", "usable_controllers"]

#: longest episodes first (the learned-model NMPC, then the other optimizers, wrapped or not) so
#: that no worker idles at the end of a run; records are put back in plan order
_COST = {"koopman-nmpc": 0, "koopman-nmpc-robust": 0, "nominal-nmpc": 1, "nominal-nmpc-robust": 1}


def usable_controllers(verbose: bool = True) -> list[str]:
    """Registered controllers that can be built here; the others are named on stderr.

    An optional controller (``rl-ppo`` without the ``[rl]`` extra or without trained policies)
    is skipped by the default run instead of failing every episode.
    """
    usable = []
    for name in registry.available():
        try:
            registry.make(name)
        except (ImportError, ValueError) as exc:
            if verbose:
                print(f"note: controller {name!r} skipped ({exc})", file=sys.stderr)
            continue
        usable.append(name)
    return usable


def _map_table(env_ids: list[str], maps: Sequence[str] | Mapping[str, Sequence[str]] | None,
               random_maps: int | None) -> dict[str, list[str]]:  # fmt: skip
    if maps is None:
        table = {e: list(TASK_MAPS.get(e, BUILTIN_MAPS)) for e in env_ids}
    elif isinstance(maps, Mapping):
        missing = [e for e in env_ids if e not in maps]
        if missing:
            raise ValueError(f"maps has no entry for env {missing[0]!r}; it has {sorted(maps)}")
        table = {e: [os.fspath(m) for m in maps[e]] for e in env_ids}
    else:
        if isinstance(maps, (str, os.PathLike)):
            maps = [maps]
        table = {e: [os.fspath(m) for m in maps] for e in env_ids}
    if random_maps:  # the seeded random layouts are one more map row
        table = {e: m if RANDOM_MAP in m else [*m, RANDOM_MAP] for e, m in table.items()}
    return table


def evaluate(
    env_ids: str | Sequence[str] = tuple(TASK_MAPS),
    controller_names: Sequence[Any] | Mapping[str, Any] | None = None,
    maps: Sequence[str] | Mapping[str, Sequence[str]] | None = None,
    slips: Sequence[str] = SLIP_SETTINGS,
    episodes: int = 2,
    seed: int = 0,
    workers: int | None = None,
    backend: str = "process",
    out: str | os.PathLike | None = None,
    resume: bool = False,
    tolerance: float = PARAMS.goal_tolerance,
    max_episode_steps: int = PARAMS.max_episode_steps,
    progress: bool = False,
    calibration_budget: int = PARAMS.calibration_budget,
    calibration_seed: int = 0,
    start_noise: float = 0.0,
    env_kwargs: Mapping[str, Any] | None = None,
    random_maps: int | None = None,
    gifs: bool = False,
    config_check: Callable[[dict[str, Any]], None] | None = None,
) -> Results:
    """Run every controller configuration on every (env, map, slip) cell.

    Parameters
    ----------
    env_ids : str or sequence of str
        Environment ids.
    controller_names : sequence or mapping, optional
        Controller configurations (default: every usable registered controller): registered
        names, ``"name:key=value,..."`` texts, :class:`~evaluation.configs.ControllerConfig`,
        factories / controller classes, or a mapping ``{label: entry}`` where an entry is any
        of those or a ``(name or factory, {options})`` pair. Each configuration is one row.
        A factory must be defined at module level to reach worker processes.
    maps : sequence or mapping, optional
        Maps for every env (shipped names, ``"random"``, or paths of JSON map files), or a
        mapping env id -> maps (default: each task's paper maps).
    slips : sequence of str
        Setting names (``nominal``, ``low``, ``high``, ``random``, ``drift``) or comma-separated
        lambdas.
    episodes : int
        Trials per cell (trial i uses seed ``seed + i``).
    seed : int
        Base seed.
    workers : int, optional
        Worker processes (default: all cores).
    backend : str
        ``"process"`` or ``"ray"``.
    out : path, optional
        Directory for the JSONL episode log (and, from the CLI, the reports).
    resume : bool
        Continue the run logged in ``out`` (its settings must match).
    tolerance : float
        Goal tolerance [m].
    max_episode_steps : int
        Time limit [periods].
    progress : bool
        Show a progress bar on stderr.
    calibration_budget : int
        Team-transitions every controller may simulate on the cell's calibration plant before
        its episodes (the same for all; default the paper's 1000 x 1000).
    calibration_seed : int
        Seed of the calibration plant and data (never one of the episode seeds' streams).
    start_noise : float
        Env option: seeded perturbation of the start poses [m and rad] so that trials differ
        even without slip (0: the map's starts, as the paper).
    env_kwargs : mapping, optional
        Further ``gym.make`` keywords for every episode (and calibration plant), e.g.
        ``{"n_robots": 5}``; ``goal_tolerance``, ``max_episode_steps`` and ``start_noise``
        here override the arguments above. Recorded in the results and checked on resume.
    random_maps : int, optional
        Add a ``random`` map row to every env with this many seeded layouts (one per trial;
        the same layouts for every controller).
    gifs : bool
        Record trial 0 of every cell as ``OUT/animations/*.gif`` (needs ``out``).
    config_check : callable, optional
        Called with the run's configuration (what results.json records under ``config``)
        before any episode; raising ``ValueError`` stops the run there (``--baseline`` refuses
        a baseline of other settings this way).

    Returns
    -------
    Results

    Raises
    ------
    ValueError
        Any bad argument, before an episode starts.
    RunInterrupted
        Ctrl-C; the finished episodes are in ``out``'s log (resume with ``resume=True``).
    """
    env_ids = [env_ids] if isinstance(env_ids, str) else list(env_ids)
    configs = controller_configs(usable_controllers(progress) if controller_names is None else controller_names)
    map_table = _map_table(env_ids, maps, random_maps)
    slips = [s if isinstance(s, str) else ",".join(str(v) for v in s) for s in slips]
    workers = (os.cpu_count() or 1) if workers is None else workers
    if backend not in BACKENDS:
        raise ValueError(f"backend={backend!r} is not one of {list(BACKENDS)}")
    if gifs and out is None:
        raise ValueError("gifs=True needs an output directory (out=...) for the animations")
    settings = env_settings(env_kwargs, tolerance, max_episode_steps, start_noise)
    validate_plan(env_ids, configs, map_table, slips, episodes, workers, settings, calibration_budget,
                  random_maps)  # fmt: skip
    config = {
        "env_ids": env_ids, "controllers": [c.label for c in configs],
        "controller_configs": [c.to_dict() for c in configs],
        "calibration": {"budget": calibration_budget, "seed": calibration_seed,
                        "unit": "team-transitions, offered to every controller alike"},
        "maps": map_table, "map_files": map_fingerprints(map_table), "slips": slips, "episodes": episodes,
        "random_maps": random_maps, "env_settings": settings.as_dict(), "gifs": bool(gifs),
        # the dedicated settings also at the top level (schema v2 readers)
        "start_noise": settings.as_dict()["start_noise"], "tolerance": settings.as_dict()["goal_tolerance"],
        "max_episode_steps": settings.as_dict()["max_episode_steps"],
        "seed": seed, "workers": workers, "backend": backend,
    }  # fmt: skip
    plan = plan_episodes(env_ids, configs, map_table, slips, episodes, seed, settings, calibration_budget,
                         calibration_seed, random_maps, gifs, os.fspath(out) if out is not None else "")  # fmt: skip
    if config_check is not None:
        config_check(config)
    log_file, done = open_log(out, config, resume) if out is not None else (None, {})
    todo = sorted((spec for spec in plan if spec.key not in done),
                  key=lambda s: _COST.get(registry.split_name(s.controller_name)[1], 2))  # fmt: skip
    bar = Progress(len(todo), progress)
    records = dict(done)
    try:
        with run_episodes(todo, workers, backend) as stream:
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
    return Results([records[spec.key] for spec in plan], config)
