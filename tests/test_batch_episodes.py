"""koopman_envs.episodes.batch: one episode per sub-environment of the vector env equals
the per-episode runner's episode on a lone env, result for result and bit for bit, with real
controllers under the settings the protocols use (perturbed starts, `realistic` uncertainty,
movers through the tracker, random layouts, both tasks)."""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np
import pytest

import controllers
from koopman_envs.episodes.batch import info_row, run_episodes_in_batch
from koopman_envs.episodes.single import run_episode

SETTINGS = [
    ("KoopNav-TargetReaching-v0", {"map": "map1", "start_noise": 0.05, "max_episode_steps": 120}),
    (
        "KoopNav-TargetReaching-v0",
        {"map": "random", "uncertainty": "realistic", "movers": {"count": 3}, "max_episode_steps": 90},
    ),
    ("KoopNav-Formation-v0", {"map": "map3", "slip": "high", "max_episode_steps": 150}),
]


#: controllers whose decisions take milliseconds in Python run shorter episodes: DWA (5-10 ms per
#: period) acts team by team like consensus and ORCA, through the same path of the batch runner;
#: its 18 episodes of up to 90-150 periods took 25 CPU-s (on Map 1 and Map 3 they ran to the limit)
PERIODS = {"dwa": 40}


def _same(first: object, second: object) -> bool:
    if isinstance(first, np.ndarray) or isinstance(second, np.ndarray):
        return np.array_equal(np.asarray(first), np.asarray(second))
    return first == second


@pytest.mark.parametrize(
    # slow: ORCA's and DWA's batches, 0.6-1.5 CPU-s each (issue 61); consensus and the policies
    # keep the batch's path in the default run
    "name",
    [
        "consensus",
        pytest.param("orca", marks=pytest.mark.slow),
        pytest.param("dwa", marks=pytest.mark.slow),
        "rl-ppo",
        "rl-ppo-set",
        "rl-ppo-set-movers",
    ],
)
@pytest.mark.parametrize(
    ("env_id", "kwargs"), SETTINGS, ids=["map1-noise", "random-realistic-movers", "formation"]
)
def test_a_batch_of_episodes_is_the_per_episode_runs(env_id: str, kwargs: dict, name: str) -> None:
    _check_batch(env_id, kwargs, name)


def test_episodes_that_end_at_different_steps_are_each_kept_whole() -> None:
    """ORCA on Map 2 with perturbed starts: the episodes arrive at different periods (161-165),
    and every one ends where its lone run ends while the others go on."""
    pytest.importorskip("pyrvo", reason="the crowd needs pyrvo: the [crowd] extra")
    batched = _check_batch(
        "KoopNav-TargetReaching-v0", {"map": "map2", "start_noise": 0.05}, "orca", seeds=[3, 11, 12, 40, 41]
    )
    assert len({r.steps for r in batched}) > 1


def _check_batch(env_id: str, kwargs: dict, name: str, seeds: list[int] | None = None) -> list:
    """Episodes of ``seeds`` (three by default: a batch of several, each checked against its lone
    run, for every controller and setting) in one vector env, against the lone runs."""
    if name == "orca":
        pytest.importorskip("pyrvo", reason="the crowd needs pyrvo: the [crowd] extra")
    if name.startswith("rl-"):  # these decide for every running team in one call (act_many)
        pytest.importorskip("stable_baselines3")
        assert controllers.make(name).acts_in_batch
    seeds = seeds or [3, 11, 40]
    if name in PERIODS:
        kwargs = {**kwargs, "max_episode_steps": PERIODS[name]}
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


def test_a_policy_that_acts_in_batch_decides_for_all_teams_in_one_call(monkeypatch) -> None:
    """The learned policies' act_many serves every running environment in one call per period
    (never their act), and its teams' decision times are recorded, one per period."""
    pytest.importorskip("stable_baselines3")
    from baselines.sb3.policy import RLPolicyController

    calls: list[int] = []
    act_many = RLPolicyController.act_many.__func__  # type: ignore[attr-defined]

    def counted(cls, teams, observations, infos):
        calls.append(len(teams))
        return act_many(cls, teams, observations, infos)

    def refused(self, observation, info):
        raise AssertionError("act() called in a batch")

    monkeypatch.setattr(RLPolicyController, "act_many", classmethod(counted))
    monkeypatch.setattr(RLPolicyController, "act", refused)
    seeds = [1, 2, 3]
    policies = [controllers.make("rl-ppo") for _ in seeds]
    venv = gym.make_vec("KoopNav-TargetReaching-v0", num_envs=3, map="map1", max_episode_steps=40)
    results = run_episodes_in_batch(venv, policies, seeds)
    assert calls[0] == 3 and len(calls) == max(r.steps for r in results)
    assert [len(p.stats().solve_times) for p in policies] == [r.steps for r in results]
