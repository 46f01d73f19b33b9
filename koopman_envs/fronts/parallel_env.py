"""PettingZoo front: every robot is an agent acting at the same time (``ParallelEnv``)."""

from __future__ import annotations

import inspect
import textwrap
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from numpy.typing import NDArray
from pettingzoo import AECEnv, ParallelEnv
from pettingzoo.utils import OrderEnforcingWrapper
from pettingzoo.utils.conversions import parallel_to_aec

from koopman_envs.checks import check_choice
from koopman_envs.engine.config import EngineConfig
from koopman_envs.engine.engine import NavigationEngine
from koopman_envs.engine.keywords import ENV_KEYWORDS, takes_env_keywords
from koopman_envs.fronts.single_env import SingleEnvFront
from koopman_envs.params import PARAMS
from koopman_envs.settings.reset_options import parse_reset_options

if TYPE_CHECKING:  # pragma: no cover - typing only (rendering imports matplotlib when first used)
    from koopman_envs.rendering.renderer import Renderer

__all__ = ["KoopNavParallelEnv", "make_call", "make_constructors"]

#: ``pettingzoo.test.api_test`` and ``parallel_api_test`` check that reset takes ``options`` by
#: passing ``{"options": 1}``: that key is accepted without effect so that they pass, while any
#: other unknown key is still a ValueError
_API_TEST_OPTIONS = ("options",)


