"""The plant: the robots' motion, kinematic or physical, in the engine's step and in the
calibration plant that twins an environment's robots for controllers that learn.

**The engine's plant pass.** :func:`make_physics` builds the physics plant's worlds
(``plant="mujoco"``; None on the kinematic plant) and :func:`advance_plant` runs one control
period on whichever plant the engine has: the paper's unicycle with drawn slip
(:func:`~koopman_envs.sim.dynamics.advance_teams`, after the slip zones' pass) or the MuJoCo
robots (:meth:`~koopman_envs.sim.physics.world.PhysicsWorld.advance`).

**The calibration plant**: an environment's robots without the task. A controller that needs data about the robots it will drive (a learned prediction model, a
measured prediction error) gets it here, as it would on real robots: it puts teams at poses of
its choosing, sends commands of its choosing and observes the poses that result. The plant is an
open field (no obstacles, targets, collisions or episode ends) with the same unicycle kinematics,
RK4 period and slip process as the environment it twins; it never reveals the slip means. On the
physics plant (``plant="mujoco"``) the teams are the environment's MuJoCo robots on its floor
(each team's frictions drawn when it is placed), and the motors' limits bound what the
commands achieve.
The slip process is the environment's base level over time: its setting, one random level per
team (``slip="random"``), a listed schedule counted from each :meth:`CalibrationPlant.reset` or
:meth:`CalibrationPlant.rollout`, or drift (``slip="drift"``, the same law, drawn per team). Slip
zones are features of a map, and the plant has no map: it does not model them.

Every simulated period of every team counts against a budget of team-transitions, the same for
every controller (default: the paper's 1000 trajectories x 1000 periods), so a comparison can
state exactly how much data each controller used::

    from koopman_envs import make_plant
    plant = make_plant("KoopNav-Formation-v0", slip="high", budget=1_000_000, seed=0)
    plant.reset(start_poses)                  # (B, N, 3)
    poses = plant.step(commands)              # (B, N, 2) -> (B, N, 3), B transitions spent
    states = plant.rollout(start, commands)   # (T, B, N, 2) -> (T + 1, B, N, 3), T * B spent
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from koopman_envs.checks import check_int
from koopman_envs.engine.config import EngineConfig
from koopman_envs.params import DRIFT_MEAN_INTERVAL, PARAMS, PHYSICS, RANDOM_SLIP_MAX
from koopman_envs.sim.dynamics import advance_teams
from koopman_envs.sim.rollout import rollout
from koopman_envs.sim.slip.sampling import draw_random_lambdas
from koopman_envs.tasks.base import task_for_env

__all__ = [
    "BudgetExceeded",
    "CalibrationPlant",
    "DYNAMICS_VERSION",
    "advance_plant",
    "make_physics",
    "make_plant",
]

#: Bump when the simulated kinematics or slip process change: it is part of every plant
#: signature, so cached calibrations of the old dynamics are not reused.
DYNAMICS_VERSION = 1

# The plant's slip draws come from their own stream of the seed, so a controller that draws its
# inputs from ``default_rng(seed)`` does not correlate them with the slip.
_SLIP_STREAM = 0x534C4950  # "SLIP"


def make_physics(config: EngineConfig, num_envs: int, *, open_field: bool = False) -> Any:
    """The :class:`~koopman_envs.sim.physics.world.PhysicsWorld` of ``num_envs`` environments
    of ``config``, or None on the kinematic plant (MuJoCo is imported only here, for
    ``plant="mujoco"``); with ``open_field``, the calibration plant's: no obstacles, no zones."""
    if config.plant != "mujoco":
        return None
    from koopman_envs.sim.physics.world import PhysicsWorld

    assert config.floor is not None  # EngineConfig sets the floor of every physics config
    return PhysicsWorld(
        num_envs,
        config.n_robots,
        0 if open_field else config.n_obstacles,
        0 if open_field else config.n_slip_zones,
        float(np.max(config.robot_radius)),
        config.floor,
    )


