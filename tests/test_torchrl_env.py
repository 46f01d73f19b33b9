"""The batched multi-agent TorchRL env (baselines.marl.torchrl_env): TorchRL's spec check, and step for
step the vector env it wraps, ends of episodes included."""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest

# the [torchrl] extra: skipped without it, found without importing it (importing it costs several
# CPU-s, which every pytest-xdist worker would pay at collection)
if importlib.util.find_spec("torchrl") is None:
    pytest.skip("needs torchrl", allow_module_level=True)


import gymnasium as gym  # noqa: E402

ENV = "KoopNav-Formation-v0"
KWARGS = {"map": "random", "n_robots": 4, "max_episode_steps": 25}


def test_the_batched_env_passes_torchrls_spec_check() -> None:
    from torchrl.envs.utils import check_env_specs

    from baselines.marl.torchrl_env import GROUP, KoopNavMultiAgentEnv

    env = KoopNavMultiAgentEnv(ENV, 3, **KWARGS)
    check_env_specs(env)
    assert env.group_map == {GROUP: [f"{GROUP}_{i}" for i in range(4)]}
    assert env.full_action_spec_unbatched[GROUP, "action"].shape == (4, 2)


def test_a_rollout_is_the_vector_envs_step_for_step() -> None:
    """Every observation, reward and flag of a 60-step rollout of 5 environments (each episode
    truncated at 25 steps, so every environment ends and restarts twice) equals the vector env's
    driven with the same actions: the final observation under "next" at an episode's end, the
    new episode's first one after TorchRL's partial reset."""
    from baselines.marl.torchrl_env import GROUP, KoopNavMultiAgentEnv

    k, steps = 5, 60
    env = KoopNavMultiAgentEnv(ENV, k, **KWARGS)
    env.set_seed(7)
    td = env.rollout(steps, break_when_any_done=False)
    venv = gym.make_vec(ENV, num_envs=k, autoreset_mode="SameStep", **KWARGS)
    obs, _ = venv.reset(seed=7)
    np.testing.assert_array_equal(obs.reshape(k, 4, -1), td[GROUP, "observation"][:, 0].numpy())
    actions = td[GROUP, "action"].numpy().astype(np.float64)
    ends = 0
    for s in range(steps):
        obs, _, terminated, truncated, info = venv.step(actions[:, s].reshape(k, -1))
        ended = terminated | truncated
        ends += int(ended.sum())
        final = obs.copy()
        if ended.any():
            final[ended] = info["final_obs"][ended]
        np.testing.assert_array_equal(final.reshape(k, 4, -1), td["next", GROUP, "observation"][:, s].numpy())
        np.testing.assert_array_equal(
            info["robot_rewards"].astype(np.float32), td["next", GROUP, "reward"][:, s, :, 0].numpy()
        )
        np.testing.assert_array_equal(ended, td["next", "done"][:, s, 0].numpy())
        np.testing.assert_array_equal(terminated, td["next", "terminated"][:, s, 0].numpy())
        if s + 1 < steps:
            np.testing.assert_array_equal(obs.reshape(k, 4, -1), td[GROUP, "observation"][:, s + 1].numpy())
    assert ends >= 2 * k  # every environment ended (and restarted) at least twice


def test_a_reset_of_an_environment_whose_episode_runs_is_refused_by_name() -> None:
    import torch
    from tensordict import TensorDict

    from baselines.marl.torchrl_env import KoopNavMultiAgentEnv

    env = KoopNavMultiAgentEnv(ENV, 3, **KWARGS)
    td = env.reset()
    env.rand_step(td)
    with pytest.raises(ValueError, match=r"a reset of environments \[1\] whose episode has not ended"):
        env.reset(TensorDict({"_reset": torch.tensor([[False], [True], [False]])}, batch_size=[3]))


