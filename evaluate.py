"""KoopNav evaluator: run every controller on every cell, report success rates and final distances.

``python evaluate.py`` runs the quick default leaderboard (both tasks, their maps, three slip
settings, every registered controller, a few episodes each), prints the tables and writes
Markdown, JSON, CSV and figures to ``results/``. ``python evaluate.py --paper`` runs the paper's
protocol (SPEC section 5: 10 trials per cell) and prints tables 1-5. From Python::

    from evaluate import evaluate
    results = evaluate("KoopNav-Formation-v0", ["koopman-nmpc", "consensus"], maps=["map3"],
                       slips=["nominal", "high"], episodes=5, seed=0)
    print(results.to_markdown())

Episodes run in worker processes; each episode's seed depends only on the base seed and its
index in the cell, so results do not depend on the worker count. Each finished episode is
appended to ``OUT/episodes.jsonl`` at once; ``--resume`` continues an interrupted run. An
episode that raises is recorded with its error, the others go on, and the exit code is the
number of failed episodes (capped at 100); a failed ``--check`` exits with 101.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import multiprocessing as mp
import os
import signal
import sys
import time
import traceback
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np

import controllers
import koopman_envs
from controllers.calibration import calibrate_controller, data_spec_for
from evaluation.ablation import ablation_configs, ablation_markdown, check_factors
from evaluation.configs import ControllerConfig, parse_controller
from evaluation.aggregate import Cell
from evaluation.results import SCHEMA_VERSION, Results, json_safe
from koopman_envs.params import PARAMS, SLIP_SETTINGS, slip_lambdas
from koopman_envs.plant import make_plant
from koopman_envs.sim.maps import BUILTIN_MAPS, load_map
from koopman_envs.engine import EngineConfig
from koopman_envs.episode import run_episode as run_controller_episode
from koopman_envs.tasks.base import TASKS, task_for_env

__all__ = ["Cell", "EpisodeSpec", "Results", "SCHEMA_VERSION", "evaluate", "main", "paper_protocol", "quick_protocol"]

TASK_MAPS = {spec.env_id: spec.paper_maps for spec in TASKS.values()}
FAILED_CHECK_EXIT = 101
INTERRUPTED_EXIT = 130  # the shell's code for a run stopped by Ctrl-C (128 + SIGINT)


# --------------------------------------------------------------------------- the plan
@dataclass(frozen=True)
class EpisodeSpec:
    """One episode to run: a cell plus the trial index (which fixes the seed)."""

    env_id: str
    controller: str  # the configuration's label (its row in the reports)
    map: str
    slip: str  # a setting name, or comma-separated lambdas
    trial: int
    seed: int
    tolerance: float
    max_episode_steps: int
    controller_name: str = ""  # registered name (default: the label)
    controller_options: str = "{}"  # JSON object of factory options
    calibration_budget: int = PARAMS.calibration_budget
    calibration_seed: int = 0
    start_noise: float = 0.0

    @property
    def key(self) -> str:
        """Unique id of the episode within a run."""
        return f"{self.env_id}|{self.controller}|{self.map}|{self.slip}|{self.trial}"

    @property
    def cell(self) -> tuple[str, str, str, str]:
        """(env, controller, map, slip)."""
        return (self.env_id, self.controller, self.map, self.slip)

    @property
    def config(self) -> ControllerConfig:
        """The controller configuration of this episode."""
        options = json.loads(self.controller_options)
        return ControllerConfig(self.controller, self.controller_name or self.controller, tuple(sorted(options.items())))


def _slip_value(slip: str) -> str | list[float]:
    return slip if slip in SLIP_SETTINGS else [float(v) for v in slip.split(",")]


def plan_episodes(
    env_ids: Sequence[str],
    configs: Sequence[ControllerConfig],
    maps: dict[str, Sequence[str]],
    slips: Sequence[str],
    episodes: int,
    seed: int,
    tolerance: float,
    max_episode_steps: int,
    calibration_budget: int = PARAMS.calibration_budget,
    calibration_seed: int = 0,
    start_noise: float = 0.0,
) -> list[EpisodeSpec]:
    """Every episode of a run, in a fixed order. Trial i of every cell uses seed ``seed + i``,
    so all controllers face the same slip draws on the same map (paired comparison)."""
    plan = []
    for env_id in env_ids:
        for cfg in configs:
            options = json.dumps(dict(cfg.options), sort_keys=True)
            for map_name in maps[env_id]:
                for slip in slips:
                    for trial in range(episodes):
                        plan.append(EpisodeSpec(env_id, cfg.label, map_name, slip, trial, seed + trial,
                                                tolerance, max_episode_steps, cfg.name, options,
                                                calibration_budget, calibration_seed, start_noise))  # fmt: skip
    return plan


def validate_arguments(
    env_ids: Sequence[str],
    configs: Sequence[ControllerConfig],
    maps: dict[str, Sequence[str]],
    slips: Sequence[str],
    episodes: int,
    workers: int,
    calibration_budget: int = PARAMS.calibration_budget,
    start_noise: float = 0.0,
) -> None:
    """Raise ``ValueError`` naming the bad value and what exists."""
    for env_id in env_ids:
        if env_id not in koopman_envs.ENV_IDS:
            raise ValueError(f"env {env_id!r} is not one of {list(koopman_envs.ENV_IDS)}")
        for map_name in maps[env_id]:
            if map_name != "random":
                try:
                    load_map(map_name)
                except ValueError as exc:
                    raise ValueError(f"map {map_name!r}: {exc}") from None
    labels = [cfg.label for cfg in configs]
    duplicated = sorted({label for label in labels if labels.count(label) > 1})
    if duplicated:
        raise ValueError(f"controller labels {duplicated} appear twice; give each configuration its own label=")
    for cfg in configs:
        cfg.validate()
    data_spec_for(calibration_budget)  # raises for a budget that is not an integer >= 1
    for env_id in env_ids:  # env options the env itself rejects (e.g. a negative start_noise)
        EngineConfig.create(task_for_env(env_id).name, map="random", start_noise=start_noise)
    for slip in slips:
        try:
            slip_lambdas(_slip_value(slip), PARAMS.n_robots)
        except ValueError as exc:
            raise ValueError(f"slip {slip!r}: {exc}") from None
    if not isinstance(episodes, int) or episodes < 1:
        raise ValueError(f"episodes={episodes!r} must be an integer >= 1")
    if not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers={workers!r} must be an integer >= 1")


def usable_controllers(verbose: bool = True) -> list[str]:
    """Registered controllers that can be built here; the others are named on stderr.

    An optional controller (``rl-ppo`` without the ``[rl]`` extra or without trained policies)
    is skipped by the default run instead of failing every episode.
    """
    usable = []
    for name in controllers.available():
        try:
            controllers.make(name)
        except (ImportError, ValueError) as exc:
            if verbose:
                print(f"note: controller {name!r} skipped ({exc})", file=sys.stderr)
            continue
        usable.append(name)
    return usable


# --------------------------------------------------------------------------- one episode
_CONTROLLER_CACHE: dict[tuple, Any] = {}


def _controller_for(spec: EpisodeSpec) -> tuple[Any, dict[str, Any] | None]:
    """The calibrated controller of a cell and its calibration summary.

    Controllers are reused within a worker (their NLPs are built once per structure). A
    controller that calibrates gets the cell's calibration plant (the env's robots in an open
    field, slip means hidden), the run's budget and seed, once per worker and plant; the evaluator
    hands it nothing else about the env. A calibration that raises is remembered and re-raised
    for every episode of its cell, which are recorded as errors; other cells go on.
    """
    cfg = spec.config
    plant = make_plant(spec.env_id, slip=_slip_value(spec.slip), budget=spec.calibration_budget,
                       seed=spec.calibration_seed)  # fmt: skip
    key = (cfg.label, cfg.name, spec.controller_options, plant.signature, spec.calibration_budget,
           spec.calibration_seed)  # fmt: skip
    if key not in _CONTROLLER_CACHE:
        ctrl = cfg.build()
        try:
            _CONTROLLER_CACHE[key] = (ctrl, calibrate_controller(ctrl, plant, seed=spec.calibration_seed))
        except Exception as exc:  # noqa: BLE001 - recorded for the cell, the run goes on
            _CONTROLLER_CACHE[key] = CalibrationError(f"calibration of {cfg.label!r} failed: {type(exc).__name__}: {exc}")
    entry = _CONTROLLER_CACHE[key]
    if isinstance(entry, CalibrationError):
        raise entry
    return entry


class CalibrationError(RuntimeError):
    """A controller's calibration raised (recorded for every episode of its cell)."""


