"""Episode bookkeeping and the shaped reward of one step, compiled (weights: :class:`RewardWeights`).

The fixed terms of a task's scoring travel to the kernel as one record (:func:`score_rule`, made
once per engine), the episode counters as the rows of one array (:data:`SETTLED`,
:data:`ELAPSED`), the episode ends of a step likewise (:data:`SUCCESS`, :data:`TERMINATED`,
:data:`TRUNCATED`) and the three reward outputs as one plain tuple (:data:`Rewards`). numba
reads a record's fields by name, and types a record argument at a call as fast as a plain array,
a plain tuple of arrays nearly so (about 0.1 us an array more than a loose argument); a named
tuple it types field by field in Python, microseconds a call, and this kernel runs on every step
of a single env.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from koopman_envs.tasks.base import RewardWeights

__all__ = [
    "ELAPSED",
    "SCORE_RULE",
    "SETTLED",
    "SUCCESS",
    "TERMINATED",
    "TRUNCATED",
    "Rewards",
    "numpy_sum",
    "score_rule",
    "score_step",
    "slot_errors",
]

#: the record of :func:`score_rule`: the task's rule (success radius, settle periods, time
#: limit, whether the formation error is charged) and its reward weights
SCORE_RULE = np.dtype(
    [
        ("goal_tolerance", np.float64),
        ("settle_steps", np.int64),
        ("max_episode_steps", np.int64),  # -1: no time limit
        ("formation", np.bool_),
        ("w_progress", np.float64),
        ("w_effort", np.float64),
        ("w_settle", np.float64),
        ("w_formation", np.float64),
        ("w_success", np.float64),
        ("w_collision", np.float64),
    ]
)
#: the rows of the episode ends :func:`score_step` writes, a (3, K) bool array
SUCCESS, TERMINATED, TRUNCATED = 0, 1, 2
#: the rows of the episode counters, a (2, K) int64 array: periods the team has stayed within
#: the goal tolerance, periods since the reset
SETTLED, ELAPSED = 0, 1
#: :func:`score_step`'s outputs: each robot's own terms (K, N), the team's terms (K,) and the
#: team's reward (K,), a plain tuple (what numba types at a call almost as fast as loose arrays)
Rewards = tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]
#: numpy's pairwise summation block (``PW_BLOCKSIZE``)
_BLOCK = 128


@njit(cache=True, inline="always")
def numpy_sum(values: NDArray[np.float64], start: int, count: int) -> float:  # pragma: no cover - compiled
    """The sum of ``values[start:start + count]`` (1-d float64) exactly as ``np.add.reduce`` of
    that contiguous run adds it: numpy's pairwise summation (below 8 terms one after another;
    up to 128 in eight interleaved partial sums; beyond, the halves at a multiple of 8), added
    to numpy's starting value 0.0. A team's total reward is summed here, in the kernel that
    scores it, rather than by a numpy reduction per step (about a microsecond of call on every
    step of a single env); ``tests/test_reward_sum.py`` checks it against numpy's."""
    if count <= _BLOCK:
        return 0.0 + _block_sum(values, start, count)
    return 0.0 + _halves_sum(values, start, count)