def advance_plant(
    engine: Any, commands: NDArray[np.float64], active: NDArray[np.bool_] | None
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The poses (K, 3, N) one period after ``engine.state`` under ``commands`` (K, N, 2), and
    the commands' effort (K, N), for the ``active`` environments (None: all) of ``engine`` (a
    :class:`~koopman_envs.engine.engine.NavigationEngine`; typed ``Any`` so that the two
    modules do not import each other)."""
    stepping = engine.all_active if active is None else active
    new = np.empty_like(engine.state)
    effort = np.empty(engine.distances.shape)
    limits = (engine.command_low, engine.command_high, engine.effort_scale)
    if engine.physics is not None:
        engine.physics.advance(engine.state, commands, stepping, *limits, new, effort)
        return new, effort
    slip = engine.slip
    slip.prepare(active)
    # one branch per step: maps without zones scale the draws by the base levels directly
    means = slip.lambdas
    if engine.zones is not None:
        means = engine.zones.slip_means(engine.state, slip.lambdas, engine.zone_means)
    advance_teams(
        engine.state, commands, slip.unit, slip.cursor, means, stepping, limits, PARAMS.dt, new, effort
    )
    return new, effort


class BudgetExceeded(RuntimeError):
    """A request would spend more team-transitions than the plant's budget has left."""


