"""Behaviour the fronts share: copies (copy.deepcopy, pickle) that keep their state and render,
and PettingZoo's ``max_cycles`` name of the episode limit."""

from __future__ import annotations

import copy
import pickle
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from pettingzoo.test import max_cycles_test

from koopman_envs import formation_v0, target_reaching_v0
from koopman_envs.params import PARAMS

ID = "KoopNav-Formation-v0"
N = 3

COPIES: dict[str, Callable[[Any], Any]] = {
    "deepcopy": copy.deepcopy,
    "pickle": lambda env: pickle.loads(pickle.dumps(env)),
}


class Front:
    """One front driven through one interface: ``step(action)`` with the flat team action
    (2N,) returns the team's observation (the vector env: the batch of two)."""

    def __init__(self, name: str, **kwargs: Any) -> None:
        self.name = name
        if name == "gym":
            self.env = gym.make(ID, **kwargs)
        elif name == "vector":
            self.env = gym.make_vec(ID, num_envs=2, **kwargs)
        elif name == "parallel":
            self.env = formation_v0.parallel_env(**kwargs)
        else:
            self.env = formation_v0.env(**kwargs)

    def reset(self, seed: int, options: dict | None = None) -> np.ndarray:
        out = self.env.reset(seed=seed, options=options)
        if self.name == "aec":
            return self.team_observation(self.env)
        observation = out[0]
        if self.name == "parallel":
            return np.concatenate([observation[a] for a in self.env.possible_agents])
        return observation

    @staticmethod
    def team_observation(env: Any) -> np.ndarray:
        return np.concatenate([env.observe(a) for a in env.possible_agents])

    def step(self, env: Any, action: np.ndarray) -> np.ndarray:
        """Step ``env`` (this front's env or a copy of it) with the team action."""
        if self.name == "gym":
            return env.step(action)[0]
        if self.name == "vector":
            return env.step(np.stack([action, action[::-1]]))[0]
        blocks = {f"robot_{i}": action[2 * i : 2 * i + 2] for i in range(N)}
        if self.name == "parallel":
            observations = env.step(blocks)[0]
            return np.concatenate([observations[a] for a in env.possible_agents])
        for _ in range(N):
            env.step(blocks[env.agent_selection])
        return self.team_observation(env)

    def poses(self, env: Any) -> np.ndarray:
        return env.unwrapped.engine.poses.copy()


FRONTS = ["gym", "vector", "parallel", "aec"]
RENDERING_FRONTS = ["gym", "parallel", "aec"]  # the vector env does not render


@pytest.mark.parametrize("how", COPIES)
@pytest.mark.parametrize("name", RENDERING_FRONTS)
def test_a_rendered_env_copies_and_the_copy_renders(name: str, how: str) -> None:
    front = Front(name, render_mode="rgb_array", slip="high")
    env = front.env
    front.reset(seed=0)
    for _ in range(3):
        front.step(env, np.full(2 * N, 0.3))
    first = env.render()
    clone = COPIES[how](env)
    frame = clone.render()
    assert isinstance(frame, np.ndarray) and frame.shape == first.shape and frame.dtype == np.uint8
    np.testing.assert_array_equal(frame, first)  # same trail, same clock, same picture
    np.testing.assert_array_equal(env.render(), first)  # the original still draws
    action = np.full(2 * N, 0.2)
    front.step(env, action)
    front.step(clone, action)
    np.testing.assert_array_equal(clone.render(), env.render())
    clone.close()
    env.close()


@pytest.mark.parametrize("how", COPIES)
@pytest.mark.parametrize("name", FRONTS)
def test_a_copy_keeps_the_state_and_replays_the_original(name: str, how: str) -> None:
    """Poses, step count and random generators are copied: with the same actions the copy and
    the original produce the same observations (slip draws included), and not a fresh episode."""
    front = Front(name, slip="high", map="random")
    env = front.env
    front.reset(seed=4)
    rng = np.random.default_rng(0)
    actions = rng.uniform(-0.6, 0.6, (40, 2 * N))
    for action in actions[:10]:
        front.step(env, action)
    clone = COPIES[how](env)
    np.testing.assert_array_equal(front.poses(clone), front.poses(env))
    np.testing.assert_array_equal(clone.unwrapped.engine.elapsed, env.unwrapped.engine.elapsed)
    assert clone.unwrapped.engine.elapsed[0] == 10
    for action in actions[10:]:
        np.testing.assert_array_equal(front.step(clone, action), front.step(env, action))
    np.testing.assert_array_equal(front.poses(clone), front.poses(env))


