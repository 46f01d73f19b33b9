"""Centralized Gymnasium environments: one agent commands the whole team."""

from __future__ import annotations

import textwrap
from typing import TYPE_CHECKING, Any, cast

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

from koopman_envs.checks import check_choice
from koopman_envs.engine.config import EngineConfig
from koopman_envs.engine.engine import START_NOISE_ATTEMPTS, NavigationEngine
from koopman_envs.engine.keywords import ENV_KEYWORDS, keyword_table, takes_env_keywords
from koopman_envs.fronts.single_env import SingleEnvFront
from koopman_envs.params import DRIFT_MEAN_INTERVAL, PARAMS, RANDOM_SLIP_MAX
from koopman_envs.settings.reset_options import parse_reset_options
from koopman_envs.sim.formations import FORMATION_SHAPES
from koopman_envs.tasks.base import RewardWeights
from koopman_envs.tasks.observation import feature_size

if TYPE_CHECKING:  # pragma: no cover - typing only (rendering imports matplotlib when first used)
    from koopman_envs.rendering.renderer import Renderer

__all__ = ["KoopNavEnv", "TargetReachingEnv", "FormationEnv"]


class KoopNavEnv(SingleEnvFront, gym.Env):
    """Shared implementation of the two centralized tasks; use a subclass or ``gym.make``."""

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": int(round(1 / PARAMS.dt))}
    task_name = ""

    @takes_env_keywords("gym")
    def __init__(self, render_mode: str | None = None, **keywords: Any) -> None:
        if render_mode is not None:
            check_choice("render_mode", render_mode, self.metadata["render_modes"], " or None")
        #: the env's keywords resolved and checked (:class:`koopman_envs.EngineConfig`): the public
        #: way to read its team size, task, movers and radii (``engine`` is internal)
        self.config = EngineConfig.create(self.task_name, front="gym", **keywords)
        self.engine = NavigationEngine(self.config, num_envs=1)
        self.action_space, self.observation_space = self.engine.team_spaces()
        self.render_mode = render_mode
        self._renderer: Renderer | None = None
        self._trail: list[NDArray[np.float64]] = []

    # --------------------------------------------------------------- Gym API
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[NDArray[np.float32], dict[str, Any]]:
        """Start a new episode.

        Parameters
        ----------
        seed : int, optional
            Reseeds the env's generator (map draws, start noise, slip).
        options : dict, optional
            Replacements for this episode only: ``start_poses`` (N, 3) of x [m], y [m],
            heading [rad] instead of the map's starts (no ``start_noise``), and ``targets``
            (N, 3) instead of the map's targets. Each is checked (shape, finite, inside the
            workspace, clear of obstacles and of each other) and an unknown key is a
            ``ValueError``; see :func:`koopman_envs.settings.reset_options.parse_reset_options` and
            docs/reset_options.md.

        Returns
        -------
        observation : ndarray of float32
        info : dict
        """
        overrides = parse_reset_options(options, self.config.n_robots)[0]  # before any change
        super().reset(seed=seed)
        self.engine.reset_env(0, self.np_random, overrides)
        self._start_trail()
        obs = self.engine.features()[0].reshape(-1).astype(np.float32)
        if self.render_mode == "human":
            self.render()
        return obs, self.engine.info(0)

    def step(
        self, action: NDArray[np.floating[Any]]
    ) -> tuple[NDArray[np.float32], float, bool, bool, dict[str, Any]]:
        engine = self.engine
        if engine.maps[0] is None:
            raise RuntimeError("call reset() before step()")
        result = engine.step(engine.validate_commands(action))
        reward = float(result.reward[0])
        obs = result.features[0].reshape(-1).astype(np.float32)
        self._extend_trail()
        # truncated only with max_episode_steps given to the class itself: gym.make keeps the limit
        # in its TimeLimit wrapper and gives the env none
        return obs, reward, bool(result.terminated[0]), bool(result.truncated[0]), engine.info(0)

    # ---------------------------------------------------------- for models
    # render, close, observation_layout and scenario: SingleEnvFront's

    @property
    def lambdas(self) -> NDArray[np.float64]:
        """Per-robot slip means of the period that starts now: the episode's level, or the
        schedule's at the current time, with the slip zones the robots stand in applied
        (ground truth; controllers must not read it)."""
        return cast("NDArray[np.float64]", self.engine.slip_means()[0])  # row 0 of (K, N)

    @property
    def friction(self) -> NDArray[np.float64] | None:
        """Per-robot wheel-ground friction coefficient of the last period on the physics plant
        (``plant="mujoco"``: the zone or surface each robot drove on; ground truth, not in
        ``info``, and controllers must not read it); None on the kinematic plant, which has none."""
        physics = self.engine.physics
        return None if physics is None else physics.friction[0].copy()


_W = RewardWeights()

