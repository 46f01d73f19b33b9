"""Native Gymnasium vector env: K copies stepped together by the batched engine."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space
from numpy.typing import NDArray

from koopman_envs.checks import check_int
from koopman_envs.config import EngineConfig
from koopman_envs.engine import NavigationEngine
from koopman_envs.keywords import takes_env_keywords
from koopman_envs.reset_options import parse_reset_options
from koopman_envs.scenario import Scenario

__all__ = ["KoopNavVectorEnv"]


class KoopNavVectorEnv(VectorEnv):
    """K KoopNav environments in one batched simulator (``gym.make_vec`` entry point).

    Observations, rewards and flags are batched along the first axis. ``info`` holds the same
    keys as the single env, batched (``poses`` (K, N, 3), ``targets`` (K, N, 3), ``distances``
    (K, N), ``collision`` (K,), ``is_success`` (K,)), each with its ``_key`` mask. After a step,
    ``info["robot_rewards"]`` (K, N) also holds every robot's own reward as the PettingZoo front
    gives it: its own progress/effort/formation terms plus the team terms.

    Parameters
    ----------
    num_envs : int
        Number of environments K.
    task : str
        ``"target_reaching"`` or ``"formation"`` (set by the registration).
    autoreset_mode : str or AutoresetMode
        ``"NextStep"`` (Gymnasium's default) or ``"SameStep"`` (final observation and info in
        ``info["final_obs"]`` / ``info["final_info"]``, as SB3 expects).
    render_mode : None
        The vector env does not render (anything else is a ``ValueError``).
    **keywords
        The env keywords of :data:`koopman_envs.keywords.ENV_KEYWORDS`, as for the single env
        (``map``, ``slip``, ``n_robots``, ``formation``, ``start_noise``, ...);
        ``max_episode_steps`` (default ``PARAMS.max_episode_steps``) comes from the registration,
        and this env truncates by itself. Sub-env i draws its map, start noise and slip (drift
        included) from its own generator and has its own slip zones on random maps, so it stays
        equal to the single env seeded ``s + i``.
    """

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": []}

    @takes_env_keywords("vector")
    def __init__(
        self,
        num_envs: int,
        task: str,
        autoreset_mode: str | AutoresetMode = AutoresetMode.NEXT_STEP,
        render_mode: str | None = None,
        **keywords: Any,
    ) -> None:
        check_int("num_envs", num_envs, 1)
        if render_mode is not None:
            raise ValueError(
                f"render_mode={render_mode!r}: the vector env does not render; render a single env"
            )
        try:
            mode = AutoresetMode(autoreset_mode)
        except ValueError as exc:
            allowed = [AutoresetMode.NEXT_STEP.value, AutoresetMode.SAME_STEP.value]
            raise ValueError(f"autoreset_mode={autoreset_mode!r} is not one of {allowed}") from exc
        if mode == AutoresetMode.DISABLED:
            raise ValueError("autoreset_mode='Disabled' is not supported; use NextStep or SameStep")
        self.metadata = {**self.metadata, "autoreset_mode": mode}
        #: the same mode as an attribute, where TorchRL's GymWrapper and others look for it
        self.autoreset_mode = mode
        self.config = EngineConfig.create(task, front="vector", **keywords)
        self.num_envs = int(num_envs)
        self.engine = NavigationEngine(self.config, num_envs=self.num_envs)
        self.single_action_space, self.single_observation_space = self.engine.team_spaces()
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.render_mode = None
        self._rngs: list[np.random.Generator] | None = None
        self._autoreset = np.zeros(self.num_envs, dtype=bool)
        self._all = np.ones(self.num_envs, dtype=bool)

    # --------------------------------------------------------------- API
    def reset(
        self,
        *,
        seed: int | Sequence[int | None] | None = None,
        options: dict[str, Any] | None = None,
    ) -> tuple[NDArray[np.float32], dict[str, Any]]:
        """Start a new episode in every sub-environment.

        Parameters
        ----------
        seed : int or sequence of int, optional
            An int s seeds sub-env i with s + i; a sequence gives one seed (or None) per sub-env.
        options : dict, optional
            ``start_poses`` and/or ``targets`` as for the single env, for this episode only
            (auto-resets use the map's): an (N, 3) array applies to every sub-env, a (K, N, 3)
            array gives sub-env i its row i. An unknown key or an invalid pose is a
            ``ValueError`` (:func:`koopman_envs.reset_options.parse_reset_options`,
            docs/reset_options.md); a pose rejected on sub-env i's map leaves the sub-envs
            before i already reset, so reset again.

        Returns
        -------
        observations : ndarray of float32, shape (K, N * F)
        info : dict
        """
        overrides = parse_reset_options(options, self.config.n_robots, self.num_envs)  # before any change
        if seed is None:
            seeds: Sequence[int | None] = [None] * self.num_envs
        elif isinstance(seed, (int, np.integer)):
            seeds = [int(seed) + i for i in range(self.num_envs)]
        else:
            seeds = list(seed)
            if len(seeds) != self.num_envs:
                raise ValueError(
                    f"seed has {len(seeds)} entries; expected one per environment ({self.num_envs})"
                )
        if self._rngs is None:
            self._rngs = [seeding.np_random(s)[0] for s in seeds]
        else:
            for i, s in enumerate(seeds):
                if s is not None:
                    self._rngs[i] = seeding.np_random(s)[0]
        for i in range(self.num_envs):
            self.engine.reset_env(i, self._rngs[i], overrides[i])
        self._autoreset[:] = False
        return self._observations(self.engine.features()), self._info()

    def step(
        self, actions: NDArray[np.floating[Any]]
    ) -> tuple[
        NDArray[np.float32], NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_], dict[str, Any]
    ]:
        engine = self.engine
        if self._rngs is None:
            raise RuntimeError("call reset() before step()")
        commands = engine.validate_commands(actions)
        if self.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP:
            return self._step_next(commands)
        return self._step_same(commands)

    def _step_next(
        self, commands: NDArray[np.float64]
    ) -> tuple[
        NDArray[np.float32], NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_], dict[str, Any]
    ]:
        engine = self.engine
        assert self._rngs is not None  # step() has checked that reset() made the generators
        pending = np.flatnonzero(self._autoreset)
        if pending.size:
            for i in pending:
                engine.reset_env(int(i), self._rngs[i])
            result = engine.step(commands, active=~self._autoreset)
        else:
            result = engine.step(commands)
        reward = result.robot_reward.sum(-1) + result.team_reward
        self._autoreset = result.terminated | result.truncated
        info = self._info()
        info["robot_rewards"] = result.robot_reward + result.team_reward[:, None]
        info["_robot_rewards"] = self._all
        return (
            self._observations(result.features),
            reward,
            result.terminated,
            result.truncated,
            info,
        )

    def _step_same(
        self, commands: NDArray[np.float64]
    ) -> tuple[
        NDArray[np.float32], NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_], dict[str, Any]
    ]:
        engine = self.engine
        assert self._rngs is not None  # step() has checked that reset() made the generators
        result = engine.step(commands)
        reward = result.robot_reward.sum(-1) + result.team_reward
        done = result.terminated | result.truncated
        obs = self._observations(result.features)
        info = self._info()
        if done.any():
            final_obs = obs.copy()
            final_info = info
            for i in np.flatnonzero(done):
                engine.reset_env(int(i), self._rngs[i])
            fresh = self._observations(engine.features())
            obs = np.where(done[:, None], fresh, obs)
            info = self._info()
            info["final_obs"] = final_obs
            info["_final_obs"] = done.copy()
            info["final_info"] = final_info
            info["_final_info"] = done.copy()
        info["robot_rewards"] = result.robot_reward + result.team_reward[:, None]
        info["_robot_rewards"] = self._all
        return obs, reward, result.terminated, result.truncated, info

    def _observations(self, features: NDArray[np.float64]) -> NDArray[np.float32]:
        return features.reshape(self.num_envs, -1).astype(np.float32)

    def _info(self) -> dict[str, Any]:
        info: dict[str, Any] = self.engine.batch_info()
        for key in list(info):
            info["_" + key] = self._all
        return info

    def scenario(self, index: int) -> Scenario:
        """Scenario of sub-environment ``index`` (see :class:`koopman_envs.scenario.Scenario`)."""
        return self.engine.scenario(index)


def make_target_reaching_vec(num_envs: int = 1, **kwargs: Any) -> KoopNavVectorEnv:
    """``vector_entry_point`` of ``KoopNav-TargetReaching-v0``."""
    return KoopNavVectorEnv(num_envs, "target_reaching", **kwargs)


def make_formation_vec(num_envs: int = 1, **kwargs: Any) -> KoopNavVectorEnv:
    """``vector_entry_point`` of ``KoopNav-Formation-v0``."""
    return KoopNavVectorEnv(num_envs, "formation", **kwargs)


__all__ += ["make_target_reaching_vec", "make_formation_vec"]
