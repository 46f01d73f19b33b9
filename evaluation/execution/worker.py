"""One episode of a run, as a worker process runs it: build the env and the calibrated controller,
run the episode, return its record. Never raises: an error becomes the episode's record."""

from __future__ import annotations

import copy
import dataclasses
import json
import time
import traceback
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from controllers.base import Calibratable, ControllerStats
from controllers.calibration import calibrate_controller
from evaluation.episodes.records import finished_status
from evaluation.run.plan import EpisodeSpec, slip_value
from koopman_envs import EpisodeResult, make_plant, run_episode, run_episodes_in_batch

__all__ = ["CalibrationError", "batch_cell", "episode_record", "run_batch", "runs_in_batch"]

_CONTROLLER_CACHE: dict[tuple, Any] = {}
_COMMON_SUMMARY = frozenset(ControllerStats().summary())


class CalibrationError(RuntimeError):
    """A controller's calibration raised (recorded for every episode of its cell)."""


def _controller_for(spec: EpisodeSpec) -> tuple[Any, dict[str, Any] | None]:
    """The calibrated controller of a cell and its calibration summary.

    Controllers are reused within a worker (their NLPs are built once per structure). A
    controller that calibrates gets the cell's calibration plant (the env's robots in an open
    field, slip means hidden), the run's budget and seed, once per worker and plant; the evaluator
    hands it nothing else about the env. A calibration that raises is remembered and re-raised
    for every episode of its cell, which are recorded as errors; other cells go on.
    """
    cfg = spec.config
    plant = make_plant(
        spec.env_id,
        slip=slip_value(spec.slip),
        budget=spec.calibration_budget,
        seed=spec.calibration_seed,
        **json.loads(spec.env_kwargs),
    )
    key = (
        cfg.label,
        cfg.name,
        spec.controller_options,
        plant.signature,
        spec.calibration_budget,
        spec.calibration_seed,
    )
    if key not in _CONTROLLER_CACHE:
        ctrl = cfg.build()
        try:
            _CONTROLLER_CACHE[key] = (ctrl, calibrate_controller(ctrl, plant, seed=spec.calibration_seed))
        except Exception as exc:  # noqa: BLE001 - recorded for the cell, the run goes on
            _CONTROLLER_CACHE[key] = CalibrationError(
                f"calibration of {cfg.label!r} failed: {type(exc).__name__}: {exc}"
            )
    entry = _CONTROLLER_CACHE[key]
    if isinstance(entry, CalibrationError):
        raise entry
    return entry


def _result_fields(spec: EpisodeSpec, result: EpisodeResult, stats: ControllerStats) -> dict[str, Any]:
    """The measured fields of an episode's record (the one-env runner's or the batch's result);
    the first trial of a cell keeps its paths and obstacles (figures)."""
    summary = stats.summary()
    fields = dict(
        status=finished_status(summary["failures"], len(stats.solve_times) or result.steps),
        success=result.success,
        # beside success: the stricter success, the fault of the collision that ended the
        # episode and success with the collisions no robot could avoid excused
        strict_success=result.strict_success,
        success_excusing_unavoidable=result.success_excusing_unavoidable,
        collision=result.collision,
        collision_at_fault=result.collision_at_fault,
        truncated=result.truncated,
        steps=result.steps,
        time_to_goal=result.time_to_goal,
        final_poses=result.final_poses.tolist(),
        targets=result.targets.tolist(),
        final_distance=result.final_distance.tolist(),
        path_length=result.path_length.tolist(),
        control_effort=result.control_effort.tolist(),
        formation_rms=result.formation_rms,
        straight_distance=result.straight_distance.tolist(),
        min_clearance=result.min_clearance,
        clearance_min_m=result.clearance_min_m,
        accel_rms=result.accel_rms.tolist(),
        # the metrics the suite reports test (docs/benchmark.md, "Metrics")
        jerk_rms=None if result.jerk_rms is None else result.jerk_rms.tolist(),
        near_obstacle_share=result.near_obstacle_share.tolist(),
        path_ratio=result.path_ratio,
        decisions=result.decisions,
        deadline_misses=result.deadline_misses,
        late_periods=result.late_periods,
        angular_accel_rms=result.angular_accel_rms.tolist(),
        solve_ms_median=summary["solve_ms_median"],
        solve_ms_p95=summary["solve_ms_p95"],
        # every step's decision time, so that a cell's p95 is taken over its steps
        solve_ms=[round(1e3 * t, 3) for t in stats.solve_times],
        solver_failures=summary["failures"],
        # what a controller reports beyond the common summary (e.g. the safety filter's counts)
        controller_extra={k: v for k, v in summary.items() if k not in _COMMON_SUMMARY} or None,
        trajectory=np.round(result.trajectory[:, :, :2], 4).tolist() if spec.trial == 0 else None,
        obstacles=result.obstacles.tolist() if spec.trial == 0 and result.obstacles is not None else None,
    )
    if spec.trial == 0 and result.mover_trajectory is not None:  # only an episode with movers has it
        fields["mover_trajectory"] = np.round(result.mover_trajectory, 4).tolist()
    return fields


