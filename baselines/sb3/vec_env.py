"""The KoopNav native vector env seen through stable-baselines3's ``VecEnv`` interface.

SB3 expects same-step auto reset (the final observation in ``infos[i]["terminal_observation"]``)
and, as its documentation recommends, actions normalized to [-1, 1]; this adapter provides both
on top of :class:`koopman_envs.fronts.vector_env.KoopNavVectorEnv`, so training runs on the
batched simulator rather than on a list of single envs.

Two layouts:

``"robot"`` (default; parameter sharing)
    Every robot of every environment is one SB3 sub-env: K environments of N robots appear as
    K * N sub-envs, each observing its own feature block (see
    :mod:`koopman_envs.tasks.observation`) and commanding its own (v, omega), rewarded with its
    own reward (``info["robot_rewards"]``). One small policy then drives every robot, as in
    decentralized multi-robot RL; it sees N times the samples of a centralized policy and its
    input does not grow with the team.
``"team"``
    One sub-env per environment: the flat team observation and joint action (centralized).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, cast

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvStepReturn

import koopman_envs  # noqa: F401 - registers the ids
from baselines.features.robot_features import FEATURE_SETS, feature_bounds, feature_count, robot_features
from baselines.features.set_features import (
    SET_FEATURE_BOUND,
    SetFeatureConfig,
    set_features,
    split_movers,
    without_message_ages,
)
from baselines.shaping import RewardShaping
from koopman_envs.checks import check_choice

if TYPE_CHECKING:  # pragma: no cover - typing only
    from koopman_envs import KoopNavVectorEnv

__all__ = [
    "FEATURE_SETS",
    "LAYOUTS",
    "KoopNavSB3VecEnv",
    "MixtureVecEnv",
    "feature_count",
    "robot_features",
    "scale_action",
    "split_envs",
]

LAYOUTS = ("robot", "team")


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
        Number of simulated environments K (SB3 sees K * N sub-envs in the ``"robot"`` layout).
    seed : int, optional
        Seed of the first reset (environment i gets ``seed + i``).
    layout : str
        ``"robot"`` (one shared policy per robot) or ``"team"`` (centralized).
    collision_penalty : float
        ``"robot"`` layout only: extra penalty for a robot that collides, beyond the env's team
        term (training-side shaping, recorded in the policy's metadata).
    precision_shaping : float
        ``"robot"`` layout only: weight w of a potential-based term ``w * (log(d_prev + eps) -
        log(d + eps))`` (d = the robot's distance to its target, eps = 5 cm) added to its
        reward. The env's progress term pays per metre, so the last decimetres that the 0.1 m
        goal tolerance asks for are worth little; this term pays per halving of the distance.
        Being potential-based (Ng et al., 1999), it speeds up learning without rewarding any
        behaviour but getting closer (exactly policy-invariant as the discount tends to 1).
    mover_shaping : float
        ``"robot"`` layout, env with movers: weight w of a proximity cost ``-w * max(0, 1 - c /
        b)`` charged to each robot every step, c its surface clearance to the nearest mover (true
        states: a training signal, not an observation), b = :data:`baselines.shaping.MOVER_SHAPING_BAND`. Unlike
        the precision term it is not potential-based: it asks for distance to movers, which a
        mover collision's one-off penalty teaches only after the fact.
    features : str
        ``"robot"`` layout: the feature set of :func:`robot_features`.
    set_config : SetFeatureConfig, optional
        ``"robot"`` layout: observe sets of team-mates and obstacles
        (:func:`baselines.features.set_features.set_features`) instead of ``features``; the observation
        then has the same size for every team size.
    **env_kwargs
        Environment keywords (``map="random"``, ``slip="random"``, ...).
    """

    def __init__(
        self,
        env_id: str,
        num_envs: int,
        seed: int | None = None,
        layout: str = "robot",
        collision_penalty: float = 0.0,
        precision_shaping: float = 0.0,
        mover_shaping: float = 0.0,
        features: str = "bearing",
        set_config: SetFeatureConfig | None = None,
        **env_kwargs: Any,
    ) -> None:
        check_choice("layout", layout, LAYOUTS)
        if set_config is not None and layout != "robot":
            raise ValueError(f"set observations need layout='robot', not {layout!r}")
        self.set_config = set_config
        self.layout = layout
        self.venv = gym.make_vec(env_id, num_envs=num_envs, autoreset_mode="SameStep", **env_kwargs)
        # a KoopNav id's vector entry point is a KoopNavVectorEnv (make_vec types it as any VectorEnv)
        unwrapped = cast("KoopNavVectorEnv", self.venv.unwrapped)
        config = unwrapped.config  # the env's keywords resolved (koopman_envs.EngineConfig)
        self.n_envs, self.n_robots = num_envs, config.n_robots
        self._formation = config.task.formation
        # one robot's block by name (koopman_envs.layout), the front's public seam
        observed = unwrapped.observation_layout
        # the policies read the robots' beliefs but not the message ages (a comm setting appends them)
        self._message_ages = observed.comm
        self._observed = observed  # where split_movers finds the listed movers: a set policy may read them
        if observed.movers and set_config is None:
            raise ValueError(
                "an env with movers trains only set policies (--policy set: movers are their third set)"
            )
        if observed.beams:
            raise ValueError(
                "the SB3 adapter's policies read the listed obstacles; sensing='lidar' is not supported"
            )
        movers = config.movers
        # the training terms (baselines.shaping) apply to the shared per-robot policy only
        self.shaping = RewardShaping(
            collision_penalty,
            precision_shaping,
            mover_shaping if layout == "robot" else 0.0,
            config.task.reward.collision,
            None if movers is None or movers.count == 0 else config.robot_radius + movers.radius,
        )
        self.features = check_choice("features", features, FEATURE_SETS)
        observation: spaces.Space[Any]
        if set_config is not None:
            physical, _ = unwrapped.robot_spaces()
            bound = SET_FEATURE_BOUND
            observation = spaces.Box(-bound, bound, shape=(set_config.size,), dtype=np.float32)
            width = num_envs * self.n_robots
        elif layout == "robot":
            physical, block = unwrapped.robot_spaces()
            low, high = feature_bounds(block.low, block.high, self.n_robots, features)
            observation = spaces.Box(low, high, dtype=np.float32)
            width = num_envs * self.n_robots
        else:
            # the team spaces of a KoopNav vector env are Boxes (NavigationEngine.team_spaces)
            physical = cast(spaces.Box, self.venv.single_action_space)
            observation = self.venv.single_observation_space
            width = num_envs
        self._low = physical.low.astype(np.float64)
        self._high = physical.high.astype(np.float64)
        action_space = spaces.Box(-1.0, 1.0, shape=physical.shape, dtype=np.float32)
        super().__init__(width, observation, action_space)
        self._seed = seed
        self._actions: np.ndarray | None = None

    def __setstate__(self, state: dict[str, Any]) -> None:
        """Unpickle (a resume checkpoint holds the adapter, :mod:`baselines.resume`), upgrading the
        state of a checkpoint written before the adapter kept the env's observation layout: it
        kept the listed movers' count and the obstacle slots (``_mover_slots``,
        ``_n_obstacle_obs``), which the layout of its own env must repeat, or the checkpoint is
        refused by name."""
        state = dict(state)
        if "_observed" not in state and "_mover_slots" in state:
            observed = cast("KoopNavVectorEnv", state["venv"].unwrapped).observation_layout
            kept = (state.pop("_mover_slots"), state.pop("_n_obstacle_obs"))
            if kept != (observed.movers, observed.n_obstacle_obs):
                raise ValueError(
                    f"a resume checkpoint's vector env lists {kept[0]} movers and {kept[1]} obstacles "
                    f"per robot where its env's layout has {observed.movers} and "
                    f"{observed.n_obstacle_obs}: it is not this env's; start the seed afresh"
                )
            state["_observed"] = observed
        self.__dict__.update(state)

    def _split(self, team_obs: np.ndarray) -> np.ndarray:
        """Team observations (K, N*F) in the adapter's layout."""
        blocks, movers = split_movers(team_obs.reshape(self.n_envs, self.n_robots, -1), self._observed)
        team_obs = blocks.reshape(self.n_envs, -1)
        if self._message_ages:
            team_obs = without_message_ages(team_obs, self.n_robots)
        if self.set_config is not None:
            blocks = team_obs.reshape(self.n_envs, self.n_robots, -1)
            observed = set_features(
                blocks, self._observed.n_obstacle_obs, self._formation, self.set_config, movers
            )
            return observed.reshape(self.n_envs * self.n_robots, -1)
        if self.layout == "robot":
            blocks = team_obs.reshape(self.n_envs, self.n_robots, -1)
            return robot_features(blocks, self.features).reshape(self.n_envs * self.n_robots, -1)
        return team_obs

    def reset(self) -> np.ndarray:
        obs, info = self.venv.reset(seed=self._seed)
        self._seed = None  # later resets continue the generators
        self.shaping.reset(info)
        return self._split(obs)

    def step_async(self, actions: np.ndarray) -> None:
        command = scale_action(np.asarray(actions, dtype=np.float64), self._low, self._high)
        self._actions = command.reshape(self.n_envs, -1)

    def step_wait(self) -> VecEnvStepReturn:
        obs, rewards, terminated, truncated, info = self.venv.step(self._actions)
        dones = terminated | truncated
        crashed = involved = None
        if self.layout == "robot":
            rewards, crashed, involved = self.shaping(info["robot_rewards"], info)
            per_env = self.n_robots
        else:
            per_env = 1
        # per sub-env: did its episode end by its own doing (terminal) or not (bootstrapped)
        own_end = np.repeat(terminated, per_env).reshape(self.n_envs, per_env)
        if crashed is not None and involved is not None:
            # credit assignment: only the robots that touched something are terminal (and pay the
            # collision penalty); a crash of a team-mate merely cuts the others' episodes short
            own_end[crashed] = involved[crashed]
        infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        if "final_obs" in info:
            final_obs = self._split(info["final_obs"]).reshape(self.n_envs, per_env, -1)
            final_info = info["final_info"]
            ended = info["_final_obs"]
            for i in np.flatnonzero(ended):
                for r in range(per_env):
                    entry = infos[i * per_env + r]
                    entry["terminal_observation"] = final_obs[i, r]
                    entry["TimeLimit.truncated"] = bool(not own_end[i, r])
                    entry["is_success"] = bool(final_info["is_success"][i])
        rewards = np.asarray(rewards).reshape(-1)
        dones = np.repeat(dones, per_env)
        return self._split(obs), rewards.astype(np.float32), dones, infos

    def seed(self, seed: int | None = None) -> Sequence[None]:
        self._seed = seed
        return [None] * self.num_envs

    def close(self) -> None:
        self.venv.close()

    def get_attr(self, attr_name: str, indices=None) -> list[Any]:
        return [getattr(self.venv.unwrapped, attr_name)] * len(list(self._get_indices(indices)))

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        setattr(self.venv.unwrapped, attr_name, value)

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs) -> list[Any]:
        method = getattr(self.venv.unwrapped, method_name)
        return [method(*method_args, **method_kwargs) for _ in self._get_indices(indices)]

    def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
        return [False] * len(list(self._get_indices(indices)))