@njit(cache=True, inline="always")
def _block_sum(values: NDArray[np.float64], start: int, n: int) -> float:  # pragma: no cover - compiled
    """numpy's ``pairwise_sum`` of ``values[start:start + n]`` for n <= 128 (one block)."""
    if n < 8:
        res: float = -0.0  # numpy's start: a sum of -0.0 terms stays -0.0
        for i in range(start, start + n):
            res += values[i]
        return res
    r0, r1, r2, r3 = values[start], values[start + 1], values[start + 2], values[start + 3]
    r4, r5, r6, r7 = values[start + 4], values[start + 5], values[start + 6], values[start + 7]
    i = 8
    while i < n - n % 8:
        at = start + i
        r0 += values[at]
        r1 += values[at + 1]
        r2 += values[at + 2]
        r3 += values[at + 3]
        r4 += values[at + 4]
        r5 += values[at + 5]
        r6 += values[at + 6]
        r7 += values[at + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += values[start + i]
        i += 1
    return res


@njit(cache=True)
def _halves_sum(values: NDArray[np.float64], start: int, n: int) -> float:  # pragma: no cover - compiled
    """numpy's ``pairwise_sum`` for n > 128: the sum of the first half (n // 2 down to a multiple
    of 8) plus the sum of the rest, each split again until it fits a block. numpy recurses; this
    walks the same tree with a stack (a cached numba function that recurses can crash a kernel
    of another module that calls it)."""
    starts, counts = np.empty(64, dtype=np.int64), np.empty(64, dtype=np.int64)
    stages, partial = np.empty(64, dtype=np.int64), np.empty(64)
    top, done = 0, 0
    starts[0], counts[0], stages[0] = start, n, 0
    while top >= 0:
        first, size, stage = starts[top], counts[top], stages[top]
        if size <= _BLOCK:
            partial[done] = _block_sum(values, first, size)
            done += 1
            top -= 1
            continue
        half = size // 2
        half -= half % 8
        if stage < 2:  # the first half, then the rest
            stages[top] = stage + 1
            top += 1
            starts[top] = first if stage == 0 else first + half
            counts[top] = half if stage == 0 else size - half
            stages[top] = 0
        else:  # both summed: their sum stands for this run
            done -= 1
            partial[done - 1] = partial[done - 1] + partial[done]
            top -= 1
    total: float = partial[0]
    return total


def score_rule(
    weights: RewardWeights,
    formation: bool,
    goal_tolerance: float,
    settle_steps: int,
    max_episode_steps: int | None,
) -> NDArray[np.void]:
    """The fixed terms of a task's scoring as the one-element record :func:`score_step` takes.

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

    Returns
    -------
    ndarray of :data:`SCORE_RULE`, shape (1,)
    """
    terms = (
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
    )
    return np.array([terms], dtype=SCORE_RULE)


@njit(cache=True)
def score_step(
    rule: NDArray[np.void],
    prev_distances: NDArray[np.float64],
    distances: NDArray[np.float64],
    effort: NDArray[np.float64],
    formation_error: NDArray[np.float64],
    collision: NDArray[np.int64],
    active: NDArray[np.bool_],
    counters: NDArray[np.int64],
    rewards: Rewards,
    ends: NDArray[np.bool_],
) -> None:  # pragma: no cover - compiled
    """Update the settle and time counters and score one step of K environments.

    Per robot: ``progress * (d_prev - d) - effort * e + settle * [d <= goal_tolerance]``
    ``- formation * ||e_i||`` (formation task; the true slot error of the engine's state, not the
    observation's clipped copy);
    per team: ``success * [success] - collision * [collision]``. Success: every robot within
    ``goal_tolerance`` for ``settle_steps`` consecutive periods and no collision. Inactive
    environments score zero and neither terminate nor truncate.

    Parameters
    ----------
    rule : ndarray of SCORE_RULE, shape (1,)
        The task's rule and weights (:func:`score_rule`).
    prev_distances, distances, effort : ndarray, shape (K, N)
        Target distances [m] before and after the step and the command effort.
    formation_error : ndarray, shape (K, N)
        Distance of each robot from its formation slot after the step [m] (ignored unless the
        rule charges it).
    collision : ndarray of int, shape (K,)
        Collision flags after the step.
    active : ndarray of bool, shape (K,)
        Environments that stepped.
    counters : ndarray of int, shape (2, K)
        Rows :data:`SETTLED` and :data:`ELAPSED`, updated in place.
    rewards : tuple of ndarray, shapes (K, N), (K,) and (K,)
        Outputs (:data:`Rewards`): each robot's own terms, the team's, and the team's reward,
        its robots' terms summed as numpy sums them (:func:`numpy_sum`) plus the team's.
    ends : ndarray of bool, shape (3, K)
        Output: rows :data:`SUCCESS`, :data:`TERMINATED` and :data:`TRUNCATED`.
    """
    r = rule[0]
    settled, elapsed = counters[SETTLED], counters[ELAPSED]
    robot_reward, team_reward, total = rewards
    # the rule's terms as locals, read once: a record's fields are memory that the writes below
    # could alias, so the loop would load them again and again
    goal_tolerance, settle_steps, max_steps, formation = (
        r.goal_tolerance,
        r.settle_steps,
        r.max_episode_steps,
        r.formation,
    )
    w_progress, w_effort, w_settle, w_formation = r.w_progress, r.w_effort, r.w_settle, r.w_formation
    w_success, w_collision = r.w_success, r.w_collision
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
        ends[SUCCESS, k] = done
        elapsed[k] += stepped
        ends[TERMINATED, k] = (hit or done) and active[k]
        ends[TRUNCATED, k] = max_steps > 0 and elapsed[k] >= max_steps and active[k]
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
        total[k] = numpy_sum(robot_reward[k], 0, n_robots) + team_reward[k]


@njit(cache=True)
def slot_errors(
    state: NDArray[np.float64], offset: NDArray[np.float64], out: NDArray[np.float64]
) -> None:  # pragma: no cover - compiled
    """Distance of every robot from its formation slot relative to the leader [m] into ``out``
    (K, N) (the leader's is 0): ``hypot((x_i - x_0) - dx_i, (y_i - y_0) - dy_i)`` for ``state``
    (K, 3, N) and the slot ``offset`` (K, 2, N), in numpy's order of operations (``math.hypot``
    is the C library's, as ``np.hypot``), in one call instead of six numpy ones per step."""
    for k in range(state.shape[0]):
        for i in range(state.shape[2]):
            ex = state[k, 0, i] - state[k, 0, 0] - offset[k, 0, i]
            ey = state[k, 1, i] - state[k, 1, 0] - offset[k, 1, i]
            out[k, i] = math.hypot(ex, ey)
