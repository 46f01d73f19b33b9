"""KoopNav's native vector env as one batched multi-agent TorchRL env (the ``[torchrl]`` extra).

TorchRL's ``PettingZooWrapper`` runs one KoopNav env per TorchRL env, and BenchMARL batches them
with a ``SerialEnv``: every period of every environment goes through Python (MAPPO on 3 robots
collects 795 frames/s that way at 600 environments, 7,760 through this env:
``bench/benchmarl_speed.py``). :class:`KoopNavMultiAgentEnv` hands TorchRL the compiled vector env
instead (``batch_size = [num_envs]``, as TorchRL's ``VmasEnv`` does for VMAS), so BenchMARL sees
an env that is already vectorized and steps all environments in one call.

Layout (one group, ``"robot"``, holding every robot, as the PettingZoo wrapper's):

- ``("robot", "observation")`` (K, N, F): each robot's own observation block
  (:mod:`koopman_envs.layout`), what the PettingZoo env hands robot i;
- ``("robot", "action")`` (K, N, 2): (v, omega) per robot within the actuation limits;
- ``("robot", "reward")`` (K, N, 1): each robot's reward (the env's ``robot_rewards``, plus the
  PPO policies' training terms when asked for: :mod:`baselines.shaping`);
- ``("robot", "info")``: :data:`INFO_KEYS` per robot (K, N, 1);
- ``("robot", "terminated")`` (K, N, 1): whether the step ended this robot's episode by its own
  doing: the team's ``terminated``, except that a collision ends it only for the robots that
  touched something (the SB3 adapter's credit rule, :mod:`baselines.sb3.vec_env`): for a team-mate of
  a crashed robot the episode was cut short, and its value is bootstrapped, not zeroed.
  BenchMARL's MAPPO and IPPO read it for GAE (``(group, "terminated")``); it is an entry of the
  group, not of the done spec, so TorchRL's resets stay per environment;
- ``"done"``, ``"terminated"``, ``"truncated"`` (K, 1): per environment (the team's episode).

An environment whose episode ends is reset in the same step (the vector env's ``SameStep``
mode): the step returns its final observation under ``"next"``, and TorchRL's partial reset of
it (``"_reset"``) hands out the first observation of its new episode, which the env already drew.
Seeding: ``set_seed(s)`` seeds environment i with s + i at the next full reset, as the vector env
does, so a batch is reproducible.

``observation_stats=(mean, std)`` (per entry of a robot's block; :func:`observation_statistics`
measures them) hands out ``(block - mean) / std`` instead of the raw block: a fixed input scale
for the policy network (positions in metres, headings as cosines and distances to 60 m share an
MLP's input), which an exported policy applies the same way (:mod:`baselines.marl.marl_policy`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, cast

import gymnasium as gym
import numpy as np
import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.data import Bounded, Categorical, Composite, Unbounded
from torchrl.envs import EnvBase

import koopman_envs  # noqa: F401 - registers the ids
from baselines.features.robot_features import FEATURE_SETS, feature_bounds, robot_features
from baselines.shaping import RewardShaping
from koopman_envs.checks import check_choice

if TYPE_CHECKING:
    from koopman_envs import KoopNavVectorEnv

__all__ = ["GROUP", "INFO_KEYS", "KoopNavMultiAgentEnv", "observation_statistics"]

#: the group holding every robot (the name the PettingZoo wrapper gives KoopNav's agents)
GROUP = "robot"
#: per-robot info entries (K, N, 1), as floats (BenchMARL logs them as ``collection_robot_info_*``):
#: the team's success and whether this robot collided, at the end of the step
INFO_KEYS = ("is_success", "collision")


def observation_statistics(
    env_id: str,
    num_envs: int = 64,
    steps: int = 200,
    seed: int = 0,
    features: str | None = None,
    **env_kwargs: Any,
) -> tuple[np.ndarray, np.ndarray]:
    """Mean and standard deviation (float32, per entry of a robot's observation block, with the
    entries of :func:`~baselines.features.robot_features.robot_features` ``features`` appended
    when given) of the blocks of ``num_envs`` environments of ``env_id`` over ``steps`` periods of
    uniform random actions (seeded: the same figures every call). An entry that never varies (an
    empty slot) gets 1 as its deviation, so that it passes unscaled."""
    venv = gym.make_vec(env_id, num_envs=num_envs, autoreset_mode="SameStep", **env_kwargs)
    n = int(cast("KoopNavVectorEnv", venv.unwrapped).config.n_robots)
    obs, _ = venv.reset(seed=seed)
    space = cast(gym.spaces.Box, venv.action_space)
    rng = np.random.default_rng(seed)
    blocks = [np.asarray(obs, dtype=np.float64).reshape(num_envs * n, -1)]
    for _ in range(steps):
        obs, *_ = venv.step(rng.uniform(space.low, space.high))
        blocks.append(np.asarray(obs, dtype=np.float64).reshape(num_envs * n, -1))
    venv.close()
    data = np.concatenate(blocks)
    if features is not None:
        data = (
            robot_features(data.reshape(-1, n, data.shape[-1]), features)
            .reshape(len(data), -1)
            .astype(np.float64)
        )
    std = data.std(axis=0)
    return data.mean(axis=0).astype(np.float32), np.where(std > 1e-6, std, 1.0).astype(np.float32)


class KoopNavMultiAgentEnv(EnvBase):
    """``num_envs`` KoopNav environments of ``env_id`` as one batched multi-agent TorchRL env.

    Parameters
    ----------
    env_id : str
        A KoopNav Gymnasium id (``"KoopNav-TargetReaching-v0"``, ``"KoopNav-Formation-v0"``).
    num_envs : int
        Environments in the batch (the vector env's; its limits apply).
    device : str or torch.device
        Where the tensors live (the simulation runs on the CPU).
    collision_penalty, precision_shaping, mover_shaping : float
        The training terms the PPO policies train with (:class:`baselines.shaping.RewardShaping`;
        default 0: the env's own reward).
    observation_stats : (mean, std), optional
        Hand out standardized blocks, ``(block - mean) / std`` (module docstring; of the
        blocks with ``features`` appended when given).
    features : str, optional
        Append to each robot's block the entries of
        :func:`baselines.features.robot_features.robot_features` (``"bearing"``: the target's
        unit bearing and log distance; ``"bearing+headings"``: also the team-mates' relative
        headings), as the ``rl-ppo`` policies read them.
    **env_kwargs
        Env keywords (``map="random"``, ``n_robots=5``, ``uncertainty="realistic"``, ...).
    """

    def __init__(
        self,
        env_id: str,
        num_envs: int,
        device: Any = "cpu",
        collision_penalty: float = 0.0,
        precision_shaping: float = 0.0,
        mover_shaping: float = 0.0,
        observation_stats: tuple[Any, Any] | None = None,
        features: str | None = None,
        **env_kwargs: Any,
    ) -> None:
        if features is not None:
            check_choice("features", features, FEATURE_SETS)
        self.features = features
        venv = gym.make_vec(env_id, num_envs=num_envs, autoreset_mode="SameStep", **env_kwargs)
        config = cast("KoopNavVectorEnv", venv.unwrapped).config
        movers = config.movers
        self.shaping = RewardShaping(
            collision_penalty,
            precision_shaping,
            mover_shaping,
            config.task.reward.collision,
            None if movers is None or movers.count == 0 else config.robot_radius + movers.radius,
        )
        super().__init__(batch_size=torch.Size([num_envs]), device=device)
        self._venv = venv
        # a KoopNav id's vector entry point is a KoopNavVectorEnv, whose spaces are Boxes
        self.n_robots = int(config.n_robots)
        n = self.n_robots
        obs_space = cast(gym.spaces.Box, venv.single_observation_space)
        act_space = cast(gym.spaces.Box, venv.single_action_space)
        self._obs_low = np.asarray(obs_space.low, dtype=np.float32).reshape(n, -1)
        self._obs_high = np.asarray(obs_space.high, dtype=np.float32).reshape(n, -1)
        if features is not None:
            self._obs_low, self._obs_high = feature_bounds(self._obs_low, self._obs_high, n, features)
        self._stats: tuple[np.ndarray, np.ndarray] | None = None
        if observation_stats is not None:
            mean, std = (np.asarray(v, dtype=np.float32).reshape(-1) for v in observation_stats)
            width = self._obs_low.shape[1]
            if mean.shape != (width,) or std.shape != (width,) or not (std > 0).all():
                raise ValueError(
                    f"observation_stats: a mean and a positive std of {width} entries (a robot's block) "
                    f"are needed, not shapes {mean.shape} and {std.shape}"
                )
            self._stats = (mean, std)
            self._obs_low, self._obs_high = (self._obs_low - mean) / std, (self._obs_high - mean) / std
        act_low = np.asarray(act_space.low, dtype=np.float32).reshape(n, 2)
        act_high = np.asarray(act_space.high, dtype=np.float32).reshape(n, 2)
        info = Composite({key: Unbounded(shape=(n, 1), dtype=torch.float32) for key in INFO_KEYS}, shape=(n,))
        self.full_observation_spec_unbatched = Composite(
            {
                GROUP: Composite(
                    {
                        "observation": Bounded(
                            torch.as_tensor(self._obs_low),
                            torch.as_tensor(self._obs_high),
                            dtype=torch.float32,
                        ),
                        "info": info,
                        "terminated": Categorical(n=2, shape=(n, 1), dtype=torch.bool),
                    },
                    shape=(n,),
                )
            }
        )
        self.full_action_spec_unbatched = Composite(
            {
                GROUP: Composite(
                    {
                        "action": Bounded(
                            torch.as_tensor(act_low), torch.as_tensor(act_high), dtype=torch.float32
                        )
                    },
                    shape=(n,),
                )
            }
        )
        self.full_reward_spec_unbatched = Composite(
            {GROUP: Composite({"reward": Unbounded(shape=(n, 1), dtype=torch.float32)}, shape=(n,))}
        )
        flag = Categorical(n=2, shape=(1,), dtype=torch.bool)
        self.full_done_spec_unbatched = Composite(
            {"done": flag, "terminated": flag.clone(), "truncated": flag.clone()}
        )
        #: BenchMARL's and TorchRL's MARL convention: group -> agent names
        self.group_map = {GROUP: [f"{GROUP}_{i}" for i in range(n)]}
        self._seed: int | None = None
        self._pending: np.ndarray | None = None  # the new episodes' first observations (K, N*F)
        self._ended = np.zeros(num_envs, dtype=bool)  # which episodes the last step ended

    # ------------------------------------------------------------------ TorchRL's hooks
    def _set_seed(self, seed: int | None) -> None:
        self._seed = None if seed is None else int(seed)

    def _blocks(self, flat: np.ndarray) -> torch.Tensor:
        blocks = np.asarray(flat, dtype=np.float32).reshape(self.batch_size[0], self.n_robots, -1)
        if self.features is not None:
            blocks = robot_features(blocks, self.features)
        if self._stats is not None:
            blocks = (blocks - self._stats[0]) / self._stats[1]
        return torch.as_tensor(blocks)

    def _flags(self, values: np.ndarray) -> torch.Tensor:
        return torch.as_tensor(np.asarray(values, dtype=bool).reshape(-1, 1))

    def _info(self, success: np.ndarray, collided: np.ndarray) -> TensorDict:
        k, n = self.batch_size[0], self.n_robots
        team = np.broadcast_to(np.asarray(success, dtype=np.float32).reshape(k, 1, 1), (k, n, 1))
        values = {"is_success": team, "collision": np.asarray(collided, dtype=np.float32).reshape(k, n, 1)}
        return TensorDict(
            {key: torch.as_tensor(np.ascontiguousarray(values[key])) for key in INFO_KEYS}, batch_size=(k, n)
        )

    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs: Any) -> TensorDictBase:
        mask = None if tensordict is None else tensordict.get("_reset", None)
        if mask is not None and self._pending is not None:
            # TorchRL resets the environments whose episode ended (all of them, if all ended in
            # the same step): the step that ended them already began their new episodes
            asked = mask.reshape(-1).cpu().numpy().astype(bool)
            if (asked & ~self._ended).any():
                raise ValueError(
                    f"a reset of environments {np.flatnonzero(asked & ~self._ended).tolist()} whose episode "
                    "has not ended: the vector env resets an environment when its episode ends (cut "
                    "episodes with the max_episode_steps keyword, not a collector's max_frames_per_traj)"
                )
            obs = self._pending
            self._ended = self._ended & ~asked
        else:
            obs, info = self._venv.reset(seed=self._seed)
            self.shaping.reset(info)
            self._ended = np.zeros(self.batch_size[0], dtype=bool)
            self._seed = None  # later resets continue each environment's generator
            self._pending = obs
        k = self.batch_size[0]
        return TensorDict(
            {
                GROUP: TensorDict(
                    {
                        "observation": self._blocks(obs),
                        "info": self._info(np.zeros(k), np.zeros((k, self.n_robots))),
                        "terminated": torch.zeros(k, self.n_robots, 1, dtype=torch.bool),
                    },
                    batch_size=(k, self.n_robots),
                ),
                "done": torch.zeros(k, 1, dtype=torch.bool),
                "terminated": torch.zeros(k, 1, dtype=torch.bool),
                "truncated": torch.zeros(k, 1, dtype=torch.bool),
            },
            batch_size=self.batch_size,
            device=self.device,
        )

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        action = tensordict.get((GROUP, "action")).detach().cpu().numpy().astype(np.float64)
        obs, _, terminated, truncated, info = self._venv.step(action.reshape(self.batch_size[0], -1))
        self._pending = obs
        ended = np.asarray(terminated) | np.asarray(truncated)
        self._ended = ended
        final = obs
        if ended.any():
            final = np.array(obs, copy=True)
            final[ended] = np.asarray(info["final_obs"])[ended]
        shaped, crashed, involved = self.shaping(info["robot_rewards"], info)
        rewards = np.asarray(shaped, dtype=np.float32)[..., None]  # (K, N, 1)
        # each robot's own end: a crash is terminal only for the robots involved
        own_end = np.repeat(np.asarray(terminated, dtype=bool)[:, None], self.n_robots, axis=1)
        if crashed is not None and involved is not None:
            own_end[crashed] = involved[crashed]
        success, collided = np.asarray(info["is_success"]), np.asarray(info["robot_collision"])
        if ended.any():  # the ended episodes' last state, not their new one's
            final_info, done_now = info["final_info"], np.asarray(info["_final_info"])
            success = np.where(done_now, final_info["is_success"], success)
            collided = np.where(done_now[:, None], final_info["robot_collision"], collided)
        k = self.batch_size[0]
        return TensorDict(
            {
                GROUP: TensorDict(
                    {
                        "observation": self._blocks(final),
                        "reward": torch.as_tensor(rewards),
                        "info": self._info(success, collided),
                        "terminated": torch.as_tensor(own_end[..., None]),
                    },
                    batch_size=(k, self.n_robots),
                ),
                "done": self._flags(ended),
                "terminated": self._flags(terminated),
                "truncated": self._flags(truncated),
            },
            batch_size=self.batch_size,
            device=self.device,
        )

    def close(self, *, raise_if_closed: bool = True) -> None:
        self._venv.close()
        super().close(raise_if_closed=raise_if_closed)