@pytest.mark.parametrize("module", [formation_v0, target_reaching_v0])
def test_pettingzoo_max_cycles_test(module) -> None:
    max_cycles_test(module)


def test_max_cycles_is_the_episode_limit() -> None:
    for kwargs in ({"max_cycles": 7}, {"max_episode_steps": 7}, {"max_cycles": 7, "max_episode_steps": 7}):
        for env in (formation_v0.parallel_env(**kwargs), formation_v0.raw_env(**kwargs).unwrapped):
            assert env.config.max_episode_steps == 7, kwargs
    assert formation_v0.parallel_env().config.max_episode_steps == PARAMS.max_episode_steps
    env = formation_v0.parallel_env(max_cycles=5)
    env.reset(seed=0)
    for _step in range(5):
        _, _, terminations, truncations, _ = env.step({a: np.zeros(2) for a in env.agents})
    assert all(truncations.values()) and not any(terminations.values()) and env.agents == []


@pytest.mark.parametrize("factory", ["parallel_env", "env", "raw_env"])
def test_max_cycles_and_max_episode_steps_must_agree(factory: str) -> None:
    make = getattr(formation_v0, factory)
    with pytest.raises(ValueError, match=r"max_cycles=5 and max_episode_steps=9 differ"):
        make(max_cycles=5, max_episode_steps=9)
    with pytest.raises(ValueError, match=r"max_cycles=0 must be an integer >= 1"):
        make(max_cycles=0)


# ------------------------------------------------------------------ reset options
# valid on map3 (formation's default map): the map's starts moved a little and turned
START_POSES = np.array([[-3.4, 0.6, 0.3], [-4.3, 1.5, -0.2], [-4.5, -0.4, 1.0]])
TARGETS = np.array([[2.5, 2.8, 0.5], [1.7, 3.6, 0.5], [1.7, 2.0, 0.5]])


@pytest.mark.parametrize("name", FRONTS)
def test_start_poses_and_targets_replace_the_maps_for_one_episode(name: str) -> None:
    front = Front(name, start_noise=0.2)  # the given poses are used exactly, without noise
    env = front.env
    front.reset(seed=0, options={"start_poses": START_POSES, "targets": TARGETS})
    engine = env.unwrapped.engine
    for k in range(engine.num_envs):
        np.testing.assert_array_equal(engine.poses[k], START_POSES)
        np.testing.assert_array_equal(engine.starts[k], START_POSES)
        np.testing.assert_array_equal(engine.targets[k], TARGETS)
        np.testing.assert_array_equal(engine.offsets[k], TARGETS[:, :2] - TARGETS[0, :2])
        np.testing.assert_allclose(engine.distances[k], np.hypot(*(TARGETS - START_POSES)[:, :2].T))
    if name != "vector":
        np.testing.assert_array_equal(env.unwrapped.scenario.targets, TARGETS)
    front.step(env, np.full(2 * N, 0.2))
    front.reset(seed=0)  # the next episode is the map's again
    spec = env.unwrapped.config.map_spec
    assert not np.array_equal(engine.poses[0], START_POSES)
    np.testing.assert_array_equal(engine.targets[0], spec.targets)


@pytest.mark.parametrize("name", FRONTS)
def test_the_maps_own_starts_as_options_replay_a_plain_reset(name: str) -> None:
    plain, given = Front(name, slip="high"), Front(name, slip="high")
    spec = plain.env.unwrapped.config.map_spec
    first = plain.reset(seed=3)
    np.testing.assert_array_equal(
        given.reset(seed=3, options={"start_poses": spec.starts, "targets": spec.targets.tolist()}), first
    )
    for action in np.random.default_rng(1).uniform(-0.6, 0.6, (20, 2 * N)):
        np.testing.assert_array_equal(given.step(given.env, action), plain.step(plain.env, action))