class MixtureVecEnv(VecEnv):
    """Several :class:`KoopNavSB3VecEnv` side by side, seen by SB3 as one ``VecEnv``.

    Each part may have its own team size, map generator settings and slip, as long as all parts
    give observations of one shape (set observations do, for any team size) and take the same
    actions. Sub-envs are numbered part by part, in the order given.

    Parameters
    ----------
    parts : sequence of KoopNavSB3VecEnv
    """

    def __init__(self, parts: Sequence[KoopNavSB3VecEnv]) -> None:
        if not parts:
            raise ValueError("a MixtureVecEnv needs at least one part")
        first = parts[0]
        for part in parts[1:]:
            if part.observation_space != first.observation_space or part.action_space != first.action_space:
                raise ValueError(
                    f"every part needs the spaces of the first ({first.observation_space}, {first.action_space}); "
                    f"got {part.observation_space}, {part.action_space}"
                )
        self.parts = list(parts)
        self._bounds = np.cumsum([0] + [p.num_envs for p in self.parts])
        super().__init__(int(self._bounds[-1]), first.observation_space, first.action_space)

    def reset(self) -> np.ndarray:
        return np.concatenate([p.reset() for p in self.parts])

    def step_async(self, actions: np.ndarray) -> None:
        for part, lo, hi in zip(self.parts, self._bounds[:-1], self._bounds[1:], strict=True):
            part.step_async(actions[lo:hi])

    def step_wait(self) -> VecEnvStepReturn:
        results = [p.step_wait() for p in self.parts]
        obs = np.concatenate([r[0] for r in results])
        rewards = np.concatenate([r[1] for r in results])
        dones = np.concatenate([r[2] for r in results])
        infos = [info for r in results for info in r[3]]
        return obs, rewards, dones, infos

    def seed(self, seed: int | None = None) -> Sequence[None]:
        for i, part in enumerate(self.parts):
            part.seed(None if seed is None else seed + 1000 * i)
        return [None] * self.num_envs

    def close(self) -> None:
        for part in self.parts:
            part.close()

    def get_attr(self, attr_name: str, indices=None) -> list[Any]:
        return [getattr(self.parts[0].venv.unwrapped, attr_name)] * len(list(self._get_indices(indices)))

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        for part in self.parts:
            part.set_attr(attr_name, value)

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs) -> list[Any]:
        return [
            getattr(self.parts[0].venv.unwrapped, method_name)(*method_args, **method_kwargs)
            for _ in self._get_indices(indices)
        ]

    def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
        return [False] * len(list(self._get_indices(indices)))


def split_envs(
    env_id: str, num_envs: int, seed: int, parts: Sequence[dict[str, Any]], **common: Any
) -> KoopNavSB3VecEnv | MixtureVecEnv:
    """``num_envs`` environments split evenly between ``parts`` (the first get one more when they
    do not divide): part i a :class:`KoopNavSB3VecEnv` with ``parts[i]`` and ``common`` as keywords,
    seeded from ``seed + 1000 i`` (as :meth:`MixtureVecEnv.seed` does: no two parts share a draw).
    One part is that env itself; more are a :class:`MixtureVecEnv`."""
    if not 1 <= len(parts) <= num_envs:
        raise ValueError(
            f"num_envs={num_envs} cannot be split between {len(parts)} parts; allowed: 1 to {num_envs} parts"
        )
    sizes = [num_envs // len(parts) + (i < num_envs % len(parts)) for i in range(len(parts))]
    envs = [
        KoopNavSB3VecEnv(env_id, size, seed=seed + 1000 * i, **common, **kwargs)
        for i, (size, kwargs) in enumerate(zip(sizes, parts, strict=True))
    ]
    return envs[0] if len(envs) == 1 else MixtureVecEnv(envs)
