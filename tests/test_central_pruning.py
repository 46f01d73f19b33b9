"""The central NMPC's pair and obstacle slots (``pair_slots``, ``obstacle_slots``; default off).

The NMPC is ``nominal-nmpc-v0``, the hand-set defaults, built without a calibration: the tuned
``nominal-nmpc`` widens its margins by the calibrated residual, so it needs ``calibrate`` first."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import controllers
from controllers.mpc.config import PARKED
from koopman_envs.episodes.single import run_episode


def _reset(n: int = 3, map_name: str = "map1", **options):
    env = gym.make("KoopNav-TargetReaching-v0", map=map_name, n_robots=n)
    obs, info = env.reset(seed=0)
    ctrl = controllers.make("nominal-nmpc-v0", **options)
    ctrl.reset(env)
    return ctrl, env, obs, info


def _pair_slots(ctrl) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    p, n = ctrl.config.pair_slots, ctrl.scenario.n_robots
    values = np.concatenate([ctrl.parameter(b) for b in ("pair_select", "pair_offset", "pair_reach")])
    return values[: n * p].reshape(p, n), values[n * p : n * p + 2 * p].reshape(p, 2), values[n * p + 2 * p :]


def test_only_pairs_that_can_meet_within_the_horizon_get_a_slot() -> None:
    ctrl, _, _, info = _reset(pair_slots=3)
    poses = np.array(info["poses"], dtype=float)
    sc = ctrl.scenario
    reach = (
        2 * sc.v_max * ctrl.config.horizon * sc.dt + 2 * 0.2 + ctrl.config.robot_offset
    )  # + radii + margin
    poses[1, :2] = poses[0, :2] + [reach - 0.05, 0.0]  # pair (0, 1) can meet
    poses[2, :2] = poses[0, :2] + [0.0, -(reach + 1.0)]  # (0, 2) and (1, 2) cannot
    ctrl._fill_slots(poses[:, :2])
    select, offset, slot_reach = _pair_slots(ctrl)
    assert ctrl.pairs_in_slots == [(0, 1), None, None]
    assert select[0].tolist() == [1.0, -1.0, 0.0] and np.all(offset[0] == 0) and slot_reach[0] > 0.4
    # unused slots are parked: zero selection, a point PARKED away, zero reach
    assert not select[1:].any() and np.all(offset[1:] == PARKED) and not slot_reach[1:].any()


def test_a_pair_keeps_its_slot_and_overflow_is_counted() -> None:
    ctrl, _, _, info = _reset(pair_slots=1)
    poses = np.array(info["poses"], dtype=float)
    poses[:, :2] = [[0.0, 0.0], [0.6, 0.0], [0.0, 0.5]]  # every pair within reach, (0, 2) nearest
    ctrl._fill_slots(poses[:, :2])
    assert ctrl.pairs_in_slots == [(0, 2)]
    assert ctrl.stats().counts["pairs_dropped"] == 2
    poses[2, :2] = [0.0, 0.9]  # (0, 2) now farther than (0, 1), but still within reach: it stays
    ctrl._fill_slots(poses[:, :2])
    assert ctrl.pairs_in_slots == [(0, 2)]


def test_each_robot_reads_its_nearest_obstacles() -> None:
    ctrl, env, _, info = _reset(map_name="map2", obstacle_slots=2)
    obstacles = np.asarray(ctrl.scenario.obstacles)
    assert obstacles.shape[0] > 2
    poses = np.array(info["poses"], dtype=float)
    ctrl._fill_slots(poses[:, :2])
    slots = ctrl.parameter("obstacles").reshape(3, 2, 3)
    for i in range(3):
        gap = np.hypot(*(poses[i, :2] - obstacles[:, :2]).T) - obstacles[:, 2]
        np.testing.assert_array_equal(slots[i], obstacles[np.argsort(gap, kind="stable")[:2]])


def test_slots_for_every_pair_and_obstacle_solve_the_same_problem() -> None:
    """With a slot for every pair and every obstacle, the pruned problem is the paper's problem
    written in another row order: IPOPT finds the same plan."""
    full, env, obs, info = _reset(map_name="map2", solver="ipopt")
    m = full.scenario.obstacles.shape[0]
    pruned, _, _, _ = _reset(map_name="map2", solver="ipopt", pair_slots=3, obstacle_slots=m)
    for _ in range(3):
        a, b = full.act(obs, info), pruned.act(obs, info)
        np.testing.assert_allclose(b, a, atol=1e-4)
        obs, _, _, _, info = env.step(a)


def test_pruned_central_nmpc_runs_a_whole_episode() -> None:
    env = gym.make("KoopNav-TargetReaching-v0", map="map1")
    result = run_episode(
        env, controllers.make("nominal-nmpc-v0", solver="rti", pair_slots=2, obstacle_slots=2), seed=0
    )
    assert result.success, result.outcome


@pytest.mark.parametrize(
    ("options", "message"),
    [({"pair_slots": -1}, "pair_slots=-1"), ({"obstacle_slots": 1.5}, "obstacle_slots=1.5")],
)
def test_bad_slot_counts_are_named(options: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        controllers.make("nominal-nmpc-v0", **options)
