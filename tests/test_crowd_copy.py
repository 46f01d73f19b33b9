"""Issue 41, item 10: a crowd env (``movers=dict(behaviour="crowd")``) copied with
``copy.deepcopy`` or pickled mid-episode stepped into "the ORCA simulator is gone", although
docs/environments.md promises that copies keep the whole state on every front (lookahead clients
such as MCTS copy the env). The copy now rebuilds its ORCA simulators from the stored state and
steps bit for bit as the original."""

from __future__ import annotations

import copy
import pickle
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import koopman_envs  # noqa: F401 - registers the ids
from koopman_envs import target_reaching_v0

pytest.importorskip("pyrvo", reason="the crowd needs pyrvo: the [crowd] extra")

ID = "KoopNav-TargetReaching-v0"
N = 3
#: periods stepped before the copy, and after it by the original and the copy
BEFORE, AFTER = 12, 40

COPIES: dict[str, Callable[[Any], Any]] = {
    "deepcopy": copy.deepcopy,
    "pickle": lambda env: pickle.loads(pickle.dumps(env)),
}


def _actions(seed: int, count: int) -> np.ndarray:
    """Gentle team actions (v, omega per robot): the robots move among the pedestrians."""
    rng = np.random.default_rng(seed)
    low, high = np.tile([-0.05, -0.3], N), np.tile([0.25, 0.3], N)
    return rng.uniform(low, high, size=(count, 2 * N))


class Runner:
    """One front behind ``step(env, action)`` -> (observation, true poses, mover states, done)."""

    def __init__(self, front: str, **kwargs: Any) -> None:
        self.front = front
        if front == "gym":
            self.env = gym.make(ID, **kwargs)
        elif front == "vector":
            self.env = gym.make_vec(ID, num_envs=2, **kwargs)
        else:
            self.env = target_reaching_v0.parallel_env(**kwargs)
        self.env.reset(seed=7)

    def step(self, env: Any, action: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool]:
        if self.front == "gym":
            observation, _, terminated, truncated, info = env.step(action)
            return observation, info["poses"], info["movers"], terminated or truncated
        if self.front == "vector":
            observation, _, terminated, truncated, info = env.step(np.stack([action, action[::-1]]))
            return observation, info["poses"], info["movers"], False  # autoreset: steps on
        blocks = {f"robot_{i}": action[2 * i : 2 * i + 2] for i in range(N)}
        observations, _, terminations, truncations, infos = env.step(blocks)
        first = infos["robot_0"]
        observation = np.concatenate([observations[a] for a in env.possible_agents])
        done = any(terminations.values()) or any(truncations.values())
        return observation, first["poses"], first["movers"], done


@pytest.mark.parametrize("how", COPIES)
@pytest.mark.parametrize("front", ["gym", "vector", "parallel"])
@pytest.mark.parametrize("aware", [False, True], ids=["oblivious", "aware"])
def test_a_copied_crowd_steps_bit_for_bit_as_the_original(front: str, how: str, aware: bool) -> None:
    runner = Runner(front, movers={"count": 4, "behaviour": "crowd", "aware": aware, "pause": 0.5})
    actions = _actions(1, BEFORE + AFTER)
    for action in actions[:BEFORE]:
        runner.step(runner.env, action)
    twin = COPIES[how](runner.env)
    start = runner.step(copy.deepcopy(runner.env), actions[BEFORE])[2]
    stepped = 0
    for action in actions[BEFORE:]:
        original, copied = runner.step(runner.env, action), runner.step(twin, action)
        for a, b in zip(original[:3], copied[:3], strict=True):
            np.testing.assert_array_equal(a, b)
        assert original[3] == copied[3]
        stepped += 1
        if original[3]:
            break
    assert stepped >= 30, f"only {stepped} periods compared (the episode ended early)"
    assert not np.array_equal(original[2], start)  # the crowd walked meanwhile


@pytest.mark.parametrize("how", COPIES)
@pytest.mark.parametrize("behaviour", ["constant", "waypoints"])
def test_copied_movers_of_the_other_behaviours_step_as_the_original(behaviour: str, how: str) -> None:
    """The movers' positions and velocities are views of one state array; a copy made them
    arrays of their own, so the copy's reported mover states (info["movers"]) stood still."""
    runner = Runner("gym", movers={"count": 5, "behaviour": behaviour, "pause": 0.5})
    actions = _actions(4, BEFORE + AFTER)
    for action in actions[:BEFORE]:
        runner.step(runner.env, action)
    twin = COPIES[how](runner.env)
    for action in actions[BEFORE:]:
        original, copied = runner.step(runner.env, action), runner.step(twin, action)
        for a, b in zip(original[:3], copied[:3], strict=True):
            np.testing.assert_array_equal(a, b)
        if original[3]:
            break


def test_a_copy_of_a_copy_and_the_original_diverge_only_by_their_actions() -> None:
    """The copy owns its simulators: stepping it leaves the original's crowd where it was."""
    runner = Runner("gym", movers={"count": 6, "behaviour": "crowd", "pause": 0.0})
    for action in _actions(2, 10):
        runner.step(runner.env, action)
    twin = copy.deepcopy(copy.deepcopy(runner.env))
    before = runner.env.unwrapped.engine.movers.states()
    for action in _actions(3, 15):
        twin.step(action)
    np.testing.assert_array_equal(runner.env.unwrapped.engine.movers.states(), before)
    assert not np.array_equal(twin.unwrapped.engine.movers.states(), before)


def test_a_crowd_copied_before_its_first_reset_resets() -> None:
    env = gym.make(ID, movers={"count": 3, "behaviour": "crowd"})
    twin = pickle.loads(pickle.dumps(env))
    a, b = env.reset(seed=4)[0], twin.reset(seed=4)[0]
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(env.step(np.zeros(6))[0], twin.step(np.zeros(6))[0])
