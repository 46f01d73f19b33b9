"""RL baseline: a short real training run, loading, deterministic play, clear errors."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

import controllers  # noqa: E402
from baselines.policy import SHIPPED, RLPolicyController, load_policy  # noqa: E402
from baselines.train import main as train_main  # noqa: E402


@pytest.fixture(scope="module")
def trained_root(tmp_path_factory):
    root = tmp_path_factory.mktemp("policies")
    code = train_main(["--env", "KoopNav-Formation-v0", "--timesteps", "4096", "--n-envs", "8",
                       "--eval-freq", "100000", "--out", str(root / "formation")])  # fmt: skip
    assert code == 0
    return root


def play(ctrl, seed: int = 0) -> tuple[dict, list]:
    env = gym.make("KoopNav-Formation-v0", map="map3", max_episode_steps=60)
    obs, info = env.reset(seed=seed)
    ctrl.reset(env.unwrapped.scenario, seed=seed)
    actions = []
    while True:
        action = ctrl.act(obs, info)
        actions.append(action)
        obs, _, terminated, truncated, info = env.step(action)
        if terminated or truncated:
            return info, actions


def test_short_training_saves_a_loadable_policy(trained_root) -> None:
    model, norm, metadata = load_policy(trained_root / "formation")
    assert metadata["timesteps"] == 4096 and metadata["algo"] == "ppo"
    assert {"stable_baselines3", "torch"} <= set(metadata["versions"])
    assert norm["mean"].shape == (87,)
    info, actions = play(RLPolicyController(policy_root=trained_root))
    assert len(actions) > 0 and all(a.shape == (6,) for a in actions)
    assert all(np.all(np.abs(a[0::2]) <= 0.6 + 1e-9) for a in actions)


def test_inference_is_deterministic(trained_root) -> None:
    _, first = play(RLPolicyController(policy_root=trained_root), seed=3)
    _, second = play(RLPolicyController(policy_root=trained_root), seed=3)
    np.testing.assert_array_equal(np.asarray(first), np.asarray(second))


def test_missing_and_corrupt_policy_files(tmp_path, trained_root) -> None:
    with pytest.raises(ValueError, match="no trained policy .*`python -m baselines.train"):
        RLPolicyController(policy_root=tmp_path / "empty")
    broken = tmp_path / "broken" / "formation"
    broken.mkdir(parents=True)
    for name in ("policy.zip", "obs_norm.npz", "metadata.json"):
        (broken / name).write_bytes((trained_root / "formation" / name).read_bytes())
    (broken / "policy.zip").write_bytes(b"PK\x03\x04 truncated")
    with pytest.raises(ValueError, match="corrupt or unreadable.*python -m baselines.train"):
        load_policy(broken)
    (broken / "obs_norm.npz").unlink()
    with pytest.raises(ValueError, match=r"\['obs_norm.npz'\] are missing"):
        load_policy(broken)


def test_registered_through_the_entry_point() -> None:
    assert "rl-ppo" in controllers.available()


@pytest.mark.skipif(not (SHIPPED / "formation").exists(), reason="no shipped policy yet")
@pytest.mark.parametrize("env_id", ["KoopNav-TargetReaching-v0", "KoopNav-Formation-v0"])
def test_shipped_policies_play_an_episode(env_id: str) -> None:
    ctrl = controllers.make("rl-ppo")
    env = gym.make(env_id, max_episode_steps=100)
    obs, info = env.reset(seed=0)
    ctrl.reset(env.unwrapped.scenario, seed=0)
    obs, *_ = env.step(ctrl.act(obs, info))
    assert env.observation_space.contains(obs)
