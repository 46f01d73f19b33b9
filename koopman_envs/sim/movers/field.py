"""The movers of K environments in one batch (:class:`MoverField`): their state, the placement
at reset, the motion per period, the robots' contacts with them and the observation's mover
items (:func:`mover_features`).

The behaviours and their parameters are defined in :mod:`koopman_envs.settings.moving_obstacles`; the arena and
the placement are :mod:`~koopman_envs.sim.movers.placement`'s, the compiled motion
:mod:`~koopman_envs.sim.movers.motion`'s and the crowd's ORCA :mod:`~koopman_envs.sim.movers.crowd`'s.
What the field adds:

* **Clear starts.** Every mover is placed, by :data:`START_CLEARANCE` (more at high speed), clear
  of every start and target, so no episode starts with a mover on a robot or its goal.
* **Randomness.** Each environment draws from a child of its generator
  (:func:`~koopman_envs.sim.perception.child_generator`): the env's own stream (map, starts,
  slip) is untouched, so an episode with movers pairs with the same episode without. The
  waypoint draws come from a per-environment pool of uniforms refilled from that child, so a
  sub-environment of a batch draws exactly as a lone environment does.
* **Motion.** ``"constant"`` and ``"waypoints"`` run in compiled loops (numba, as the robots'
  physics); ``"crowd"`` steps one ORCA simulator (RVO2 through ``pyrvo``) per environment with
  the preferred velocities of the waypoint kernel, the static obstacles as polygons and, when
  ``aware``, the robots as agents placed where they are each period.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from koopman_envs.layout import FAR, MoverEntry
from koopman_envs.params import FAULT_STOPPED_SPEED
from koopman_envs.settings.moving_obstacles import MOVER_FEATURES, MoverConfig
from koopman_envs.sim.collision import CollisionFault, CollisionKind, mover_collisions
from koopman_envs.sim.movers.crowd import orca_restore, orca_simulator, orca_step
from koopman_envs.sim.movers.motion import (
    DRAW_SIZE,
    first_goals,
    follow_waypoints,
    move_constant,
    walker_model,
)
from koopman_envs.sim.movers.placement import PlacementError, arena_into, place_movers, place_movers_batch
from koopman_envs.sim.nearest import nearest_first_by_rank
from koopman_envs.sim.perception import child_generator
from koopman_envs.sim.rows import rows_index

__all__ = [
    "MOVER_FEATURES",
    "START_CLEARANCE",
    "MoverField",
    "mover_features",
]

#: free space between a mover and any start or target at reset [m] (ours; at least one second
#: of the mover's travel, so none reaches a robot before the robot can move)
START_CLEARANCE = 0.5


class MoverField:
    """The movers of K environments: state, random pools and (for ``"crowd"``) ORCA simulators.

    Parameters
    ----------
    num_envs : int
        Batch size K.
    config : MoverConfig
        The setting (``count`` > 0).
    n_robots : int
        Robots per environment (the aware crowd's extra agents).
    dt : float
        Control period [s].
    workspace : tuple of float
        (x_min, x_max, y_min, y_max) [m].

    Attributes
    ----------
    position, velocity : ndarray, shape (K, C, 2)
        True mover positions [m] and velocities [m/s] (world frame).
    goal : ndarray, shape (K, C, 2)
        Current waypoint of each mover (``"waypoints"``, ``"crowd"``).
    arena : ndarray, shape (K, 4)
        Each environment's arena (:func:`~koopman_envs.sim.movers.placement.mover_arena`).
    """

    def __init__(
        self,
        num_envs: int,
        config: MoverConfig,
        n_robots: int,
        dt: float,
        workspace: tuple[float, float, float, float],
    ) -> None:
        k, c = num_envs, config.count
        self.config, self.num_envs, self.count, self.n_robots = config, k, c, n_robots
        self.dt = float(dt)
        x_min, x_max, y_min, y_max = (float(v) for v in workspace)
        self.workspace = (x_min, x_max, y_min, y_max)
        self._workspace = np.array(self.workspace)
        # one array (x, y, vx, vy) per mover, so that the info's copy is one memcpy; the kernels
        # work on the two views
        self._states = np.zeros((k, c, 4))
        self.position = self._states[..., :2]
        self.velocity = self._states[..., 2:]
        self.goal = np.zeros((k, c, 2))
        self.leg_speed = np.zeros((k, c))
        self.waiting = np.zeros((k, c), dtype=np.int64)  # periods left to pause at a waypoint
        self.arena = np.zeros((k, 4))
        #: which robots touch a mover after the last step (K, N)
        self.hit = np.zeros((k, n_robots), dtype=bool)
        #: whose fault each robot's mover contacts are (K, N): a
        #: :class:`~koopman_envs.sim.collision.CollisionFault` code, NONE without a contact
        self.fault = np.zeros((k, n_robots), dtype=np.int64)
        self.radius = np.full(c, config.radius)
        self.pause_periods = int(round(config.pause / self.dt))
        #: the motion kernels' fixed terms, one record (the crowd's walkers only set velocities)
        self._model = walker_model(
            config.radius, config.speed, self.pause_periods, self.dt, config.behaviour != "crowd"
        )
        # the static obstacles as the kernels read them (set per reset: random maps change)
        self.obstacles: list[NDArray[np.float64]] = [np.zeros((0, 3))] * k
        self._obstacles = np.zeros((k, 3, 0))  # padded to the widest map's: rows x, y, radius
        self.waypoints = config.behaviour in ("waypoints", "crowd")
        self.pool_size = max(4096, 8 * c * DRAW_SIZE)
        self.pool = np.zeros((k, self.pool_size))
        self.cursor = np.full(k, self.pool_size, dtype=np.int64)
        self.rngs: list[np.random.Generator | None] = [None] * k
        self._all_rows = np.arange(k, dtype=np.int64)
        self._parents: list[np.random.Generator | None] = [None] * k
        self._orca: list[object | None] = [None] * k
        #: each environment's robot radius at its reset (a copy rebuilds ORCA's robot agents)
        self._robot_radius = np.zeros(k)
        #: the last :attr:`trail_length` positions of every mover, for drawing (a ring per
        #: environment; off, and free, until :meth:`keep_trail` turns it on)
        self.trail_length = 0
        self._trail = np.zeros((k, 0, c, 2))
        self._trail_count = np.zeros(k, dtype=np.int64)

    # ------------------------------------------------------------------ reset
    def reset_env(
        self,
        index: int,
        rng: np.random.Generator,
        obstacles: NDArray[np.float64],
        starts: NDArray[np.float64],
        targets: NDArray[np.float64],
        robot_radius: float,
    ) -> None:
        """Place environment ``index``'s movers for a new episode: :meth:`reset_envs` for one."""
        self.reset_envs(
            [index], [rng], [obstacles], np.asarray(starts)[None], np.asarray(targets)[None], robot_radius
        )

    def reset_envs(
        self,
        rows: list[int],
        rngs: list[np.random.Generator],
        obstacles: list[NDArray[np.float64]],
        starts: NDArray[np.float64],
        targets: NDArray[np.float64],
        robot_radius: float,
    ) -> None:
        """Place the movers of environments ``rows`` for their new episodes (module docstring),
        all in one pass: environment ``rows[b]`` draws from a child of ``rngs[b]`` among its
        ``obstacles[b]`` (M, 3), clear of ``starts[b]`` and ``targets[b]`` (B, N, 3), exactly as
        it would alone.

        Raises
        ------
        ValueError
            The movers do not fit in the arena clear of the map (too many or too large; or too
            fast, named when slower movers would fit: ``speed`` x 1 s is kept from every start and
            target).
        """
        cfg = self.config
        children: list[np.random.Generator] = []
        for index, rng, source in zip(rows, rngs, obstacles):
            if self._parents[index] is not rng:
                self._parents[index] = rng
                self.rngs[index] = child_generator(rng)
                self.cursor[index] = self.pool_size
            child = self.rngs[index]
            assert child is not None  # spawned above at the latest
            children.append(child)
            # a fixed map's obstacles are the same read-only array every episode: installed once
            if (
                self.obstacles[index] is not source
                or getattr(source, "flags", None) is None
                or source.flags.writeable
            ):
                self._set_obstacles(index, _as_obstacles(source))
        blocks = [self.obstacles[index] for index in rows]
        if len({block.shape for block in blocks}) > 1:  # obstacle counts differ: one at a time
            for b, index in enumerate(rows):
                self.reset_envs(
                    [index], [rngs[b]], [obstacles[b]], starts[b : b + 1], targets[b : b + 1], robot_radius
                )
            return
        # writable copies: the compiled loops take the two as one type, and a map's arrays
        # may be read-only (frozen maps)
        starts, targets = np.array(starts, dtype=np.float64), np.array(targets, dtype=np.float64)
        stacked = np.stack(blocks) if blocks else np.zeros((0, 0, 3))
        where = rows_index(rows)
        arenas = np.empty((len(rows), 4))
        for b in range(len(rows)):
            arena_into(starts[b], targets[b], stacked[b], self._workspace, arenas[b])
        self.arena[where] = arenas
        clearance = robot_radius + max(START_CLEARANCE, cfg.speed * 1.0)
        try:
            placed = place_movers_batch(
                children, cfg.count, cfg.radius, arenas, stacked, starts, targets, clearance
            )
        except PlacementError as exc:
            b = exc.row
            self._refuse_fast(exc, arenas[b], stacked[b], (starts[b], targets[b]), robot_radius, clearance)
            raise
        self.position[where] = placed
        self.waiting[where] = 0
        self.hit[where] = False
        self.fault[where] = CollisionFault.NONE
        if self.trail_length:
            self._trail_count[where] = 0
            self._record(np.asarray(rows, dtype=np.int64))
        if cfg.behaviour == "constant":
            heading = np.stack([child.uniform(-math.pi, math.pi, cfg.count) for child in children])
            self.velocity[where, :, 0] = cfg.speed * np.cos(heading)
            self.velocity[where, :, 1] = cfg.speed * np.sin(heading)
            return
        for b, index in enumerate(rows):
            self.velocity[index] = 0.0
            self.pool[index] = children[b].random(self.pool_size)
            self.cursor[index] = 0
            first_goals(
                self.position[index], self.goal[index], self.leg_speed[index], self.pool[index],
                self.cursor[index:index + 1], self.arena[index], self._obstacles[index], self._model,
            )  # fmt: skip
            if cfg.behaviour == "crowd":
                self._robot_radius[index] = robot_radius
                self._orca[index] = orca_simulator(
                    stacked[b], placed[b], cfg, self.n_robots, robot_radius, self.dt
                )

    def _refuse_fast(
        self,
        exc: ValueError,
        arena: NDArray[np.float64],
        obstacles: NDArray[np.float64],
        keep_clear: tuple[NDArray[np.float64], NDArray[np.float64]],
        robot_radius: float,
        clearance: float,
    ) -> None:
        """A placement that failed only for the speed's clearance says so (it said "use fewer or
        smaller movers" for ``speed=100``): ``ValueError`` naming the speed when the same movers
        fit at the slowest clearance; otherwise nothing (the caller re-raises ``exc``)."""
        cfg = self.config
        if cfg.speed <= START_CLEARANCE:
            return
        try:  # a private generator: the env's streams are untouched (and the episode fails anyway)
            place_movers(
                np.random.default_rng(0), cfg.count, cfg.radius, arena, obstacles, keep_clear,
                robot_radius + START_CLEARANCE,
            )  # fmt: skip
        except ValueError:
            return
        head = str(exc).split(" clear of ")[0]
        raise ValueError(
            f"{head}: movers.speed={cfg.speed!r} m/s keeps them {clearance:g} m (robot radius "
            f"{robot_radius:g} m + speed x 1 s) from every start and target; at movers.speed <= "
            f"{START_CLEARANCE:g} they fit: use a lower speed (or fewer movers, or a roomier map)"
        ) from None

    def _set_obstacles(self, index: int, obstacles: NDArray[np.float64]) -> None:
        """Install environment ``index``'s static obstacles (M, 3); :attr:`obstacles` keeps the
        array itself, so the next episode on the same map finds it installed."""
        m = obstacles.shape[0]
        if m > self._obstacles.shape[2]:  # a map with more obstacles: widen (padding reads radius 0)
            wider = np.zeros((self.num_envs, 3, m))
            wider[:, :, : self._obstacles.shape[2]] = self._obstacles
            wider[:, :2, self._obstacles.shape[2] :] = 1e6  # far away: never met
            self._obstacles = wider
        self.obstacles[index] = obstacles
        self._obstacles[index, :2], self._obstacles[index, 2] = 1e6, 0.0
        self._obstacles[index, :, :m] = obstacles.T

    def keep_trail(self, length: int) -> None:
        """Record the last ``length`` positions of every mover from now on (:meth:`trail_of`)."""
        if length != self.trail_length:
            self.trail_length = length
            self._trail = np.zeros((self.num_envs, length, self.count, 2))
            self._trail_count[:] = 0
            self._record(np.arange(self.num_envs))

    def _record(self, rows: NDArray[np.int64]) -> None:
        length = self.trail_length
        self._trail[rows, self._trail_count[rows] % length] = self.position[rows]
        self._trail_count[rows] += 1

    def trail_of(self, index: int) -> NDArray[np.float64]:
        """Environment ``index``'s recorded mover positions, oldest first, shape (T, C, 2)
        (T <= :attr:`trail_length`; the current positions alone before :meth:`keep_trail`)."""
        count, length = int(self._trail_count[index]), self.trail_length
        if length == 0 or count == 0:
            now: NDArray[np.float64] = self.position[index][None].copy()
            return now
        order = np.arange(count - min(count, length), count) % length
        recorded: NDArray[np.float64] = self._trail[index, order]  # fancy indexing: a copy
        return recorded

    # ------------------------------------------------------------------- step
    def step(
        self, robots_before: NDArray[np.float64], robots_after: NDArray[np.float64], rows: NDArray[np.int64]
    ) -> None:
        """Advance the movers of the environments in ``rows`` by one period.

        ``robots_before`` and ``robots_after`` (K, 3, N) are the robots' true poses at the
        start and the end of the period (the aware crowd sees where they are and how they move).
        """
        if self.config.behaviour == "constant":
            # the two views, not the (K, C, 4) array: the kernel ran 5-10% faster on them (measured)
            move_constant(self.position, self.velocity, rows, self._model, self.arena, self._obstacles)
        else:
            self._walk(robots_before, robots_after, rows)
        if self.trail_length:
            self._record(rows)

    def _walk(
        self, robots_before: NDArray[np.float64], robots_after: NDArray[np.float64], rows: NDArray[np.int64]
    ) -> None:
        """One period of the waypoint walkers, and of ORCA for a crowd."""
        cfg = self.config
        for k in rows:  # the few environments whose pools run low: a fresh block from their child
            if self.cursor[k] + self.count * DRAW_SIZE > self.pool_size:
                rng = self.rngs[k]
                assert rng is not None
                self.pool[k] = rng.random(self.pool_size)
                self.cursor[k] = 0
        crowd = cfg.behaviour == "crowd"
        # the walkers' tuple made here, not kept: position and velocity are views of _states,
        # which a copy or an unpickled field makes anew
        walkers = (self.position, self.velocity, self.goal, self.leg_speed, self.waiting)
        follow_waypoints(walkers, (self.pool, self.cursor), rows, self._model, self.arena, self._obstacles)
        if crowd:
            orca_step(
                self._orca,
                rows,
                self.position,
                self.velocity,
                robots_before,
                robots_after,
                cfg.aware,
                self.dt,
            )

    def meet(
        self,
        before: NDArray[np.float64],
        state: NDArray[np.float64],
        stepping: NDArray[np.bool_],
        robot_radius: NDArray[np.float64],
        collision: NDArray[np.int64],
    ) -> None:
        """Mark in :attr:`hit` the robots of ``state`` (K, 3, N) that overlap a mover and OR
        ``CollisionKind.MOVER`` into their environments' ``collision`` (K,): every environment,
        as the other collision flags, so that a finished one keeps reporting its collision.

        :attr:`fault` gets whose fault each contact is (:class:`~koopman_envs.sim.collision.CollisionFault`),
        from the robots' motion over the period, ``before`` to ``state`` (K, 3, N), in the
        environments that moved (``stepping``, (K,)); the others keep theirs (nothing moved)."""
        self.hit[:] = False
        mover_collisions(
            (before, state),
            robot_radius,
            self.position,
            self.radius,
            self._all_rows,
            stepping,
            CollisionKind.MOVER,
            FAULT_STOPPED_SPEED * self.dt,
            (collision, self.hit, self.fault),
        )

    # ------------------------------------------------------------------- read
    def states(self) -> NDArray[np.float64]:
        """Every mover's (x, y, vx, vy), shape (K, C, 4) (a copy)."""
        return self._states.copy()

    def discs(self) -> NDArray[np.float64]:
        """The movers as discs, (K, 3, C): rows x, y, radius [m] (what the lidar's beams hit)."""
        discs = np.empty((self.num_envs, 3, self.count))
        discs[:, :2] = self.position.transpose(0, 2, 1)
        discs[:, 2] = self.radius
        return discs

    def __getstate__(self) -> dict[str, object]:
        # ORCA simulators are C++ objects without pickling: the copy keeps which environments
        # had one and rebuilds them from the stored positions and velocities (__setstate__)
        state = self.__dict__.copy()
        state["_orca"] = [None] * self.num_envs
        state["_orca_live"] = [sim is not None for sim in self._orca]
        # views of _states: a copy or a pickle would make them arrays of their own, which the
        # kernels would move while the info's states() stood still; __setstate__ makes new views
        del state["position"], state["velocity"]
        return state

    def __setstate__(self, state: dict[str, object]) -> None:
        live = state.pop("_orca_live", None)
        self.__dict__.update(state)
        self.position = self._states[..., :2]
        self.velocity = self._states[..., 2:]
        if not isinstance(live, list):
            return
        for k, had in enumerate(live):
            if had:  # an episode under way: its simulator from the state (crowd.orca_restore)
                self._orca[k] = orca_restore(
                    self.obstacles[k], self.position[k], self.velocity[k], self.config, self.n_robots,
                    float(self._robot_radius[k]), self.dt,
                )  # fmt: skip


def _as_obstacles(obstacles: NDArray[np.float64]) -> NDArray[np.float64]:
    """``obstacles`` as (M, 3) float64 rows: the array itself when it is one already (a map's)."""
    if isinstance(obstacles, np.ndarray) and obstacles.dtype == np.float64 and obstacles.ndim == 2:
        if obstacles.shape[1] == 3:
            return obstacles
    return np.asarray(obstacles, dtype=np.float64).reshape(-1, 3)


# ---------------------------------------------------------------------- kernels
@njit(cache=True)
def mover_features(
    own: NDArray[np.float64],
    robot_radius: NDArray[np.float64],
    position: NDArray[np.float64],
    velocity: NDArray[np.float64],
    mover_radius: float,
    slots: int,
    at: int,
    low: NDArray[np.float64],
    high: NDArray[np.float64],
    out: NDArray[np.float64],
) -> None:  # pragma: no cover - compiled
    """Write the ``slots`` nearest movers into ``out[k, i, at:]`` (K, N, F), nearest first by
    surface clearance, each item's entries as :class:`~koopman_envs.layout.MoverEntry` names
    them: body-frame dx, dy to the centre, body-frame velocity vx, vy, clearance;
    absent ones read (0, 0, 0, 0, FAR), as do movers not observed (NaN rows: no track yet, or a
    track dropped). ``own`` (K, 3, N) holds the robots' pose estimates.

    Every mover has the one radius, so the order of the clearances is that of the squared
    centre distances (ties in index order, as :func:`~koopman_envs.sim.nearest.nearest_first` orders): one root per listed
    mover."""
    n_envs, _, n_robots = own.shape
    count = position.shape[1]
    distance2 = np.empty(count)
    order = np.empty(count, dtype=np.int64)
    for k in range(n_envs):
        # a mover not observed (a NaN row: no confirmed track) is not listed
        observed = 0
        for m in range(count):
            observed += not math.isnan(position[k, m, 0])
        listed = min(observed, slots)
        for i in range(n_robots):
            x, y, theta = own[k, 0, i], own[k, 1, i], own[k, 2, i]
            c, s = math.cos(theta), math.sin(theta)
            for m in range(count):
                dx, dy = position[k, m, 0] - x, position[k, m, 1] - y
                distance2[m] = dx * dx + dy * dy if not math.isnan(dx) else math.inf
            nearest_first_by_rank(distance2, order, count)
            col = at
            reach = robot_radius[i] + mover_radius
            for q in range(listed):
                m = order[q]
                dx, dy = position[k, m, 0] - x, position[k, m, 1] - y
                vx, vy = velocity[k, m, 0], velocity[k, m, 1]
                gap = math.sqrt(distance2[m]) - reach
                e = col + MoverEntry.DX
                out[k, i, e] = min(max(c * dx + s * dy, low[e]), high[e])
                e = col + MoverEntry.DY
                out[k, i, e] = min(max(c * dy - s * dx, low[e]), high[e])
                e = col + MoverEntry.VX
                out[k, i, e] = min(max(c * vx + s * vy, low[e]), high[e])
                e = col + MoverEntry.VY
                out[k, i, e] = min(max(c * vy - s * vx, low[e]), high[e])
                e = col + MoverEntry.CLEARANCE
                out[k, i, e] = min(max(gap, low[e]), high[e])
                col += MOVER_FEATURES
            for _ in range(listed, slots):
                for f in range(MOVER_FEATURES):
                    out[k, i, col + f] = 0.0
                out[k, i, col + MoverEntry.CLEARANCE] = FAR
                col += MOVER_FEATURES
