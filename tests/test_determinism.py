"""Same seed, same result, bit for bit: repeated runs, other processes, vector vs single env."""

from __future__ import annotations

import hashlib
import itertools
import multiprocessing as mp
from collections.abc import Sequence

import gymnasium as gym
import numpy as np
import pytest

import koopman_envs  # noqa: F401 - registers the ids


def rollout_digest(
    env_id: str, map_name: str, slip: str, seed: int, steps: int = 400, start_noise: float = 0.0
) -> str:
    """SHA-256 of every observation, reward and pose of a seeded random-action rollout."""
    env = gym.make(env_id, map=map_name, slip=slip, start_noise=start_noise)
    actions = np.random.default_rng(seed).uniform(-1, 1, (steps, 6)).astype(np.float32)
    digest = hashlib.sha256()
    obs, info = env.reset(seed=seed)
    for action in actions:
        digest.update(obs.tobytes())
        digest.update(info["poses"].tobytes())
        obs, reward, terminated, truncated, info = env.step(action * env.action_space.high)
        digest.update(np.float64(reward).tobytes())
        if terminated or truncated:
            obs, info = env.reset()
    return digest.hexdigest()


CASES = [
    ("KoopNav-TargetReaching-v0", "map1", "high", 7),
    ("KoopNav-Formation-v0", "random", "low", 11),
    ("KoopNav-Formation-v0", "map4", "high", 5, 400, 0.2),  # start_noise draws from the same generator
]


@pytest.mark.parametrize("case", CASES)
def test_same_seed_same_rollout(case) -> None:
    assert rollout_digest(*case) == rollout_digest(*case)


def test_different_seed_different_slip() -> None:
    a = rollout_digest("KoopNav-TargetReaching-v0", "map1", "high", 1)
    b = rollout_digest("KoopNav-TargetReaching-v0", "map1", "high", 2)
    assert a != b


def test_same_rollout_in_other_processes() -> None:
    here = [rollout_digest(*case) for case in CASES]
    with mp.get_context("spawn").Pool(1) as pool:  # one fresh interpreter: its start-up is most of the cost
        there = pool.starmap(rollout_digest, CASES)
    assert here == there


def covering(*choices: Sequence[object]) -> list:
    """One pytest parameter per combination of two-valued ``choices``. The default run keeps the
    combinations whose value indices add up to an even number: with three choices, every pair of
    values of any two of them (the four pairs) is among those; with two, every value of each.
    The rest run with ``-m slow`` (600 steps of 4 sub-envs and 4 single envs: seconds each)."""
    return [
        pytest.param(
            *combination,
            marks=[pytest.mark.slow] if sum(index) % 2 else [],
            id="-".join(
                str(v) for value in combination for v in (value if isinstance(value, tuple) else [value])
            ),
        )
        for index in itertools.product(*(range(len(values)) for values in choices))
        for combination in [tuple(values[i] for values, i in zip(choices, index, strict=True))]
    ]


MODES = ["NextStep", "SameStep"]


@pytest.mark.parametrize(("env_id", "mode", "start_noise"), covering(koopman_envs.ENV_IDS, MODES, [0.0, 0.3]))
def test_vector_env_matches_single_envs(env_id: str, mode: str, start_noise: float) -> None:
    """Sub-env i seeded s + i is the single env seeded s + i, across auto-resets (with perturbed starts too)."""
    vector_matches_single_envs(
        env_id, mode, dict(map="random", slip="high", max_episode_steps=60, start_noise=start_noise)
    )


ZONES_AND_SCHEDULES = {
    "random zones, drift": dict(map="random", random_map={"n_slip_zones": 2}, slip="drift", start_noise=0.1),
    "zone map, listed schedule": dict(slip=[(0.0, "low"), (2.0, [0.3, 0.0, 0.1]), (5.0, "high")]),
}


@pytest.mark.parametrize(
    ("env_id", "mode", "variant"), covering(koopman_envs.ENV_IDS, MODES, list(ZONES_AND_SCHEDULES))
)
def test_vector_env_matches_single_envs_with_zones_and_drift(env_id: str, mode: str, variant: str) -> None:
    """The same with slip zones (per sub-env on random maps; map5 / map6) and changing slip."""
    kwargs = dict(ZONES_AND_SCHEDULES[variant], max_episode_steps=60)
    kwargs.setdefault("map", "map5" if "Target" in env_id else "map6")
    vector_matches_single_envs(env_id, mode, kwargs)


