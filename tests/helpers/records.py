"""Episode records made by hand for the statistics' tests: one complete, valid record
(:func:`evaluation.episodes.records.record_problem` accepts it) whose outcome and final pose a test
chooses, so that two controllers' episodes on a seed pair, and equal poses make bit-identical twins."""

from __future__ import annotations

from typing import Any


def episode_record(
    controller: str, seed: int, success: bool, pose: float, map_name: str = "map1"
) -> dict[str, Any]:
    """A target-reaching episode of ``controller`` on ``map_name`` at nominal slip with ``seed``:
    a success 1 cm from the goal or an obstacle collision 1 m away, its one robot ending at
    ``(pose, 0, 0)`` (the pose tells distinct episodes apart)."""
    return {
        "key": f"{controller}-{map_name}-{seed}",
        "env_id": "KoopNav-TargetReaching-v0",
        "controller": controller,
        "map": map_name,
        "slip": "nominal",
        "trial": seed,
        "seed": seed,
        "status": "ok",
        "success": success,
        "collision": None if success else "obstacle",
        "steps": 100,
        "time_to_goal": 9.0 if success else None,
        "final_poses": [[pose, 0.0, 0.0]],
        "final_distance": [0.01 if success else 1.0],
        "path_length": [2.0],
        "control_effort": [1.0],
        "formation_rms": None,
        "solve_ms_median": 1.0,
        "solve_ms_p95": 1.0,
        "solver_failures": 0,
    }
