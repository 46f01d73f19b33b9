"""A trained policy's decisions: its observations as network inputs, the deterministic action of
its actor, and the joint command; played over a batch of episodes for a success rate."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, cast

import numpy as np
from numpy.typing import NDArray

from baselines.features.robot_features import robot_features
from baselines.features.set_features import (
    SetFeatureConfig,
    set_features,
    split_movers,
    state_layout,
    without_message_ages,
)

if TYPE_CHECKING:  # pragma: no cover - typing only
    from koopman_envs import KoopNavVectorEnv

__all__ = ["command_of", "deterministic_action", "policy_command", "policy_inputs", "success_rate"]


def deterministic_action(model: Any, obs: NDArray[np.float32]) -> NDArray[np.float32]:
    """The deterministic actions of a model (or of its :class:`~baselines.sb3.actor.ActorNetwork`)
    for a batch of normalized observations.

    A PPO actor (a Gaussian head: the action is the mean, clipped into the action space as
    ``predict`` clips it) runs compiled (:mod:`baselines.sb3.actor`): a row's action does not depend
    on the rest of the batch, so a batched evaluation equals the per-episode one bit for bit,
    and one team's decision costs a fraction of torch's. The weights are read at this call:
    pass the model's ``compile_actor`` once where it does not change between calls (a
    controller), the model itself where it does (an evaluation during training). Other models
    (SAC's squashed head) go through ``predict``.
    """
    from baselines.sb3.actor import ActorNetwork, compile_actor

    actor = model if isinstance(model, ActorNetwork) else compile_actor(model)
    if actor is None:
        action, _ = model.predict(obs, deterministic=True)
        return np.asarray(action)
    return actor(obs)


def policy_inputs(
    norm: dict,
    layout: str,
    observation: NDArray,
    n_robots: int,
    features: str = "bearing",
    neighbours: int | None = None,
    set_config: SetFeatureConfig | None = None,
    formation: bool = False,
    message_ages: bool = False,
    mover_slots: int = 0,
) -> tuple[NDArray[np.float32], tuple[int, ...]]:
    """The normalized network inputs of (a batch of) observations: one row per robot for the
    ``"robot"`` layout, per team for ``"team"``; and the batch shape of ``observation``.
    Parameters as :func:`policy_command`."""
    obs = np.asarray(observation, dtype=np.float64)
    batch_shape = obs.shape[:-1]
    # the blocks' parts by name: the listed obstacles (and the task: ``formation`` is given for set
    # policies only) are what the width leaves for them
    observed = state_layout(obs.shape[-1] // n_robots, n_robots, comm=message_ages, movers=mover_slots)
    blocks, movers = split_movers(obs.reshape(batch_shape + (n_robots, -1)), observed)
    obs = blocks.reshape(batch_shape + (-1,))
    if message_ages:
        obs = without_message_ages(obs, n_robots)
    if set_config is not None:
        blocks = obs.reshape(batch_shape + (n_robots, -1))
        obs = set_features(blocks, observed.n_obstacle_obs, formation, set_config, movers).astype(np.float64)
        obs = obs.reshape(-1, obs.shape[-1])
    elif layout == "robot":
        blocks = obs.reshape(batch_shape + (n_robots, -1))
        obs = robot_features(blocks, features, neighbours).astype(np.float64)
        obs = obs.reshape(-1, obs.shape[-1])
    if obs.shape[-1] != norm["mean"].shape[-1]:
        raise ValueError(
            f"the policy takes {norm['mean'].shape[-1]} inputs per {'robot' if layout == 'robot' else 'team'}, "
            f"this env gives {obs.shape[-1]}: a {layout!r}-layout policy runs only with the env settings "
            "it was trained on (n_obstacle_obs; for the 'team' layout also n_robots)"
        )
    obs = (obs - norm["mean"]) / np.sqrt(norm["var"] + norm["epsilon"])
    rows = np.clip(obs, -norm["clip"], norm["clip"]).astype(np.float32)
    return rows.reshape(-1, rows.shape[-1]), batch_shape


def command_of(
    action: NDArray, layout: str, n_robots: int, v_max: float, omega_max: float, batch_shape: tuple[int, ...]
) -> NDArray[np.float64]:
    """The joint commands (v, omega per robot, flat; of ``batch_shape``) of the policy's
    actions in [-1, 1] (the rows of :func:`policy_inputs`)."""
    from baselines.sb3.vec_env import scale_action

    high = np.array([v_max, omega_max])
    if layout == "team":
        high = np.tile(high, n_robots)
    return scale_action(np.asarray(action, dtype=np.float64), -high, high).reshape(batch_shape + (-1,))


def policy_command(
    model: Any,
    norm: dict,
    layout: str,
    observation: NDArray,
    n_robots: int,
    v_max: float,
    omega_max: float,
    features: str = "bearing",
    neighbours: int | None = None,
    set_config: SetFeatureConfig | None = None,
    formation: bool = False,
    message_ages: bool = False,
    mover_slots: int = 0,
) -> NDArray[np.float64]:
    """Deterministic joint command (v, omega per robot, flat; batched like the input) of a policy.

    Parameters
    ----------
    model : stable_baselines3 model or ActorNetwork
        The policy, or its compiled actor (:func:`baselines.sb3.actor.compile_actor`).
    norm : dict
        Observation normalization (``mean``, ``var``, ``clip``, ``epsilon``) saved with the model.
    layout : str
        ``"robot"``: the shared policy sees each robot's block (plus
        :func:`baselines.features.robot_features.robot_features`) and commands that robot;
        ``"team"``: it sees the flat team observation and commands everybody.
    observation : ndarray, shape (N * F,) or (K, N * F)
        The centralized observation of the Gymnasium env (or a batch of them).
    n_robots : int
    v_max, omega_max : float
        Actuation limits: the policy acts in [-1, 1].
    features : str
        ``"robot"`` layout: the feature set the policy was trained with (its metadata).
    neighbours : int, optional
        ``"robot"`` layout: team-mates per block the policy was trained with (N_train - 1); a
        team of another size then shows each robot its nearest ones (see
        :func:`baselines.features.robot_features.robot_features`). Default: all.
    set_config : SetFeatureConfig, optional
        A set policy's observation settings (its metadata): each robot then reads
        :func:`baselines.features.set_features.set_features`, for any team size, and ``features`` and
        ``neighbours`` are ignored.
    formation : bool
        Whether the observation is the formation task's (set policies only).
    message_ages : bool
        Whether each robot's block ends with the team-mates' message ages and arrival flags (an
        env with a ``comm`` setting); they are dropped before the network.
    mover_slots : int
        Movers listed at the end of each robot's block (an env with ``movers``): a set policy with
        mover slots reads them, every other policy has them dropped.
    """
    rows, batch_shape = policy_inputs(
        norm,
        layout,
        observation,
        n_robots,
        features,
        neighbours,
        set_config,
        formation,
        message_ages,
        mover_slots,
    )
    action = deterministic_action(model, rows)
    return command_of(action, layout, n_robots, v_max, omega_max, batch_shape)


def success_rate(
    model: Any,
    norm: dict,
    layout: str,
    features: str,
    env_id: str,
    episodes: int,
    seed: int,
    *,
    set_config: SetFeatureConfig | None = None,
    **env_kwargs: Any,
) -> float:
    """Success rate of the deterministic policy over ``episodes`` episodes, played as one batch.

    Episode i runs in sub-env i of ``gym.make_vec(env_id, num_envs=episodes, **env_kwargs)``
    reset with ``seed``, i.e. seeded ``seed + i`` like the single env. ``set_config``: a set
    policy's observation settings (see :func:`policy_command`).
    """
    import gymnasium as gym

    from baselines.sb3.actor import compile_actor

    actor = compile_actor(model) or model  # the weights as they are now, read once
    venv = gym.make_vec(env_id, num_envs=episodes, **env_kwargs)
    obs, _ = venv.reset(seed=seed)
    # a KoopNav id's vector entry point is a KoopNavVectorEnv (make_vec types it as any VectorEnv)
    unwrapped = cast("KoopNavVectorEnv", venv.unwrapped)
    config, layout_of_env = unwrapped.config, unwrapped.observation_layout
    n_robots = config.n_robots
    scenario = unwrapped.scenario(0)  # the actuation limits, as a controller knows them
    v_max, omega_max = float(scenario.v_max), float(scenario.omega_max)
    done = np.zeros(episodes, dtype=bool)
    success = np.zeros(episodes, dtype=bool)
    while not done.all():
        action = policy_command(
            actor,
            norm,
            layout,
            obs,
            n_robots,
            v_max,
            omega_max,
            features,
            set_config=set_config,
            formation=config.task.formation,
            message_ages=layout_of_env.comm,
            mover_slots=layout_of_env.movers,
        )
        obs, _, terminated, truncated, info = venv.step(action)
        ended = (terminated | truncated) & ~done
        success[ended] = info["is_success"][ended]
        done |= ended
    venv.close()
    return float(success.mean())