_SLIP_TABLE = """
    ======== ========= ========= =========
    setting  lambda_1  lambda_2  lambda_3
    ======== ========= ========= =========
    nominal  0         0         0
    low      0         0.05      0.1
    high     0         0.1       0.2
    ======== ========= ========= =========

    For other team sizes robot 1 stays slip-free and the others are spaced linearly up to the
    setting's largest lambda. A sequence of per-robot lambda >= 0 is accepted too, and
    ``"random"`` draws a new level per episode (largest lambda uniform on [0, {max:g}]; for training).

    Levels that change within an episode (``params.py`` documents the law):

    * ``slip="drift"``: every robot's level is redrawn uniformly on [0, {max:g}] at the events of
      its own Poisson process (holding times Exponential with mean {interval:g} s). The draws come
      from the env's ``np_random``: the first levels and holding times at reset, after every other
      reset draw, the later ones at the end of the step that reaches them; the other settings
      draw nothing of this, so their rollouts are unchanged.
    * ``slip=[(0.0, [0, 0.1, 0.2]), (5.0, [0.3, 0.3, 0.3])]``: (time [s], lambdas) pairs, times
      from 0 and strictly increasing; ``lambdas`` is anything ``slip`` takes as a level (a name,
      one number, one per robot). Each level holds from its time until the next.

    A change at time t applies from the first period that starts at or after t.

    Slip zones of the map (``MapSpec.slip_zones``, docs/environments.md, "Maps"): inside a ``"replace"``
    zone a robot's mean is the zone's lambda, inside an ``"add"`` zone the zone's lambda is added;
    overlapping zones: the last listed ``replace`` zone wins, ``add`` zones sum on top. The mean of
    a period is taken where the robot is at the period's start; only the scale of the draws
    changes, so an env with zones consumes its generator exactly as one without.
    ``env.unwrapped.lambdas`` holds every robot's mean for the period that starts now (ground
    truth; ``info`` carries no slip data, as controllers must not read it).

    With ``plant="mujoco"`` nothing is drawn: the robots are TurtleBot3-class bodies in MuJoCo,
    ``slip`` names the floor ("nominal" carpet, "low" gravel, "high" ice, a surface name or a
    friction in (0, 2], friction drawn per episode), zones are friction zones, and the wheels slip
    where the friction gives out (docs/physics.md); ``lambdas`` is then zero.
"""

_SLIP_DOC = _SLIP_TABLE.format(max=RANDOM_SLIP_MAX, interval=DRIFT_MEAN_INTERVAL)

_SHAPES = ", ".join(FORMATION_SHAPES)


def _arguments(task: str) -> str:
    """The Arguments table of the env docstrings, from the one keyword table (ENV_KEYWORDS)."""
    own = [("render_mode", "str or None", "None", "'rgb_array' or 'human' (matplotlib)")]
    table = keyword_table("gym", own, task=task)
    table = table.replace("{", "{{").replace("}", "}}")  # _COMMON_DOC is formatted once more
    return (
        textwrap.indent(table, "    ")
        + "\n\n    ``max_episode_steps`` is usually given to ``gym.make``, which applies it with its ``TimeLimit``."
    )


_X_MIN, _X_MAX, _Y_MIN, _Y_MAX = PARAMS.workspace
_OBSTACLES_LISTED: int = next(k.default for k in ENV_KEYWORDS if k.name == "n_obstacle_obs")
#: values of the docstrings that params.py, the keyword table and the engine own
_DOC_VALUES = {
    "n_obstacle_obs": _OBSTACLES_LISTED,
    "features_target": feature_size(PARAMS.n_robots, _OBSTACLES_LISTED, formation=False),
    "features_formation": feature_size(PARAMS.n_robots, _OBSTACLES_LISTED, formation=True),
    "attempts": START_NOISE_ATTEMPTS,
    "workspace": f"{_X_MAX - _X_MIN:g} x {_Y_MAX - _Y_MIN:g} m",
}