def test_the_training_terms_are_the_sb3_adapters() -> None:
    """With the PPO policies' collision penalty and precision potential, the batched env's rewards
    equal the SB3 adapter's for the same actions (one shaping, baselines.shaping), crashes and
    episode ends included: the robots drive ahead at full speed, turning a little."""
    from baselines.marl.torchrl_env import GROUP, KoopNavMultiAgentEnv

    pytest.importorskip("stable_baselines3")
    import torch

    from baselines.sb3.vec_env import KoopNavSB3VecEnv

    k, steps, terms = 6, 80, {"collision_penalty": 10.0, "precision_shaping": 5.0}
    kwargs = {**KWARGS, "max_episode_steps": 60}
    env = KoopNavMultiAgentEnv(ENV, k, **terms, **kwargs)
    env.set_seed(3)
    sb3 = KoopNavSB3VecEnv(ENV, k, seed=3, **terms, **kwargs)
    sb3.reset()
    td = env.reset()
    rng = np.random.default_rng(0)
    crashes = bystanders = 0
    for _ in range(steps):
        unit = np.column_stack([np.ones(k * 4), rng.uniform(-0.3, 0.3, k * 4)]).astype(np.float32)
        physical = sb3._low + (unit + 1.0) * 0.5 * (sb3._high - sb3._low)  # SB3's scale_action
        td[GROUP, "action"] = torch.as_tensor(physical.reshape(k, 4, 2), dtype=torch.float32)
        td, td_next = env.step_and_maybe_reset(td)
        sb3.step_async(unit)
        _, rewards, dones, infos = sb3.step_wait()
        np.testing.assert_allclose(
            rewards.reshape(k, 4), td["next", GROUP, "reward"][..., 0].numpy(), atol=1e-4
        )
        # each robot's own end, as SB3 bootstraps it: terminal unless its episode was cut short
        own = td["next", GROUP, "terminated"][..., 0].numpy()
        sb3_own = [d and not info["TimeLimit.truncated"] for d, info in zip(dones, infos, strict=True)]
        np.testing.assert_array_equal(own, np.reshape(sb3_own, (k, 4)))
        team = td["next", "terminated"].numpy()[:, 0]
        assert (own <= team[:, None]).all()
        bystanders += int((team[:, None] & ~own).sum())
        crashes += int(team.sum())
        td = td_next
    assert crashes > 0 and bystanders > 0  # the collision credit was exercised


def test_standardized_observations_are_the_raw_blocks_scaled_and_checked() -> None:
    """``observation_stats`` hands out (block - mean) / std of the same rollout, the specs' bounds
    scaled alike (TorchRL's check), and a mean of the wrong width is refused by name."""
    from torchrl.envs.utils import check_env_specs

    from baselines.marl.torchrl_env import GROUP, KoopNavMultiAgentEnv, observation_statistics

    mean, std = observation_statistics(ENV, num_envs=4, steps=20, **KWARGS)
    assert mean.shape == std.shape == (KoopNavMultiAgentEnv(ENV, 1, **KWARGS)._obs_low.shape[1],)
    assert (std > 0).all() and np.array_equal(
        mean, observation_statistics(ENV, num_envs=4, steps=20, **KWARGS)[0]
    )
    raw, scaled = (
        KoopNavMultiAgentEnv(ENV, 3, **KWARGS),
        KoopNavMultiAgentEnv(ENV, 3, observation_stats=(mean, std), **KWARGS),
    )
    check_env_specs(scaled)
    import torch

    rollouts = []
    for env in (raw, scaled):
        env.set_seed(3)
        torch.manual_seed(0)  # the same random actions
        rollouts.append(env.rollout(10, break_when_any_done=False))
    first, second = rollouts
    for key in ((GROUP, "observation"), ("next", GROUP, "observation")):
        np.testing.assert_allclose(second[key].numpy(), (first[key].numpy() - mean) / std, rtol=0, atol=1e-6)
    with pytest.raises(ValueError, match=r"observation_stats: a mean and a positive std of \d+ entries"):
        KoopNavMultiAgentEnv(ENV, 2, observation_stats=(mean[:-1], std[:-1]), **KWARGS)


def test_features_are_appended_as_the_ppo_policies_read_them() -> None:
    """``features="bearing+headings"``: every robot's observation is its block with
    baselines.features.robot_features appended (the rl-ppo policies' input), within the specs' bounds
    (TorchRL's check), standardized by statistics of the same widened blocks; an unknown feature
    set is refused by name."""
    from torchrl.envs.utils import check_env_specs

    from baselines.features.robot_features import robot_features
    from baselines.marl.torchrl_env import GROUP, KoopNavMultiAgentEnv, observation_statistics

    plain = KoopNavMultiAgentEnv(ENV, 3, **KWARGS)
    featured = KoopNavMultiAgentEnv(ENV, 3, features="bearing+headings", **KWARGS)
    check_env_specs(featured)
    import torch

    rollouts = []
    for env in (plain, featured):
        env.set_seed(4)
        torch.manual_seed(1)
        rollouts.append(env.rollout(8, break_when_any_done=False))
    raw = rollouts[0][GROUP, "observation"].numpy()
    np.testing.assert_array_equal(
        rollouts[1][GROUP, "observation"].numpy(), robot_features(raw, "bearing+headings")
    )
    mean, std = observation_statistics(ENV, num_envs=4, steps=20, features="bearing+headings", **KWARGS)
    assert mean.shape == (featured._obs_low.shape[1],) and (std > 0).all()
    check_env_specs(
        KoopNavMultiAgentEnv(ENV, 2, features="bearing+headings", observation_stats=(mean, std), **KWARGS)
    )
    with pytest.raises(ValueError, match="features"):
        KoopNavMultiAgentEnv(ENV, 2, features="bearings", **KWARGS)