@pytest.mark.parametrize(
    ("env_and_shape", "mode"),
    covering([("KoopNav-TargetReaching-v0", "line"), ("KoopNav-Formation-v0", "circle")], MODES),
)
def test_vector_env_matches_single_envs_with_a_formation_shape(
    env_and_shape: tuple[str, str], mode: str
) -> None:
    """The same for six robots laid out in a formation shape on random maps."""
    env_id, shape = env_and_shape
    kwargs = {
        "map": "random",
        "n_robots": 6,
        "formation": shape,
        "slip": "high",
        "max_episode_steps": 60,
        "start_noise": 0.1,
    }
    vector_matches_single_envs(env_id, mode, kwargs)


def vector_matches_single_envs(
    env_id: str, mode: str, kwargs: dict, steps: int = 300, min_episodes: int = 10
) -> None:
    """Step a vector env of 4 and 4 single envs with the same random actions for ``steps``
    steps; compare everything (and that at least ``min_episodes`` episodes ended). The callers'
    episodes last at most 60 steps (6 s: past the listed slip schedule's last change at 5 s), so
    that 300 steps cross at least 16 auto-resets (600 steps of 120-step episodes took twice the
    CPU for the same ones)."""
    num_envs, seed = 4, 100
    venv = gym.make_vec(env_id, num_envs=num_envs, autoreset_mode=mode, **kwargs)
    assert type(venv.unwrapped).__name__ == "KoopNavVectorEnv"  # the native batched env
    envs = [gym.make(env_id, **kwargs) for _ in range(num_envs)]
    vobs, vinfo = venv.reset(seed=seed)
    for i, env in enumerate(envs):
        obs, info = env.reset(seed=seed + i)
        np.testing.assert_array_equal(obs, vobs[i])
    pending = [False] * num_envs
    rng = np.random.default_rng(0)
    episodes = 0
    for _ in range(steps):
        actions = rng.uniform(-0.7, 0.7, (num_envs, *venv.single_action_space.shape)).astype(np.float32)
        vobs, vrew, vterm, vtrunc, vinfo = venv.step(actions)
        for i, env in enumerate(envs):
            if mode == "NextStep" and pending[i]:
                obs, info = env.reset()
                reward, done = 0.0, False
            else:
                obs, reward, term, trunc, info = env.step(actions[i])
                done = term or trunc
                assert (term, trunc) == (vterm[i], vtrunc[i])
                if done and mode == "SameStep":
                    np.testing.assert_array_equal(obs, vinfo["final_obs"][i])
                    obs, info = env.reset()
            pending[i] = done
            episodes += done
            np.testing.assert_array_equal(obs, vobs[i])
            np.testing.assert_array_equal(info["poses"], vinfo["poses"][i])
            np.testing.assert_array_equal(env.unwrapped.scenario.starts, venv.unwrapped.scenario(i).starts)
            for key, value in info.items():  # every key of the single env's info, same value
                np.testing.assert_array_equal(np.asarray(value), np.asarray(vinfo[key][i]), err_msg=key)
            np.testing.assert_array_equal(env.unwrapped.lambdas, venv.unwrapped.engine.slip_means()[i])
            assert reward == vrew[i]
    assert episodes >= min_episodes  # autoreset was exercised many times


def test_vector_env_seed_list_and_spaces() -> None:
    venv = gym.make_vec("KoopNav-TargetReaching-v0", num_envs=3)
    obs, info = venv.reset(seed=[1, 2, 3])
    assert obs.shape == (3, 81) and venv.observation_space.contains(obs)
    assert info["poses"].shape == (3, 3, 3) and info["_poses"].all()
    with pytest.raises(ValueError, match="one per environment"):
        venv.reset(seed=[1, 2])
    with pytest.raises(ValueError, match="autoreset_mode"):
        gym.make_vec("KoopNav-TargetReaching-v0", num_envs=2, autoreset_mode="Sometimes")


def test_zero_start_noise_is_the_default_rollout() -> None:
    """start_noise=0 draws nothing, so it replays the rollout of an env built without the option."""
    for case in CASES[:2]:
        assert rollout_digest(*case, start_noise=0.0) == rollout_digest(*case)
    assert rollout_digest(*CASES[2]) != rollout_digest(*CASES[2][:5])