# pettingzoo ships no type information (no py.typed), so to the type checker ParallelEnv is Any
class KoopNavParallelEnv(SingleEnvFront, ParallelEnv):  # type: ignore[misc]
    """N robots as N agents ``robot_0 .. robot_{N-1}`` on the shared simulator core.

    Each agent observes its own block of :mod:`koopman_envs.tasks.observation` (own pose and
    target, the other robots and the nearest obstacles relative to itself, and for formation its
    formation error) and sends ``(v [m/s], omega [rad/s])``, saturated to the actuation limits.
    Its reward is its own progress / effort (/ formation) terms plus the shared team terms
    (collision penalty, success bonus); the episode ends for all agents together. ``state()``
    returns the centralized observation of the Gymnasium env.

    ``copy.deepcopy`` and pickling copy the whole state, as for the Gymnasium env: poses, step
    count, live agents and random generators, so that the copy and the original, stepped with
    the same actions, stay equal (the AEC form from ``env()`` too). A rendered env's figure is
    not copied; the copy draws a new one.

    Parameters
    ----------
    task : str
        ``"target_reaching"`` or ``"formation"``.
    render_mode : str, optional
        ``"rgb_array"`` or ``"human"`` (matplotlib), as for the Gymnasium env.
    **keywords
        The env keywords of :data:`koopman_envs.engine.keywords.ENV_KEYWORDS`, as for the Gymnasium env
        (``map``, ``slip``, ``n_robots``, ``formation``, ``start_noise``, ...), plus
        ``max_episode_steps``: the time limit in control periods (default
        ``PARAMS.max_episode_steps``; this env truncates by itself), and ``max_cycles``, the same
        limit under the name PettingZoo's MPE environments give it (what
        ``pettingzoo.test.max_cycles_test`` passes); giving both names with different values is
        a ``ValueError``.
    """

    metadata: dict[str, Any] = {
        "render_modes": ["human", "rgb_array"],
        "render_fps": int(round(1 / PARAMS.dt)),
        "is_parallelizable": True,
        "name": "koopnav_v0",
    }

    @takes_env_keywords("parallel")
    def __init__(
        self, task: str = "target_reaching", render_mode: str | None = None, **keywords: Any
    ) -> None:
        if render_mode is not None:
            check_choice("render_mode", render_mode, self.metadata["render_modes"], " or None")
        # a PettingZoo env truncates by itself: without max_episode_steps / max_cycles, the default limit
        #: the env's keywords resolved and checked (:class:`koopman_envs.EngineConfig`): the public
        #: way to read its team size, task, movers and radii (``engine`` is internal)
        self.config = EngineConfig.create(task, front="parallel", **keywords)
        self.metadata = {**self.metadata, "name": f"koopnav_{task}_v0"}
        self.engine = NavigationEngine(self.config, num_envs=1)
        n = self.config.n_robots
        self.possible_agents = [f"robot_{i}" for i in range(n)]
        self.agents: list[str] = []
        self._index = {name: i for i, name in enumerate(self.possible_agents)}
        # one space object per agent: spaces carry their own sampling generator
        per_agent = {a: self.engine.robot_spaces() for a in self.possible_agents}
        self.action_spaces = {a: pair[0] for a, pair in per_agent.items()}
        self.observation_spaces = {a: pair[1] for a, pair in per_agent.items()}
        self.state_space = self.engine.team_spaces()[1]
        self.render_mode = render_mode
        self._rng: np.random.Generator | None = None
        self._features: NDArray[np.float64] | None = None
        self._renderer: Renderer | None = None
        self._trail: list[NDArray[np.float64]] = []

    def observation_space(self, agent: str) -> spaces.Box:
        return self.observation_spaces[agent]

    def action_space(self, agent: str) -> spaces.Box:
        return self.action_spaces[agent]

    def reset(
        self, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, NDArray[np.float32]], dict[str, dict[str, Any]]]:
        """Start a new episode for every agent.

        Parameters
        ----------
        seed : int, optional
            Reseeds the env's generator (map draws, start noise, slip).
        options : dict, optional
            As for the Gymnasium env: ``start_poses`` (N, 3) and/or ``targets`` (N, 3) replace
            the map's for this episode, robot i being ``robot_i``; an unknown key or an invalid
            pose is a ``ValueError`` (:func:`koopman_envs.settings.reset_options.parse_reset_options`,
            docs/reset_options.md). The key ``"options"`` is ignored: PettingZoo's API tests
            pass ``{"options": 1}`` to check that ``reset`` takes the keyword.

        Returns
        -------
        observations, infos : dict
            Per agent.
        """
        overrides = parse_reset_options(options, self.config.n_robots, ignored=_API_TEST_OPTIONS)[0]
        if seed is not None or self._rng is None:
            self._rng = seeding.np_random(seed)[0]
        self.engine.reset_env(0, self._rng, overrides)
        self.agents = list(self.possible_agents)
        self._features = self.engine.features()[0]
        self._start_trail()
        return self._observations(), self._infos()

    def step(
        self, actions: dict[str, Any]
    ) -> tuple[
        dict[str, NDArray[np.float32]],
        dict[str, float],
        dict[str, bool],
        dict[str, bool],
        dict[str, dict[str, Any]],
    ]:
        if not self.agents:
            raise RuntimeError("the episode is over: call reset() before step()")
        missing = [a for a in self.agents if a not in actions]
        unknown = [a for a in actions if a not in self._index]
        if missing or unknown:
            raise ValueError(
                f"actions must have one entry per live agent {self.agents}; "
                f"missing {missing}, unknown {unknown}"
            )
        joint = np.zeros((1, len(self.possible_agents), 2))
        for agent, act in actions.items():
            arr = np.asarray(act, dtype=np.float64)
            if arr.shape != (2,):
                raise ValueError(
                    f"action of {agent} has shape {arr.shape}; expected (2,): (v [m/s], omega [rad/s])"
                )
            joint[0, self._index[agent]] = arr
        result = self.engine.step(self.engine.validate_commands(joint))
        self._features = result.features[0]
        team = float(result.team_reward[0])
        rewards = {a: float(result.robot_reward[0, self._index[a]]) + team for a in self.agents}
        term, trunc = bool(result.terminated[0]), bool(result.truncated[0])
        terminations = {a: term for a in self.agents}
        truncations = {a: trunc for a in self.agents}
        observations, infos = self._observations(), self._infos()
        self._extend_trail()
        if term or trunc:
            self.agents = []
        return observations, rewards, terminations, truncations, infos

    def _observations(self) -> dict[str, NDArray[np.float32]]:
        assert self._features is not None  # only reset() and step() call this, after setting them
        feats = self._features.astype(np.float32)
        return {a: feats[self._index[a]] for a in self.agents}

    def _infos(self) -> dict[str, dict[str, Any]]:
        shared = self.engine.info(0)
        return {a: {**shared, "robot": self._index[a]} for a in self.agents}

    def state(self) -> NDArray[np.float32]:
        """Centralized observation (all agents' blocks, robot 0 first)."""
        if self._features is None:
            raise RuntimeError("call reset() before state()")
        return self._features.reshape(-1).astype(np.float32)

    # render, close, observation_layout and scenario: SingleEnvFront's (as the Gymnasium env's)


