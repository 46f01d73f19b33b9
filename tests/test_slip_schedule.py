"""Slip levels that change within an episode: listed schedules and drift (law, reproducibility,
untouched draws of the other settings), in the envs, the calibration plant and the evaluator."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import koopman_envs  # noqa: F401 - registers the ids
from koopman_envs import make_plant
from koopman_envs.engine.config import EngineConfig
from koopman_envs.engine.engine import NavigationEngine
from koopman_envs.params import DRIFT_MEAN_INTERVAL, PARAMS, RANDOM_SLIP_MAX
from koopman_envs.sim.maps.map_spec import MapSpec

TR = "KoopNav-TargetReaching-v0"
FO = "KoopNav-Formation-v0"


def open_field(n: int = 3) -> MapSpec:
    starts = [[0.0, 2.0 * i, 0.0] for i in range(n)]
    return MapSpec("open", [], starts, [[5.0, 2.0 * i, 0.0] for i in range(n)])


def levels(env: gym.Env, steps: int, command: np.ndarray | None = None) -> np.ndarray:
    """``env.unwrapped.lambdas`` before each of ``steps`` steps, (steps, N)."""
    out = []
    for _ in range(steps):
        out.append(env.unwrapped.lambdas)
        env.step(np.zeros(6) if command is None else command)
    return np.array(out)


def test_a_listed_schedule_changes_at_its_times() -> None:
    """Each level holds from its time on; a change at 0.3 s (2.9999999999999996 periods in
    floating point) applies from period 3, the one that starts at 0.3 s."""
    env = gym.make(TR, map=open_field(), slip=[(0.0, "nominal"), (0.3, [0.1, 0.2, 0.3]), (1.05, 0.5)])
    env.reset(seed=0)
    seen = levels(env, 15)
    np.testing.assert_array_equal(seen[:3], 0.0)
    np.testing.assert_array_equal(seen[3:11], np.tile([0.1, 0.2, 0.3], (8, 1)))
    np.testing.assert_array_equal(seen[11:], 0.5)
    env.reset()  # a new episode starts the schedule again
    np.testing.assert_array_equal(env.unwrapped.lambdas, 0.0)


def test_a_schedule_scales_the_same_draws() -> None:
    """The schedule only changes the scale: turning in place, the realized turn slip after the
    change is exactly 3x that of a constant-level env with the same seed."""
    spin = np.array([0.0, PARAMS.omega_max] * 3)
    scheduled = gym.make(TR, map=open_field(), slip=[(0.0, 0.1), (1.0, 0.3)])
    constant = gym.make(TR, map=open_field(), slip=0.1)
    turns = []
    for env in (scheduled, constant):
        _, info = env.reset(seed=2)
        out = []
        for _ in range(20):
            before = info["poses"][:, 2]
            info = env.step(spin)[4]
            out.append((info["poses"][:, 2] - before + np.pi) % (2 * np.pi) - np.pi)
        turns.append(np.array(out) / (PARAMS.omega_max * PARAMS.dt) - 1.0)  # gamma per period
    np.testing.assert_array_equal(turns[0][:10], turns[1][:10])
    np.testing.assert_allclose(turns[0][10:], 3.0 * turns[1][10:], rtol=1e-9)


def test_drift_is_reproducible_and_leaves_the_other_draws_alone() -> None:
    """Same seed, same levels; the random map and the start noise of the episode are those of the
    same env without drift (the drift draws come after them)."""
    kwargs = dict(map="random", start_noise=0.2)
    a, b, nominal = (gym.make(FO, **kwargs, **extra) for extra in ({"slip": "drift"}, {"slip": "drift"}, {}))
    for env in (a, b, nominal):
        env.reset(seed=9)
    for key in ("obstacles", "starts", "targets"):
        expected = getattr(nominal.unwrapped.scenario, key)
        np.testing.assert_array_equal(getattr(a.unwrapped.scenario, key), expected)
    np.testing.assert_array_equal(levels(a, 300), levels(b, 300))
    other = gym.make(FO, slip="drift", **kwargs)
    other.reset(seed=10)
    assert not np.array_equal(levels(other, 5)[0], levels(a, 5)[0])


def test_drift_follows_its_law() -> None:
    """Levels uniform on [0, RANDOM_SLIP_MAX], and in each period every robot's level changes with
    probability 1 - exp(-dt / DRIFT_MEAN_INTERVAL) (Poisson changes seen at the periods' starts)."""
    config = EngineConfig.create("target_reaching", map=open_field(), slip="drift")
    k, steps = 128, 600
    engine = NavigationEngine(config, num_envs=k)
    for i in range(k):
        engine.reset_env(i, np.random.default_rng(i))
    zero = np.zeros((k, 3, 2))
    seen = [engine.slip_means()]
    for _ in range(steps):
        engine.step(zero)
        seen.append(engine.slip_means())
    seen = np.array(seen)  # (steps + 1, K, N)
    changed = seen[1:] != seen[:-1]
    p = -math.expm1(-PARAMS.dt / DRIFT_MEAN_INTERVAL)
    assert abs(changed.mean() - p) < 4 * math.sqrt(p * (1 - p) / changed.size)  # ~4 sigma
    assert seen.min() >= 0.0 and seen.max() <= RANDOM_SLIP_MAX
    first = seen[0].reshape(-1)
    assert abs(first.mean() - RANDOM_SLIP_MAX / 2) < 4 * RANDOM_SLIP_MAX / math.sqrt(12 * first.size)
    assert len({tuple(row) for row in seen[0]}) == k  # every env its own levels


@pytest.mark.parametrize("slip", ["drift", [(0.0, [0.0, 0.1, 0.2]), (2.0, "high"), (3.5, 0.3)]])
def test_the_plant_follows_the_schedule(slip) -> None:
    """A step sequence of the plant equals its rollout; a drift plant changes levels within a
    rollout, and its signature differs from the constant settings'."""
    a = make_plant(TR, slip=slip, budget=10_000, seed=4)
    b = make_plant(TR, slip=slip, budget=10_000, seed=4)
    commands = np.random.default_rng(0).uniform(-1, 1, (60, 2, 3, 2))
    states = a.rollout(np.zeros((2, 3, 3)), commands)
    b.reset(np.zeros((2, 3, 3)))
    np.testing.assert_array_equal(states[1:], np.array([b.step(c) for c in commands]))
    constant = {make_plant(TR, slip=s, budget=1).signature for s in ("nominal", "high", "random")}
    assert a.signature not in constant
    assert not any("lambda" in k or "slip" in k for k in vars(a) if not k.startswith("_"))


def test_drift_is_an_evaluator_cell() -> None:
    import evaluate as ev

    results = ev.evaluate(
        ev.RunSpec(FO, ["consensus"], ["map6"], ["drift"], episodes=2, env_kwargs={"max_episode_steps": 20}),
        workers=1,
    )
    assert [r["slip"] for r in results.records] == ["drift", "drift"]
    assert all(r["status"] == "ok" for r in results.records)


def test_a_copy_keeps_the_drift_clock_and_the_zones() -> None:
    import copy
    import pickle

    env = gym.make(TR, map="map5", slip="drift")
    env.reset(seed=1)
    commands = np.random.default_rng(0).uniform(-0.6, 0.6, (120, 6))
    for command in commands[:40]:
        env.step(command)
    for clone in (copy.deepcopy(env), pickle.loads(pickle.dumps(env))):
        for command in commands[40:]:
            a, b = env.step(command)[4]["poses"], clone.step(command)[4]["poses"]
            np.testing.assert_array_equal(a, b)
            np.testing.assert_array_equal(env.unwrapped.lambdas, clone.unwrapped.lambdas)
        env.reset(seed=1)
        for command in commands[:40]:
            env.step(command)
