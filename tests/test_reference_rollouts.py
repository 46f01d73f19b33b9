"""Reference rollouts of the compiled kernels: every observation, reward, flag and info value of
seeded random-action episodes, and of the safety filter's calls, hashed and compared with the
digests computed on main before the kernels' arguments were grouped and the step's Python was
cut (8d7e200, issue 61). The settings reach each kernel: the reward and formation terms, the
observation writer, perception (pose noise, radio with latency, drops and range, actuation
delay, lidar with noise and dropouts), the mover tracker and the mover motions, slip zones and
drift, and both autoreset modes of the vector env. Floats are rounded to 1e-9, as in
tests/test_collision_fault.py: a CPU whose libraries round a transcendental in the last bit
otherwise still gives the same digest, while any change of substance shows."""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import koopman_envs  # noqa: F401 - registers the ids
from controllers.safety.barriers import BarrierFilter
from controllers.safety.options import SafetyOptions

TR, FO = "KoopNav-TargetReaching-v0", "KoopNav-Formation-v0"


def _put(digest: Any, value: Any) -> None:
    """Hash ``value``: dicts key by key, arrays with their dtype and shape (floats rounded to
    1e-9 and -0.0 made 0.0), Python scalars with their type."""
    if isinstance(value, dict):
        for key in sorted(value):
            digest.update(key.encode())
            _put(digest, value[key])
    elif isinstance(value, (list, tuple)):
        for item in value:
            _put(digest, item)
    else:
        array = np.asarray(value)
        digest.update(f"{type(value).__name__}{array.dtype}{array.shape}".encode())
        if array.dtype.kind == "f":
            array = np.round(array.astype(np.float64), 9) + 0.0
        digest.update(np.ascontiguousarray(array).tobytes())


def _gym(env_id: str, seed: int, steps: int, **kwargs: Any) -> str:
    env = gym.make(env_id, **kwargs)
    digest, rng = hashlib.sha256(), np.random.default_rng(seed)
    _put(digest, env.reset(seed=seed))
    for _ in range(steps):
        action = rng.uniform(-1, 1, env.action_space.shape).astype(np.float32) * env.action_space.high
        result = env.step(action)
        _put(digest, result)
        if result[2] or result[3]:
            _put(digest, env.reset())
    return digest.hexdigest()


def _vector(env_id: str, seed: int, steps: int, mode: str, **kwargs: Any) -> str:
    env = gym.make_vec(
        env_id, num_envs=3, vectorization_mode="vector_entry_point", autoreset_mode=mode, **kwargs
    )
    digest, rng = hashlib.sha256(), np.random.default_rng(seed)
    _put(digest, env.reset(seed=seed))
    for _ in range(steps):
        _put(digest, env.step(rng.uniform(-1, 1, env.action_space.shape) * env.action_space.high))
    return digest.hexdigest()


def _filter(steps: int) -> str:
    """The safety filter around random poses and commands: with and without movers, widened
    margins and a larger perceived mover (infeasible QPs among them)."""
    env = gym.make(TR, map="map1")
    env.reset(seed=0)
    scenario = env.unwrapped.scenario
    barrier = BarrierFilter(scenario, SafetyOptions())
    digest, rng = hashlib.sha256(), np.random.default_rng(1)
    for t in range(steps):
        poses = scenario.starts + rng.normal(0, 1.5, scenario.starts.shape)
        command = rng.uniform(-1, 1, (3, 2)) * [0.6, 0.8]
        movers = rng.uniform(-8, 8, (4, 4)) if t % 2 else None
        widen = rng.uniform(0, 0.2, 3) if t % 3 == 0 else None
        step = barrier.filter(poses, command, movers, widen, 0.4 if t % 5 == 0 else None)
        _put(
            digest,
            [
                step.command,
                step.changed,
                step.infeasible,
                step.relaxation,
                step.barrier_min,
                step.constraints,
            ],
        )
    return digest.hexdigest()


#: name -> (rollout, its digest on main at 8d7e200)
ROLLOUTS: dict[str, tuple[Callable[[], str], str]] = {
    "gym, formation, slip zones and drift": (
        lambda: _gym(FO, 4, 150, map="map5", slip="drift"),
        "22093b9866504a72e86500313bf518eb0b95b0ca6301886dd1e5e71cc6c0c60f",
    ),
    "gym, harsh uncertainty": (
        lambda: _gym(TR, 6, 150, uncertainty="harsh"),
        "a31c208b98ffbc4a08571a0ffb9a573f7f93b9e31e1ccdc842092f69a7e6ed08",
    ),
    "gym, radio and actuation delay": (
        lambda: _gym(TR, 13, 150, actuation_delay=2, comm=dict(latency=2, drop=0.3, range=6.0)),
        "16c012316c620f1c72e2a7426f15bb09b3638cbe1688f6768dc0df9dcf0025ab",
    ),
    "gym, lidar among movers, harsh": (
        lambda: _gym(TR, 11, 150, sensing="lidar", movers=4, uncertainty="harsh"),
        "33b8b1440aeb2134274d5465bc6ed3f881e5614eb4f8c319f1aebd283a11dfe8",
    ),
    "gym, tracked movers": (
        lambda: _gym(TR, 8, 150, movers=dict(count=6, speed=0.5)),
        "5b2d77fb4ffeaf3cbdf6b07f9ba7a72f0acd41b557db836c6635744adc089036",
    ),
    "gym, waypoint walkers, random maps, realistic": (
        lambda: _gym(
            FO, 10, 150, map="random", movers=dict(count=6, behaviour="waypoints"), uncertainty="realistic"
        ),
        "912f006622312a601decbfd11b4de16f35627bffe93e39ad4122b4de7db51aee",
    ),
    "vector, random maps, next step": (
        lambda: _vector(TR, 20, 100, "NextStep", map="random", n_robots=9),
        "488255492389ef8fa379e59fbc598c864e4af2dd81df03094661a22df3fef0a4",
    ),
    "vector, movers, same step": (
        lambda: _vector(FO, 21, 100, "SameStep", movers=4, uncertainty="realistic"),
        "214ecefd15329e63e91790e122fbdb48c4b90d934f09919441312e74b147a762",
    ),
    "safety filter": (
        lambda: _filter(150),
        "7dacad8eeaa3436fc0162aced4f12751062e6dfce8f5048c8bbcb141cd1b5922",
    ),
}


@pytest.mark.parametrize("name", list(ROLLOUTS))
def test_the_rollout_is_as_on_main_before_the_kernels_changed(name: str) -> None:
    run, digest = ROLLOUTS[name]
    assert run() == digest


if __name__ == "__main__":  # print the digests (to record them on a reference commit)
    for name, (run, _) in ROLLOUTS.items():
        print(f'"{name}": "{run()}"')