def make_constructors(
    task: str,
) -> tuple[Callable[..., KoopNavParallelEnv], Callable[..., AECEnv], Callable[..., AECEnv]]:
    """The three PettingZoo constructors of one task: ``parallel_env``, ``env``, ``raw_env``."""

    def parallel_env(**kwargs: Any) -> KoopNavParallelEnv:
        return KoopNavParallelEnv(task, **kwargs)

    def raw_env(**kwargs: Any) -> AECEnv:
        return parallel_to_aec(KoopNavParallelEnv(task, **kwargs))

    def env(**kwargs: Any) -> AECEnv:
        return OrderEnforcingWrapper(raw_env(**kwargs))

    # the keywords of KoopNavParallelEnv, without ``task`` (fixed here)
    parameters = list(inspect.signature(KoopNavParallelEnv).parameters.values())
    signature = inspect.Signature([p.replace(kind=p.KEYWORD_ONLY) for p in parameters if p.name != "task"])
    for fn, what in ((parallel_env, "parallel"), (raw_env, "unwrapped turn-based"), (env, "turn-based")):
        fn.__doc__ = f"Create the {what} KoopNav {task} environment (keywords of KoopNavParallelEnv)."
        # a function takes any attribute, but typeshed's function type declares no __signature__
        # (the attribute inspect.signature reads first)
        fn.__signature__ = signature  # type: ignore[union-attr]
    return parallel_env, env, raw_env


def module_doc(task: str, doc: str) -> str:
    """A PettingZoo module's docstring with its values filled in: ``{make_call}`` (:func:`make_call`),
    ``{v_max}``, ``{omega_max}`` (params.py) and ``{features}`` (the default observation size)."""
    from koopman_envs.tasks.base import TASKS
    from koopman_envs.tasks.observation import feature_size

    listed = next(k.default for k in ENV_KEYWORDS if k.name == "n_obstacle_obs")
    values = {
        "{make_call}": make_call(task),
        "{v_max}": f"{PARAMS.v_max:g}",
        "{omega_max}": f"{PARAMS.omega_max:.3f}",
        "{features}": str(feature_size(PARAMS.n_robots, listed, formation=TASKS[task].formation)),
    }
    for key, value in values.items():
        doc = doc.replace(key, value)
    return doc


def make_call(task: str) -> str:
    """``<task>_v0.parallel_env(...)`` with every keyword at its default, for the module docstrings
    (generated from the constructor's signature, itself generated from the keyword table)."""
    from koopman_envs.tasks.base import TASKS

    head = f"{task}_v0.parallel_env("
    defaults = {"map": TASKS[task].default_map, "max_episode_steps": PARAMS.max_episode_steps}
    parameters = inspect.signature(KoopNavParallelEnv).parameters.values()
    words = " ".join(f"{p.name}={defaults.get(p.name, p.default)!r}," for p in parameters if p.name != "task")
    lines = textwrap.wrap(
        words[:-1] + ")", width=100 - len(head), break_long_words=False, break_on_hyphens=False
    )
    return head + ("\n" + " " * len(head)).join(lines)