def run_episode(spec: EpisodeSpec) -> dict[str, Any]:
    """Run one episode and return its record (never raises: errors are recorded)."""
    import gymnasium as gym

    start = time.perf_counter()
    record: dict[str, Any] = {"key": spec.key, **asdict(spec)}
    try:
        env = gym.make(
            spec.env_id,
            map=spec.map,
            slip=_slip_value(spec.slip),
            goal_tolerance=spec.tolerance,
            max_episode_steps=spec.max_episode_steps,
            start_noise=spec.start_noise,
        )
        ctrl, calibration = _controller_for(spec)
        record["calibration"] = calibration
        result = run_controller_episode(env, ctrl, seed=spec.seed)
        stats = ctrl.stats()
        summary = stats.summary()
        record.update(
            status="ok",
            success=result.success,
            collision=result.collision,
            truncated=result.truncated,
            steps=result.steps,
            time_to_goal=result.time_to_goal,
            final_poses=result.final_poses.tolist(),
            targets=result.targets.tolist(),
            final_distance=result.final_distance.tolist(),
            path_length=result.path_length.tolist(),
            control_effort=result.control_effort.tolist(),
            formation_rms=result.formation_rms,
            solve_ms_median=summary["solve_ms_median"],
            solve_ms_p95=summary["solve_ms_p95"],
            # every step's decision time, so that a cell's p95 is taken over its steps
            solve_ms=[round(1e3 * t, 3) for t in stats.solve_times],
            solver_failures=summary["failures"],
            trajectory=np.round(result.trajectory[:, :, :2], 4).tolist() if spec.trial == 0 else None,
            obstacles=env.unwrapped.scenario.obstacles.tolist() if spec.trial == 0 else None,
        )
    except Exception as exc:  # noqa: BLE001 - one bad episode must not lose the others
        record.update(status="error", error=f"{type(exc).__name__}: {exc}", traceback=traceback.format_exc())
    record["wall_seconds"] = time.perf_counter() - start
    return record


