"""The one episode runner and the metrics it defines (shared by evaluator, demos, bench, tests)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from evaluation.stats.aggregate import aggregate
from koopman_envs.episodes.single import run_episode


class ScriptedEnv:
    """A stand-in env whose distances follow a script: enter tolerance, leave, enter again, succeed."""

    def __init__(self, distances: list[float]) -> None:
        real = gym.make("KoopNav-TargetReaching-v0")
        real.reset(seed=0)
        self.unwrapped = self
        self.scenario = real.unwrapped.scenario
        self.script = distances
        self.k = 0

    def _info(self) -> dict:
        d = self.script[self.k]
        done = self.k == len(self.script) - 1
        return {
            "poses": np.zeros((3, 3)),
            "targets": np.zeros((3, 3)),
            "distances": np.full(3, d),
            "collision": False,
            "collision_code": 0,
            "is_success": done,
        }

    def reset(self, *, seed=None, options=None):
        self.k = 0
        return np.zeros(3), self._info()

    def step(self, action):
        self.k += 1
        return np.zeros(3), 1.0, self.k == len(self.script) - 1, False, self._info()


class Still:
    def act(self, observation, info):
        return np.zeros(6)


def test_time_to_goal_is_the_start_of_the_final_settled_stretch() -> None:
    # step:         0    1     2    3     4     5
    env = ScriptedEnv([1.0, 0.05, 0.5, 0.05, 0.05, 0.05])
    result = run_episode(env, Still())
    assert result.success and result.steps == 5
    assert result.time_to_goal == pytest.approx(3 * env.scenario.dt)  # not step 1, the first visit
    assert result.total_reward == 5.0 and result.outcome == "success"


def test_runner_on_a_real_env_matches_the_env() -> None:
    env = gym.make("KoopNav-Formation-v0", map="map4", slip="high", max_episode_steps=40)
    result = run_episode(env, Still(), seed=3)
    assert result.truncated and not result.success and result.steps == 40
    assert result.trajectory.shape == (41, 3, 3) and result.formation_rms is not None
    np.testing.assert_array_equal(result.trajectory[0], env.unwrapped.scenario.starts)


def test_cell_p95_is_taken_over_the_cells_steps() -> None:
    base = {
        "env_id": "E",
        "controller": "c",
        "map": "m",
        "slip": "s",
        "status": "ok",
        "success": True,
        "collision": None,
        "final_distance": [0.01],
        "time_to_goal": 1.0,
        "path_length": [1.0],
        "control_effort": [1.0],
        "formation_rms": None,
        "solve_ms_median": 1.0,
        "solver_failures": 0,
    }
    fast = [1.0] * 95 + [2.0] * 5
    slow = [100.0] * 3
    records = [
        {**base, "seed": 0, "solve_ms": fast, "solve_ms_p95": float(np.percentile(fast, 95))},
        {**base, "seed": 1, "solve_ms": slow, "solve_ms_p95": 100.0},
    ]
    (cell,) = aggregate(records)
    assert cell.solve_ms_p95 == pytest.approx(np.percentile(fast + slow, 95))
    assert cell.solve_ms_p95 != max(r["solve_ms_p95"] for r in records)