_COMMON_DOC = """
    ## Action Space
    ``Box(shape=(2N,), float32)``: the command of every robot in order,
    ``[v_0, omega_0, v_1, omega_1, ...]``. An array of shape ``(N, 2)`` is accepted too.

    | Num    | Action                 | Min      | Max     | Unit  |
    |--------|------------------------|----------|---------|-------|
    | 2i     | forward speed v_i      | -{p.v_max:g}     | {p.v_max:g}     | m/s   |
    | 2i + 1 | turn rate omega_i      | -{p.omega_max:.3f}   | {p.omega_max:.3f}   | rad/s |

    Values beyond the limits saturate (as real actuators do); a wrong shape or a NaN/inf entry
    raises ``ValueError``.

    ## Observation Space
    ``Box(shape=(N * F,), float32)``: one block of F entries per robot, robot 0 first, as listed
    in :mod:`koopman_envs.tasks.observation` (pose, target in the body frame, the other robots,
    the nearest obstacles, and for formation the formation error). With the defaults ({p.n_robots} robots,
    {n_obstacle_obs} obstacles listed) F = {features_target} for target reaching and {features_formation} for formation.

    ``info`` always carries the true structured state: ``poses`` (N, 3), ``targets`` (N, 3),
    ``distances`` (N,) to the targets [m], ``collision`` (bool), ``collision_code`` (int bit
    flags: 1 obstacle, 2 robot, 4 workspace; ``CollisionKind.describe(code)`` names them),
    ``robot_collision`` (N,), ``collision_fault`` (N,) (whose fault: 0 none, 1 the robot's, 2 a
    mover's; ``CollisionFault.describe(code)``), ``robots_at_fault`` and ``robots_not_at_fault``,
    ``is_success`` (bool) and ``settled_steps``; formation adds
    ``formation_error`` (N,) [m]. Every value is a number or an array.

    ## Dynamics and Slip
    Unicycle kinematics with slip (paper eq. 15), RK4 at {p.dt:g} s. Each period, per robot,
    alpha, beta, gamma ~ Exponential(mean lambda_i) from the env's own ``np_random``:
{slip_table}
    ## Rewards
    Per robot: ``{w.progress:g} * progress [m] - {w.effort:g} * ((v/v_max)^2 + (omega/omega_max)^2)``
    ``{formation_term} + {w.settle:g} * [within goal_tolerance]``; once for the team: ``-{w.collision:g}`` on a collision, ``+{w.success:g}`` on success. See
    :class:`koopman_envs.tasks.base.RewardWeights`.

    ## Starting State
    The map's start poses (a new seeded random layout per reset with ``map="random"``). With
    ``start_noise`` = s > 0, every reset moves each robot's start position by a point drawn
    uniformly in a disc of radius s [m] and turns its heading by an angle uniform in [-s, s]
    [rad] (wrapped to [-pi, pi)), from the env's own ``np_random``; a draw that leaves the
    workspace or overlaps an obstacle or another robot is redrawn for the whole team ({attempts} tries,
    then a ``ValueError`` naming ``start_noise``, also a ``RuntimeError``).
    ``env.unwrapped.scenario.starts`` holds the starts actually used.
    ``reset(options={{"start_poses": poses}})`` starts one episode at the given (N, 3) poses
    instead, and ``options={{"targets": targets}}`` replaces the targets (docs/reset_options.md).

    ## Teams and formation shapes
    ``n_robots`` may be at most the map's starts: 3 on map1..map6, 6 on map7 and map8 (a smaller
    team takes the first ``n_robots`` starts and targets); ``map="random"`` takes any team size.
    ``formation`` names a shape of :mod:`koopman_envs.sim.formations`:
    {shapes}, neighbours {p.formation_spacing:g} m apart (``params.formation_spacing``). On a
    formation map the leader's target stays and follower i's target becomes the leader's target
    plus offset i of the shape, turned to the leader target's heading; with ``map="random"`` the
    team starts and ends in the shape (target reaching too). Shaped targets that leave the workspace, overlap an
    obstacle or each other are a ``ValueError`` at construction; ``formation`` on a fixed
    target-reaching map is one too.

    ## Episode End
    1. Termination: any collision (robot-obstacle, robot-robot, or a centre leaving the
       {workspace} workspace).
    2. Termination (success): every robot has stayed within ``goal_tolerance`` of its target
       for {p.settle_time:g} s ({p.settle_steps} periods); ``info["distances"]`` is then the settled distance.
    3. Truncation: ``max_episode_steps`` ({p.max_episode_steps} periods by default).

    ## Arguments
{arguments}

    ## Vectorized environment
    ``gym.make_vec(id, num_envs=K)`` returns :class:`koopman_envs.fronts.vector_env.KoopNavVectorEnv`,
    which steps all K copies in one compiled pass; sub-env i seeded ``s + i`` equals the single env
    seeded ``s + i``.

    ## Version History
    * v0: initial release.
"""


class TargetReachingEnv(KoopNavEnv):
    __doc__ = """## Description
    N differential-drive robots (default 3) each drive to their own target pose on a map of
    circular obstacles while their wheels slip at random (Zhang & Karydis, target reaching).

    >>> import gymnasium as gym, koopman_envs
    >>> env = gym.make("KoopNav-TargetReaching-v0", map="map1", slip="high")
""" + _COMMON_DOC.format(
        slip_table=_SLIP_DOC,
        formation_term="",
        arguments=_arguments("target_reaching"),
        shapes=_SHAPES,
        w=_W,
        p=PARAMS,
        **_DOC_VALUES,
    )
    task_name = "target_reaching"


class FormationEnv(KoopNavEnv):
    __doc__ = """## Description
    Leader-follower formation: robot 0 leads to its target and every follower's target is the
    leader's target plus the map's formation offset; the reward also charges the formation error
    ``e_i = (p_i - p_0) - offset_i``.

    >>> import gymnasium as gym, koopman_envs
    >>> env = gym.make("KoopNav-Formation-v0", map="map3", slip="low")
""" + _COMMON_DOC.format(
        slip_table=_SLIP_DOC,
        formation_term=f"- {_W.formation:g} * ||e_i|| [m]",
        arguments=_arguments("formation"),
        shapes=_SHAPES,
        w=_W,
        p=PARAMS,
        **_DOC_VALUES,
    )
    task_name = "formation"
