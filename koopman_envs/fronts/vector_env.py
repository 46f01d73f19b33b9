"""Native Gymnasium vector env: K copies stepped together by the batched engine."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import TYPE_CHECKING, Any

import gymnasium as gym
import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space
from numpy.typing import NDArray

from koopman_envs.checks import check_choice, check_int, choice_message
from koopman_envs.engine.config import EngineConfig
from koopman_envs.engine.engine import NavigationEngine
from koopman_envs.engine.keywords import takes_env_keywords
from koopman_envs.layout import ObservationLayout
from koopman_envs.params import LIMITS
from koopman_envs.scenario import Scenario
from koopman_envs.settings.reset_options import parse_reset_options

if TYPE_CHECKING:  # pragma: no cover - typing only (rendering imports matplotlib when first used)
    from koopman_envs.rendering.renderer import Renderer

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
    render_mode : None or "rgb_array"
        ``"rgb_array"``: :meth:`render` returns one frame per sub-env, as Gymnasium's
        ``SyncVectorEnv`` does (its vector wrappers that tile or record frames work unchanged).
        Trails are kept only then. ``"human"`` is a ``ValueError``: render a single env, or
        tile these frames with ``gymnasium.wrappers.vector.HumanRendering``.
    **keywords
        The env keywords of :data:`koopman_envs.engine.keywords.ENV_KEYWORDS`, as for the single env
        (``map``, ``slip``, ``n_robots``, ``formation``, ``start_noise``, ...);
        ``max_episode_steps`` (default ``PARAMS.max_episode_steps``) comes from the registration,
        and this env truncates by itself. Sub-env i draws its map, start noise and slip (drift
        included) from its own generator and has its own slip zones on random maps, so it stays
        equal to the single env seeded ``s + i``.
    """

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": ["rgb_array"], "render_fps": 10}

    @takes_env_keywords("vector")
    def __init__(
        self,
        num_envs: int,
        task: str,
        autoreset_mode: str | AutoresetMode = AutoresetMode.NEXT_STEP,
        render_mode: str | None = None,
        **keywords: Any,
    ) -> None:
        # every array is batched over it (the engine also checks the batch's estimated memory)
        check_int("num_envs", num_envs, 1, maximum=LIMITS.num_envs)
        check_choice(
            "render_mode",
            render_mode,
            [None, "rgb_array"],
            " for the vector env; 'human': render a single env, or wrap this one in "
            "gymnasium.wrappers.vector.HumanRendering",
        )
        try:
            mode = AutoresetMode(autoreset_mode)
        except ValueError as exc:
            allowed = [AutoresetMode.NEXT_STEP.value, AutoresetMode.SAME_STEP.value]
            raise ValueError(choice_message("autoreset_mode", autoreset_mode, allowed)) from exc
        if mode == AutoresetMode.DISABLED:
            raise ValueError("autoreset_mode='Disabled' is not supported; use NextStep or SameStep")
        self.metadata = {**self.metadata, "autoreset_mode": mode}
        #: the same mode as an attribute, where TorchRL's GymWrapper and others look for it
        self.autoreset_mode = mode
        #: the env's keywords resolved and checked (:class:`koopman_envs.EngineConfig`): the public
        #: way to read its team size, task, movers and radii (``engine`` is internal)
        self.config = EngineConfig.create(task, front="vector", **keywords)
        self.num_envs = int(num_envs)
        self.engine = NavigationEngine(self.config, num_envs=self.num_envs)
        self.single_action_space, self.single_observation_space = self.engine.team_spaces()
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.render_mode = render_mode
        #: each sub-env's poses since its episode started (only with a render mode)
        self._trails: list[list[NDArray[np.float64]]] = []
        self._renderers: list[Renderer] = []
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
            ``ValueError`` (:func:`koopman_envs.settings.reset_options.parse_reset_options`,
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
        if options is None:  # every sub-env on its map's starts and targets: one batched reset
            self.engine.reset_envs(range(self.num_envs), self._rngs)
        else:
            for i in range(self.num_envs):
                self.engine.reset_env(i, self._rngs[i], overrides[i])
        self._autoreset[:] = False
        self._record(restarted=range(self.num_envs))
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
            engine.reset_envs(pending.tolist(), [self._rngs[i] for i in pending])
            self._record(restarted=pending)
            result = engine.step(commands, active=~self._autoreset)
        else:
            result = engine.step(commands)
        self._record()
        reward = result.reward
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
        self._record()
        reward = result.reward
        done = result.terminated | result.truncated
        obs = self._observations(result.features)
        info = self._info()
        if done.any():
            final_obs = obs.copy()
            # as Gymnasium's SyncVectorEnv builds it: the finished sub-envs' entries, each key's
            # mask true for those sub-envs only
            final_info = {key: (done.copy() if key.startswith("_") else value) for key, value in info.items()}
            ended = np.flatnonzero(done)
            engine.reset_envs(ended.tolist(), [self._rngs[i] for i in ended])
            self._record(restarted=ended)
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

    def _record(self, restarted: Iterable[int] | None = None) -> None:
        """Keep the trails for :meth:`render`: start the ``restarted`` sub-envs' trails at their
        current poses, or (None) add every sub-env's current poses. Nothing without a render mode."""
        if self.render_mode is None:
            return
        poses = self.engine.poses
        if restarted is None:
            for trail, pose in zip(self._trails, poses):
                trail.append(pose.copy())
            return
        if not self._trails:
            self._trails = [[] for _ in range(self.num_envs)]
        for i in restarted:
            self._trails[int(i)] = [poses[int(i)].copy()]

    def render(self) -> tuple[NDArray[np.uint8], ...] | None:
        """One (H, W, 3) frame per sub-env, as ``SyncVectorEnv.render`` returns them (None without
        a render mode)."""
        if self.render_mode is None:
            gym.logger.warn(
                "render() called without a render_mode; pass render_mode='rgb_array' to gym.make_vec"
            )
            return None
        if not self._trails:
            raise RuntimeError("call reset() before render()")
        from koopman_envs.rendering.renderer import Renderer, draw_engine_env

        while len(self._renderers) < self.num_envs:
            self._renderers.append(Renderer())
        frames = [
            draw_engine_env(self._renderers[i], self.engine, i, self._trails[i]) for i in range(self.num_envs)
        ]
        return tuple(frame for frame in frames if frame is not None)

    def close_extras(self, **kwargs: Any) -> None:
        """Close the renderers' figures and the plant's thread pool."""
        self.engine.close()
        for renderer in self._renderers:
            renderer.close()
        self._renderers = []

    @property
    def observation_layout(self) -> ObservationLayout:
        """One robot's observation block by name (:class:`koopman_envs.layout.ObservationLayout`),
        known before the first reset."""
        return self.engine.observation_layout

    def scenario(self, index: int) -> Scenario:
        """Scenario of sub-environment ``index`` (see :class:`koopman_envs.scenario.Scenario`)."""
        return self.engine.scenario(index)

    def robot_spaces(self) -> tuple[gym.spaces.Box, gym.spaces.Box]:
        """(action, observation) spaces of one robot: its (v, omega) and its observation block
        (the team spaces repeat them once per robot, robot 0 first)."""
        return self.engine.robot_spaces()


def make_target_reaching_vec(num_envs: int = 1, **kwargs: Any) -> KoopNavVectorEnv:
    """``vector_entry_point`` of ``KoopNav-TargetReaching-v0``."""
    return KoopNavVectorEnv(num_envs, "target_reaching", **kwargs)


def make_formation_vec(num_envs: int = 1, **kwargs: Any) -> KoopNavVectorEnv:
    """``vector_entry_point`` of ``KoopNav-Formation-v0``."""
    return KoopNavVectorEnv(num_envs, "formation", **kwargs)


__all__ += ["make_target_reaching_vec", "make_formation_vec"]
