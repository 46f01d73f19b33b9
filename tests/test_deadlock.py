"""The central NMPC's way out of a stall (controllers/mpc/detour.py, ``unstall``): Map 2's
crossing, where the real-time iteration stopped two robots face to face and one behind the
central obstacle, is solved; where nothing stalls the controller is unchanged, bit for bit.

The nominal NMPC here is ``nominal-nmpc-v0``, the hand-set defaults the stall resolution was
designed with: the tuned ``nominal-nmpc`` turns it off (``unstall=False``) and widens its margins
by the calibrated residual (controllers/tuned/nominal-nmpc.json)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import controllers
import koopman_envs  # noqa: F401 - registers the ids
from controllers.calibration import calibrate_controller
from controllers.mpc.detour import DETOUR_PERIODS, STALL_PERIODS, DeadlockResolver, StallMonitor
from koopman_envs.engine.plant import make_plant


def _episode(name: str, map_name: str, slip: str = "nominal", seed: int = 0, **options):
    env = gym.make("KoopNav-TargetReaching-v0", map=map_name, slip=slip, start_noise=0.05)
    ctrl = controllers.make(name, solver="rti", fallback_solver=None, **options)
    if "koopman" in name:  # the shipped model of the slip setting (no fit)
        calibrate_controller(ctrl, make_plant("KoopNav-TargetReaching-v0", slip=slip), seed=0)
    obs, info = env.reset(seed=seed)
    ctrl.reset(env, seed=seed)
    commands = []
    while True:
        commands.append(np.asarray(ctrl.act(obs, info)))
        obs, _, terminated, truncated, info = env.step(commands[-1])
        if terminated or truncated:
            return info, commands, ctrl.stats().counts


# koopman-nmpc-v0's crossing runs with -m slow: two whole Map 2 episodes of the central NMPC are
# the check, and nominal-nmpc-v0 runs the same detour code on the same crossing in the default run
# (both hand-set: the tuned koopman-nmpc's margins pass the crossing without stalling)
@pytest.mark.parametrize("name", ["nominal-nmpc-v0", pytest.param("koopman-nmpc-v0", marks=pytest.mark.slow)])
def test_the_map2_crossing_deadlock_is_resolved(name: str) -> None:
    stuck, _, counts = _episode(name, "map2", unstall=False)
    assert not stuck["is_success"] and not stuck["collision"]
    assert max(stuck["distances"]) > 1.0  # a robot stopped more than a metre from its target
    assert not any(key.startswith("unstall") for key in counts)
    solved, _, counts = _episode(name, "map2")
    assert solved["is_success"] and not solved["collision"], solved["distances"]
    assert counts["unstall_yield"] >= 1  # a robot gave way to a team-mate


def test_without_a_stall_nothing_changes() -> None:
    """Map 1 (no stall): the same commands, bit for bit, with and without ``unstall``."""
    on, commands_on, counts = _episode("nominal-nmpc-v0", "map1", slip="high")
    off, commands_off, _ = _episode("nominal-nmpc-v0", "map1", slip="high", unstall=False)
    assert on["is_success"] and not any(key.startswith("unstall") for key in counts)
    assert len(commands_on) == len(commands_off)
    for a, b in zip(commands_on, commands_off, strict=True):
        np.testing.assert_array_equal(a, b)


def test_a_stall_is_named_after_the_stated_periods_and_only_away_from_the_target() -> None:
    monitor = StallMonitor(2)
    target = np.array([5.0, 0.0])
    named = [monitor.stalled(0, np.array([0.0, 0.0]), target, 0.1) for _ in range(STALL_PERIODS + 1)]
    assert named == [False] * STALL_PERIODS + [True]
    # at the target: never
    assert not any(monitor.stalled(1, target, target, 0.1) for _ in range(3 * STALL_PERIODS))


def test_the_lower_priority_robot_steps_aside_and_the_other_keeps_its_target() -> None:
    """Two robots face to face on one line: robot 1 (lower priority) gets a point beside robot
    0's path, robot 0 its own target; after DETOUR_PERIODS both track their targets again."""
    resolver = DeadlockResolver(np.array([0.2, 0.2]), np.zeros((0, 3)), 0.015)
    positions = np.array([[0.0, 0.0], [0.5, 0.05]])
    targets = np.array([[3.0, 0.0, 0.0], [-3.0, 0.0, 0.0]])
    for _ in range(STALL_PERIODS):
        goals, started = resolver.goals(positions, targets, 0.1)
        assert started == []
    goals, started = resolver.goals(positions, targets, 0.1)
    assert started == ["restart", "yield"]  # robot 0 restarts toward its target, robot 1 yields
    np.testing.assert_array_equal(goals[0], targets[0, :2])
    # beside robot 0's path (the x axis), on robot 1's side, clear of both radii and the margin
    assert goals[1][1] > 0.4 + 0.015 and abs(goals[1][0] - 0.5) < 1e-9
    for _ in range(DETOUR_PERIODS - 1):
        goals, _ = resolver.goals(positions + [[0.0, 0.0], [0.0, 1.0]], targets, 0.1)
    goals, _ = resolver.goals(positions + [[0.0, 0.0], [0.0, 1.0]], targets, 0.1)
    np.testing.assert_array_equal(goals, targets[:, :2])


def test_a_bad_unstall_option_names_the_value() -> None:
    with pytest.raises(ValueError, match=r"unstall='yes' must be True or False"):
        controllers.make("nominal-nmpc", unstall="yes")