def test_vector_options_per_sub_env() -> None:
    venv = gym.make_vec(ID, num_envs=2)
    per_env = np.stack([START_POSES, START_POSES + [0.1, 0.0, 0.5]])
    venv.reset(seed=0, options={"start_poses": per_env})
    np.testing.assert_array_equal(venv.unwrapped.engine.poses, per_env)
    with pytest.raises(
        ValueError, match=r"options\['start_poses'\] has shape \(3, 3, 3\); allowed: \(3, 3\) or \(2, 3, 3\)"
    ):
        venv.reset(options={"start_poses": np.stack([START_POSES] * 3)})


BAD_OPTIONS = [
    (
        {"start_pose": START_POSES},
        r"reset options \['start_pose'\] are not supported; allowed keys: \['start_poses', 'targets', 'layout'\]",
    ),
    ({"start_poses": START_POSES[:2]}, r"options\['start_poses'\] has shape \(2, 3\); allowed: \(3, 3\)"),
    ({"targets": "north"}, r"options\['targets'\]='north' is not an array of numbers"),
    (
        {"start_poses": np.where(np.eye(3) > 0, np.nan, START_POSES)},
        r"options\['start_poses'\] has a non-finite entry at index \[0, 0\] \(nan\)",
    ),
    (
        {"start_poses": np.vstack([[9.9, 0.6, 0.0], START_POSES[1:]])},
        r"options\['start_poses'\]: start of robot 0 at \[9.9, 0.6\] is not inside the workspace",
    ),
    (
        {"start_poses": np.vstack([[-0.6, 2.0, 0.0], START_POSES[1:]])},
        r"options\['start_poses'\]: start of robot 0 at \[-0.6, 2.0\] overlaps obstacle 2 \[-0.6, 2.0, 0.4\] \(map 'map3'\)",
    ),
    (
        {"start_poses": START_POSES + [[0, 0, 0], [0.8, -0.8, 0], [0, 0, 0]]},
        r"options\['start_poses'\]: overlapping starts of robots 0 and 1",
    ),
    (
        {"targets": TARGETS + [[-2.5, -2.8, 0], [0, 0, 0], [0, 0, 0]]},
        r"options\['targets'\]: target of robot 0 at \[0.0, 0.0\] overlaps obstacle",
    ),
    (["start_poses"], r"options=\['start_poses'\] must be a dict or None"),
]


@pytest.mark.parametrize("options, message", BAD_OPTIONS)
@pytest.mark.parametrize("name", FRONTS)
def test_invalid_reset_options_are_rejected_and_change_nothing(name: str, options, message: str) -> None:
    front = Front(name)
    front.reset(seed=0)
    front.step(front.env, np.full(2 * N, 0.3))
    engine = front.env.unwrapped.engine
    before = engine.poses.copy(), engine.targets.copy(), engine.elapsed.copy()
    with pytest.raises(ValueError, match=message):
        front.env.reset(seed=1, options=options)
    np.testing.assert_array_equal(engine.poses, before[0])
    np.testing.assert_array_equal(engine.targets, before[1])
    np.testing.assert_array_equal(engine.elapsed, before[2])


def test_start_poses_are_checked_against_each_random_map() -> None:
    env = gym.make(ID, map="random")
    with pytest.raises(
        ValueError, match=r"options\['start_poses'\]: .* \(map 'random'\); allowed: \(x, y, heading\) rows"
    ):
        env.reset(seed=0, options={"start_poses": np.zeros((3, 3))})
    obs, info = env.reset(seed=0)
    starts = info["poses"] + [0.05, 0.0, 0.0]  # this seed's map, its starts nudged
    _, info = env.reset(seed=0, options={"start_poses": starts})
    np.testing.assert_array_equal(info["poses"], starts)


def test_only_pettingzoos_api_probe_is_ignored() -> None:
    """pettingzoo.test passes options={"options": 1} to check the keyword: the PettingZoo fronts
    accept that key (their API tests pass), the Gymnasium fronts reject it like any unknown key."""
    par = formation_v0.parallel_env()
    par.reset(seed=0, options={"options": 1})
    with pytest.raises(ValueError, match="not supported"):
        par.reset(seed=0, options={"options": 1, "seed": 2})
    with pytest.raises(ValueError, match=r"reset options \['options'\] are not supported"):
        gym.make(ID).reset(seed=0, options={"options": 1})


def _numeric(value) -> bool:
    return isinstance(value, (bool, int, float, np.ndarray, np.generic))