class CalibrationPlant:
    """A batched open-field twin of an environment's robots (see the module docstring).

    Parameters
    ----------
    config : EngineConfig
        The environment's validated configuration (team size and slip process are used).
    budget : int
        Team-transitions this plant may simulate in total (>= 1).
    seed : int
        Seed of the plant's slip draws (>= 0).

    Attributes
    ----------
    n_robots : int
        Team size N.
    dt : float
        Control period [s].
    v_max, omega_max : float
        The environment's actuation limits [m/s], [rad/s]. The plant applies commands as given
        (the paper's identification data excite the robots beyond them).
    budget, used : int
        Team-transitions allowed and spent.
    signature : str
        Opaque hash of everything that determines the plant's behaviour (team size, period, slip
        process, dynamics version): a cache key for calibrations, not a way to read the slip.
    """

    def __init__(self, config: EngineConfig, budget: int, seed: int = 0) -> None:
        self.budget = check_int("budget", budget, 1)
        self.seed = check_int("seed", seed, 0)
        self.n_robots = config.n_robots
        self.dt = PARAMS.dt
        self.v_max, self.omega_max = PARAMS.v_max, PARAMS.omega_max
        self.used = 0
        self._random_slip = config.random_slip
        self._schedule = config.slip_schedule
        self._lambdas = None if config.random_slip or self._schedule is not None else config.lambdas.copy()
        self._rng = np.random.default_rng(np.random.SeedSequence(self.seed, spawn_key=(_SLIP_STREAM,)))
        self._poses: NDArray[np.float64] | None = None
        #: slip means of the next period, (N,) or (B, N)
        self._team_lambdas: NDArray[np.float64] | None = None
        self._clock = 0  # periods since the teams' reset (slip schedules)
        slip: Any = "random" if config.random_slip else [float(v) for v in config.lambdas]
        if self._schedule is not None:
            slip = self._schedule.describe()
        blob = {"n_robots": self.n_robots, "dt": self.dt, "slip": slip, "dynamics": DYNAMICS_VERSION}
        if config.random_slip:
            blob["random_slip_max"] = RANDOM_SLIP_MAX
        self._config = config
        #: the physics plant's worlds of the teams of the last reset; None on the kinematic plant
        self._world: Any = None
        if config.plant == "mujoco":
            blob.update(plant=config.plant, floor=config.floor, physics=dataclasses.asdict(PHYSICS))
        self.signature = hashlib.sha256(json.dumps(blob, sort_keys=True).encode()).hexdigest()[:16]

    @property
    def remaining(self) -> int:
        """Team-transitions still available."""
        return self.budget - self.used

    def _spend(self, transitions: int) -> None:
        if transitions > self.remaining:
            raise BudgetExceeded(
                f"the request needs {transitions} team-transitions but only {self.remaining} of the "
                f"calibration budget of {self.budget} remain"
            )
        self.used += transitions

    def _check_poses(self, poses: Any, what: str) -> NDArray[np.float64]:
        arr = np.asarray(poses, dtype=np.float64)
        if arr.ndim != 3 or arr.shape[1:] != (self.n_robots, 3) or arr.shape[0] < 1:
            raise ValueError(f"{what} has shape {arr.shape}; expected (B, {self.n_robots}, 3) with B >= 1")
        if not np.isfinite(arr).all():
            raise ValueError(f"{what} contains NaN or inf")
        return arr

    def _slip_for(self, batch: int) -> NDArray[np.float64]:
        """Slip means of the first period of ``batch`` new teams: fixed, one random level per
        team, the schedule's first levels or a drift draw per team."""
        schedule = self._schedule
        if schedule is not None:
            if schedule.drift:
                return self._rng.uniform(0.0, RANDOM_SLIP_MAX, (batch, self.n_robots))
            return np.broadcast_to(schedule.levels[0], (batch, self.n_robots)).copy()
        if not self._random_slip:
            # __init__ keeps the lambdas exactly when the slip is neither random nor scheduled
            assert self._lambdas is not None
            return self._lambdas
        return np.stack([draw_random_lambdas(self._rng, self.n_robots) for _ in range(batch)])

    def _next_levels(self, levels: NDArray[np.float64], clock: int) -> NDArray[np.float64]:
        """Slip means (B, N) of the period ``clock`` after a reset, from those of the one before.

        Drift: every robot's level is redrawn with probability 1 - exp(-dt / mean interval) per
        period, which is the environment's Poisson process of changes seen at the periods'
        starts (the number of changes in one period is Poisson, and only the last one counts).
        """
        schedule = self._schedule
        if schedule is None:
            return levels
        if not schedule.drift:
            return np.broadcast_to(schedule.levels_at(clock * self.dt), levels.shape).copy()
        switch = self._rng.uniform(size=levels.shape) < -math.expm1(-self.dt / DRIFT_MEAN_INTERVAL)
        return np.where(switch, self._rng.uniform(0.0, RANDOM_SLIP_MAX, levels.shape), levels)

    def reset(self, poses: NDArray[np.float64]) -> None:
        """Put B teams at the given poses, shape (B, N, 3); costs no budget."""
        self._poses = self._check_poses(poses, "poses").copy()
        if self._config.plant == "mujoco":  # teams at rest on an open floor, their frictions drawn
            self._world = make_physics(self._config, len(self._poses), open_field=True)
            for team, pose in enumerate(self._poses):
                self._world.reset_env(team, self._rng, pose, np.zeros((0, 3)))
        self._team_lambdas = self._slip_for(self._poses.shape[0])
        self._clock = 0

    def step(self, commands: NDArray[np.float64]) -> NDArray[np.float64]:
        """Apply one period of commands (B, N, 2) to the teams of the last :meth:`reset`.

        Returns the poses one period later, shape (B, N, 3); spends B team-transitions. A
        sequence of steps gives the same poses as one :meth:`rollout` of the same commands.
        """
        if self._poses is None:
            raise RuntimeError("call reset(poses) before step()")
        # reset() and rollout(), which set the poses, set the teams' slip means with them
        assert self._team_lambdas is not None
        commands = np.asarray(commands, dtype=np.float64)
        if commands.shape != self._poses.shape[:2] + (2,):
            raise ValueError(f"commands has shape {commands.shape}; expected {self._poses.shape[:2] + (2,)}")
        if self._world is not None:
            self._check_and_spend(commands[None])
            self._poses = self._physics_step(self._poses, commands)
        else:
            self._poses = self._simulate(self._poses, commands[None], self._team_lambdas)[1]
        self._clock += 1
        self._team_lambdas = self._next_levels(self._team_lambdas, self._clock)
        return self._poses.copy()

    def rollout(self, start: NDArray[np.float64], commands: NDArray[np.float64]) -> NDArray[np.float64]:
        """Reset B teams to ``start`` (B, N, 3) and apply ``commands`` (T, B, N, 2) open loop.

        Returns the poses at every period, shape (T + 1, B, N, 3); spends T * B team-transitions.
        """
        start = self._check_poses(start, "start")
        commands = np.asarray(commands, dtype=np.float64)
        if commands.ndim != 4 or commands.shape[1:] != start.shape[:2] + (2,):
            raise ValueError(f"commands has shape {commands.shape}; expected (T,) + {start.shape[:2] + (2,)}")
        if self._config.plant == "mujoco":  # period by period, as a sequence of step() calls
            self._check_and_spend(commands)
            self.reset(start)
            states = np.empty((commands.shape[0] + 1, *start.shape))
            states[0] = start
            for t, command in enumerate(commands):
                states[t + 1] = self._poses = self._physics_step(states[t], command)
            self._clock = commands.shape[0]
            return states
        lambdas = self._slip_for(start.shape[0])
        steps = commands.shape[0]
        if self._schedule is None:
            states = self._simulate(start, commands, lambdas)
        else:
            # period by period, drawing as a sequence of step() calls does: the period's slip,
            # then the next period's levels
            self._check_and_spend(commands)
            states = np.empty((steps + 1, *start.shape))
            states[0] = start
            for t in range(steps):
                states[t + 1] = rollout(states[t], commands[t : t + 1], lambdas, self._rng, dt=self.dt)[1]
                lambdas = self._next_levels(lambdas, t + 1)
        self._poses, self._team_lambdas, self._clock = states[-1].copy(), lambdas, steps
        return states

    def _physics_step(self, poses: NDArray[np.float64], commands: NDArray[np.float64]) -> NDArray[np.float64]:
        """One period of the physics plant's teams from ``poses`` (B, N, 3): the commands go to
        the wheels as given (only the motors' limits bound them), as the kinematic plant applies them."""
        state = np.ascontiguousarray(poses.transpose(0, 2, 1))
        new, effort = np.empty_like(state), np.empty(poses.shape[:2])
        unbounded, unit = np.full(2, np.inf), np.ones(2)
        everyone = np.ones(len(poses), dtype=bool)
        self._world.advance(state, commands, everyone, -unbounded, unbounded, unit, new, effort)
        return new.transpose(0, 2, 1).copy()

    def _check_and_spend(self, commands: NDArray[np.float64]) -> None:
        if not np.isfinite(commands).all():
            raise ValueError("commands contain NaN or inf")
        self._spend(commands.shape[0] * commands.shape[1])

    def _simulate(
        self, start: NDArray[np.float64], commands: NDArray[np.float64], lambdas: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        self._check_and_spend(commands)
        return rollout(start, commands, lambdas, self._rng, dt=self.dt)


def make_plant(
    env: Any, *, budget: int = PARAMS.calibration_budget, seed: int = 0, **env_kwargs: Any
) -> CalibrationPlant:
    """The calibration plant of an environment.

    Parameters
    ----------
    env : str or env
        A registered env id (then ``env_kwargs`` are its keyword arguments, validated as
        ``gym.make`` would), or an env of any front (wrapped or not), whose settings are used.
    budget : int
        Team-transitions allowed (default: the paper's 1000 x 1000).
    seed : int
        Seed of the plant's slip draws.
    """
    if isinstance(env, str):
        kwargs = {k: v for k, v in env_kwargs.items() if k != "render_mode"}
        # the plant has no map: without one, do not hold the team size to a default map's starts
        kwargs.setdefault("map", "random")
        config = EngineConfig.create(task_for_env(env).name, **kwargs)
    else:
        if env_kwargs:
            raise ValueError(
                f"env keyword arguments {sorted(env_kwargs)} go with an env id, not an env instance"
            )
        found = getattr(getattr(env, "unwrapped", env), "config", None)
        if not isinstance(found, EngineConfig):
            raise ValueError(f"{type(env).__name__} is not a KoopNav environment (no EngineConfig)")
        config = found
    return CalibrationPlant(config, budget, seed)
