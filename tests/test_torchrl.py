"""KoopNav runs unchanged under TorchRL (the library under BenchMARL): its Gymnasium clients
(GymEnv by id, GymWrapper on an env and on the native vector env) and its PettingZoo client pass
TorchRL's own ``check_env_specs`` and roll out. Needs the ``[torchrl]`` extra (CI installs it)."""

from __future__ import annotations

import importlib.util

import gymnasium as gym
import pytest

# the [torchrl] extra: skipped without it, found without importing it (importing it costs several
# CPU-s, which every pytest-xdist worker would pay at collection)
if importlib.util.find_spec("torchrl") is None:
    pytest.skip("needs torchrl", allow_module_level=True)

import koopman_envs  # noqa: F401  (registers the envs)


def test_gym_env_by_id() -> None:
    """GymEnv passes frameskip=1 and drops it only on Python's own unknown-keyword phrase."""
    from torchrl.envs import GymEnv
    from torchrl.envs.utils import check_env_specs

    env = GymEnv("KoopNav-Formation-v0")
    check_env_specs(env)
    rollout = env.rollout(5)
    assert rollout["next", "reward"].shape == (5, 1)


def test_gym_wrapper_on_an_env() -> None:
    from torchrl.envs import GymWrapper
    from torchrl.envs.utils import check_env_specs

    env = GymWrapper(gym.make("KoopNav-TargetReaching-v0", map="map1", slip="high"))
    check_env_specs(env)
    assert env.rollout(3)["next", "observation"].shape[0] == 3


def test_gym_wrapper_on_the_native_vector_env() -> None:
    """TorchRL needs same-step autoreset (or none); the vector env offers it by keyword."""
    from torchrl.envs import GymWrapper
    from torchrl.envs.utils import check_env_specs

    venv = GymWrapper(gym.make_vec("KoopNav-Formation-v0", num_envs=4, autoreset_mode="SameStep"))
    check_env_specs(venv)
    assert venv.rollout(3).shape == (4, 3)


def test_pettingzoo_wrapper_with_five_robots() -> None:
    from torchrl.envs import PettingZooWrapper
    from torchrl.envs.utils import check_env_specs

    from koopman_envs import formation_v0

    env = PettingZooWrapper(formation_v0.parallel_env(n_robots=5, map="random", slip="high"), use_mask=True)
    check_env_specs(env)
    assert env.rollout(3).shape == (3,)