def test_every_info_value_is_a_number_or_an_array() -> None:
    """RL libraries (TorchRL, Gymnasium's vector envs) stack infos into tensors: no text."""
    from koopman_envs import formation_v0

    env = gym.make("KoopNav-Formation-v0", map="map3")
    _, info = env.reset(seed=0)
    _, _, _, _, step_info = env.step(env.action_space.sample())
    for values in (info, step_info):
        assert all(_numeric(v) for v in values.values()), {k: type(v) for k, v in values.items()}
    vec = gym.make_vec("KoopNav-Formation-v0", num_envs=2, vectorization_mode="vector_entry_point")
    _, infos = vec.reset(seed=0)
    assert all(_numeric(v) for k, v in infos.items() if not k.startswith("_")), {
        k: type(v) for k, v in infos.items()
    }
    par = formation_v0.parallel_env()
    _, agent_infos = par.reset(seed=0)
    for values in agent_infos.values():
        assert all(_numeric(v) for v in values.values()), {k: type(v) for k, v in values.items()}


def test_the_vector_env_exposes_its_autoreset_mode() -> None:
    from gymnasium.vector import AutoresetMode

    for mode in (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP):
        vec = gym.make_vec(
            "KoopNav-TargetReaching-v0",
            num_envs=2,
            vectorization_mode="vector_entry_point",
            autoreset_mode=mode,
        )
        assert vec.unwrapped.autoreset_mode == mode == vec.unwrapped.metadata["autoreset_mode"]


def _drive_one_into_the_wall(vec, steps: int = 120) -> list[tuple[dict, np.ndarray]]:
    """Sub-env 0 drives its team straight ahead (it collides or leaves the map first); sub-env 1
    stands still. Returns (info, done) of every step."""
    out = []
    forward = np.tile([0.6, 0.0], 3)
    for _ in range(steps):
        _, _, terminated, truncated, info = vec.step(np.stack([forward, np.zeros(6)]))
        out.append((info, terminated | truncated))
        if (terminated | truncated).any():
            break
    return out


def test_same_step_final_info_masks_match_gymnasiums_sync_env() -> None:
    """The finished sub-env's final_info entries, with each key's mask true for it alone, as
    Gymnasium's SyncVectorEnv builds them (issue 31: every inner mask was true)."""
    native = gym.make_vec("KoopNav-TargetReaching-v0", num_envs=2, autoreset_mode="SameStep")
    sync = gym.vector.SyncVectorEnv(
        [lambda: gym.make("KoopNav-TargetReaching-v0")] * 2, autoreset_mode=gym.vector.AutoresetMode.SAME_STEP
    )
    native.reset(seed=4)
    sync.reset(seed=4)
    ours, theirs = _drive_one_into_the_wall(native), _drive_one_into_the_wall(sync)
    assert len(ours) == len(theirs) and ours[-1][1].tolist() == [True, False]
    mine, reference = ours[-1][0]["final_info"], theirs[-1][0]["final_info"]
    for key in reference:
        if key.startswith("_"):
            np.testing.assert_array_equal(mine[key], reference[key], err_msg=key)
    assert mine["_collision"].tolist() == [True, False]
    np.testing.assert_allclose(mine["poses"][0], reference["poses"][0])


def test_the_vector_env_renders_one_frame_per_sub_env_as_the_single_env_does() -> None:
    vec = gym.make_vec("KoopNav-Formation-v0", num_envs=2, render_mode="rgb_array", map="random")
    singles = [gym.make("KoopNav-Formation-v0", render_mode="rgb_array", map="random") for _ in range(2)]
    vec.reset(seed=7)
    for i, env in enumerate(singles):
        env.reset(seed=7 + i)
    action = np.tile([0.3, 0.1], 3)
    for _ in range(5):
        vec.step(np.stack([action, action]))
        for env in singles:
            env.step(action)
    frames = vec.render()
    assert isinstance(frames, tuple) and len(frames) == 2
    for frame, env in zip(frames, singles):
        expected = env.render()
        assert frame.shape == expected.shape and frame.dtype == np.uint8
        assert np.abs(frame.astype(float) - expected).mean() < 0.1
    assert np.abs(frames[0].astype(float) - frames[1]).mean() > 0.5  # two different episodes
    with pytest.raises(ValueError, match=r"render_mode='human' is not one of \[None, 'rgb_array'\]"):
        gym.make_vec("KoopNav-Formation-v0", num_envs=2, render_mode="human")
    vec.close()
