"""Under runtime uncertainty the observation is built from what the robots believe: each robot's
block (koopman_envs.tasks.observation) is recomputed here from the info's observed part alone
(``observed_poses``, ``known_poses``, ``message_age``, ``lidar_ranges``, ``observed_movers``)
plus the map, and must equal the env's observation every period; the same blocks built from the
true poses must not (so the comparison can tell the two apart)."""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import controllers
import koopman_envs  # noqa: F401 - registers the ids
from koopman_envs.tasks.observation import AGE_MAX, FAR

TR, FO = "KoopNav-TargetReaching-v0", "KoopNav-Formation-v0"


def _believed_blocks(env: Any, info: dict[str, Any]) -> np.ndarray:
    """Every robot's observation block, (N, F), from the believed state in ``info`` (the layout
    of the koopman_envs.tasks.observation docstring), clipped into the observation space."""
    engine = env.unwrapped.engine
    cfg, scenario = engine.config, env.unwrapped.scenario
    n, radius = cfg.n_robots, cfg.robot_radius
    own, known, age = info["observed_poses"], info["known_poses"], info["message_age"]
    targets, obstacles = scenario.targets, scenario.obstacles
    blocks = []
    for i in range(n):
        x, y, theta = own[i]
        c, s = math.cos(theta), math.sin(theta)

        def body(dx: float, dy: float, c: float = c, s: float = s) -> list[float]:
            return [c * dx + s * dy, c * dy - s * dx]

        tx, ty = targets[i, 0] - x, targets[i, 1] - y
        row = [x, y, c, s, *body(tx, ty), math.hypot(tx, ty)]
        row += [math.cos(targets[i, 2] - theta), math.sin(targets[i, 2] - theta)]
        for j in range(n):
            if j == i:
                continue
            if age[i, j] < 0:  # nothing heard of j yet
                row += [0.0, 0.0, FAR]
            else:
                dx, dy = known[i, j, 0] - x, known[i, j, 1] - y
                row += [*body(dx, dy), math.hypot(dx, dy) - radius[i] - radius[j]]
        if cfg.lidar is not None:
            row += list(info["lidar_ranges"][i])
        else:
            gaps = np.hypot(obstacles[:, 0] - x, obstacles[:, 1] - y) - obstacles[:, 2] - radius[i]
            order = np.argsort(gaps, kind="stable")[: cfg.n_obstacle_obs]
            for m in order:
                row += [*body(obstacles[m, 0] - x, obstacles[m, 1] - y), gaps[m]]
            row += [0.0, 0.0, FAR] * (cfg.n_obstacle_obs - len(order))
        if cfg.task.formation:
            offset = scenario.formation_offsets[i]
            heard = age[i, 0] >= 0
            row += [x - known[i, 0, 0] - offset[0], y - known[i, 0, 1] - offset[1]] if heard else [0.0, 0.0]
        if not cfg.comm.perfect:
            for j in range(n):
                if j != i:
                    row += [min(age[i, j], AGE_MAX), 1.0] if age[i, j] >= 0 else [AGE_MAX, 0.0]
        if engine.builder.mover_slots:
            movers = info["observed_movers"][info["mover_tracked"]]  # those with a track
            gaps = np.hypot(movers[:, 0] - x, movers[:, 1] - y) - radius[i] - cfg.movers.radius
            order = np.argsort(gaps, kind="stable")[: engine.builder.mover_slots]
            for m in order:
                vx, vy = movers[m, 2:]
                row += [*body(movers[m, 0] - x, movers[m, 1] - y), *body(vx, vy), gaps[m]]
            row += [0.0, 0.0, 0.0, 0.0, FAR] * (engine.builder.mover_slots - len(order))
        blocks.append(row)
    space = env.observation_space
    return np.clip(np.array(blocks), space.low.reshape(n, -1), space.high.reshape(n, -1))


def _truth(info: dict[str, Any]) -> dict[str, Any]:
    """``info`` as if the robots knew the truth: true poses, every message fresh."""
    poses = info["poses"]
    n = poses.shape[0]
    return {
        **info,
        "observed_poses": poses,
        "known_poses": np.broadcast_to(poses[None], (n, n, 3)),
        "message_age": np.zeros((n, n), dtype=np.int64),
    }


CASES = {
    "harsh-state": (TR, {"uncertainty": "harsh"}),
    "harsh-lidar-formation": (FO, {"uncertainty": "harsh", "sensing": "lidar"}),
    "pose-noise-only": (FO, {"pose_noise": {"xy": 0.1, "heading": 0.05, "drift_xy": 0.05}}),
    "late-messages-only": (FO, {"comm": {"latency": 3, "drop": 0.3}}),
    "realistic-movers": (TR, {"uncertainty": "realistic", "movers": {"count": 6, "speed": 0.3}}),
}


@pytest.mark.parametrize("case", list(CASES))
def test_the_observation_is_the_believed_state(case: str) -> None:
    env_id, kwargs = CASES[case]
    env = gym.make(env_id, max_episode_steps=120, **kwargs)
    ctrl = controllers.make("consensus")
    obs, info = env.reset(seed=2)
    ctrl.reset(env, seed=2)
    n = env.unwrapped.config.n_robots
    periods, unheard, stale, off_truth = 0, 0, 0, 0.0
    while True:
        believed = _believed_blocks(env, info)
        np.testing.assert_allclose(
            obs.reshape(n, -1), believed, rtol=1e-6, atol=1e-5, err_msg=f"period {periods}"
        )
        off_truth = max(off_truth, float(np.abs(_believed_blocks(env, _truth(info)) - believed).max()))
        off = ~np.eye(n, dtype=bool)
        unheard += int((info["message_age"][off] < 0).sum())
        stale += int((info["message_age"][off] > 0).sum())
        obs, _, terminated, truncated, info = env.step(ctrl.act(obs, info))
        periods += 1
        if terminated or truncated:
            break
    assert periods >= 60, periods
    # the blocks built from the truth differ by more than the tolerance: the check is not vacuous
    assert off_truth > 0.01, off_truth
    if "comm" in kwargs or kwargs.get("uncertainty") in ("harsh", "realistic"):
        assert unheard > 0 and stale > 0  # some team-mates unheard (absent), some heard late