# --------------------------------------------------------------------------- running
class _Progress:
    """Progress on stderr: a tqdm bar on a terminal, one line per episode otherwise (CI logs)."""

    def __init__(self, total: int, enabled: bool) -> None:
        self.total, self.done, self.enabled = total, 0, enabled
        self.start = time.perf_counter()
        self.bar = None
        if enabled and sys.stderr.isatty():
            from tqdm import tqdm

            self.bar = tqdm(total=total, file=sys.stderr, unit="episode", dynamic_ncols=True)

    def update(self, record: dict[str, Any]) -> None:
        self.done += 1
        if not self.enabled:
            return
        mark = "ok" if record["status"] == "ok" and record.get("success") else record.get("collision") or (
            "error" if record["status"] != "ok" else "fail")  # fmt: skip
        what = f"{record['controller']} {record['map']} {record['slip']} #{record['trial']}: {mark}"
        if self.bar is not None:
            self.bar.set_postfix_str(what, refresh=False)
            self.bar.update()
        else:
            elapsed = time.perf_counter() - self.start
            print(f"[{self.done}/{self.total} {elapsed:.0f}s] {what}", file=sys.stderr, flush=True)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


class RunInterrupted(KeyboardInterrupt):
    """Ctrl-C during a run: the episodes finished so far are in the log; ``--resume`` continues."""

    def __init__(self, finished: int, total: int) -> None:
        super().__init__(f"interrupted after {finished}/{total} episodes")
        self.finished, self.total = finished, total