def batch_cell(spec: EpisodeSpec) -> EpisodeSpec:
    """What the episodes of one batch share: the spec without its trial, seed and suite layout."""
    return dataclasses.replace(spec, trial=0, seed=0, layout=None, layout_family=None, layout_tier=None)


def runs_in_batch(spec: EpisodeSpec) -> bool:
    """Whether an episode may run in a batch of its cell (:func:`run_batch`): its controller's
    class decides for many teams at once (``acts_in_batch``, read from the class as
    :func:`~koopman_envs.episodes.batch.run_episodes_in_batch` reads it, nothing built)
    and calibrates nothing, the compute is free (no ``--realtime``: the one-env runner charges
    it), and it records no animation. A controller whose class is not known without a call (a
    factory function without a class annotation) runs alone."""
    if spec.animation or spec.compute is not None:
        return False
    try:
        kind = spec.config.controller_class()
    except Exception:  # noqa: BLE001 - a controller that cannot be found runs alone (and records its error)
        return False
    return (
        kind is not None
        and bool(getattr(kind, "acts_in_batch", False))
        and not issubclass(kind, Calibratable)
    )


def run_batch(specs: Sequence[EpisodeSpec]) -> list[dict[str, Any]]:
    """The records of a cell's episodes run together in the vector env
    (:func:`~koopman_envs.episodes.batch.run_episodes_in_batch`), equal to
    :func:`episode_record`'s but for the timing fields; never raises. If the batch fails anywhere
    (a controller or env error), every episode is run again alone, so that each episode's error is
    its own and the others keep their results."""
    if len(specs) == 1 or len({batch_cell(s) for s in specs}) != 1:
        return [episode_record(spec) for spec in specs]
    start = time.perf_counter()
    try:
        first = specs[0]
        built = first.config.build()
        # copies of one fresh build, as many fresh builds but without resolving the factory again
        teams = [built] + [copy.deepcopy(built) for _ in specs[1:]]
        venv = gym.make_vec(first.env_id, num_envs=len(specs), **first.make_kwargs())
        try:
            # a suite run's episodes each on their own layout (one reset option per sub-env)
            layouts = [spec.layout for spec in specs]
            options = None if first.layout is None else {"layout": layouts}
            results = run_episodes_in_batch(venv, teams, [spec.seed for spec in specs], options=options)
        finally:
            venv.close()
    except Exception:  # noqa: BLE001 - each episode again alone: its error is recorded as its own
        return [episode_record(spec) for spec in specs]
    share = (time.perf_counter() - start) / len(specs)
    records = []
    for spec, ctrl, result in zip(specs, teams, results, strict=True):
        record = spec.record_fields()
        record["calibration"] = None  # a batched controller calibrates nothing (runs_in_batch)
        record.update(_result_fields(spec, result, ctrl.stats()))
        record["wall_seconds"] = share
        records.append(record)
    return records


def episode_record(spec: EpisodeSpec) -> dict[str, Any]:
    """The record of one episode, run alone: the env and the cell's calibrated controller built,
    the episode run by :func:`koopman_envs.run_episode`, its animation saved (never raises: an
    error is recorded as the episode's)."""
    start = time.perf_counter()
    record: dict[str, Any] = spec.record_fields()
    try:
        env = gym.make(spec.env_id, render_mode="rgb_array" if spec.animation else None, **spec.make_kwargs())
        ctrl, calibration = _controller_for(spec)
        record["calibration"] = calibration
        result = run_episode(
            env,
            ctrl,
            seed=spec.seed,
            options=spec.reset_options(),
            render=bool(spec.animation),
            compute=spec.compute,
        )
        record.update(_result_fields(spec, result, ctrl.stats()))
        if spec.animation:
            from koopman_envs import save_episode

            path = Path(spec.run_dir) / spec.animation
            path.parent.mkdir(parents=True, exist_ok=True)
            save_episode(result.frames, path)
        env.close()
    except Exception as exc:  # noqa: BLE001 - one bad episode must not lose the others
        record.update(status="error", error=f"{type(exc).__name__}: {exc}", traceback=traceback.format_exc())
    record["wall_seconds"] = time.perf_counter() - start
    return record
