"""Episode bookkeeping and the shaped reward of one step, compiled (weights: :class:`RewardWeights`)."""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from koopman_envs.tasks.base import RewardWeights

__all__ = ["score_step"]


def score_step(
    weights: RewardWeights,
    formation: bool,
    goal_tolerance: float,
    settle_steps: int,
    max_episode_steps: int | None,
    prev_distances: NDArray[np.float64],
    distances: NDArray[np.float64],
    effort: NDArray[np.float64],
    formation_error: NDArray[np.float64],
    collision: NDArray[np.int64],
    active: NDArray[np.bool_],
    settled: NDArray[np.int64],
    elapsed: NDArray[np.int64],
    robot_reward: NDArray[np.float64],
    team_reward: NDArray[np.float64],
    success: NDArray[np.bool_],
    terminated: NDArray[np.bool_],
    truncated: NDArray[np.bool_],
) -> None:
    """Update the settle and time counters and score one step of K environments.

    Per robot: ``progress * (d_prev - d) - effort * e + settle * [d <= goal_tolerance]``
    ``- formation * ||e_i||`` (formation task; the true slot error of the engine's state, not the
    observation's clipped copy);
    per team: ``success * [success] - collision * [collision]``. Success: every robot within
    ``goal_tolerance`` for ``settle_steps`` consecutive periods and no collision. Inactive
    environments score zero and neither terminate nor truncate.

    Parameters
    ----------
    weights : RewardWeights
        Reward weights of the task.
    formation : bool
        Charge the formation error.
    goal_tolerance : float
        Success radius [m].
    settle_steps : int
        Periods a team must stay within tolerance.
    max_episode_steps : int or None
        Time limit in periods (None: no truncation).
    prev_distances, distances, effort : ndarray, shape (K, N)
        Target distances [m] before and after the step and the command effort.
    formation_error : ndarray, shape (K, N)
        Distance of each robot from its formation slot after the step [m] (ignored unless
        ``formation``).
    collision : ndarray of int, shape (K,)
        Collision flags after the step.
    active : ndarray of bool, shape (K,)
        Environments that stepped.
    settled, elapsed : ndarray of int, shape (K,)
        Counters, updated in place.
    robot_reward, team_reward, success, terminated, truncated : ndarray
        Outputs, shapes (K, N), (K,), (K,), (K,), (K,).
    """
    _score(
        prev_distances,
        distances,
        effort,
        formation_error,
        collision,
        active,
        settled,
        elapsed,
        goal_tolerance,
        settle_steps,
        -1 if max_episode_steps is None else max_episode_steps,
        formation,
        weights.progress,
        weights.effort,
        weights.settle,
        weights.formation,
        weights.success,
        weights.collision,
        robot_reward,
        team_reward,
        success,
        terminated,
        truncated,
    )


@njit(cache=True)
def _score(
    prev_distances: NDArray[np.float64],
    distances: NDArray[np.float64],
    effort: NDArray[np.float64],
    formation_error: NDArray[np.float64],
    collision: NDArray[np.int64],
    active: NDArray[np.bool_],
    settled: NDArray[np.int64],
    elapsed: NDArray[np.int64],
    goal_tolerance: float,
    settle_steps: int,
    max_episode_steps: int,
    formation: bool,
    w_progress: float,
    w_effort: float,
    w_settle: float,
    w_formation: float,
    w_success: float,
    w_collision: float,
    robot_reward: NDArray[np.float64],
    team_reward: NDArray[np.float64],
    success: NDArray[np.bool_],
    terminated: NDArray[np.bool_],
    truncated: NDArray[np.bool_],
) -> None:  # pragma: no cover - compiled
    n_envs, n_robots = distances.shape
    for k in range(n_envs):
        stepped = 1 if active[k] else 0
        mask = 1.0 if active[k] else 0.0
        worst = distances[k, 0]
        for i in range(1, n_robots):
            worst = max(worst, distances[k, i])
        settled[k] = (settled[k] + stepped) * (1 if worst <= goal_tolerance else 0)
        hit = collision[k] != 0
        done = settled[k] >= settle_steps and not hit
        success[k] = done
        elapsed[k] += stepped
        terminated[k] = (hit or done) and active[k]
        truncated[k] = max_episode_steps > 0 and elapsed[k] >= max_episode_steps and active[k]
        for i in range(n_robots):
            reward = (prev_distances[k, i] - distances[k, i]) * w_progress
            reward -= effort[k, i] * w_effort
            reward += w_settle if distances[k, i] <= goal_tolerance else 0.0
            if formation:
                reward -= w_formation * formation_error[k, i]
            robot_reward[k, i] = reward * mask
        team = (1.0 if done else 0.0) * w_success
        team -= (1.0 if hit else 0.0) * w_collision
        team_reward[k] = team * mask