def _ignore_sigint() -> None:
    """Worker initializer: Ctrl-C is the main process's to handle (it stops the pool cleanly)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _config_signature(config: dict[str, Any]) -> dict[str, Any]:
    """The parts of a configuration that must match for a resume."""
    keys = ("env_ids", "controller_configs", "maps", "slips", "episodes", "seed", "tolerance", "max_episode_steps",
            "calibration", "start_noise")  # fmt: skip
    return {k: config[k] for k in keys}


def _read_log(log: Path, config: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """Finished episodes of a previous run with the same configuration (key -> record)."""
    lines = log.read_text(encoding="utf-8").splitlines()
    if not lines:
        return {}
    try:
        header = json.loads(lines[0])
    except json.JSONDecodeError:
        raise ValueError(f"{log} is not a KoopNav episode log (bad first line); nothing was overwritten") from None
    if header.get("kind") != "koopnav-run" or header.get("config") != _config_signature(config):
        raise ValueError(
            f"{log} belongs to a run with another configuration ({header.get('config')}); "
            "use another --out directory or the same options to resume; nothing was overwritten"
        )
    done = {}
    for line in lines[1:]:
        try:
            rec = json.loads(line)
        except json.JSONDecodeError:
            continue  # a line cut by the interruption: that episode simply runs again
        done[rec["key"]] = rec
    return done


def _run_ray(todo: list[EpisodeSpec], workers: int):
    """Episodes as Ray tasks: on a local Ray instance, or on the cluster at ``RAY_ADDRESS``."""
    try:
        import ray
    except ImportError:
        raise ValueError("--backend ray needs Ray: pip install -e '.[ray]'") from None
    started_here = not ray.is_initialized()
    if started_here:
        address = os.environ.get("RAY_ADDRESS")
        ray.init(address=address, num_cpus=None if address else workers, include_dashboard=False,
                 log_to_driver=False)  # fmt: skip
    try:
        remote = ray.remote(num_cpus=1)(run_episode)
        pending = [remote.remote(spec) for spec in todo]
        while pending:
            ready, pending = ray.wait(pending, num_returns=1)
            yield ray.get(ready[0])
    finally:
        if started_here:
            ray.shutdown()


def evaluate(
    env_ids: str | Sequence[str] = tuple(TASK_MAPS),
    controller_names: Sequence[str] | None = None,
    maps: Sequence[str] | dict[str, Sequence[str]] | None = None,
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
) -> Results:
    """Run every controller on every (env, map, slip) cell.

    Parameters
    ----------
    env_ids : str or sequence of str
        Environment ids.
    controller_names : sequence of str or ControllerConfig, optional
        Controller configurations: registered names, ``"name:key=value,..."`` texts or
        :class:`~evaluation.configs.ControllerConfig` (default: every usable registered one).
    maps : sequence or dict, optional
        Maps for every env, or a dict env id -> maps (default: each task's paper maps).
    slips : sequence of str
        Setting names or comma-separated per-robot lambdas.
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
        Continue the run logged in ``out``.
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

    Returns
    -------
    Results
    """
    env_ids = [env_ids] if isinstance(env_ids, str) else list(env_ids)
    configs = [parse_controller(c) for c in (controller_names or usable_controllers(progress))]
    if maps is None:
        map_table = {e: list(TASK_MAPS.get(e, BUILTIN_MAPS)) for e in env_ids}
    elif isinstance(maps, dict):
        map_table = {e: list(maps[e]) for e in env_ids}
    else:
        map_table = {e: list(maps) for e in env_ids}
    slips = [s if isinstance(s, str) else ",".join(str(v) for v in s) for s in slips]
    workers = (os.cpu_count() or 1) if workers is None else workers
    if backend not in ("process", "ray"):
        raise ValueError(f"backend={backend!r} is not one of ['process', 'ray']")
    validate_arguments(env_ids, configs, map_table, slips, episodes, workers, calibration_budget, start_noise)
    config = {
        "env_ids": env_ids, "controllers": [c.label for c in configs],
        "controller_configs": [c.to_dict() for c in configs],
        "calibration": {"budget": calibration_budget, "seed": calibration_seed,
                        "unit": "team-transitions, offered to every controller alike"},
        "maps": map_table, "slips": slips, "episodes": episodes, "start_noise": start_noise,
        "seed": seed, "tolerance": tolerance, "max_episode_steps": max_episode_steps, "workers": workers,
        "backend": backend,
    }  # fmt: skip
    plan = plan_episodes(env_ids, configs, map_table, slips, episodes, seed, tolerance, max_episode_steps,
                         calibration_budget, calibration_seed, start_noise)  # fmt: skip
    done: dict[str, dict[str, Any]] = {}
    log_file = None
    if out is not None:
        out_dir = Path(out)
        out_dir.mkdir(parents=True, exist_ok=True)
        log = out_dir / "episodes.jsonl"
        if log.exists() and log.stat().st_size > 0:
            if not resume:
                raise ValueError(f"{log} exists: pass --resume to continue that run, or choose another --out")
            done = _read_log(log, config)
            log_file = open(log, "a", encoding="utf-8")  # noqa: SIM115 - closed below
        else:
            log_file = open(log, "w", encoding="utf-8")  # noqa: SIM115
            log_file.write(json.dumps({"kind": "koopnav-run", "config": _config_signature(config)}) + "\n")
            log_file.flush()
    # longest episodes first (the learned-model NMPC, then the other optimizers) so that no worker
    # idles at the end of the run; records are put back in plan order below
    cost = {"koopman-nmpc": 0, "nominal-nmpc": 1}
    todo = sorted((spec for spec in plan if spec.key not in done),
                  key=lambda spec: cost.get(spec.controller_name, 2))  # fmt: skip
    bar = _Progress(len(todo), progress)
    records = dict(done)
    try:
        with contextlib.ExitStack() as stack:
            if backend == "ray":
                stream = _run_ray(todo, workers)
            elif workers == 1 or len(todo) <= 1:
                stream = (run_episode(spec) for spec in todo)
            else:
                # the context manager terminates the workers on every exit: success, error or Ctrl-C
                pool = stack.enter_context(mp.get_context("spawn").Pool(min(workers, len(todo)),
                                                                        initializer=_ignore_sigint))  # fmt: skip
                stream = pool.imap_unordered(run_episode, todo, chunksize=1)
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
    ordered = [records[spec.key] for spec in plan]
    return Results(ordered, config)


# --------------------------------------------------------------------------- protocols
#: ``start_noise`` of the default leaderboard (ours): starts moved within 5 cm and turned within
#: 0.05 rad, so that trials differ even without slip (the paper protocol keeps the exact starts)
QUICK_START_NOISE = 0.05


def quick_protocol() -> dict[str, Any]:
    """The default leaderboard: both tasks, their maps, three slips, 2 episodes per cell, perturbed starts."""
    return {"env_ids": list(TASK_MAPS), "maps": {e: list(m) for e, m in TASK_MAPS.items()}, "episodes": 2,
            "start_noise": QUICK_START_NOISE}  # fmt: skip


def paper_protocol(strict: bool = False) -> dict[str, Any]:
    """SPEC section 5: maps 1-2 (target reaching), 3-4 (formation), 3 slips, 10 trials per cell,
    Koopman-NMPC, nominal NMPC and (formation) consensus with collision avoidance.

    ``strict=True`` (``--paper-strict``) runs the NMPCs in the paper's exact formulation: hard
    collision and formation constraints and the paper's 0.015 m margins (our default softens the
    constraints with exact-penalty slacks; see :class:`controllers.nmpc.NMPCConfig`).
    """
    names = ["koopman-nmpc", "nominal-nmpc", "consensus"]
    if strict:
        paper = (("soft_constraints", False), ("uncertainty_margin", 0.0))
        configs = [ControllerConfig(n, n, paper if n.endswith("nmpc") else ()) for n in names]
    else:
        configs = [parse_controller(n) for n in names]
    return {
        "env_ids": list(TASK_MAPS),
        "maps": {e: list(m) for e, m in TASK_MAPS.items()},
        "episodes": 10,
        "controllers": configs,
    }


def ablation_protocol(factors: Sequence[str] | None = None) -> dict[str, Any]:
    """The ablation (:mod:`evaluation.ablation`): the paper maps under high slip, 20 trials per cell."""
    return {
        "env_ids": list(TASK_MAPS),
        "maps": {e: list(m) for e, m in TASK_MAPS.items()},
        "episodes": 20,
        "slips": ["high"],
        "controllers": ablation_configs(factors),
    }


# --------------------------------------------------------------------------- checks
def check_thresholds(results: Results, path: str | os.PathLike) -> list[str]:
    """Cells below the committed thresholds (empty list = pass).

    The TOML file holds ``[[cell]]`` tables with any of ``env``, ``controller``, ``map``,
    ``slip`` (omitted = any) and limits ``min_success_rate`` (0-1) and/or
    ``max_final_distance_cm`` (mean over robots and successful runs).
    """
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10: the same parser as the tomli backport
        import tomli as tomllib

    try:
        with open(path, "rb") as fh:
            spec = tomllib.load(fh)
    except OSError as exc:
        raise ValueError(f"thresholds file {os.fspath(path)!r} cannot be read: {exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"thresholds file {os.fspath(path)!r} is not valid TOML: {exc}") from None
    rules = spec.get("cell")
    if not isinstance(rules, list) or not rules:
        raise ValueError(f"thresholds file {os.fspath(path)!r} has no [[cell]] tables")
    problems = []
    for rule in rules:
        unknown = set(rule) - {"env", "controller", "map", "slip", "min_success_rate", "max_final_distance_cm"}
        if unknown:
            raise ValueError(f"thresholds file {os.fspath(path)!r}: unknown keys {sorted(unknown)}")
        matched = [
            c for c in results.cells
            if all(rule.get(k) in (None, v) for k, v in (("env", c.env_id), ("controller", c.controller),
                                                          ("map", c.map), ("slip", c.slip)))
        ]  # fmt: skip
        if not matched:
            problems.append(f"no evaluated cell matches {rule}")
        for c in matched:
            name = f"{c.env_id} / {c.controller} / {c.map} / {c.slip}"
            if "min_success_rate" in rule and not c.success_rate >= rule["min_success_rate"]:
                problems.append(f"{name}: success rate {c.success_rate:.2f} < {rule['min_success_rate']:.2f}")
            if "max_final_distance_cm" in rule:
                mean = c.distance_settled.team_mean
                mean = float("inf") if math.isnan(mean) else mean
                if not mean <= rule["max_final_distance_cm"]:
                    problems.append(f"{name}: final distance {mean:.1f} cm > {rule['max_final_distance_cm']:.1f} cm")
    return problems


# --------------------------------------------------------------------------- CLI
def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="evaluate.py", description=__doc__.split("\n")[0])
    parser.add_argument("--env", nargs="+", help=f"environment ids (default: {list(TASK_MAPS)})")
    parser.add_argument("--maps", nargs="+", help="maps (default: each task's: map1 map2 / map3 map4)")
    parser.add_argument("--slips", nargs="+", help="nominal low high, or per-robot lambdas like 0,0.1,0.2")
    parser.add_argument("--controllers", nargs="+", metavar="NAME[:KEY=VALUE,...]",
                        help=f"controller configurations (default: every registered one: {controllers.available()})")
    parser.add_argument("--episodes", type=int, help="trials per cell (default 2; 10 with --paper, 20 with --ablation)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--workers", type=int, help="worker processes (default: all cores)")
    parser.add_argument("--backend", choices=["process", "ray"], default="process")
    parser.add_argument("--out", default="results", help="output directory (default: results)")
    parser.add_argument("--resume", action="store_true", help="continue the run logged in --out")
    parser.add_argument("--tolerance", type=float, default=PARAMS.goal_tolerance, help="goal tolerance [m]")
    parser.add_argument("--max-episode-steps", type=int, default=PARAMS.max_episode_steps)
    parser.add_argument("--calibration-budget", type=int, default=PARAMS.calibration_budget,
                        help="team-transitions every controller may simulate to calibrate (default: the paper's "
                             "1000 x 1000)")  # fmt: skip
    parser.add_argument("--calibration-seed", type=int, default=0, help="seed of the calibration plant and data")
    parser.add_argument("--start-noise", type=float,
                        help=f"seeded start perturbation [m, rad] (default {QUICK_START_NOISE}; 0 with --paper and "
                             "--ablation, which keep the maps' starts)")  # fmt: skip
    protocol = parser.add_mutually_exclusive_group()
    protocol.add_argument("--paper", action="store_true", help="the paper's protocol (SPEC section 5)")
    protocol.add_argument("--paper-strict", action="store_true",
                          help="the paper's protocol with its exact NMPC: hard constraints, 0.015 m margins")
    protocol.add_argument("--ablation", nargs="*", metavar="FACTOR",
                          help="ablation of the NMPC's design factors (default all: model margins constraints) on the "
                               "paper maps under high slip; writes docs/ablation.md")  # fmt: skip
    parser.add_argument("--ablation-out", default=str(Path(__file__).parent / "docs" / "ablation.md"),
                        help="where --ablation writes its report (default: docs/ablation.md)")
    parser.add_argument("--check", metavar="THRESHOLDS", help="TOML thresholds; exit 101 if a cell falls below")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    return parser


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        if args.ablation is not None:
            protocol = ablation_protocol(check_factors(args.ablation))
        elif args.paper or args.paper_strict:
            protocol = paper_protocol(strict=args.paper_strict)
        else:
            protocol = quick_protocol()
        env_ids = args.env or protocol["env_ids"]
        if args.maps:
            maps: dict[str, list[str]] = {e: args.maps for e in env_ids}
        else:
            maps = {e: protocol["maps"].get(e, list(BUILTIN_MAPS)) for e in env_ids}
        start = time.perf_counter()
        results = evaluate(
            env_ids,
            args.controllers or protocol.get("controllers"),
            maps,
            args.slips or protocol.get("slips") or list(SLIP_SETTINGS),
            args.episodes or protocol["episodes"],
            args.seed,
            args.workers,
            args.backend,
            args.out,
            args.resume,
            args.tolerance,
            args.max_episode_steps,
            progress=not args.quiet,
            calibration_budget=args.calibration_budget,
            calibration_seed=args.calibration_seed,
            start_noise=protocol.get("start_noise", 0.0) if args.start_noise is None else args.start_noise,
        )
        wall = time.perf_counter() - start
        results.config["wall_seconds"] = wall
        paths = results.write(args.out)
        if args.ablation is not None:
            command = "python evaluate.py --ablation " + " ".join(args.ablation) if args.ablation else ""
            command = (command or "python evaluate.py --ablation") + (f" --episodes {args.episodes}" if args.episodes else "")
            report = ablation_markdown(results, args.ablation, command=command.strip())
            report += f"\n{len(results.records)} episodes in {wall:.0f} s on {results.config['workers']} workers.\n"
            Path(args.ablation_out).parent.mkdir(parents=True, exist_ok=True)
            Path(args.ablation_out).write_text(report, encoding="utf-8")
            paths["ablation"] = Path(args.ablation_out)
        problems = check_thresholds(results, args.check) if args.check else []
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except RunInterrupted as exc:
        words = list(sys.argv[1:] if argv is None else argv)
        again = " ".join(["python evaluate.py", *words, *([] if "--resume" in words else ["--resume"])])
        print(f"\n{exc}; continue with: {again}", file=sys.stderr)
        return INTERRUPTED_EXIT
    print(results.to_markdown())
    print(f"\n{len(results.records)} episodes in {wall:.1f} s; wrote {', '.join(str(p) for p in paths.values())} "
          f"and {Path(args.out) / 'figures'}/")  # fmt: skip
    failed = results.failed_episodes
    if failed:
        print(f"{len(failed)} episode(s) raised; see {paths['markdown']}", file=sys.stderr)
    if problems:
        print("threshold check failed:\n" + "\n".join(f"  - {p}" for p in problems), file=sys.stderr)
        return FAILED_CHECK_EXIT
    if args.check:
        print(f"threshold check passed ({args.check})")
    return min(len(failed), 100)


if __name__ == "__main__":
    raise SystemExit(main())
