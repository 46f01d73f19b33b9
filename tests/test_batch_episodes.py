"""koopman_envs.fronts.batch_episodes: one episode per sub-environment of the vector env equals
the per-episode runner's episode on a lone env, result for result and bit for bit, with real
controllers under the settings the protocols use (perturbed starts, `realistic` uncertainty,
movers through the tracker, random layouts, both tasks)."""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np
import pytest

import controllers
from koopman_envs.fronts.batch_episodes import info_row, run_episodes_in_batch
from koopman_envs.fronts.episode import run_episode

SETTINGS = [
    ("KoopNav-TargetReaching-v0", {"map": "map1", "start_noise": 0.05, "max_episode_steps": 120}),
    (
        "KoopNav-TargetReaching-v0",
        {"map": "random", "uncertainty": "realistic", "movers": {"count": 3}, "max_episode_steps": 90},
    ),
    ("KoopNav-Formation-v0", {"map": "map3", "slip": "high", "max_episode_steps": 150}),
]


def _same(first: object, second: object) -> bool:
    if isinstance(first, np.ndarray) or isinstance(second, np.ndarray):
        return np.array_equal(np.asarray(first), np.asarray(second))
    return first == second


@pytest.mark.parametrize("name", ["consensus", "orca", "dwa"])
@pytest.mark.parametrize(
    ("env_id", "kwargs"), SETTINGS, ids=["map1-noise", "random-realistic-movers", "formation"]
)
def test_a_batch_of_episodes_is_the_per_episode_runs(env_id: str, kwargs: dict, name: str) -> None:
    _check_batch(env_id, kwargs, name)


def test_episodes_that_end_at_different_steps_are_each_kept_whole() -> None:
    """ORCA on Map 2 with perturbed starts: the episodes arrive at different periods (161-165),
    and every one ends where its lone run ends while the others go on."""
    pytest.importorskip("pyrvo")
    batched = _check_batch("KoopNav-TargetReaching-v0", {"map": "map2", "start_noise": 0.05}, "orca")
    assert len({r.steps for r in batched}) > 1


def _check_batch(env_id: str, kwargs: dict, name: str) -> list:
    if name == "orca":
        pytest.importorskip("pyrvo")
    seeds = [3, 11, 12, 40, 41]
    venv = gym.make_vec(env_id, num_envs=len(seeds), **kwargs)
    batched = run_episodes_in_batch(venv, [controllers.make(name) for _ in seeds], seeds)
    lone = controllers.make(name)
    for seed, result in zip(seeds, batched, strict=True):
        expected = run_episode(gym.make(env_id, **kwargs), lone, seed=seed)
        for field in dataclasses.fields(expected):
            assert _same(getattr(result, field.name), getattr(expected, field.name)), (seed, field.name)
    assert len({r.final_poses.tobytes() for r in batched}) == len(seeds)  # distinct episodes
    return batched


def test_an_info_row_is_the_lone_envs_info() -> None:
    kwargs = {"map": "map2", "uncertainty": "realistic", "movers": {"count": 2}}
    env = gym.make("KoopNav-TargetReaching-v0", **kwargs)
    _, info = env.reset(seed=5)
    venv = gym.make_vec("KoopNav-TargetReaching-v0", num_envs=2, **kwargs)
    _, infos = venv.reset(seed=[9, 5])
    row = info_row(infos, 1)
    assert sorted(row) == sorted(info)
    for key, value in info.items():
        assert type(row[key]) is type(value) or isinstance(value, np.ndarray), key
        assert np.array_equal(np.asarray(row[key]), np.asarray(value)), key


def test_bad_batches_are_refused_by_name() -> None:
    venv = gym.make_vec("KoopNav-TargetReaching-v0", num_envs=2)
    with pytest.raises(ValueError, match=r"1 policies and 2 seeds for 2 environments"):
        run_episodes_in_batch(venv, [controllers.make("consensus")], [0, 1])
    same_step = gym.make_vec("KoopNav-TargetReaching-v0", num_envs=2, autoreset_mode="SameStep")
    with pytest.raises(ValueError, match=r"needs 'NextStep'"):
        run_episodes_in_batch(same_step, [controllers.make("consensus")] * 2, [0, 1])
