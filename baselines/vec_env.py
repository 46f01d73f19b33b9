"""The KoopNav native vector env seen through stable-baselines3's ``VecEnv`` interface.

SB3 expects same-step auto reset (the final observation in ``infos[i]["terminal_observation"]``)
and, as its documentation recommends, actions normalized to [-1, 1]; this adapter provides both
on top of :class:`koopman_envs.fronts.vector_env.KoopNavVectorEnv`, so training runs on the
batched simulator rather than on a list of single envs.
"""

from __future__ import annotations

from typing import Any, Sequence

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from stable_baselines3.common.vec_env.base_vec_env import VecEnv

import koopman_envs  # noqa: F401 - registers the ids

__all__ = ["KoopNavSB3VecEnv", "scale_action"]


def scale_action(normalized: np.ndarray, low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """Map actions from [-1, 1] to the physical box [low, high] (clipped first)."""
    normalized = np.clip(normalized, -1.0, 1.0)
    return low + 0.5 * (normalized + 1.0) * (high - low)


class KoopNavSB3VecEnv(VecEnv):
    """SB3 ``VecEnv`` over ``gym.make_vec(env_id, num_envs, autoreset_mode="SameStep")``.

    Parameters
    ----------
    env_id : str
        A KoopNav id.
    num_envs : int
        Batch size.
    seed : int, optional
        Seed of the first reset (sub-env i gets ``seed + i``).
    **env_kwargs
        Environment keywords (``map="random"``, ``slip="random"``, ...).
    """

    def __init__(self, env_id: str, num_envs: int, seed: int | None = None, **env_kwargs: Any) -> None:
        self.venv = gym.make_vec(env_id, num_envs=num_envs, autoreset_mode="SameStep", **env_kwargs)
        physical = self.venv.single_action_space
        self._low = physical.low.astype(np.float64)
        self._high = physical.high.astype(np.float64)
        action_space = spaces.Box(-1.0, 1.0, shape=physical.shape, dtype=np.float32)
        super().__init__(num_envs, self.venv.single_observation_space, action_space)
        self._seed = seed
        self._actions: np.ndarray | None = None

    def reset(self) -> np.ndarray:
        obs, _ = self.venv.reset(seed=self._seed)
        self._seed = None  # later resets continue the generators
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = scale_action(np.asarray(actions, dtype=np.float64), self._low, self._high)

    def step_wait(self):
        obs, rewards, terminated, truncated, info = self.venv.step(self._actions)
        dones = terminated | truncated
        infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        if "final_obs" in info:
            final_obs = info["final_obs"]
            final_info = info["final_info"]
            for i in np.flatnonzero(info["_final_obs"]):
                infos[i]["terminal_observation"] = final_obs[i]
                infos[i]["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
                infos[i]["is_success"] = bool(final_info["is_success"][i])
        return obs, rewards.astype(np.float32), dones, infos

    def seed(self, seed: int | None = None) -> Sequence[None]:
        self._seed = seed
        return [None] * self.num_envs

    def close(self) -> None:
        self.venv.close()

    def get_attr(self, attr_name: str, indices=None) -> list[Any]:
        return [getattr(self.venv.unwrapped, attr_name)] * len(self._get_indices(indices))

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        setattr(self.venv.unwrapped, attr_name, value)

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs) -> list[Any]:
        method = getattr(self.venv.unwrapped, method_name)
        return [method(*method_args, **method_kwargs) for _ in self._get_indices(indices)]

    def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
        return [False] * len(self._get_indices(indices))
